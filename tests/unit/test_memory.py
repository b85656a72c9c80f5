"""The incremental history of eq (19) against its direct sum."""
import math

import numpy as np
import pytest
from mpi4py import MPI

from contactvisco.model.memory_kernel import memory_terms
from contactvisco.fem import geometry, problem as problem_module
from contactvisco.scene import loader as scene_module
from contactvisco.model.memory import DirectHistory, History, direct_sum, prony
from contactvisco.solver.newton import BlockSNES

KERNELS = {
    "constant": [(100.0, math.inf, "full")],
    "exponential": [(30.0, 0.25, "full")],
    "prony": [(30.0, 0.05, "full"), (5.0, 2.0, "full"), (1.0, math.inf, "full")],
    "prony-parts": [(30.0, 0.05, "deviatoric"), (5.0, 2.0, "volumetric"),
                    (-2.0, math.inf, "deviatoric"), (1.0, 0.3, "full")],
}


@pytest.mark.parametrize("name", KERNELS)
@pytest.mark.parametrize("k", [0.1, 0.013])
def test_incremental_equals_direct_sum(name, k):
    terms = KERNELS[name]
    rng = np.random.default_rng(7)
    strains = [rng.standard_normal(12) for _ in range(40)]     # three 2 x 2 strain blocks
    history = History(terms, k, "paper", d=2)
    for n in range(1, len(strains) + 1):
        incremental = history.advance(strains[n - 1])     # H_n from eps_0 .. eps_{n-1}
        exact = direct_sum(prony(terms, 2), k, strains[:n])
        assert np.max(np.abs(incremental - exact)) <= 1e-12 * np.max(np.abs(exact))


def test_weights_of_eq19():
    """k/2 on eps_0, k on eps_1..eps_{n-2}, 3k/2 on eps_{n-1} (constant kernel, alpha = 1);
    k on eps_0 at n = 1."""
    k = 0.1
    history = History([(1.0, math.inf, "full")], k)
    unit = np.eye(5)
    assert np.allclose(history.advance(unit[0]), k * unit[0])
    for n in range(2, 6):
        H = history.advance(unit[n - 1])
        expected = np.array([k / 2] + [k] * (n - 2) + [1.5 * k] + [0.0] * (5 - n))
        assert np.allclose(H, expected, atol=1e-15)


@pytest.mark.mpi
def test_history_function_in_a_run():
    """The DG0 history stress Function after n steps of the paper scene equals the direct sum
    of eq (19) over the strains of the converged steps."""
    scene = scene_module.load("paper", ["geometry.cells=[8, 8]", "time.steps=5",
                                        "memory.kernel='exponential'", "memory.alpha=[80.0]",
                                        "memory.tau=[0.3]"])
    geo = geometry.build(scene, MPI.COMM_WORLD)
    problem = problem_module.build(scene, geo)
    snes = BlockSNES(problem.F, problem.J, problem.unknowns, problem.bcs, MPI.COMM_WORLD)
    terms = memory_terms(scene)
    k = scene["time"]["T"] / scene["time"]["steps"]
    strains = []
    memory = problem.memory
    for n in range(scene["time"]["steps"] + 1):
        problem.time.stage(n * k)
        if n > 0:
            strains.append(memory.eps_function.x.array.copy())     # eps(u_{n-1}), committed
            exact = direct_sum(prony(terms, 2), k, strains)
            assert np.max(np.abs(memory.H.x.array - exact)) <= 1e-12 * np.max(np.abs(exact))
        snes.solve()
        problem.time.commit()
    assert len(strains) == 5 and np.max(np.abs(strains[-1])) > 1e-3


@pytest.mark.parametrize("rule", ["paper", "trapezoid"])
@pytest.mark.parametrize("name", ["constant", "prony-parts"])
def test_non_uniform_steps_equal_the_direct_sum(rule, name):
    """Steps of any sizes (as step cutting makes them): the incremental history equals eq (19)
    with the trapezoid weights of the non-uniform grid, to round-off. A rejected step may be
    prepared again with another size."""
    terms = KERNELS[name]
    rng = np.random.default_rng(11)
    steps = rng.uniform(0.01, 0.2, 25)
    history = History(terms, rule=rule, d=2)
    times, strains = [], []
    t = 0.0
    for n, k in enumerate(steps):
        eps = rng.standard_normal(12)
        history.commit(eps, None if n == 0 else steps[n - 1])
        times.append(t)
        strains.append(eps)
        history.explicit(3 * k)                      # a rejected attempt changes nothing
        exact = direct_sum(prony(terms, 2), times, strains, t + k, rule)
        assert np.max(np.abs(history.explicit(k) - exact)) <= 1e-12 * np.max(np.abs(exact))
        t += k
    table = DirectHistory(lambda s: 7.0 * math.exp(-s / 0.3), rule=rule)
    for n, (eps, k) in enumerate(zip(strains, steps)):
        table.commit(eps, None if n == 0 else steps[n - 1])
    recursion = History([(7.0, 0.3, "full")], rule=rule, d=2)
    for n, eps in enumerate(strains):
        recursion.commit(eps, None if n == 0 else steps[n - 1])
    assert np.allclose(table.explicit(0.05), recursion.explicit(0.05), rtol=1e-12, atol=0)
