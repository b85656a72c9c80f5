"""A PETSc SNES generalized Newton over block-assembled UFL residuals (DOLFINx 0.5 has no SNES
wrapper of its own).

Each Newton step solves J(w) dw = -F(w) for all unknowns w = (u, lambda_nu, lambda_tau) at
once; J is the UFL derivative of F, i.e. an element of the generalized (Clarke) Jacobian of
the semismooth residual.
"""
from __future__ import annotations

import numpy as np
from dolfinx import fem
from dolfinx.fem.petsc import (assemble_matrix_block, assemble_vector_block,
                               create_matrix_block, create_vector_block)
from petsc4py import PETSc

#: SNES defaults. Measured on this problem: the basic (full-step) line search converges in
#: 1-5 iterations whatever the augmentation parameter; bt/cp get worse as it grows.
#: The divergence tolerance is off: its default stops large-parameter runs after one step.
DEFAULT_OPTIONS = {
    "snes_type": "newtonls",
    "snes_linesearch_type": "basic",
    "snes_rtol": 1e-10,
    "snes_atol": 1e-10,
    "snes_stol": 0.0,
    "snes_max_it": 50,
    "snes_divergence_tolerance": -1.0,
    "ksp_type": "preonly",
    "pc_type": "lu",
    "pc_factor_mat_solver_type": "mumps",
}

_INSERT, _ADD = PETSc.InsertMode.INSERT, PETSc.InsertMode.ADD
_FORWARD = PETSc.ScatterMode.FORWARD


class NewtonFailure(RuntimeError):
    """SNES did not converge."""

    def __init__(self, message, reason, residuals):
        super().__init__(message)
        self.reason = reason
        self.residuals = residuals


class BlockSNES:
    """SNES over the unknowns `functions` with residual blocks F and Jacobian blocks J."""

    def __init__(self, F, J, functions, bcs, comm, scene_options=None):
        self.F = [fem.form(f) for f in F]
        self.J = [[None if a is None else fem.form(a) for a in row] for row in J]
        self.functions = functions
        self.bcs = bcs
        self.b = create_vector_block(self.F)
        self.x = create_vector_block(self.F)
        self.A = create_matrix_block(self.J)
        self.residuals: list[float] = []

        # Command-line options win over the scene, the scene over DEFAULT_OPTIONS. Options set
        # here are removed again after setFromOptions so they do not leak into later solvers.
        opts = PETSc.Options()
        merged = dict(DEFAULT_OPTIONS)
        merged.update(scene_options or {})
        inserted = [key for key in merged if not opts.hasName(key)]
        for key in inserted:
            opts[key] = merged[key]

        self.snes = PETSc.SNES().create(comm)
        self.snes.setFunction(self._residual, self.b)
        self.snes.setJacobian(self._jacobian, self.A)
        self.snes.setMonitor(lambda snes, it, norm: self.residuals.append(float(norm)))
        self.snes.setFromOptions()
        for key in inserted:
            opts.delValue(key)

    def _to_functions(self, x):
        offset = 0
        array = x.getArray(readonly=True)
        for f in self.functions:
            n = f.vector.getLocalSize()
            f.vector.array[:] = array[offset:offset + n]
            f.vector.ghostUpdate(addv=_INSERT, mode=_FORWARD)
            offset += n

    def _from_functions(self, x):
        offset = 0
        array = x.getArray()
        for f in self.functions:
            n = f.vector.getLocalSize()
            array[offset:offset + n] = f.vector.array
            offset += n
        x.ghostUpdate(addv=_INSERT, mode=_FORWARD)

    def _residual(self, snes, x, b):
        # SNES updates only the owned entries of x; the lifting of the Dirichlet rows below
        # reads x's ghosts too. Stale ghosts go unnoticed while all prescribed values are 0.
        x.ghostUpdate(addv=_INSERT, mode=_FORWARD)
        # Copy SNES's iterate into the Functions (ghosts included) before assembling.
        self._to_functions(x)
        with b.localForm() as local:
            local.set(0.0)
        # Rows of Dirichlet dofs become x - g: SNES then drives them to g.
        assemble_vector_block(b, self.F, self.J, bcs=self.bcs, x0=x, scale=-1.0)

    def _jacobian(self, snes, x, A, P):
        A.zeroEntries()
        assemble_matrix_block(A, self.J, bcs=self.bcs, diagonal=1.0)
        A.assemble()

    def solve(self) -> int:
        """Newton from the current Functions; returns the iteration count or raises
        NewtonFailure. The Functions hold the converged solution afterwards."""
        self.residuals = []
        self._from_functions(self.x)
        self.snes.solve(None, self.x)
        self._to_functions(self.x)
        reason = self.snes.getConvergedReason()
        if reason > 0 and not np.isfinite(self.x.norm()):
            reason = -4      # never accept a non-finite solution as converged
        if reason <= 0:
            raise NewtonFailure(
                f"Newton did not converge (SNES reason {reason}) after "
                f"{self.snes.getIterationNumber()} iterations; residual history "
                f"{['%.3e' % r for r in self.residuals]}", reason, list(self.residuals))
        return self.snes.getIterationNumber()
