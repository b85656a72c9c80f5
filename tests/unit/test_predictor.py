"""Where Newton starts and what it factorizes, checked as pieces and on the paper scene:

- the extrapolation of the last two accepted states is exact for unknowns linear in time,
  with unequal step sizes (a cut step's halves);
- the bound's reaction, extrapolated in its square inside the zone at the bound, follows an
  edge moving at a steady speed exactly, releasing the nodes it passes; which nodes lie
  inside that zone is found on 1 and 2 ranks; at 128^2 cells it saves Newton iterations
  and changes no converged state;
- a prediction changes how many iterations a step takes, not the state it converges to;
- a step whose Newton fails from the prediction is solved from the last accepted state,
  without a cut;
- the linear solver's operator is replaced (and its preconditioner rebuilt) only when the
  assembled Newton matrix differs from it, bit for bit.
"""
from types import SimpleNamespace

import pytest

import numpy as np
from mpi4py import MPI

from contactvisco import load_scene, solve
from contactvisco.fem import geometry as geometry_module
from contactvisco.fem.problem import build
from contactvisco.solver import newton as solver_module
from contactvisco.solver import predictor as predictor_module
from contactvisco.solver.newton import NewtonFailure
from contactvisco.solver.time_loop import advance

SMALL = {"geometry": {"cells": [12, 12]}, "output": {"probes": []}}


def _function(values):
    return SimpleNamespace(x=SimpleNamespace(array=np.array(values, dtype=float)))


def test_extrapolation_is_exact_for_unknowns_linear_in_time():
    a, b = np.array([1.0, -2.0, 0.5]), np.array([0.3, 4.0, -1.0])
    unknowns = [_function(a), _function(b)]
    predict = predictor_module.Extrapolation(unknowns)
    for t in (0.0, 0.1):                             # accepted states w(t) = w0 + t v
        unknowns[0].x.array[:] = a + t * b
        unknowns[1].x.array[:] = b - 3 * t * a
        predict.record(t)
        assert not predict.apply(0.2) or t == 0.1
    assert predict.apply(0.15)                       # half a step, as after a cut
    assert np.allclose(unknowns[0].x.array, a + 0.15 * b, rtol=0, atol=1e-14)
    assert np.allclose(unknowns[1].x.array, b - 0.45 * a, rtol=0, atol=1e-14)
    predict.record(0.15)                             # states at 0.1 and 0.15: step 0.05
    assert predict.apply(0.35)
    assert np.allclose(unknowns[0].x.array, a + 0.35 * b, rtol=0, atol=1e-14)


def test_the_reaction_square_follows_a_steadily_moving_edge():
    """R(x, t) = c sqrt(x - a(t)) for x > a(t), the edge a moving at a steady speed: the
    extrapolation of R^2 gives R(t_2) wherever the edge has not reached the node, and a
    positive lambda (a node off the bound) wherever it has; the linear extrapolation of R
    keeps some of those nodes at the bound."""
    x = np.linspace(0.0, 1.0, 41)
    edge = {0.0: 0.1, 0.1: 0.2, 0.25: 0.35}          # a(t) = 0.1 + t, steps 0.1 and 0.15

    def lam(t):
        return -2.0 * np.sqrt(np.maximum(x - edge[t], 0.0))
    older, newer, truth = lam(0.0), lam(0.1), lam(0.25)
    inside = (older < 0) & (newer < 0)
    predicted = predictor_module.extrapolate_reaction(older, newer, 1.5, inside)
    stays, leaves = inside & (truth < 0), inside & (truth == 0)
    assert stays.sum() > 10 and leaves.sum() >= 5
    assert np.allclose(predicted[stays], truth[stays], rtol=1e-12, atol=1e-14)
    assert np.all(predicted[leaves] > 0)
    linear = newer + 1.5 * (newer - older)
    assert np.count_nonzero(linear[leaves] < 0) >= 3  # the linear rule misses these
    outside = ~inside                                 # elsewhere: the linear rule
    assert np.array_equal(predicted[outside], linear[outside])


@pytest.mark.mpi
def test_the_zone_at_the_bound_has_its_edge_nodes_outside():
    """On the bottom of the paper square (16 x 2 cells, so that 2 ranks share Gamma_C; node
    k at x = k / 16), the nodes k = 5..12 at the bound and node 2 alone: inside the zone
    are nodes 6 to 11, on every rank that holds them (ghosts included), each owned once."""
    comm = MPI.COMM_WORLD
    scene = load_scene("paper", geometry={"cells": [16, 2]}, output={"probes": []})
    problem = build(scene, geometry_module.build(scene, comm))
    xy = problem.contact.Q_coordinates
    on_bottom = np.zeros(len(xy), dtype=bool)
    on_bottom[problem.contact.nodes.nodes] = True
    k = np.round(xy[:, 0] * 16)
    bound = on_bottom & (((k >= 5) & (k <= 12)) | (k == 2))
    inside = problem.contact.bound_zone.interior(bound)
    owned = problem.contact.lambda_nu.function_space.dofmap.index_map.size_local
    held = comm.allreduce(int(np.count_nonzero(inside[:owned])))
    right = comm.allreduce(bool(np.array_equal(inside, on_bottom & (k >= 6) & (k <= 11))),
                           op=MPI.LAND)
    assert comm.allreduce(bool(np.allclose(xy[on_bottom, 1], 0.0)), op=MPI.LAND)
    assert right and held == 6


def test_the_reaction_square_saves_iterations_not_the_answer():
    """The paper scene at 128^2 cells (iterative solver), 6 steps after t_0: with the
    reaction extrapolated in its square the steps after the second take fewer Newton
    iterations in all (the edge of the zone at the bound crosses about 2 nodes a step), and
    every contact value is the linear rule's to the Newton tolerance."""
    runs = {}
    for choice in ("linear", "extrapolate"):
        runs[choice] = solve(load_scene("paper", geometry={"cells": [128, 128]},
                                        time={"T": 0.6, "steps": 6},
                                        solver={"linear_solver": "iterative",
                                                "predictor": choice},
                                        output={"probes": []}))
    later = {key: sum(s["newton_iterations"] for s in run.steps[3:])
             for key, run in runs.items()}
    assert later["extrapolate"] < later["linear"]
    squared, plain = _contact_values(runs["extrapolate"]), _contact_values(runs["linear"])
    assert np.max(np.abs(squared - plain)) <= 1e-10 * np.max(np.abs(plain))


def _contact_values(result):
    table = result.contact[-1]
    return np.concatenate([np.ravel(table[key]) for key in
                           ("u_nu", "u_tau", "lambda_nu", "reaction_nu", "reaction_tau")])


def test_prediction_changes_the_iterations_not_the_answer():
    runs = {}
    for choice in ("none", "extrapolate"):
        scene = load_scene("paper", solver={"predictor": choice})
        runs[choice] = solve(scene)
    iterations = {key: sum(s["newton_iterations"] for s in run.steps)
                  for key, run in runs.items()}
    assert iterations["extrapolate"] < iterations["none"]
    predicted, plain = _contact_values(runs["extrapolate"]), _contact_values(runs["none"])
    assert np.max(np.abs(predicted - plain)) <= 1e-10 * np.max(np.abs(plain))
    for run in runs.values():                        # some factorizations were kept
        setups = sum(s["preconditioner_setups"] for s in run.steps)
        assert 0 < setups < sum(s["newton_iterations"] for s in run.steps)


def _paper_problem(**overrides):
    scene = load_scene("paper", **SMALL, **overrides)
    problem = build(scene, geometry_module.build(scene, MPI.COMM_SELF))
    return scene, problem, solver_module.create(problem, MPI.COMM_SELF)


def test_a_failed_prediction_falls_back_to_the_accepted_state():
    """Newton made to fail from every prediction (after 3 iterations): each step is solved
    again from the last accepted state, is not cut, counts both attempts' iterations, and
    ends where the unpredicted step ends."""
    ends, spent = {}, {}
    for broken in (False, True):
        scene, problem, snes = _paper_problem()
        predict = predictor_module.Extrapolation(problem.unknowns)
        if broken:
            solve_once, apply_once = snes.solve, predict.apply
            predicted = []

            def apply(t):
                predicted.append(apply_once(t))
                return predicted[-1]

            def solve():
                if predicted and predicted.pop():
                    raise NewtonFailure("made to fail", -5, [1.0, 0.5, 0.25, 0.1])
                return solve_once()
            predict.apply, snes.solve = apply, solve
        try:
            k = scene["time"]["T"] / scene["time"]["steps"]
            spent[broken] = []
            for n in range(4):
                states = list(advance(problem, snes, n * k, 0, lambda text: None,
                                      predict=predict if broken else None))
                assert len(states) == 1 and states[0].cuts == 0
                spent[broken].append(states[0].iterations)
            ends[broken] = problem.u.x.array.copy()
        finally:
            snes.destroy()
    # Steps 2 and 3 had a prediction (two accepted states before them): 3 more iterations.
    assert spent[True] == spent[False][:2] + [i + 3 for i in spent[False][2:]]
    assert np.max(np.abs(ends[True] - ends[False])) <= 1e-12 * np.max(np.abs(ends[False]))


def test_the_operator_changes_only_with_the_newton_matrix():
    """With the direct solver the Jacobian is copied into the linear solver's operator only
    when it differs from it (one ulp in one entry suffices); the iterative solver assembles
    into its operator, except with a kept preconditioner (the front rule, on by default),
    which has an operator of its own."""
    scene, problem, snes = _paper_problem()
    _, _, iterative = _paper_problem(solver={"linear_solver": "iterative"})
    assert snes.reuse and not iterative.reuse
    assert (iterative.operator.handle == iterative.system.J_red.handle) == \
        (iterative.kept is None)
    assert iterative.kept is not None
    iterative.destroy()
    snes.enable_stale(0)          # exact reuse alone (nearby matrices: test_stale_factors.py)
    try:
        snes.solve()
        assert snes.setups >= 1
        matrix, operator = snes.system.J_red, snes.operator
        setups, state = snes.setups, operator.stateGet()
        snes._to_operator(matrix)                        # the same matrix again: kept
        assert (snes.setups, operator.stateGet()) == (setups, state)
        rows, columns, values = matrix.getValuesCSR()
        row = int(np.argmax(np.diff(rows) > 0))
        entry = rows[row]
        changed = np.nextafter(values[entry], np.inf)    # one entry, one ulp
        matrix.setValue(row + matrix.getOwnershipRange()[0], columns[entry], changed)
        matrix.assemble()
        snes._to_operator(matrix)                        # a different matrix: copied
        assert snes.setups == setups + 1 and operator.stateGet() != state
        assert operator.getValue(row + operator.getOwnershipRange()[0],
                                 columns[entry]) == changed
    finally:
        snes.destroy()
