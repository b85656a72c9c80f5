"""linear_solver = "auto" with the iterative solver for the first state and the direct one,
with its kept factors, for the states after it (newton.AUTO_DIRECT_LATER), and back to the
iterative one where the direct one factorizes in every step (newton.LATER_FACTORIZATIONS).
The thresholds are lowered so that small meshes take these paths. Whatever solver a state
takes, the contact values are the direct solver's to the Newton tolerance, on 1 and 2 ranks.
"""
import re

import numpy as np
import pytest
from mpi4py import MPI

from contactvisco.fem import geometry, problem as problem_module
from contactvisco.scene import loader as scene_module
from contactvisco.solver import newton as solver_module
from contactvisco.solver.check import check
from contactvisco.solver.time_loop import simulate
from helpers import run_stopped_after_checkpoint

#: BoomerAMG where PETSc has hypre, else GAMG.
AMG = "gmres/" + solver_module.iterative_options()["pc_type"]

PAPER = ["geometry.cells=[24, 24]", "time.T=0.6", "time.steps=6"]
IRONING = ["geometry.parameters.h=0.03", "time.T=0.4", "time.steps=8"]
KEYS = ("u_nu", "u_tau", "lambda_nu", "reaction_nu", "reaction_tau")


@pytest.fixture
def small_thresholds(monkeypatch):
    """auto iterative from 10 u unknowns in 2D, the later states direct below 10^6."""
    for name in ("AUTO_ITERATIVE", "AUTO_ITERATIVE_GAMG"):
        monkeypatch.setitem(getattr(solver_module, name), 2, 10)
    monkeypatch.setitem(solver_module.AUTO_DIRECT_LATER, 2, 10**6)


def _scene(name, sets, linear_solver="auto"):
    scene = scene_module.load(name, sets + [f"solver.linear_solver='{linear_solver}'",
                                            "output.figures=false"])
    scene["output"]["probes"] = []
    return scene


def _run(name, sets, linear_solver="auto", **kwargs):
    return simulate(_scene(name, sets, linear_solver), comm=MPI.COMM_WORLD, progress=False,
                    keep_tables=True, **kwargs)


def _assert_same_contact(a, b, steps=None):
    """The contact values of two runs agree at every step (or at the last `steps`) to well
    within the Newton tolerance, relative to the largest value of each kind."""
    n = steps or len(a.tables)
    assert len(a.tables) >= n and len(b.tables) == n
    pairs = list(zip(a.tables[-n:], b.tables))
    assert pairs
    for ta, tb in pairs:
        for key in KEYS:
            scale = max(np.max(np.abs(ta[key])), 1e-12)
            assert np.max(np.abs(np.asarray(ta[key]) - tb[key])) <= 1e-8 * scale, key


@pytest.mark.mpi
def test_auto_takes_the_direct_solver_after_the_first_state(small_thresholds):
    """The first state is solved by the iterative solver (its Newton iterations are the
    iterative run's), the later ones by the direct solver with kept factors: their Newton
    iterations are the direct run's, and they factorize less than once per step."""
    auto = _run("paper", PAPER)
    direct = _run("paper", PAPER, "direct")
    iterative = _run("paper", PAPER, "iterative")
    assert auto.linear_solver == f"{AMG}; after the first state preonly/lu"
    assert check(_scene("paper", PAPER))["linear_solver"].startswith(auto.linear_solver)
    newton = [[s["newton_iterations"] for s in r.steps] for r in (auto, direct, iterative)]
    assert newton[0][0] == newton[2][0]
    assert newton[0][1:] == newton[1][1:]
    setups = [s["preconditioner_setups"] for s in auto.steps[1:]]
    assert sum(setups) <= 2 + solver_module.LATER_FACTORIZATIONS * len(setups)
    _assert_same_contact(auto, direct)
    _assert_same_contact(auto, iterative)


@pytest.mark.mpi
def test_the_direct_solver_gives_way_where_each_step_factorizes(small_thresholds):
    """On the ironing scene the load moves along the contact boundary: each later step
    changes more rows than the kept factors serve, the direct solver factorizes in nearly
    every Newton iteration and auto goes back to the iterative solver at the first step past
    the budget of LATER_FACTORIZATIONS per step beyond two; the answer stays the direct
    run's."""
    auto = _run("ironing", IRONING)
    direct = _run("ironing", IRONING, "direct")
    found = re.fullmatch(rf"{AMG}; after the first state preonly/lu; after (\d+) solves "
                         rf"{AMG}", auto.linear_solver)
    assert found, auto.linear_solver
    solves = int(found.group(1))
    setups = np.cumsum([s["preconditioner_setups"] for s in auto.steps[1:1 + solves]])
    budget = 2 + solver_module.LATER_FACTORIZATIONS * np.arange(1, solves + 1)
    assert setups[-1] > budget[-1] and np.all(setups[:-1] <= budget[:-1])
    assert 1 + solves < len(auto.steps)       # states were left for the iterative solver
    _assert_same_contact(auto, direct)


@pytest.mark.mpi
def test_a_restart_continues_with_the_later_states_solver(small_thresholds, tmp_path_factory,
                                                          monkeypatch):
    """A run stopped after its checkpoint of 3 states and restarted solves its first state
    (a later one) with the direct solver, and ends at the uninterrupted run's answer."""
    comm = MPI.COMM_WORLD
    folders = [comm.bcast(str(tmp_path_factory.mktemp(name)) if comm.rank == 0 else None)
               for name in ("whole", "stopped")]
    scene = _scene("paper", PAPER)
    whole = simulate(scene, out=folders[0], comm=comm, progress=False, keep_tables=True)
    run_stopped_after_checkpoint(monkeypatch, 3, lambda: simulate(
        scene, out=folders[1], comm=comm, progress=False))
    restarted = simulate(scene, out=folders[1], comm=comm, progress=False, restart=True,
                         keep_tables=True)
    assert restarted.linear_solver == "preonly/lu"
    assert len(restarted.steps) == len(whole.steps) - 3
    _assert_same_contact(whole, restarted, steps=len(restarted.steps))


@pytest.mark.parametrize("sets, later", [
    ([], "preonly/lu"),
    (["time.grid='logarithmic'", "time.first=0.01", "time.per_decade=4"], AMG),
    (["material.law='hencky'"], AMG),
    (["solver.linear_solver='iterative'"], AMG),
    (["solver.linear_solver='direct'"], "preonly/lu"),
])
def test_which_solver_the_later_states_take(small_thresholds, sets, later):
    """auto's direct solver for the later states only where the Newton matrix stays the same
    from step to step at a fixed contact state: not on a grid of varying steps nor with a
    nonlinear bulk law; a solver the scene names is kept for every state."""
    scene = scene_module.load("paper", ["geometry.cells=[4, 4]", *sets])
    problem = problem_module.build(scene, geometry.build(scene, MPI.COMM_WORLD))
    first = solver_module.create(problem, MPI.COMM_WORLD)
    named = scene["solver"]["linear_solver"] == "direct"
    first_solver = first.linear_solver()
    assert first_solver == ("preonly/lu" if named else AMG)
    for_later = solver_module.for_later_states(problem, MPI.COMM_WORLD, first)
    assert for_later.linear_solver() == later and for_later.later
    assert (for_later is first) == (later == first_solver)
    assert for_later.auto_direct == (for_later is not first)
    for_later.destroy()
    problem.release_garbage()
