"""What every Newton solver of contactvisco.solver shares: a PETSc SNES over UFL forms
(NewtonSolver) with its options, its failures (NewtonFailure, SlidingLimit), the reuse of
factorizations, and the near-nullspace of elasticity for algebraic multigrid. The linear
systems built on it are in contactvisco.solver.newton (the displacement, coupled and condensed
systems, and `create`, which picks one) and contactvisco.solver.interface_newton (two bodies
of one mesh); both import this module and not each other.

PETSc options: each solver (NewtonSolver) writes its own under a prefix of its own,
contactvisco_<n>_, when it is set up, and removes them when it is destroyed (SolverOptions);
the command line's (unprefixed) options are copied under the prefix, so they act on every
solver. Options that no solver read are reported by unused_options, from PETSc's record of
reads where petsc4py gives it (Options.used; petsc4py 3.18 has none).

Preconditioner reuse: the Newton matrix of a linear bulk law depends on the iterate only
through each contact node's branch of the law (free, compliant, at the bound, stick or slip),
so consecutive iterations and steps often assemble the same matrix. With the direct solver
each Jacobian is assembled into a matrix of its own and fingerprinted (a hash of its local
values, compared on every rank); only when it differs from the linear solver's operator is it
copied there, so an unchanged operator keeps its factorization and the solve is exactly the
one a new factorization would give. The price is one more matrix of the system's size, small
beside the LU factors; the iterative solver, whose memory is mostly the matrix, assembles
into its operator directly and rebuilds its AMG hierarchy at every Jacobian.

Factorizations of nearby matrices (the condensed system with the direct solver): a Newton
matrix J that differs from the factorized operator P in only a few rows (a few contact nodes
changed branch) is J = P + E Delta with E the identity's columns of those rows, so P^-1 J is
the identity plus a matrix of rank at most their number s, and a Krylov method preconditioned
by P's factors solves J x = b in at most s + 1 iterations (in exact arithmetic). By default
such a step is solved directly, by P's factors and the Woodbury identity for the s changed
rows (low_rank.LowRankSolve, a python KSP: one triangular solve per solve and one per changed
row and factorization), refined to STALE_RTOL on J's own residual, and P is refactorized when
J differs from it in more than LOW_RANK_ROWS rows, when the rows met since the factorization
exceed STALE_MAX_IT, or when a solve did not converge. With LOW_RANK off it is solved by
FGMRES (right-preconditioned: its residual is J's own) to STALE_RTOL with P's factors, and P
is refactorized when J differs from it in more than STALE_ROWS rows, or when the last solve
with P took more than STALE_KRYLOV iterations or did not converge. A factorization costs 9
to 15 triangular solves at 64^2 to 128^2 cells (docs/scaling.md), so each kept factorization
saves most of a Newton iteration's time. Matrices equal to P are solved by P's factors alone
(KSP preonly), bit for bit as before.
"""
from __future__ import annotations

import hashlib
import itertools
import weakref

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from contactvisco.errors import SceneError
from contactvisco.fem import compat, parts
from contactvisco.solver import floating, low_rank


#: SNES defaults: full Newton steps (the basic line search) and no divergence tolerance (its
#: default stops runs with a large augmentation parameter after one step); docs/scaling.md
#: gives the measurements behind them.
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

#: A direct solver keeps its factorization for Newton matrices that differ from the factorized
#: one in at most this many rows (over all ranks), solving them by FGMRES (module description).
STALE_ROWS = 16

#: FGMRES with an earlier matrix's factors: relative and absolute residual tolerance (the
#: residual of J x = b, against |b|), and the most iterations before the factorization is
#: renewed (the step is then taken from the last Krylov iterate).
STALE_RTOL = 1e-12
STALE_ATOL = 1e-300
STALE_MAX_IT = 2 * STALE_ROWS + 8

#: The next Newton matrix is factorized when the last solve with an earlier matrix's factors
#: took more FGMRES iterations than this (each costs a triangular solve and a product).
STALE_KRYLOV = 4

#: On (the default): a Newton matrix within LOW_RANK_ROWS rows of the factorized one is
#: solved with P's factors and a low-rank correction of those rows (low_rank.LowRankSolve:
#: one triangular solve per solve, and one per changed row and factorization), instead of
#: FGMRES within STALE_ROWS rows (about one triangular solve per changed row and solve); P is
#: factorized again when the rows met since its factorization exceed STALE_MAX_IT or a solve
#: fails to converge. The row bound is the one measured best on the paper scene at 64^2 and
#: 128^2 cells (docs/scaling.md).
LOW_RANK = True
LOW_RANK_ROWS = 24


#: The displacement system with the direct solver keeps its factorization for a Newton matrix
#: of another step size (another memory weight) until the FGMRES iterations beyond the first
#: of the solves with its factors add up to more than NEARBY_BUDGET, about what a
#: factorization costs in triangular solves (9 to 15 at 64^2 to 128^2 cells, docs/scaling.md):
#: renting before buying, at most twice the cost of the better choice made in hindsight; or
#: until a solve does not converge within NEARBY_MAX_IT iterations (enable_nearby).
NEARBY_BUDGET = 10
NEARBY_MAX_IT = 12
#: Every solver keeps its options in PETSc's database under its own prefix PREFIX<n>_. PETSc
#: looks an option that is missing there up under PREFIX alone (it drops the number of a
#: numbered prefix), so options given as -contactvisco_<option> act on every solver.
PREFIX = "contactvisco_"
_SOLVER_NUMBERS = itertools.count()

#: Scene options (solver.petsc_options) -> the solvers (by number) that were given the option
#: and have not read it, neither at setup nor in any solve so far.
_UNREAD_SCENE_OPTIONS: dict[str, set[int]] = {}


def option_read(name: str) -> bool | None:
    """PETSc's record of whether an object has read the option `name` (without '-'), or None
    where petsc4py does not give it (no Options.used, as in petsc4py 3.18)."""
    used = getattr(PETSc.Options(), "used", None)
    return None if used is None else bool(used(name))


def unused_options(arguments) -> list[str]:
    """Options of the command line (arguments, e.g. ['-snes_monitor', '-ksp_type', 'cg']) and
    of scenes that no solver read: misspelled, or for a solver that was not used. Empty where
    PETSc's record of reads is not available (option_read)."""
    names = [a.lstrip("-") for a in arguments if a.startswith("-") and len(a) > 1
             and not _is_number(a)]
    unused = [f"-{name}" for name in names if option_read(name) is False]
    unused += [f"-{name} (solver.petsc_options)"
               for name, solvers in sorted(_UNREAD_SCENE_OPTIONS.items()) if solvers]
    return unused


def _is_number(text: str) -> bool:
    try:
        float(text)
        return True
    except ValueError:
        return False


def _remove_prefix(prefix: str):
    """Delete every option under `prefix` from PETSc's database (local to the process)."""
    if PETSc.Sys.isFinalized():
        return
    opts = PETSc.Options()
    for key in [k for k in opts.getAll() if k.startswith(prefix)]:
        opts.delValue(key)


class SolverOptions:
    """The PETSc options of one solver, under its own prefix in PETSc's database from its
    setup (write) until it is destroyed (remove). The command line (the unprefixed options in
    the database: petsc4py.init's arguments, PETSC_OPTIONS) wins over the scene
    (solver.petsc_options), the scene over the solver's defaults."""

    def __init__(self, scene_options=None, defaults=None):
        self.number = next(_SOLVER_NUMBERS)
        self.prefix = f"{PREFIX}{self.number}_"
        command_line = {key: value for key, value in PETSc.Options().getAll().items()
                        if not key.startswith(PREFIX)}
        scene = {key: value for key, value in (scene_options or {}).items()
                 if key not in command_line}
        self.values = {**DEFAULT_OPTIONS, **(defaults or {}), **scene, **command_line}
        self.command_line = list(command_line)
        self.scene = list(scene)
        self._removal = None

    def write(self):
        """Put the options into PETSc's database under the prefix; they leave it by remove(),
        or when this object is collected."""
        opts = PETSc.Options()
        for key, value in self.values.items():
            opts[self.prefix + key] = value
        self._removal = weakref.finalize(self, _remove_prefix, self.prefix)

    def given(self, key: str) -> str | None:
        """The value the solver's objects see for `key`: its own, else the one under PREFIX
        for all solvers (None: not given)."""
        if key in self.values:
            value = self.values[key]
            if isinstance(value, bool):
                return str(value).lower()
            return "" if value is None else str(value)
        return PETSc.Options().getAll().get(PREFIX + key)

    def origin(self, key: str) -> str:
        """Where option `key` came from, for messages: the scene key or the command line."""
        return f"solver.petsc_options.{key}" if key in self.scene else f"the option -{key}"

    def read(self, key: str) -> bool | None:
        """Whether PETSc has read this solver's option `key` (option_read)."""
        return option_read(self.prefix + key)

    def given_read(self) -> list[str]:
        """'-key value' of the scene's and the command line's options that PETSc has read
        under the prefix; all of them where PETSc's record is not available."""
        return [f"-{key} {self.given(key)}".strip() for key in self.scene + self.command_line
                if self.read(key) is not False]

    def note_reads(self):
        """Keep PETSc's record of reads where it outlives the prefixed options: the scene
        options this solver has not read in _UNREAD_SCENE_OPTIONS (unused_options), and a read
        copy of a command-line option as a read of the option itself (marked by hasName), so
        that neither unused_options nor PETSc's -options_left report it. Where the record is
        not available, every copy counts as read."""
        if self._removal is None or not self._removal.alive:
            return
        for key in self.scene:
            unread = _UNREAD_SCENE_OPTIONS.setdefault(key, set())
            if self.read(key) is False:
                unread.add(self.number)
            else:
                unread.discard(self.number)
        for key in self.command_line:
            if self.read(key) is not False:
                PETSc.Options().hasName(key)

    def remove(self):
        """Take every option under the prefix out of PETSc's database (idempotent), after
        noting the reads."""
        self.note_reads()
        if self._removal is not None:
            self._removal()


_INSERT, _ADD = PETSc.InsertMode.INSERT, PETSc.InsertMode.ADD
_FORWARD = PETSc.ScatterMode.FORWARD

class NewtonFailure(RuntimeError):
    """A Newton solve (PETSc SNES) that did not converge.

    Parameters
    ----------
    message : str
        What failed, with the step and a likely cause.
    reason : int
        The SNES converged reason (negative: diverged).
    residuals : list of float
        The residual norms of the last attempt.
    """

    def __init__(self, message, reason, residuals):
        super().__init__(message)
        self.reason = reason
        self.residuals = residuals


class SlidingLimit(NewtonFailure):
    """A run stopped because a slave node of two bodies in contact (obstacle.shape = "body")
    slid past the small-sliding limit of its pairing, made once in the reference
    configuration: its tangential displacement relative to the master exceeds half its
    master facet (fem.body_contact.BodyContact.sliding). A NewtonFailure, so that the
    command line ends with exit 3; the steps completed before are kept.

    Parameters
    ----------
    message : str
        The node's position, its slip, the limit and the time.
    position : tuple of float
        The slave node's reference coordinates.
    slip, limit : float
        The tangential displacement relative to the master at the node, and half its
        master facet's size.
    t : float
        The time of the step that went past the limit (not recorded).
    """

    def __init__(self, message, position, slip, limit, t):
        super().__init__(message, 0, [])
        self.position, self.slip, self.limit, self.t = position, slip, limit, t


def residual_summary(residuals) -> str:
    """The residual history in a few words: its first and last norms and its length (the
    whole history is NewtonFailure.residuals)."""
    if not residuals:
        return "residual history: none computed"
    return (f"residual history |F| {residuals[0]:.2e} -> {residuals[-1]:.2e} "
            f"({len(residuals)} values)")


class NewtonSolver:
    """A PETSc SNES over UFL forms, shared by both linear systems: its options (SolverOptions,
    under a prefix of its own), monitor, solve and failure report."""

    def __init__(self, comm, functions, scene_options=None, defaults=None, reuse=False):
        self.functions = functions
        self.reuse = reuse               # keep the factorization of an unchanged matrix
        self.residuals: list[float] = []
        self.krylov_iterations: list[int] = []
        self.options = SolverOptions(scene_options, defaults)
        self.snes = PETSc.SNES().create(comm)
        self.setups = 0                  # preconditioner set-ups (factorizations) of a solve
        self.solves = 0                  # solves so far (steps and cut steps, failed ones too)
        self.all_setups = 0              # and their set-ups
        self._fingerprint = None         # of the matrix the preconditioner was built from
        self.stale_rows = 0              # keep P's factors for J differing in <= these rows
        self._factorized = None          # the CSR values of the factorized operator P
        self._stale = False              # the current step is solved with an earlier P
        self.low_rank = None             # the solves with P's factors and J's changed rows
        self._krylov_limit = 0           # the most FGMRES iterations the row count allows
        self.floating = None             # floating motions (solver.floating)
        self.nearby = False              # keep P's factors for any nearby J (enable_nearby)
        self._nearby_extra = 0           # FGMRES iterations beyond the first since P's factors
        self.nearby_solves = 0           # solves with an earlier matrix's factors (a run's)
        self.kept = None                 # the iterative solver's kept preconditioner (linear)
        self.fresh_prolongations = 0     # GAMG prolongations rebuilt after a failed solve
        self.later = False               # for the states after the first (newton.create)
        self.auto_direct = False         # auto's direct solver for them (AUTO_DIRECT_LATER)
        self._loose = None               # the front rule's choice for the next solve (linear)
        self._state = None               # and the contact state it was taken at

    def _finish_setup(self):
        """Give the SNES (and through it the KSP, PC, line search and the factorization or
        fieldsplit objects they make) the prefix and its options. On failure the solver is
        destroyed, its options removed, and a SceneError names the given options."""
        self.snes.setMonitor(_weak(self._monitor))
        self.snes.setOptionsPrefix(self.options.prefix)
        self.options.write()
        try:
            self.snes.setFromOptions()
            self._check_options()
        except PETSc.Error as err:
            error = self._rejected(err)
            self.destroy()
            raise error from None
        except BaseException:
            self.destroy()
            raise
        self.options.note_reads()

    def _check_options(self):
        """Refuse options this linear system cannot follow (raises SceneError)."""

    def _rejected(self, err) -> SceneError:
        """The error for an option value PETSc rejected, naming the given options it had read
        (by scene key where the scene gave one, so that the message gets its origin)."""
        reason = f"PETSc error {err.ierr}" + (": unknown type" if err.ierr == 86 else "")
        named = ", ".join(self.options.given_read()) or "none"
        scene_keys = [key for key in self.options.scene if self.options.read(key) is not False]
        if scene_keys:
            return SceneError(f"solver.petsc_options.{scene_keys[0]}: PETSc rejected an "
                              f"option value ({reason}); the given options it had read: "
                              f"{named}", key=f"solver.petsc_options.{scene_keys[0]}")
        return SceneError(f"PETSc rejected a command-line option value ({reason}); the "
                          f"given options it had read: {named}")

    def destroy(self):
        """Free the SNES and its vectors and matrices and take its options out of PETSc's
        database (idempotent); the object is unusable afterwards."""
        self.options.remove()
        if self.__dict__.get("floating") is not None:
            self.floating.destroy()
            self.floating = None
        if self.__dict__.get("low_rank") is not None:
            self.low_rank.forget()
        owned = ("snes", "b", "x", "A", "_x_jacobian", "_du", "_trial", "_trial_b",
                 "kept") + (
            ("operator",) if self.reuse or self.__dict__.get("kept") is not None
            else ())                                # else the operator is A or J_red
        for name in owned:
            obj = self.__dict__.get(name)
            if obj is not None:
                obj.destroy()

    def _fresh_prolongation(self):
        """Where GAMG keeps its prolongation across set-ups (pc_gamg_reuse_interpolation)
        and the last solve did not converge, build a new prolongation at every set-up from
        now on (newton.GAMG_REUSE_INTERPOLATION): a kept prolongation that let a solve fail
        is not trusted for the rest of the run.

        Called before each set-up. The option is turned off under the solver's prefix and
        the preconditioner made anew (its type set away and back, its options read again),
        rather than reset by PCReset: after PCReset, PETSc 3.18's GAMG kept its level
        solvers at the old sizes, and a set-up whose aggregation gave coarse levels of other
        sizes failed ("Cannot change local size of Amat after use"). The operator keeps the
        rigid motions as its near-nullspace, from which the new GAMG takes them."""
        ksp = self.snes.getKSP()
        pc = ksp.getPC()
        if pc.getType() != "gamg" or ksp.getConvergedReason() >= 0:
            return
        key = (pc.getOptionsPrefix() or "") + "pc_gamg_reuse_interpolation"
        options = PETSc.Options()
        if options.getBool(key, False):
            options[key] = False
            pc.setType(PETSc.PC.Type.NONE)
            pc.setType(PETSc.PC.Type.GAMG)
            pc.setFromOptions()
            self.fresh_prolongations += 1

    def _to_operator(self, A):
        """Hand the freshly assembled Newton matrix A to the linear solver: copied into the
        SNES's operator (and the preconditioner rebuilt from it, counted in `setups`) unless
        A is bitwise the operator already there, on every rank; then the operator's PETSc
        state is unchanged and PCSetUp keeps its factorization. Without `reuse` A is the
        operator itself. With floating motions (solver.floating) the operator gets its null
        spaces among them."""
        if self.floating is not None:
            self.floating.prepare(A, self.b)
        if not self.reuse:
            if self.kept is None:
                self.setups += 1
                self._fresh_prolongation()
            elif self.kept.build_next(self.snes.getKSP(), A, self._loose, self._state):
                A.copy(self.operator, structure=PETSc.Mat.Structure.SAME_NONZERO_PATTERN)
                self.setups += 1
                self._fresh_prolongation()
            return
        if self.stale_rows > 0:
            self._to_operator_or_stale(A)
            return
        fingerprint = matrix_fingerprint(A)
        same = fingerprint is not None and fingerprint == self._fingerprint
        if A.getComm().tompi4py().allreduce(same, op=MPI.LAND):
            if self.nearby:
                self._use_factors(self.snes.getKSP(), stale=False)
            return
        if self.nearby and self._fingerprint is not None and not self._nearby_exhausted():
            self._krylov_limit = NEARBY_MAX_IT
            self._use_factors(self.snes.getKSP(), stale=True)
            self.nearby_solves += 1
            return
        A.copy(self.operator, structure=PETSc.Mat.Structure.SAME_NONZERO_PATTERN)
        self._fingerprint = fingerprint
        self.setups += 1
        if self.nearby:
            self._nearby_extra = 0
            self._use_factors(self.snes.getKSP(), stale=False)

    def enable_nearby(self):
        """Keep the factorization of the operator P for every Newton matrix J while FGMRES
        with P's factors solves J x = b to STALE_RTOL, until the iterations beyond the first
        of those solves add up to more than NEARBY_BUDGET (or one does not converge within
        NEARBY_MAX_IT). A new step size changes the memory's weight on every row of the bulk
        operator, J = P + (w(k') - w(k)) M, and P^-1 J = I + (w(k') - w(k)) P^-1 M is close to
        the identity for nearby k. Only with the direct solver's defaults (reuse, KSP preonly,
        PC lu) of the displacement system, whose SNES must have J as its Jacobian matrix and P
        as its preconditioner matrix; otherwise nothing changes."""
        ksp = self.snes.getKSP()
        if self.reuse and ksp.getType() == "preonly" and ksp.getPC().getType() == "lu":
            self.nearby = True

    def _nearby_exhausted(self) -> bool:
        """The last solve with an earlier matrix's factors did not converge, or the solves
        with P's factors took more than NEARBY_BUDGET iterations beyond their first (the same
        on every rank: the KSP's reductions are global)."""
        ksp = self.snes.getKSP()
        if not self._stale:
            return False
        self._nearby_extra += max(ksp.getIterationNumber() - 1, 0)
        return (ksp.getConvergedReason() != PETSc.KSP.ConvergedReason.CONVERGED_RTOL
                or self._nearby_extra > NEARBY_BUDGET)

    def enable_stale(self, rows: int | None = None):
        """Keep the factorization of the operator P for Newton matrices J that differ from it
        in at most `rows` rows (module description); only with the direct solver's defaults
        (reuse, KSP preonly, PC lu): otherwise nothing changes. The SNES must have been given
        J as its Jacobian matrix and P as its preconditioner matrix.

        Parameters
        ----------
        rows : int, optional
            s_max (default STALE_ROWS): J with at most s_max rows other than P's is solved
            by FGMRES with P's factors, P^-1 J = I + (rank <= s_max); 0 turns the mode off.
        """
        ksp = self.snes.getKSP()
        if self.reuse and ksp.getType() == "preonly" and ksp.getPC().getType() == "lu":
            self.stale_rows = ((LOW_RANK_ROWS if LOW_RANK else STALE_ROWS) if rows is None
                               else rows)
            if LOW_RANK and self.stale_rows > 0:
                self.low_rank = low_rank.LowRankSolve(STALE_RTOL, STALE_ATOL, STALE_MAX_IT)

    def _to_operator_or_stale(self, A):
        """_to_operator with stale factorizations: the rows of A that differ from P, counted
        over all ranks, decide between P's factors alone (none), FGMRES with P's factors (at
        most stale_rows, and the last such solve converged within its bound) and a new
        factorization of A (copied into P)."""
        ksp = self.snes.getKSP()
        comm = A.getComm().tompi4py()
        try:
            indptr, _, values = A.getValuesCSR()
        except PETSc.Error:
            indptr = values = None
        changed = np.zeros(0, dtype=np.int64)  # the owned rows of A other than P's (local)
        if values is None or self._factorized is None or len(values) != len(self._factorized):
            differ = -1
        else:
            entries = np.flatnonzero(values != self._factorized)
            changed = np.unique(np.searchsorted(indptr, entries, side="right")) - 1
            differ = int(changed.size)
        # (the low-rank solve is exact: only a failed one exhausts P's factors)
        exhausted = self._stale and (
            ksp.getConvergedReason() != PETSc.KSP.ConvergedReason.CONVERGED_RTOL
            or (self.low_rank is None and ksp.getIterationNumber() > STALE_KRYLOV))
        counts = comm.allgather((differ, exhausted))
        rows = -1 if any(c < 0 for c, _ in counts) else sum(c for c, _ in counts)
        if rows == 0:
            self._use_factors(ksp, stale=False)
            return
        if 0 < rows <= self.stale_rows and not any(e for _, e in counts):
            if self.low_rank is None:
                self._krylov_limit = min(rows + 2, STALE_MAX_IT)
                self._use_factors(ksp, stale=True)
                return
            start = A.getOwnershipRange()[0]
            if self.low_rank.use(np.concatenate(comm.allgather(changed + start))):
                self._use_factors(ksp, stale=True)
                return
        A.copy(self.operator, structure=PETSc.Mat.Structure.SAME_NONZERO_PATTERN)
        self._factorized = None if values is None else values.copy()
        self.setups += 1
        if self.low_rank is not None:
            self.low_rank.forget()
        self._use_factors(ksp, stale=False)

    def _use_factors(self, ksp, stale):
        """P's factors alone (preonly: A equals P), or, where A differs from P, with the
        low-rank correction of its changed rows (a python KSP, low_rank.LowRankSolve) or
        inside FGMRES (the nearby mode, or LOW_RANK off)."""
        if stale and self.low_rank is not None:
            if ksp.getType() != "python":
                ksp.setType("python")
                ksp.setPythonContext(self.low_rank)
            self._stale = True
            return
        if stale != self._stale or ksp.getType() != ("fgmres" if stale else "preonly"):
            ksp.setType("fgmres" if stale else "preonly")
            if stale:
                ksp.setGMRESRestart(STALE_MAX_IT)
                ksp.setPCSide(PETSc.PC.Side.RIGHT)
                ksp.setConvergenceTest(_weak(self._krylov_converged))
        self._stale = stale

    def _krylov_converged(self, ksp, its, rnorm):
        """FGMRES with an earlier matrix's factors: converged at |r| <= STALE_RTOL |b| (or
        STALE_ATOL); at its bound (stale row count + 2, at most STALE_MAX_IT) the iterate is
        taken as it is and the next Jacobian is factorized."""
        if its == 0:
            self._krylov_b = rnorm
        if rnorm <= max(STALE_RTOL * self._krylov_b, STALE_ATOL):
            return PETSc.KSP.ConvergedReason.CONVERGED_RTOL
        if its >= self._krylov_limit:
            return PETSc.KSP.ConvergedReason.CONVERGED_ITS
        return PETSc.KSP.ConvergedReason.ITERATING

    def _monitor(self, snes, it, norm):
        self.residuals.append(float(norm))
        if it > 0:
            self.krylov_iterations.append(snes.getKSP().getIterationNumber())

    def linear_solver(self) -> str:
        """KSP and PC types, e.g. 'preonly/lu' or 'gmres/gamg'."""
        ksp = self.snes.getKSP()
        return f"{ksp.getType()}/{ksp.getPC().getType()}"

    def describe_linear_solver(self) -> str:
        """linear_solver() as a run's header says it: with stale factorizations on (the
        direct solver's default), also how a Jacobian close to the factorized one is solved:
        by the earlier factors with the low-rank update of its changed rows (LOW_RANK), or by
        FGMRES on them, which is when the steps print Krylov iterations.

        Returns
        -------
        str
            E.g. 'preonly/lu, lu on the last factors with a low-rank update for <= 24
            changed rows'.
        """
        name = self.linear_solver()
        if self.stale_rows > 0:
            pc = self.snes.getKSP().getPC().getType()
            kept = (f"{pc} on the last factors with a low-rank update"
                    if self.low_rank is not None else f"fgmres/{pc} on the last factors")
            name = f"preonly/{pc}, {kept} for <= {self.stale_rows} changed rows"
        return name

    def solve(self) -> int:
        """Newton from the current Functions; returns the iteration count or raises
        NewtonFailure. The Functions hold the converged solution afterwards."""
        self.residuals = []
        self.krylov_iterations = []
        self.setups = 0
        if self.floating is not None:
            self.floating.unbalanced = 0
        self._from_functions(self.x)
        try:
            self.snes.solve(None, self.x)
        except PETSc.Error as err:
            # An option value PETSc checks only when it sets up the solve (a factorization
            # package, a MUMPS parameter): name the given options it had read.
            given = self.options.given_read()
            if not given:
                raise
            raise SceneError(f"PETSc stopped with error {err.ierr} while setting up the solve "
                             f"(its message is above); given options it had read: "
                             f"{', '.join(given)}") from None
        finally:                       # MUMPS reads its options in the first solve
            self.options.note_reads()
            self.solves += 1
            self.all_setups += self.setups
        self._to_functions(self.x)
        reason = self.snes.getConvergedReason()
        if (reason <= 0 and self.floating is not None
                and self.floating.unbalanced >= floating.UNBALANCED_JACOBIANS):
            raise SceneError(floating.UNBALANCED, key="solver.linear_solver")
        if reason > 0 and not np.isfinite(self.x.norm()):
            reason = -4      # never accept a non-finite solution as converged
        if reason <= 0:
            raise NewtonFailure(
                f"Newton did not converge (SNES reason {reason}) after "
                f"{self.snes.getIterationNumber()} iterations; "
                f"{residual_summary(self.residuals)}", reason, list(self.residuals))
        return self.snes.getIterationNumber()

    def _to_functions(self, x):
        offset = 0
        array = x.getArray(readonly=True)
        for f in self.functions:
            vec = compat.petsc_vector(f)
            n = vec.getLocalSize()
            vec.array[:] = array[offset:offset + n]
            vec.ghostUpdate(addv=_INSERT, mode=_FORWARD)
            offset += n

    def _from_functions(self, x):
        offset = 0
        array = x.getArray()
        for f in self.functions:
            vec = compat.petsc_vector(f)
            n = vec.getLocalSize()
            array[offset:offset + n] = vec.array
            offset += n
        x.ghostUpdate(addv=_INSERT, mode=_FORWARD)


def matrix_fingerprint(A) -> bytes | None:
    """A hash of the values of this rank's rows of the assembled AIJ matrix A (None for a
    matrix type without CSR access): equal fingerprints on every rank, with the fixed
    sparsity pattern of a Newton matrix, mean the same matrix."""
    try:
        _, _, values = A.getValuesCSR()
    except PETSc.Error:
        return None
    return hashlib.blake2b(np.ascontiguousarray(values).tobytes(), digest_size=16).digest()


def _weak(method):
    """A callback for the SNES that calls `method` through a weak reference to its object:
    the SNES keeps the callback, and a bound method would keep the solver (and through it the
    problem, mesh and communicators) in a reference cycle through PETSc that Python's
    collector cannot see."""
    ref = weakref.WeakMethod(method)

    def call(*args):
        return ref()(*args)
    return call


def rigid_body_modes(V, labels=None, count: int = 1) -> PETSc.NullSpace:
    """The rigid motions (2D: 3, 3D: 6) as an orthonormal near-nullspace of elasticity, for
    algebraic multigrid; with several parts of the mesh (two bodies in contact), those of
    each part (fem.parts.rigid_motions: 3 or 6 per part, zero off it).

    Parameters
    ----------
    V : dolfinx.fem.FunctionSpace
        The displacement space (P1, block size d).
    labels : numpy.ndarray, optional
        The part of every local node (fem.parts.part_labels).
    count : int, optional
        The number of parts; with 1 the motions of the whole mesh.

    Returns
    -------
    petsc4py.PETSc.NullSpace
        The motions m(x) = a + W (x - c) (W skew) orthonormalized by modified Gram-Schmidt.
    """
    d = V.dofmap.index_map_bs
    x = V.tabulate_dof_coordinates()[:V.dofmap.index_map.size_local, :d]
    n = x.shape[0]
    if count > 1:
        modes = [mode for per_part in parts.rigid_motions(x, labels[:n], count, V.mesh.comm)
                 for mode in per_part]
        return _orthonormal(modes, V.mesh.comm)
    modes = []
    for c in range(d):                          # translations
        mode = np.zeros((n, d))
        mode[:, c] = 1.0
        modes.append(mode)
    for a, b in ([(0, 1)] if d == 2 else [(0, 1), (1, 2), (2, 0)]):   # rotations
        mode = np.zeros((n, d))
        mode[:, a], mode[:, b] = -x[:, b], x[:, a]
        modes.append(mode)
    return _orthonormal(modes, V.mesh.comm)


def _orthonormal(modes, comm) -> PETSc.NullSpace:
    """Arrays (owned nodes, d) as an orthonormal PETSc.NullSpace (modified Gram-Schmidt)."""
    n, d = modes[0].shape
    vectors = []
    for mode in modes:
        vec = PETSc.Vec().createMPI((n * d, None), bsize=d, comm=comm)
        vec.array[:] = mode.ravel()
        vectors.append(vec)
    for i, vec in enumerate(vectors):           # modified Gram-Schmidt
        for earlier in vectors[:i]:
            vec.axpy(-earlier.dot(vec), earlier)
        vec.normalize()
    return PETSc.NullSpace().create(vectors=vectors, comm=comm)


def near_nullspace(problem) -> PETSc.NullSpace:
    """The near-nullspace of a problem's Newton matrix for algebraic multigrid: the rigid
    motions of each connected part of its mesh (rigid_body_modes).

    Parameters
    ----------
    problem : contactvisco.fem.problem.Problem
        The problem (its displacement space V).

    Returns
    -------
    petsc4py.PETSc.NullSpace
        3 (2D) or 6 (3D) orthonormal motions per part.
    """
    labels, count = parts.part_labels(problem.V)
    return rigid_body_modes(problem.V, labels, count)
