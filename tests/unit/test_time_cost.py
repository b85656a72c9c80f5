"""O(1) memory of the history recursion: for the constant and exponential kernels the state
kept between steps (the sums P_i,n and the last strain parts of contactvisco/memory.py) has the
same size after 5 and after 50 steps; the table kernel, summed directly, keeps every strain, so
its state grows by one strain array per step. benchmarks/performance/time_linearity.py times
the same contrast. (The recursion equals the direct sum of eq (19): tests/unit/test_memory.py.)"""
import math

import numpy as np
import pytest
from mpi4py import MPI

from contactvisco.fem import geometry, problem as problem_module
from contactvisco.scene import loader as scene_module
from contactvisco.model.memory import DirectHistory, History, table_kernel

ALPHA, TAU = 100.0, 0.2
RECURSIVE = {
    "constant": [(ALPHA, math.inf, "full")],
    "exponential": [(ALPHA, TAU, "full")],
    "prony": [(ALPHA, TAU, "deviatoric"), (10.0, math.inf, "volumetric")],
}
SCENE_KERNELS = {
    "constant": ["memory.kernel='constant'", f"memory.alpha={ALPHA}"],
    "exponential": ["memory.kernel='exponential'", f"memory.alpha=[{ALPHA}]",
                    f"memory.tau=[{TAU}]"],
    "table": ["memory.kernel='table'", "memory.times=[0.0, 0.5, 1.0]",
              f"memory.values=[{ALPHA}, {ALPHA * math.exp(-0.5 / TAU)}, "
              f"{ALPHA * math.exp(-1.0 / TAU)}]"],
}


def footprint(history):
    """(number of arrays, total bytes) of the state a history keeps between steps."""
    arrays = [np.asarray(a) for a in history.state().values()]
    return len(arrays), sum(a.nbytes for a in arrays)


def commit_steps(history, strains, k):
    """Commit the strains of uniform steps of size k (the first at t_0 if nothing is
    committed yet), preparing each next step."""
    for eps in strains:
        history.commit(eps, None if history.sums is None else k)
        history.explicit(k)


@pytest.mark.parametrize("name", RECURSIVE)
def test_recursive_history_state_does_not_grow(name):
    rng = np.random.default_rng(3)
    strains = [rng.standard_normal(12) for _ in range(50)]     # three 2 x 2 strain blocks
    history = History(RECURSIVE[name], 0.02, "paper", d=2)
    commit_steps(history, strains[:5], 0.02)
    after_5 = footprint(history)
    commit_steps(history, strains[5:], 0.02)
    assert footprint(history) == after_5
    # one sum per term and one strain per distinct part, each of the size of one strain
    parts = {part for _, _, part in RECURSIVE[name]}
    assert after_5 == (len(RECURSIVE[name]) + len(parts),
                       (len(RECURSIVE[name]) + len(parts)) * strains[0].nbytes)


def test_table_history_state_grows_by_one_strain_per_step():
    rng = np.random.default_rng(3)
    strains = [rng.standard_normal(12) for _ in range(50)]
    history = DirectHistory(table_kernel([0.0, 1.0], [ALPHA, ALPHA * math.exp(-1.0 / TAU)]),
                            0.02)
    sizes = {}
    for n, eps in enumerate(strains, start=1):
        history.commit(eps, None if n == 1 else 0.02)
        history.explicit(0.02)
        sizes[n] = footprint(history)
    for n in (5, 50):        # n strains and the n times t_0 .. t_{n-1}
        assert sizes[n] == (1 + n, n * strains[0].nbytes + np.zeros(n).nbytes)


@pytest.mark.parametrize("kernel", SCENE_KERNELS)
def test_history_state_of_a_problem(kernel):
    """The same on the DG history field of the paper scene (8 x 8, any number of ranks): 5 and
    50 steps of commit + prepare on a nonzero displacement."""
    scene = scene_module.load("paper", ["geometry.cells=[8, 8]", "time.steps=50"]
                              + SCENE_KERNELS[kernel])
    problem = problem_module.build(scene, geometry.build(scene, MPI.COMM_WORLD))
    history = problem.memory.history
    assert history.direct == (kernel == "table")
    problem.u.interpolate(lambda x: np.stack([0.01 * x[0] * x[1], -0.02 * x[1] ** 2]))
    k = scene["time"]["T"] / scene["time"]["steps"]
    local = problem.memory.eps_function.x.array.nbytes
    sizes = {}
    for n in range(1, 51):
        problem.time.record(None if n == 1 else k)
        problem.time.prepare(k)
        sizes[n] = footprint(history)
    assert np.max(np.abs(problem.memory.H.x.array)) > 0
    if kernel == "table":
        for n in (5, 50):
            assert sizes[n][0] == 1 + n
            assert sizes[n][1] == n * local + np.zeros(n).nbytes
    else:
        assert sizes[50] == sizes[5] == (2, 2 * local)
