"""Solves with the LU factors of a matrix P for a matrix J that differs from it in a few rows.

When a few contact nodes change branch between Newton iterations, the condensed Newton
matrix J differs from the factorized one P only in those nodes' rows R (s of them):

    J = P + U D,    U = [e_r for r in R] (n x s),    D = (J - P)[R, :] (s x n).

The Sherman-Morrison-Woodbury identity (Hager, SIAM Review 31, 1989, 221-239) gives

    J^-1 b = y - W (I + D W)^-1 D y,    y = P^-1 b,    W = P^-1 U,

with two simplifications for this U: D y = (J y)[R] - b[R] (as P y = b), and the capacitance
matrix I + D W = (J W)[R, :] (as P W = U). The columns W_r = P^-1 e_r depend on P and the
row alone, not on J's values, so each is computed once per factorization and serves every
later J whose changed rows include r. A solve then costs one triangular solve with P's
factors, one product with J and s vector updates, however many rows changed; a Krylov
method with P's factors needs about s + 1 triangular solves for the same answer.

LowRankSolve is the `solve` of a PETSc KSP of type "python" whose PC holds P's factors: it
applies the identity and refines the answer on J's own residual until
|b - J x| <= rtol |b| (one sweep in exact arithmetic; round-off may ask for a second). A
singular capacitance matrix (J singular) or a non-finite residual ends the solve with a
diverged reason, which SNES reports as a failed linear solve.
"""
from __future__ import annotations

import numpy as np
from petsc4py import PETSc

#: The most refinement sweeps of one solve; a solve that needs more reports CONVERGED_ITS
#: with its last iterate, and the caller factorizes the next matrix.
SWEEPS = 3


class LowRankSolve:
    """J x = b from the factors of P (the KSP's PC) and the rows R in which J differs.

    Parameters
    ----------
    rtol, atol : float
        Converged when |b - J x| <= max(rtol |b|, atol).
    limit : int
        The most columns W_r kept for one factorization (over all ranks); `use` refuses a
        row set that would need more.
    """

    def __init__(self, rtol: float, atol: float, limit: int):
        self.rtol, self.atol, self.limit = rtol, atol, limit
        self.columns: dict[int, PETSc.Vec] = {}   # global row r -> W_r = P^-1 e_r
        self.rows = np.zeros(0, dtype=np.int64)   # R of the current J, the same on all ranks
        self.capacitance = None                   # (J W)[R, :] of the current J
        self.computed = 0                         # columns computed, over the object's life

    # (not named reset or destroy: PETSc calls those of a KSP's python context whenever the
    # KSP changes type, and the columns outlive such changes)
    def forget(self):
        """A new factorization (or the end): every kept column is obsolete and freed."""
        for vector in self.columns.values():
            vector.destroy()
        self.columns = {}
        self.capacitance = None

    def use(self, rows) -> bool:
        """Take `rows` (the global rows where the next J differs from P, in the same order on
        every rank) for the next solves; False, and nothing changed, if the columns they add
        would exceed `limit`."""
        rows = np.asarray(rows, dtype=np.int64)
        if len(set(self.columns) | set(rows.tolist())) > self.limit:
            return False
        self.rows = rows
        self.capacitance = None       # J's values are new: built at the next solve
        return True

    def _prepare(self, ksp, J):
        """The missing columns W_r (one application of P's factors each) and the
        capacitance matrix (J W)[R, :] for the current J."""
        pc = ksp.getPC()
        start, end = J.getOwnershipRange()
        for r in self.rows.tolist():
            if r not in self.columns:
                unit, column = J.createVecRight(), J.createVecRight()
                unit.set(0.0)
                if start <= r < end:
                    unit.setValue(r, 1.0)
                unit.assemble()
                pc.apply(unit, column)
                unit.destroy()
                self.columns[r] = column
                self.computed += 1
        product = J.createVecLeft()
        local = np.zeros((len(self.rows), len(self.rows)))
        for j, r in enumerate(self.rows.tolist()):
            J.mult(self.columns[r], product)
            local[:, j] = self._entries(product, start, end)
        product.destroy()
        self.capacitance = J.getComm().tompi4py().allreduce(local)

    def _entries(self, vector, start, end) -> np.ndarray:
        """The entries of `vector` at the rows R, on every rank (zeros off the owned range;
        summed over the ranks by the caller)."""
        values = np.zeros(len(self.rows))
        owned = (self.rows >= start) & (self.rows < end)
        if owned.any():
            values[owned] = vector.getArray(readonly=True)[self.rows[owned] - start]
        return values

    def solve(self, ksp, b, x):
        """KSP python type: x = J^-1 b by the identity above, refined on J's residual."""
        J = ksp.getOperators()[0]
        if self.capacitance is None:
            self._prepare(ksp, J)
        comm = J.getComm().tompi4py()
        start, end = J.getOwnershipRange()
        pc = ksp.getPC()
        residual, y, product = b.copy(), b.duplicate(), b.duplicate()
        x.set(0.0)
        target = max(self.rtol * b.norm(), self.atol)
        norm, sweeps = residual.norm(), 0
        reason = None
        while norm > target and sweeps < SWEEPS:
            pc.apply(residual, y)
            J.mult(y, product)
            t = comm.allreduce(self._entries(product, start, end)
                               - self._entries(residual, start, end))
            try:
                c = np.linalg.solve(self.capacitance, t) if len(t) else t
            except np.linalg.LinAlgError:   # (the same on every rank: C and t are)
                reason = PETSc.KSP.ConvergedReason.DIVERGED_BREAKDOWN   # J is singular
                break
            if len(c):
                y.maxpy(-c, [self.columns[r] for r in self.rows.tolist()])
            x.axpy(1.0, y)
            J.mult(x, product)
            b.copy(residual)
            residual.axpy(-1.0, product)
            norm, sweeps = residual.norm(), sweeps + 1
        for vector in (residual, y, product):
            vector.destroy()
        if reason is None and not np.isfinite(norm):
            reason = PETSc.KSP.ConvergedReason.DIVERGED_NANORINF
        if reason is None:
            reason = (PETSc.KSP.ConvergedReason.CONVERGED_RTOL if norm <= target
                      else PETSc.KSP.ConvergedReason.CONVERGED_ITS)
        ksp.setIterationNumber(sweeps)
        ksp.setResidualNorm(norm)
        ksp.setConvergedReason(reason)
