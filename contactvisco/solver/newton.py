"""A PETSc SNES generalized Newton over UFL residuals (DOLFINx 0.5 has no SNES wrapper of its
own).

Each Newton step solves J(w) dw = -F(w) for the unknowns w = (u, lambda_nu, lambda_tau); J is
the UFL derivative of F, i.e. an element of the generalized (Clarke) Jacobian of the
semismooth residual. Two forms of that linear system, with the same iterates:

- CondensedSNES (default where the contact conditions hold node by node): the multipliers are
  eliminated node by node (contactvisco.solver.condensed) and the system has the size of u;
- BlockSNES: u and the multipliers (whole-mesh P1 fields) in one block-assembled saddle-point
  system (the Gauss contact quadrature needs it).

`create` picks one from the scene, and a direct (MUMPS) or iterative (GMRES + BoomerAMG)
linear solver.

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
by P's factors solves J x = b in at most s + 1 iterations (in exact arithmetic). Such a step
is solved by FGMRES (right-preconditioned: its residual is J's own) to STALE_RTOL with P's
factors, and P is refactorized only when J differs from it in more than STALE_ROWS rows, or
when the last solve with P took more than STALE_KRYLOV iterations or did not converge. A
factorization costs 9 to 15 triangular solves at 64^2 to 128^2 cells (docs/scaling.md), so
each kept factorization saves most of a Newton iteration's time. Matrices equal to P are solved
by P's factors alone (KSP preonly), bit for bit as before.
"""
from __future__ import annotations

import hashlib
import itertools
import weakref

import numpy as np
import ufl
from dolfinx import fem
from mpi4py import MPI
from petsc4py import PETSc

from contactvisco.fem import compat, parts
from contactvisco.solver.bordered import ObstacleForce
from contactvisco.solver import floating, linear
from contactvisco.solver.condensed import NodalCondensation
from contactvisco.errors import SceneError

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

#: The iterative linear solver: GMRES preconditioned by BoomerAMG (hypre), HMIS coarsening with
#: extended+i interpolation; the relative tolerance is tight enough for Newton to take the
#: steps of the direct solver. Iteration counts against PETSc's GAMG: docs/scaling.md.
ITERATIVE_OPTIONS = {
    "ksp_type": "gmres",
    "ksp_gmres_restart": 100,
    "ksp_rtol": 1e-10,
    "ksp_atol": 1e-14,
    "ksp_max_it": 1000,
    "pc_type": "hypre",
    "pc_hypre_type": "boomeramg",
    "pc_hypre_boomeramg_strong_threshold": 0.7,
    "pc_hypre_boomeramg_coarsen_type": "HMIS",
    "pc_hypre_boomeramg_interp_type": "ext+i",
    "pc_hypre_boomeramg_P_max": 4,
    "pc_hypre_boomeramg_agg_nl": 1,
}

#: Where PETSc has no hypre: GMRES preconditioned by PETSc's smoothed-aggregation AMG (GAMG),
#: with the rigid motions as near-nullspace. Each Jacobian has other constraint rows (other
#: active contact nodes) than the first, so the prolongation is rebuilt for every Jacobian
#: instead of being reused; the aggregation threshold is the one chosen in docs/scaling.md
#: (benchmarks/performance/gamg.py).
GAMG_OPTIONS = {
    "ksp_type": "gmres",
    "ksp_gmres_restart": 100,
    "ksp_rtol": 1e-10,
    "ksp_atol": 1e-14,
    "ksp_max_it": 1000,
    "pc_type": "gamg",
    "pc_gamg_type": "agg",
    "pc_gamg_reuse_interpolation": False,
    "pc_gamg_threshold": 0.02,
    "mg_levels_ksp_type": "chebyshev",
    "mg_levels_pc_type": "jacobi",
}

#: linear_solver = "auto" takes the iterative solver from this many displacement unknowns on
#: (by dimension), with BoomerAMG; where the measurements put the switch: docs/scaling.md
#: (in 2D 100000 since the direct solver keeps factorizations of nearby matrices: MUMPS is
#: ahead at 33282 unknowns and even at 132098).
AUTO_ITERATIVE = {2: 100_000, 3: 5_000}

#: The same where PETSc has no hypre (GAMG): docs/scaling.md.
AUTO_ITERATIVE_GAMG = {2: 530_000, 3: 22_000}


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


#: The displacement system with the direct solver keeps its factorization for a Newton matrix
#: of another step size (another memory weight) until the FGMRES iterations beyond the first
#: of the solves with its factors add up to more than NEARBY_BUDGET, about what a
#: factorization costs in triangular solves (9 to 15 at 64^2 to 128^2 cells, docs/scaling.md):
#: renting before buying, at most twice the cost of the better choice made in hindsight; or
#: until a solve does not converge within NEARBY_MAX_IT iterations (enable_nearby).
NEARBY_BUDGET = 10
NEARBY_MAX_IT = 12
#: Off: every new matrix is factorized (the measurement's reference).
NEARBY = True


def auto_iterative_size(d: int) -> int:
    """The number of displacement unknowns from which linear_solver = "auto" is iterative."""
    return (AUTO_ITERATIVE if compat.has_hypre() else AUTO_ITERATIVE_GAMG)[d]


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

#: Options whose values keep the condensed iterates the coupled method's, as a test of the
#: value PETSc reads: any other value is refused by CondensedSNES.
EQUIVALENCE_OPTIONS = {
    "snes_type": lambda value: value.lower() == "newtonls",
    "snes_linesearch_type": lambda value: value.lower() in ("basic", "none"),
    "snes_linesearch_damping": lambda value: _is_number(value) and float(value) == 1.0,
    "snes_lag_jacobian": lambda value: _is_number(value) and float(value) == 1.0,
    "snes_lag_preconditioner": lambda value: _is_number(value) and float(value) == 1.0,
}


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
        self._fingerprint = None         # of the matrix the preconditioner was built from
        self.stale_rows = 0              # keep P's factors for J differing in <= these rows
        self._factorized = None          # the CSR values of the factorized operator P
        self._stale = False              # the current step is solved with an earlier P
        self._krylov_limit = 0           # the most FGMRES iterations the row count allows
        self.floating = None             # floating motions (solver.floating)
        self.nearby = False              # keep P's factors for any nearby J (enable_nearby)
        self._nearby_extra = 0           # FGMRES iterations beyond the first since P's factors
        self.nearby_solves = 0           # solves with an earlier matrix's factors (a run's)
        self.kept = None                 # the iterative solver's kept preconditioner (linear)

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
        owned = ("snes", "b", "x", "A", "_x_jacobian", "_du") + (
            ("operator",) if self.reuse or self.__dict__.get("kept") is not None
            else ())                                # else the operator is A or J_red
        for name in owned:
            obj = self.__dict__.get(name)
            if obj is not None:
                obj.destroy()

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
            elif self.kept.build_next(self.snes.getKSP(), A):
                A.copy(self.operator, structure=PETSc.Mat.Structure.SAME_NONZERO_PATTERN)
                self.setups += 1
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
            self.stale_rows = STALE_ROWS if rows is None else rows

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
        if values is None or self._factorized is None or len(values) != len(self._factorized):
            differ = -1
        else:
            entries = np.flatnonzero(values != self._factorized)
            differ = int(np.unique(np.searchsorted(indptr, entries, side="right")).size)
        exhausted = self._stale and (
            ksp.getConvergedReason() != PETSc.KSP.ConvergedReason.CONVERGED_RTOL
            or ksp.getIterationNumber() > STALE_KRYLOV)
        counts = comm.allgather((differ, exhausted))
        rows = -1 if any(c < 0 for c, _ in counts) else sum(c for c, _ in counts)
        if rows == 0:
            self._use_factors(ksp, stale=False)
        elif 0 < rows <= self.stale_rows and not any(e for _, e in counts):
            self._krylov_limit = min(rows + 2, STALE_MAX_IT)
            self._use_factors(ksp, stale=True)
        else:
            A.copy(self.operator, structure=PETSc.Mat.Structure.SAME_NONZERO_PATTERN)
            self._factorized = None if values is None else values.copy()
            self.setups += 1
            self._use_factors(ksp, stale=False)

    def _use_factors(self, ksp, stale):
        """P's factors alone (preonly: A equals P) or inside FGMRES (A differs from P)."""
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
        direct solver's default), also that a Jacobian close to the factorized one is solved
        by FGMRES on the earlier factors, which is when the steps print Krylov iterations.

        Returns
        -------
        str
            E.g. 'preonly/lu, fgmres/lu on the last factors for <= 16 changed rows'.
        """
        name = self.linear_solver()
        if self.stale_rows > 0:
            pc = self.snes.getKSP().getPC().getType()
            name = (f"preonly/{pc}, fgmres/{pc} on the last factors for <= {self.stale_rows} "
                    "changed rows")
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


class BlockSNES(NewtonSolver):
    """SNES over all unknowns `functions` (u and the multipliers) with residual blocks F and
    Jacobian blocks J: the coupled saddle-point system."""

    system_kind = "coupled"

    def __init__(self, F, J, functions, bcs, comm, scene_options=None, defaults=None,
                 reuse=False):
        super().__init__(comm, functions, scene_options, defaults, reuse)
        J = [list(row) for row in J]
        # Multiplier dofs off Gamma_C have no entry in the ds blocks: a zero dx mass term gives
        # them a diagonal in the sparsity pattern for their Dirichlet rows.
        for i in range(1, len(functions)):
            space = functions[i].function_space
            zero = fem.Constant(space.mesh, PETSc.ScalarType(0.0))
            mass = zero * ufl.inner(ufl.TrialFunction(space), ufl.TestFunction(space)) * ufl.dx
            J[i][i] = mass if J[i][i] is None else J[i][i] + mass
        self.F = [fem.form(f) for f in F]
        self.J = [[None if a is None else fem.form(a) for a in row] for row in J]
        self.bcs = bcs
        self.b = compat.block_vector(self.F)
        self.x = compat.block_vector(self.F)
        self.A = compat.block_matrix(self.J)
        self.operator = self.A
        if reuse:
            self._assemble_jacobian()      # the operator takes the assembled pattern
            self.operator = self.A.duplicate(copy=True)
        self.snes.setFunction(_weak(self._residual), self.b)
        self.snes.setJacobian(_weak(self._jacobian), self.operator)
        self._finish_setup()

    def keep_nearby_factors(self):
        """The displacement system with the direct solver: J (the assembled matrix) and P
        (the factorized operator) given to the SNES apart, and enable_nearby."""
        if self.reuse and len(self.functions) == 1 and NEARBY:
            self.snes.setJacobian(_weak(self._jacobian), self.A, self.operator)
            self.enable_nearby()

    def _residual(self, snes, x, b):
        # SNES updates only the owned entries of x; the lifting of the Dirichlet rows below
        # reads x's ghosts too. Stale ghosts go unnoticed while all prescribed values are 0.
        x.ghostUpdate(addv=_INSERT, mode=_FORWARD)
        # Copy SNES's iterate into the Functions (ghosts included) before assembling.
        self._to_functions(x)
        with b.localForm() as local:
            local.set(0.0)
        # Rows of Dirichlet dofs become x - g: SNES then drives them to g.
        compat.assemble_block_residual(b, self.F, self.J, self.bcs, x, scale=-1.0)

    def _assemble_jacobian(self):
        self.A.zeroEntries()
        compat.assemble_block_matrix(self.A, self.J, self.bcs, diagonal=1.0)
        self.A.assemble()

    def _jacobian(self, snes, x, A, P):
        self._assemble_jacobian()
        self._to_operator(self.A)


#: Most evaluations of a force-controlled curved obstacle's closest points within one step.
MAX_PLACEMENTS = 10


def _condensation(problem):
    """The condensed system of a problem: NodalCondensation, or for a contact boundary that
    meets another body of the mesh its InterfaceCondensation."""
    if hasattr(problem.contact.obstacle, "pairing"):
        from contactvisco.solver.interface_newton import InterfaceCondensation
        return InterfaceCondensation(problem)
    return NodalCondensation(problem)


class CondensedSNES(NewtonSolver):
    """SNES over u alone, the nodal multipliers eliminated node by node in every Newton step
    (contactvisco.solver.condensed); they are updated from each displacement step, as the coupled
    Newton step's dl for that du. That holds for full Newton steps with a Jacobian at every
    iterate: options that change this are refused (_check_options), and a residual evaluated
    away from such a step stops the solve with a clear error rather than wrong iterates."""

    system_kind = "condensed"

    def __init__(self, problem, comm, scene_options=None, defaults=None, reuse=False):
        super().__init__(comm, [problem.u], scene_options, defaults, reuse)
        self.system = _condensation(problem)
        # The node blocks of a residual wait for its Jacobian (NodalCondensation.defer), not
        # in the two-body system, which transforms the condensed residual further.
        self.system.defer = type(self.system) is NodalCondensation
        u_vector = compat.petsc_vector(problem.u)
        self.b = u_vector.copy()
        self.x = u_vector.copy()
        self._x_jacobian = u_vector.copy()   # the iterate of the last Jacobian
        self._du = u_vector.copy()
        self._pending = False            # a step from _x_jacobian awaits its multiplier update
        self._residuals_since_jacobian = 0
        self._broken = None              # why the iterates left the coupled method's, if so
        obstacle = problem.contact.obstacle
        # The iterative solver's preconditioner is built from an operator of its own, copied
        # from J_red only when linear.KeptPreconditioner says so.
        if linear.KEEP and not reuse and type(self.system) is NodalCondensation and not (
                obstacle is not None and obstacle.controlled):
            self.kept = linear.KeptPreconditioner(self.system.bulk_stamp)
        self.operator = (self.system.J_red.duplicate(copy=True)
                         if reuse or self.kept is not None else self.system.J_red)
        self.snes.setFunction(_weak(self._residual), self.b)
        self.snes.setJacobian(_weak(self._jacobian), self.system.J_red, self.operator)
        # Converged when the residual of the coupled problem (u and multiplier rows) is small,
        # as with BlockSNES; the condensed residual alone leaves out the multiplier rows.
        self.snes.setConvergenceTest(_weak(self._converged))
        self.operator.setNearNullSpace(near_nullspace(problem))
        obstacle = problem.contact.obstacle
        self.force = (ObstacleForce(problem, self.system)
                      if obstacle is not None and obstacle.controlled else None)
        self._error = None               # an error raised inside a SNES callback
        if self.force is not None:
            self._shift, self._u_now = u_vector.copy(), u_vector.copy()
            self.system.defer = False
        self._finish_setup()
        self._ksp_rtol = self.snes.getKSP().getTolerances()[0]
        if self.force is None:           # the bordered solves need P's exact factors
            self.enable_stale()

    def _check_options(self):
        """The multipliers are recovered from each displacement step as the coupled Newton
        step's dl: that needs a Jacobian at every iterate and the full step taken. Options
        that change either (a lagged Jacobian or preconditioner, a line search other than the
        full step, damping, another SNES type, matrix-free or finite-difference Jacobians) are
        refused here by name."""
        problems = []
        for key, allowed in EQUIVALENCE_OPTIONS.items():
            value = self.options.given(key)
            if value is not None and not allowed(value.strip()):
                problems.append(f"{self.options.origin(key)} = {value}")
        if self.snes.getType() != "newtonls" and not problems:
            problems.append(f"the SNES type {self.snes.getType()}")
        if self.snes.getUseMF() or self.snes.getUseFD():
            problems.append("a matrix-free or finite-difference Jacobian (-snes_mf, "
                            "-snes_mf_operator, -snes_fd)")
        if problems:
            raise SceneError(
                f"{problems[0]}: the condensed Newton system (solver.linear_system = "
                "'condensed', the default with nodal contact quadrature) follows the coupled "
                "Newton method only with a Jacobian at every iterate and the full step "
                "(snes_type newtonls, snes_linesearch_type basic, no lag, no damping)"
                + (f"; also refused: {', '.join(problems[1:])}" if problems[1:] else "")
                + ". Use solver.linear_system = 'coupled' for such options")

    def solve(self) -> int:
        """Newton from the current Functions (NewtonSolver.solve). With a force-controlled
        curved obstacle, the closest points and normals are evaluated again at the converged
        position d and Newton continues from there, until d moves less than 1e-12 of the
        body's size within a solve (ObstacleForce.replace); the iterations of every solve
        are counted."""
        iterations = self._solve_once()
        for _ in range(MAX_PLACEMENTS):
            if self.force is None or not self.force.replace():
                return iterations
            iterations += self._solve_once()
        raise NewtonFailure(f"the force-controlled obstacle's position did not settle after "
                            f"{MAX_PLACEMENTS} evaluations of its closest points",
                            -5, list(self.residuals))

    def _solve_once(self) -> int:
        if self.force is not None:
            self._shift.set(0.0)
        self._pending = False
        self._broken = None
        self._error = None
        self._residuals_since_jacobian = 0
        try:
            iterations = super().solve()
            finish = getattr(self.system, "finish", None)
            if finish is not None:           # Functions that SNES's slots do not hold
                finish()
            return iterations
        except (NewtonFailure, SceneError, PETSc.Error):
            if self._error is not None:
                raise self._error from None
            if self._broken:
                raise SceneError(self._broken) from None
            raise

    def destroy(self):
        if self.__dict__.get("force") is not None:
            self.force.destroy()
            self._shift.destroy()
            self._u_now.destroy()
            self.force = None
        if self.__dict__.get("system") is not None:
            self.system.destroy()
        super().destroy()

    def _monitor(self, snes, it, norm):
        super()._monitor(snes, it, self.system.full_norm)

    def _shifted(self, x):
        """u = x + shift: SNES's iterate x with the obstacle's share of the bordered steps
        (force control; SNES's own vector is read-only in its callbacks)."""
        x.copy(self._u_now)
        self._u_now.axpy(1.0, self._shift)
        self._u_now.ghostUpdate(addv=_INSERT, mode=_FORWARD)
        return self._u_now

    def _to_functions(self, x):
        super()._to_functions(self._shifted(x) if self.force is not None and x is self.x
                              else x)

    def _residual(self, snes, x, b):
        x.ghostUpdate(addv=_INSERT, mode=_FORWARD)
        if self.force is not None:
            x = self._shifted(x)
        if self._error is not None:          # solve() raises it when SNES stops
            b.set(np.nan)
            self.system.full_norm = float("nan")
            return
        if self._pending:
            # x = x_J - y, the step from the last Jacobian's iterate: update the multipliers.
            x.copy(self._du)
            self._du.axpy(-1.0, self._x_jacobian)
            dl = self.system.update_multipliers(self._du)
            self._pending = False
            if self.force is not None:         # the bordered step: d and its share of x
                try:
                    self.force.correct([x, self._shift], self._du, dl)
                except SceneError as err:      # raised by solve() after SNES stops
                    self._error = err
                    b.set(np.nan)
                    self.system.full_norm = float("nan")
                    return
        elif self._residuals_since_jacobian > 0:
            # A second residual since the last Jacobian (a lagged Jacobian, a line search
            # trying a shorter step): the multipliers would not follow. Stop with NaN, and
            # solve() turns it into a clear error.
            self._broken = (
                "the condensed Newton system evaluated a residual away from the full Newton "
                "step of the last Jacobian (an option lagging the Jacobian or changing the "
                "line search?); use solver.linear_system = 'coupled' for such options")
            b.set(np.nan)
            self.system.full_norm = float("nan")
            return
        self._residuals_since_jacobian += 1
        self._to_functions(x)
        self.system.residual(x, b)
        if self.force is not None:             # the obstacle's force rows join the norm
            G = self.force.residual()
            self.system.full_norm = float(np.hypot(self.system.full_norm,
                                                   np.linalg.norm(G)))

    def _jacobian(self, snes, x, A, P):
        self.system.jacobian()
        self._to_operator(self.system.J_red)
        if linear.INEXACT and not self.reuse:            # the iterative solver
            atol, rtol, _, _ = snes.getTolerances()
            ksp = snes.getKSP()
            target = max(atol, rtol * self._norm0)
            ksp.setTolerances(rtol=linear.forcing(self._ksp_rtol, self.system.full_norm,
                                                  target))
        if (self.floating is not None
                and self.floating.unbalanced >= floating.UNBALANCED_JACOBIANS):
            self._error = SceneError(floating.UNBALANCED, key="solver.linear_solver")
        (self._shifted(x) if self.force is not None else x).copy(self._x_jacobian)
        self._pending = True
        self._residuals_since_jacobian = 0
        if self.force is not None:
            try:
                self.force.linearize(snes.getKSP())
            except SceneError as err:        # raised by solve() after SNES stops
                self._error = err

    def _converged(self, snes, it, norms):
        norm = self.system.full_norm
        atol, rtol, _, max_it = snes.getTolerances()
        if it == 0:
            self._norm0 = norm
        if not np.isfinite(norm):
            return PETSc.SNES.ConvergedReason.DIVERGED_FNORM_NAN
        if norm <= atol:
            return PETSc.SNES.ConvergedReason.CONVERGED_FNORM_ABS
        if it > 0 and norm <= rtol * self._norm0:
            return PETSc.SNES.ConvergedReason.CONVERGED_FNORM_RELATIVE
        if it >= max_it:
            return PETSc.SNES.ConvergedReason.DIVERGED_MAX_IT
        return PETSc.SNES.ConvergedReason.CONVERGED_ITERATING


def matrix_fingerprint(A) -> bytes | None:
    """A hash of the values of this rank's rows of the assembled AIJ matrix A (None for a
    matrix type without CSR access): equal fingerprints on every rank, with the fixed
    sparsity pattern of a Newton matrix, mean the same matrix."""
    try:
        _, _, values = A.getValuesCSR()
    except PETSc.Error:
        return None
    return hashlib.blake2b(np.ascontiguousarray(values).tobytes(), digest_size=16).digest()


def iterative_options() -> dict:
    """GMRES with BoomerAMG where PETSc has hypre, else with GAMG."""
    return ITERATIVE_OPTIONS if compat.has_hypre() else GAMG_OPTIONS


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


def create(problem, comm, scene_options=None) -> NewtonSolver:
    """The Newton solver a Problem's scene asks for (solver.linear_system, .linear_solver)."""
    solver = problem.scene["solver"]
    options = solver["petsc_options"] if scene_options is None else scene_options
    multipliers = len(problem.unknowns) > 1
    nodal = problem.scene["discretization"]["contact_quadrature"] == "nodal"
    system = solver["linear_system"]
    if system == "auto":
        system = "condensed" if multipliers and nodal else "coupled"
    if not multipliers:
        system = "displacement"                # nothing to condense: u is the only unknown
    if system == "condensed" and not nodal:
        raise SceneError("solver.linear_system = 'condensed' needs nodal contact quadrature",
                         key="solver.linear_system")
    d = problem.V.mesh.geometry.dim
    size = problem.count_unknowns()["u"]
    kind = solver["linear_solver"]
    if kind == "auto":
        kind = ("iterative" if system != "coupled" and size >= auto_iterative_size(d)
                and not _held_by_contact(problem) else "direct")
    if kind == "iterative" and system == "coupled":
        raise SceneError("solver.linear_solver = 'iterative' needs the displacement-only "
                         "system: solver.linear_system = 'condensed' (nodal contact "
                         "quadrature)", key="solver.linear_solver")
    defaults = iterative_options() if kind == "iterative" else {}
    obstacle = problem.contact and problem.contact.obstacle
    if obstacle is not None and obstacle.controlled and system != "condensed":
        raise SceneError("obstacle.force_components: force control is solved with the "
                         f"condensed Newton system, not the {system} one (it needs nodal "
                         "contact multipliers: a finite contact.g or friction)",
                         key="obstacle.force_components")
    if hasattr(obstacle, "pairing"):           # another body of the mesh (fem.body_contact)
        if not multipliers:
            from contactvisco.solver.interface_newton import InterfaceSNES
            return _with_floating(InterfaceSNES(problem, comm, options, defaults,
                                                reuse=kind == "direct"), problem, kind)
        if system != "condensed":
            raise SceneError("obstacle.shape = 'body' with contact multipliers is solved with "
                             "the condensed Newton system (solver.linear_system = 'auto' or "
                             "'condensed', nodal contact quadrature)",
                             key="solver.linear_system")
    if system == "condensed":
        newton = CondensedSNES(problem, comm, options, defaults, reuse=kind == "direct")
    else:
        newton = BlockSNES(problem.F, problem.J, problem.unknowns, problem.bcs, comm,
                           options, defaults, reuse=kind == "direct")
        if system != "displacement":           # u and the multipliers: no motions of u alone
            return newton
        newton.system_kind = system            # u alone: a block system of one block
        newton.operator.setNearNullSpace(near_nullspace(problem))
        newton.keep_nearby_factors()
    return _with_floating(newton, problem, kind)


def _held_by_contact(problem) -> bool:
    """Whether the problem pairs two bodies of its mesh and one of them has a rigid motion no
    prescribed component restrains (fem.parts.floating_motions): held only by the contact,
    its Newton matrix can be singular with an unbalanced load in an iterate
    (solver.floating), so linear_solver = "auto" takes the direct solver."""
    obstacle = problem.contact and problem.contact.obstacle
    if not hasattr(obstacle, "pairing"):
        return False
    labels, count = parts.part_labels(problem.V)
    return bool(parts.floating_motions(problem.V, problem.u_fixed, labels, count))


def _with_floating(newton, problem, kind):
    """The solver of a system in u alone (displacement, condensed, two bodies) with the
    floating rigid motions of the mesh's parts, if it has any (contactvisco.solver.floating):
    the iterative one gets its Newton matrices' null spaces among them, the direct one its
    Newton matrices stabilized where they have one."""
    newton.floating = floating.FloatingNullSpace.of(
        problem, newton.operator.createVecRight(), direct=kind != "iterative")
    return newton
