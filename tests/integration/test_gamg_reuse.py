"""GAMG keeps its prolongation across set-ups in 3D (newton.GAMG_REUSE_INTERPOLATION): a
set-up for a new Newton matrix recomputes only the Galerkin coarse operators. The run reaches
the direct solver's contact values; after a solve that did not converge, every set-up builds
a new prolongation (NewtonSolver._fresh_prolongation). GAMG is taken on both routes here (the
Debian route would take BoomerAMG), so the tests run on both."""
import types

import numpy as np
import pytest
from mpi4py import MPI
from petsc4py import PETSc

from contactvisco.fem import compat
from contactvisco.scene import loader as scene_module
from contactvisco.solver import newton as solver_module
from contactvisco.solver.newton_base import NewtonSolver
from contactvisco.solver.time_loop import simulate

BLOCK = ["geometry.parameters.h=0.125", "time.T=0.6", "time.steps=6"]
KEYS = ("u_nu", "u_tau", "lambda_nu", "reaction_nu", "reaction_tau")


def _run(linear_solver):
    scene = scene_module.load("block3d", BLOCK + [f"solver.linear_solver='{linear_solver}'",
                                                  "output.figures=false"])
    scene["output"]["probes"] = []
    return simulate(scene, comm=MPI.COMM_WORLD, progress=False, keep_tables=True)


@pytest.mark.mpi
def test_a_kept_prolongation_reaches_the_direct_answer(monkeypatch):
    """block3d with GAMG and its 3D default: after the first set-up every later one keeps
    the prolongation object (held here, so that a new one cannot take its address), across
    the steps' many set-ups, and the contact values of every step are MUMPS's to 1e-7 of
    each value's largest (the 3D slip directions move the iterates' last digits: the two
    linear solvers' runs differ by 2e-10 to 6e-9 here, on the two routes)."""
    monkeypatch.setattr(compat, "has_hypre", lambda: False)
    assert solver_module.iterative_options(3)["pc_gamg_reuse_interpolation"] is True
    seen = []
    solve = NewtonSolver.solve

    def recording(self):
        iterations = solve(self)
        pc = self.snes.getKSP().getPC()
        if pc.getType() == "gamg" and self.setups:
            assert pc.getMGLevels() >= 2          # a prolongation to compare
            seen.append((self.setups, pc.getMGInterpolation(1)))
        return iterations

    monkeypatch.setattr(NewtonSolver, "solve", recording)
    amg = _run("iterative")
    monkeypatch.undo()
    direct = _run("direct")
    assert amg.linear_solver.startswith("gmres/gamg")
    assert sum(count for count, _ in seen) >= 10, seen      # set-ups that could rebuild it
    first = seen[0][1]
    assert all(P.handle == first.handle for _, P in seen)
    assert len(amg.tables) == len(direct.tables) == 7             # t_0 and 6 steps
    for ta, tb in zip(amg.tables, direct.tables):
        for key in KEYS:
            scale = max(np.max(np.abs(tb[key])), 1e-12)
            assert np.max(np.abs(np.asarray(ta[key]) - tb[key])) <= 1e-7 * scale, key


def _grid(m):
    """The 5-point Laplacian's pattern on an m x m grid (values by _fill_grid)."""
    A = PETSc.Mat().createAIJ((m * m, m * m), nnz=5, comm=MPI.COMM_SELF)
    _fill_grid(A, m, 1.0)
    return A


def _fill_grid(A, m, weak, shift=1e-3):
    """The Laplacian with the couplings along y scaled by `weak` (the same pattern for every
    `weak`, as the Newton matrix keeps its pattern): below GAMG's threshold they are
    dropped and the aggregates become lines along x."""
    for i in range(m):
        for j in range(m):
            row, columns, values = i * m + j, [], []
            for di, dj, c in ((-1, 0, weak), (1, 0, weak), (0, -1, 1.0), (0, 1, 1.0)):
                if 0 <= i + di < m and 0 <= j + dj < m:
                    columns.append((i + di) * m + j + dj)
                    values.append(-c)
            A.setValues([row], columns + [row], values + [shift - sum(values)])
    A.assemble()


def test_a_failed_solve_gets_a_new_prolongation():
    """With pc_gamg_reuse_interpolation, a set-up after a converged solve keeps the
    prolongation; after a solve that stopped at its iteration limit (DIVERGED_MAX_IT),
    _fresh_prolongation makes the next set-up build a new one, here from a matrix whose
    weak couplings give other aggregates and a coarse level of another size (the case after
    which PETSc 3.18's PCReset left GAMG failing), and every set-up after it builds its own."""
    m = 20
    A = _grid(m)
    snes = PETSc.SNES().create(MPI.COMM_SELF)
    ksp = snes.getKSP()
    ksp.setType("gmres")
    pc = ksp.getPC()
    pc.setType("gamg")
    opts = PETSc.Options()
    keys = {"reuse_test_pc_gamg_reuse_interpolation": True,
            "reuse_test_pc_gamg_coarse_eq_limit": 10,
            "reuse_test_pc_gamg_threshold": 0.01}
    for key, value in keys.items():
        opts[key] = value
    ksp.setOptionsPrefix("reuse_test_")
    ksp.setFromOptions()
    ksp.setOperators(A)
    owner = types.SimpleNamespace(snes=snes, fresh_prolongations=0)
    b, x = A.createVecs()
    b.set(1.0)

    def solve(max_it, weak=1.0):
        """A new matrix (the same pattern, new values, as the Newton matrix): a set-up."""
        NewtonSolver._fresh_prolongation(owner)
        ksp.setTolerances(rtol=1e-10, max_it=max_it)
        solve.count += 1
        _fill_grid(A, m, weak, shift=1e-3 * solve.count)
        ksp.setOperators(A)
        ksp.solve(b, x)
        return ksp.getConvergedReason()
    solve.count = 0

    assert solve(200) > 0
    first = pc.getMGInterpolation(1)
    coarse = first.getSize()[1]
    assert solve(1) == PETSc.KSP.ConvergedReason.DIVERGED_MAX_IT
    assert owner.fresh_prolongations == 0
    assert pc.getMGInterpolation(1).handle == first.handle      # kept after a converged solve
    assert solve(200, weak=1e-4) > 0
    assert owner.fresh_prolongations == 1
    second = pc.getMGInterpolation(1)
    assert second.handle != first.handle                        # built again
    assert second.getSize()[1] != coarse                        # other aggregates
    assert solve(200, weak=1e-4) > 0
    assert pc.getMGInterpolation(1).handle != second.handle     # no longer kept
    assert owner.fresh_prolongations == 1
    for key in keys:
        opts.delValue(key)
    for obj in (snes, A, b, x):
        obj.destroy()
