"""The direct solver's factorization of an earlier Newton matrix P, kept for a matrix J that
differs from P in a few rows: P's factors with the low-rank (Woodbury) correction of those
rows (low_rank.LowRankSolve, the default) or inside FGMRES (P^-1 J is the identity plus a
matrix of rank at most the number of changed rows) solve J x = b to the tolerance of the
direct solve, and Newton takes the same iterations to the same converged state, with fewer
factorizations; a matrix that differs in more rows is factorized."""
import numpy as np
import pytest
from mpi4py import MPI
from petsc4py import PETSc

from contactvisco import load_scene, solve
from contactvisco.fem import geometry as geometry_module
from contactvisco.fem.problem import build
from contactvisco.solver import newton_base as solver_module
from contactvisco.solver import newton
from helpers import diagonal_matrix


def _contact_values(result):
    return np.concatenate([np.ravel(table[key]) for table in result.contact for key in
                           ("u_nu", "u_tau", "lambda_nu", "reaction_nu", "reaction_tau")])


def test_kept_factorizations_change_the_work_not_the_answer(monkeypatch):
    """The paper scene at its own size with every Newton matrix factorized, with P's factors
    kept inside FGMRES and with the low-rank correction: the same Newton iterations step by
    step (4 2 1 1 1 1 1 1 1 1 1), contact values within 1e-10 of the largest, fewer
    factorizations; FGMRES takes Krylov iterations (> 1) where P's factors were kept, the
    low-rank correction one sweep each (it is exact up to round-off)."""
    runs = {}
    for name, rows, low_rank in (("exact", 0, False), ("fgmres", None, False),
                                 ("low_rank", None, True)):
        monkeypatch.setattr(solver_module, "LOW_RANK", low_rank)
        if rows is not None:
            monkeypatch.setattr(solver_module, "STALE_ROWS", rows)
        runs[name] = solve(load_scene("paper", output={"probes": []}))
        monkeypatch.undo()
    exact = runs["exact"]
    for name in ("fgmres", "low_rank"):
        kept = runs[name]
        assert [s["newton_iterations"] for s in kept.steps] == \
            [s["newton_iterations"] for s in exact.steps] == [4, 2, 1, 1, 1, 1, 1, 1, 1, 1, 1]
        a, b = _contact_values(kept), _contact_values(exact)
        assert np.max(np.abs(a - b)) <= 1e-10 * np.max(np.abs(b))
        assert np.allclose(kept.contact[-1]["x"], exact.contact[-1]["x"], rtol=0, atol=0)
    setups = {key: sum(s["preconditioner_setups"] for s in run.steps)
              for key, run in runs.items()}
    assert setups["low_rank"] <= setups["fgmres"] < setups["exact"]
    assert all(k == 1 for s in exact.steps for k in s["krylov_iterations"])
    assert max(k for s in runs["fgmres"].steps for k in s["krylov_iterations"]) > 1
    assert all(k == 1 for s in runs["low_rank"].steps for k in s["krylov_iterations"])


@pytest.mark.mpi
@pytest.mark.parametrize("low_rank", [True, False], ids=["low_rank", "fgmres"])
def test_a_few_changed_rows_keep_the_factors_more_do_not(monkeypatch, low_rank):
    """A few changed rows (one on each rank, one of them off the diagonal too): the operator
    keeps its factors (no new set-up, its PETSc state unchanged) and they solve the changed
    system to 1e-12 of |b|, to the answer of a new factorization within 1e-10; by one
    sweep of the low-rank correction, or by FGMRES in more than one iteration. More rows
    than the bound changed: the matrix is copied and factorized (preonly again)."""
    monkeypatch.setattr(solver_module, "LOW_RANK", low_rank)
    comm = MPI.COMM_WORLD
    scene = load_scene("paper", geometry={"cells": [12, 12]}, output={"probes": []})
    problem = build(scene, geometry_module.build(scene, comm))
    snes = newton.create(problem, comm)
    reference = PETSc.KSP().create(comm)
    try:
        bound = solver_module.LOW_RANK_ROWS if low_rank else solver_module.STALE_ROWS
        assert snes.stale_rows == bound > 0
        snes.solve()
        ksp = snes.snes.getKSP()
        matrix, operator = snes.system.J_red, snes.operator
        snes._to_operator(matrix)
        setups, state = snes.setups, operator.stateGet()
        start = matrix.getOwnershipRange()[0]
        indptr, columns, values = matrix.getValuesCSR()
        diagonal = [(i, k) for i in range(len(indptr) - 1)
                    for k in range(indptr[i], indptr[i + 1]) if columns[k] == i + start]

        def change(rows):
            for i, k in [diagonal[j] for j in rows]:
                matrix.setValue(i + start, i + start, 1.5 * values[k])
            matrix.assemble()

        middle = len(diagonal) // 2
        change([middle])
        i, k = diagonal[middle]
        other = indptr[i] + (1 if k == indptr[i] else 0)    # an off-diagonal entry of the row
        matrix.setValue(i + start, columns[other], values[other] + 0.3 * values[k])
        matrix.assemble()
        snes._to_operator(matrix)
        assert (snes.setups, operator.stateGet()) == (setups, state)
        assert ksp.getType() == ("python" if low_rank else "fgmres")
        ksp.setOperators(matrix, operator)
        b, x = matrix.createVecs()
        b.setArray(np.random.default_rng(1 + comm.rank).standard_normal(b.getLocalSize()))
        ksp.solve(b, x)
        r = b.duplicate()
        matrix.mult(x, r)
        r.axpy(-1.0, b)
        assert r.norm() <= 1e-12 * b.norm()
        assert ksp.getConvergedReason() == PETSc.KSP.ConvergedReason.CONVERGED_RTOL
        if low_rank:
            assert ksp.getIterationNumber() == 1
        else:
            assert ksp.getIterationNumber() > 1
        reference.setOperators(matrix)
        reference.setType("preonly")
        reference.getPC().setType("lu")
        reference.getPC().setFactorSolverType("mumps")
        y = x.duplicate()
        reference.solve(b, y)
        y.axpy(-1.0, x)
        assert y.norm() <= 1e-10 * x.norm()
        change(range(0, len(diagonal), max(1, len(diagonal) // (2 * snes.stale_rows))))
        snes._to_operator(matrix)
        assert snes.setups == setups + 1 and operator.stateGet() != state
        assert ksp.getType() == "preonly"
    finally:
        reference.destroy()
        snes.destroy()


@pytest.mark.parametrize("changed, solvable", [([2.0, 4.0, 3.0], True),
                                              ([2.0, 0.0, 3.0], False)],
                         ids=["regular", "singular"])
def test_low_rank_solve_against_the_changed_matrix(changed, solvable):
    """low_rank.LowRankSolve by itself: P = diag(2, 5, 3) factorized, J = P with its row 1
    changed. A regular J: x = J^-1 b exactly in one sweep. A singular J (its capacitance
    matrix is 0): a diverged reason for SNES to see, no exception and no NaN returned as an
    answer."""
    from contactvisco.solver import low_rank
    P, J = diagonal_matrix([2.0, 5.0, 3.0]), diagonal_matrix(changed)
    ksp = PETSc.KSP().create(MPI.COMM_SELF)
    solver = low_rank.LowRankSolve(1e-12, 1e-300, 8)
    try:
        ksp.setOperators(J, P)
        ksp.getPC().setType("lu")
        ksp.setType("python")
        ksp.setPythonContext(solver)
        assert solver.use([1])
        b, x = J.createVecs()
        b.setArray([1.0, 2.0, 3.0])
        ksp.solve(b, x)
        if solvable:
            assert ksp.getConvergedReason() == PETSc.KSP.ConvergedReason.CONVERGED_RTOL
            assert ksp.getIterationNumber() == 1
            assert np.allclose(x.getArray(), [0.5, 0.5, 1.0], rtol=1e-14, atol=0)
        else:
            assert ksp.getConvergedReason() < 0
        assert solver.computed == 1 and list(solver.columns) == [1]
        assert not solver.use(range(9))           # more columns than the limit: refused
        assert list(solver.rows) == [1]
    finally:
        solver.forget()
        for obj in (ksp, P, J):
            obj.destroy()
