"""The iterative solver's preconditioner kept across Newton iterations and steps.

With a linear bulk law and a constant step size, the Newton matrix of the condensed system is
J_red = K + E: K, the bulk operator (A plus the memory's weight on the current strain, the
cell integrals), is the same in every iteration of every step, and E changes only the rows of
the contact nodes whose branch of the law changed (free, compliant, at the bound, stick,
slip). An algebraic multigrid hierarchy M built from an earlier matrix J_0 = K + E_0 is then a
preconditioner of J_red whose error J_red M^-1 - I has the rank of E - E_0 added to that of
J_0 M^-1 - I, and GMRES pays for the difference with a few more iterations instead of a new
set-up (BoomerAMG's set-up costs about as much as 5 GMRES iterations, docs/scaling.md).

KeptPreconditioner decides, before each linear solve, whether the hierarchy is built again
(the Newton matrix copied into the preconditioner's own operator, whose changed state makes
PCSetUp build it) or kept (that operator left as it is: PCSetUp then keeps the hierarchy):

- built again when the Newton matrix differs from the one of the build in more than ROWS
  rows (over all ranks);
- built again when the bulk operator changed since the build (another step size: the memory's
  weight; a Constant of the cell integrals), always when the bulk operator depends on the
  iterate (a nonlinear bulk law: `stamp` gives None);
- built again when the last solve with it did not converge, or when the iterations the
  solves with the kept hierarchy took beyond n_0 (the iterations of the first solve after the
  build) add up to more than BUDGET, about what a set-up costs in iterations: renting before
  buying, at most twice the cost of the better choice made in hindsight;
- kept otherwise.

The solves are the same to the Krylov tolerance; only the preconditioner differs. Measured
on the paper scene and block3d (docs/scaling.md), the set-ups saved were paid back in Krylov
iterations when every solve is exact, so that rule alone is off by default (KEEP); so are the
inexact solves of `forcing` (INEXACT), which added Newton iterations. What pays is the two
together where they fit the semi-smooth Newton method, the front rule (FrontRule, on by
default for the iterative solver: FRONT): loose solves with a kept hierarchy while an
iteration changes the contact state, an exact solve once it does not (to the residual
Newton's test needs: EXACT_FORCING; on a kept hierarchy within EXACT_ROWS changed rows), and
the same hierarchy for the exact solves that follow at that state (SAME_STATE), where only
the values of the rows of a law that is not piecewise linear change (3D slip directions).
"""
from __future__ import annotations

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

#: The iterations beyond n_0 that the solves with a kept hierarchy may add up to: a
#: BoomerAMG set-up costs about 4.5 to 5 GMRES iterations (V-cycles) in 2D and 3D
#: (docs/scaling.md).
BUDGET = 5

#: A kept hierarchy is built again for a Newton matrix that differs from the one of the
#: build in more than this many rows (over all ranks).
ROWS = 16

#: An exact solve under the front rule (FrontRule) keeps the hierarchy for a matrix within
#: this many rows of the build's, as a loose one does, or at the contact state of the build
#: (SAME_STATE); 0: a set-up of its own matrix otherwise (the former rule; docs/scaling.md).
EXACT_ROWS = ROWS

#: On: an exact solve keeps the hierarchy however many rows changed if every contact node is
#: in the branch of the law it was in at the build. At a fixed state only the values of
#: rows whose law is not piecewise linear change (the slip directions of 3D friction, a
#: nonlinear compliance): the Newton iterations that converge them then share one set-up
#: (docs/scaling.md). In 2D with the paper's laws a fixed state is a fixed matrix, kept anyway.
SAME_STATE = True

#: On: the rule above (an extra matrix of the system's size for the preconditioner). Off by
#: default: on the paper scene and block3d it saved set-ups but not time (docs/scaling.md).
KEEP = False
#: On: the inexact solves of `forcing`. Off by default: they added Newton iterations on the
#: paper scene (docs/scaling.md); every solve is then to the solver's own tolerance.
INEXACT = False


class KeptPreconditioner:
    """The rule above for one KSP.

    Parameters
    ----------
    stamp : callable
        () -> a value that changes whenever the bulk operator changes (compared with ==),
        or None when it depends on the iterate (the hierarchy is then built for every
        Newton matrix).
    selection : tuple of petsc4py.PETSc.IS, optional
        The index sets (rows, all columns) of the owned rows in which two Newton matrices of
        one stamp can differ (NodalCondensation.varying_rows): only these rows are read and
        compared, instead of the whole matrix; the object owns and destroys them. None:
        every row.
    """

    def __init__(self, stamp, selection=None):
        self.stamp = stamp
        self.selection = selection
        self.built = None        # the stamp of the build
        self.first = None        # Krylov iterations of the first solve after the build
        self.solves = 0          # solves since the build
        self.extra = 0           # iterations beyond the first solve's, since the build
        self.kept = 0            # solves with a kept hierarchy, over the object's life
        self.values = None       # the CSR values of the matrix of the build
        self.state = None        # the contact state (contact_state) of the build's iterate
        self.last = None         # the compared values of the matrix of the last `moved` call
        self._read = None        # (matrix, its state, (indptr, values)): `moved`'s read,
                                 # taken again by build_next for the same unchanged matrix

    def build_next(self, ksp, A, loose=None, state=None) -> bool:
        """Decide for the next solve of `ksp` (called once per Newton matrix, before its
        solve; the same on every rank): True if the preconditioner is built again, from the
        new matrix.

        With `loose` given (the front rule, FrontRule), the budget is not used: a loose
        solve keeps the hierarchy for a matrix within ROWS rows of the build's, an exact
        one (loose False) within EXACT_ROWS rows, or with any rows changed if `state` (this
        rank's contact_state of the iterate) equals the state of the build on every rank
        (SAME_STATE)."""
        stamp = self.stamp()
        iterations, reason = ksp.getIterationNumber(), ksp.getConvergedReason()
        if self.solves == 1:
            self.first = iterations
        elif self.solves > 1:
            self.extra += max(iterations - self.first, 0)
        budget = loose is not None or self.extra <= BUDGET
        bound = ROWS if loose in (None, True) else EXACT_ROWS
        keep = ((KEEP or loose is not None) and stamp is not None and self.solves > 0
                and stamp == self.built and reason > 0 and budget)
        read, self._read = self._read, None
        same_matrix = read is not None and read[0] is A and read[1] == A.stateGet()
        indptr, values = read[2] if same_matrix else self._values(A)
        if keep:
            rows = -1
            if values is not None and self.values is not None and \
                    len(values) == len(self.values):
                entries = np.flatnonzero(values != self.values)
                rows = int(np.unique(np.searchsorted(indptr, entries, side="right")).size)
            same = (SAME_STATE and loose is False and state is not None
                    and self.state is not None and np.array_equal(state, self.state))
            counts = A.getComm().tompi4py().allgather((rows, same))
            keep = (min(c for c, _ in counts) >= 0 and sum(c for c, _ in counts) <= bound) \
                or all(s for _, s in counts)
        if keep:
            self.solves += 1
            self.kept += 1
            return False
        self.built, self.solves, self.first, self.extra = stamp, 1, None, 0
        self.values = None if values is None else values.copy()
        self.state = None if state is None else state.copy()
        return True

    def moved(self, A) -> bool:
        """Whether the compared rows of A differ from those of the matrix of the last call
        (True at the first call, or where the values cannot be read), on any rank:
        collective. At a fixed contact state they differ where the law is not linear within
        the state (the slip directions of 3D friction), and in 2D with the paper's laws at a
        few rows whose entries change within a branch. The read is kept for the next
        build_next of the same unchanged matrix."""
        indptr, values = self._values(A)
        self._read = (A, A.stateGet(), (indptr, values))
        last, self.last = self.last, None if values is None else values.copy()
        moved = (values is None or last is None or len(values) != len(last)
                 or bool(np.any(values != last)))
        return bool(A.getComm().tompi4py().allreduce(moved, op=MPI.LOR))

    def _values(self, A):
        """The CSR row pointer and values of the rows of A that are compared (all, or those
        of `selection`); (None, None) for a matrix type without CSR access."""
        try:
            if self.selection is None:
                indptr, _, values = A.getValuesCSR()
                return indptr, values
            part = A.createSubMatrix(*self.selection)
            indptr, _, values = part.getValuesCSR()
            part.destroy()
            return indptr, values
        except PETSc.Error:                    # a matrix type without CSR access
            return None, None

    def destroy(self):
        """Free the index sets (idempotent)."""
        for obj in self.selection or ():
            obj.destroy()
        self.selection = None


#: The inexact solves: the linear residual is asked for SAFETY times the residual at which
#: Newton stops, and never more loosely than ETA_MAX times the current one (docs/scaling.md).
SAFETY = 0.1
ETA_MAX = 1e-2


def forcing(rtol: float, norm: float, target: float, ceiling: float = ETA_MAX,
            safety: float = SAFETY) -> float:
    """The relative tolerance of the linear solve of a Newton iteration at residual `norm`
    when Newton stops at residual `target` (max(atol, rtol_N |F_0|)):

        eta = min(ceiling, max(rtol, safety * target / norm)),

    so that the linear residual |J dx + F| <= eta |F| is at most safety * target where
    `rtol` (the solver's own tolerance) allows it: a step that leaves Newton's stopping test
    to the nonlinear error alone, the last one included, and never a tighter solve than
    `rtol`. Near the solution a Newton iteration needs only as many Krylov iterations as
    the remaining reduction to the target takes, not the full `rtol`."""
    if not (norm > 0.0 and target > 0.0):
        return rtol
    return min(ceiling, max(rtol, safety * target / norm))


#: On (the default): the front rule (FrontRule) for the iterative solver: the solves of the
#: Newton iterations that still change the contact state are loose (LOOSE) and use a kept
#: hierarchy; the solve of an iteration whose state equals the previous iterate's is to the
#: solver's own tolerance, from a preconditioner of its own matrix (docs/scaling.md).
FRONT = True

#: The relative tolerance of a loose solve (docs/scaling.md: 1e-2 made Newton cycle at t_0
#: of the paper scene at 512^2; 1e-3 and 1e-4 converged everywhere measured).
LOOSE = 1e-3

#: On (the default): an exact solve under the front rule asks for the linear residual that
#: Newton's stopping test needs, `forcing` with the ceiling LOOSE and the safety
#: EXACT_SAFETY, instead of the solver's own tolerance: the iterate before it is close to
#: the solution, and a solve to rtol relative to its residual went orders of magnitude below
#: the target. Newton's test is unchanged (docs/scaling.md).
EXACT_FORCING = True

#: `forcing`'s safety for the exact solves: their linear residual at most this share of
#: Newton's target. GMRES stops on the preconditioned residual, not the true one, so 0.1 was
#: not enough: it added Newton iterations with GAMG on block3d and left the paper scene's
#: contact values 1.3e-10 from the independent solver's at 256^2 (docs/scaling.md).
EXACT_SAFETY = 0.01

#: On (the default): an exact solve after a step that kept the contact state but changed
#: the Newton matrix (the law is not linear within the state: the slip directions of 3D
#: friction) and left a residual more than MISMATCH times what its linear solve asked for
#: asks only for REMAINDER_SAFETY of the remainder Newton's quadratic rate predicts for the
#: next iterate, where that remainder is above Newton's target (`front_tolerance`;
#: docs/scaling.md).
NONLINEAR_FORCING = True
MISMATCH = 100.0
REMAINDER_SAFETY = 0.1

#: The preconditioners (PETSc PC types) after whose loose solves NONLINEAR_FORCING applies;
#: after a loose solve with another, it applies from the next exact solve on. With BoomerAMG
#: the step after a loose one left the law's remainder (block3d 22k: 9.04e-6 against 9.02e-6
#: from an exact solve); with GAMG (the PyPI route) the residual rose after such a step
#: (block3d 52k: 1.06e-4 to 3.04e-4), and the step took 13 Newton iterations instead of 10
#: (docs/scaling.md).
AFTER_LOOSE_PCS = ("hypre",)


def front_tolerance(loose: bool, rtol: float, norm: float, target: float,
                    previous: tuple[float, float] | None = None) -> float:
    """The relative tolerance of a solve under the front rule (FrontRule): LOOSE for a loose
    one; for an exact one at residual `norm`, with Newton stopping at `target`, `forcing`
    with the ceiling LOOSE and the safety EXACT_SAFETY (EXACT_FORCING), else `rtol`, the
    solver's own tolerance.

    With `previous` = (|F_{k-1}|, eta_{k-1}), the residual and the asked tolerance of the
    iteration before, given where the Newton matrix changed at the fixed state (the caller
    passes None otherwise), and NONLINEAR_FORCING: where |F_k| > MISMATCH eta_{k-1} |F_{k-1}|,
    the step from x_{k-1} was limited by the law's nonlinearity, not by its linear solve,
    and the next residual will be at least about the quadratic remainder
    N = |F_k|^3 / |F_{k-1}|^2 (|F_{k+1}| ~ C |F_k|^2 with C = |F_k| / |F_{k-1}|^2); a
    linear residual far below N buys nothing, so for N > target

        eta = min(LOOSE, max(eta_forcing, REMAINDER_SAFETY N / |F_k|)).

    At a fixed state of a piecewise-linear law the step's residual is its linear one. In 2D
    with the paper's laws a few entries change within a branch, but the steps measured left
    at most 13 times what their solves asked, below MISMATCH, and the rule did not apply
    (docs/scaling.md)."""
    if loose:
        return LOOSE
    if not EXACT_FORCING:
        return rtol
    eta = forcing(rtol, norm, target, ceiling=LOOSE, safety=EXACT_SAFETY)
    if NONLINEAR_FORCING and previous is not None:
        norm_before, asked_before = previous
        if norm_before > 0.0 and norm > MISMATCH * asked_before * norm_before:
            remainder = norm ** 3 / norm_before ** 2
            if remainder > target:
                eta = min(LOOSE, max(eta, REMAINDER_SAFETY * remainder / norm))
    return eta


#: At most this many loose solves in one Newton solve; the later ones are exact, so a
#: sequence of loose steps that keeps changing the state cannot cycle for ever.
MAX_LOOSE = 12


def contact_state(parts) -> np.ndarray:
    """Each owned contact node's branch of the law at the iterate of the node blocks `parts`
    (condensed.eliminate plus B, C, D): the nullity m - rank D_i (how many conditions are
    active: at the bound, sticking), whether the normal multiplier row depends on u_i (C_i's
    first row: a compliant node against a free one) and which rows depend on lambda_i (D_i's
    non-zero rows). An (n, 2 + m) array of small integers; two iterates are in the
    same contact state where these arrays are equal."""
    C, D = parts["C"], parts["D"]
    # The normal row of C only (row 0): a free node's is 0, a compliant one's not. Stick and
    # slip are told apart by the nullity; a tangential row of C can be exactly 0 at one
    # iterate and not at the next within one branch, and would make every state look new.
    return np.hstack([np.asarray(parts["nullity"])[:, None],
                      np.any(C[:, :1] != 0, axis=2), np.any(D != 0, axis=2)]).astype(np.int8)


class FrontRule:
    """The accuracy of each Newton iteration's linear solve under the front rule.

    A semi-smooth Newton iteration of the contact problem does two things: it moves the
    active set (the nodes at the bound, sticking, free) towards the converged one, and, once
    the active set A_k no longer changes, it solves the problem of that active set, which for
    a linear bulk law and the piecewise-linear conditions is a linear one (Hintermueller, Ito
    and Kunisch, SIAM J. Optim. 13, 2003, 865-888: the primal-dual active set method is the
    semi-smooth Newton method, and it stops when A_{k+1} = A_k). Only that last kind of solve
    has to be accurate; an iteration that only discovers the next change of the active set
    needs the step's direction, not its last digits. So the solve at iterate k is

        loose (relative tolerance LOOSE) if k = 0 or state(x_k) != state(x_{k-1}),
        exact otherwise,

    and exact from the (MAX_LOOSE + 1)-th would-be loose solve of a Newton solve on. An
    exact solve asks for eta = min(LOOSE, max(rtol, EXACT_SAFETY target / |F(x_k)|))
    (`front_tolerance`; rtol, the solver's own tolerance, with EXACT_FORCING off): at a
    fixed state of a piecewise-linear law the next residual is the linear one, and only the
    reduction down to the target is needed.

    Newton's stopping test, on the coupled residual |F(x_k)| <= target, accepts an
    iterate after any step only where its residual is below the target. The converged
    iterate follows an exact solve whenever the last iteration did not change the state,
    so it is the one of the all-exact method to the linear tolerance's effect.

    The state is compared node by node on each rank and the counts of changed nodes summed
    over all ranks, so every rank takes the same decision."""

    def __init__(self):
        self.previous = None      # state(x_{k-1}) on this rank
        self.loose_solves = 0     # over the object's life
        self.exact_solves = 0
        self.in_solve = 0         # loose solves in the current Newton solve

    def reset(self):
        """A new Newton solve (a new step): its first iterate has no previous one."""
        self.previous = None
        self.in_solve = 0

    def loose(self, state, comm) -> bool:
        """Whether the solve at the iterate of `state` (contact_state) is loose; collective
        over `comm` (an mpi4py communicator)."""
        if self.previous is None or self.previous.shape != state.shape:
            changed = -1
        else:
            changed = int(np.count_nonzero(np.any(state != self.previous, axis=1)))
        counts = comm.allgather(changed)
        self.previous = state.copy()
        loose = (min(counts) < 0 or sum(counts) > 0) and self.in_solve < MAX_LOOSE
        if loose:
            self.loose_solves += 1
            self.in_solve += 1
        else:
            self.exact_solves += 1
        return loose
