"""The direct solver's factorization of an earlier Newton matrix P, kept for a matrix J that
differs from P in a few rows: FGMRES with P's factors solves J x = b to the tolerance of the
direct solve (P^-1 J is the identity plus a matrix of rank at most the number of changed
rows), Newton takes the same iterations to the same converged state, with fewer
factorizations; a matrix that differs in more rows is factorized."""
import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from contactvisco import load_scene, solve
from contactvisco.fem import geometry as geometry_module
from contactvisco.fem.problem import build
from contactvisco.solver import newton_base as solver_module
from contactvisco.solver import newton


def _contact_values(result):
    return np.concatenate([np.ravel(table[key]) for table in result.contact for key in
                           ("u_nu", "u_tau", "lambda_nu", "reaction_nu", "reaction_tau")])


def test_kept_factorizations_change_the_work_not_the_answer(monkeypatch):
    """The paper scene at its own size with and without kept factorizations: the same Newton
    iterations step by step (4 2 1 1 1 1 1 1 1 1 1), contact values within 1e-10 of the
    largest, fewer factorizations, and Krylov iterations (> 1) where P's factors were kept."""
    runs = {}
    for rows in (0, solver_module.STALE_ROWS):
        monkeypatch.setattr(solver_module, "STALE_ROWS", rows)
        runs[rows] = solve(load_scene("paper", output={"probes": []}))
    exact, kept = runs[0], runs[solver_module.STALE_ROWS]
    assert [s["newton_iterations"] for s in kept.steps] == \
        [s["newton_iterations"] for s in exact.steps] == [4, 2, 1, 1, 1, 1, 1, 1, 1, 1, 1]
    a, b = _contact_values(kept), _contact_values(exact)
    assert np.max(np.abs(a - b)) <= 1e-10 * np.max(np.abs(b))
    assert np.allclose(kept.contact[-1]["x"], exact.contact[-1]["x"], rtol=0, atol=0)
    setups = {key: sum(s["preconditioner_setups"] for s in run.steps)
              for key, run in runs.items()}
    assert setups[solver_module.STALE_ROWS] < setups[0]
    assert all(k == 1 for s in exact.steps for k in s["krylov_iterations"])
    assert max(k for s in kept.steps for k in s["krylov_iterations"]) > 1


def test_a_few_changed_rows_keep_the_factors_more_do_not():
    """One changed row: the operator keeps its factors (no new set-up, its PETSc state
    unchanged) and FGMRES with them solves the changed system to 1e-12; more rows than
    STALE_ROWS changed: the matrix is copied and factorized (preonly again)."""
    scene = load_scene("paper", geometry={"cells": [12, 12]}, output={"probes": []})
    problem = build(scene, geometry_module.build(scene, MPI.COMM_SELF))
    snes = newton.create(problem, MPI.COMM_SELF)
    try:
        assert snes.stale_rows == solver_module.STALE_ROWS > 0
        snes.solve()
        ksp = snes.snes.getKSP()
        matrix, operator = snes.system.J_red, snes.operator
        snes._to_operator(matrix)
        setups, state = snes.setups, operator.stateGet()
        indptr, columns, values = matrix.getValuesCSR()
        diagonal = [(i, k) for i in range(len(indptr) - 1)
                    for k in range(indptr[i], indptr[i + 1]) if columns[k] == i]

        def change(rows):
            for i, k in [diagonal[j] for j in rows]:
                matrix.setValue(i, i, 1.5 * values[k])
            matrix.assemble()

        change([len(diagonal) // 2])
        snes._to_operator(matrix)
        assert (snes.setups, operator.stateGet()) == (setups, state)
        assert ksp.getType() == "fgmres"
        ksp.setOperators(matrix, operator)
        b, x = matrix.createVecs()
        b.setArray(np.random.default_rng(1).standard_normal(b.getLocalSize()))
        ksp.solve(b, x)
        r = b.duplicate()
        matrix.mult(x, r)
        r.axpy(-1.0, b)
        assert ksp.getIterationNumber() > 1
        assert r.norm() <= 1e-12 * b.norm()
        assert ksp.getConvergedReason() == PETSc.KSP.ConvergedReason.CONVERGED_RTOL
        change(range(0, len(diagonal), max(1, len(diagonal) // (2 * snes.stale_rows))))
        snes._to_operator(matrix)
        assert snes.setups == setups + 1 and operator.stateGet() != state
        assert ksp.getType() == "preonly"
    finally:
        snes.destroy()
