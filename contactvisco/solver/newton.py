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
"""
from __future__ import annotations

import itertools
import weakref

import numpy as np
import ufl
from dolfinx import fem
from petsc4py import PETSc

from contactvisco.fem import compat
from contactvisco.solver.condensed import NodalCondensation
from contactvisco.errors import SceneError

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

#: The iterative linear solver: GMRES preconditioned by BoomerAMG (hypre), HMIS coarsening with
#: extended+i interpolation. On the condensed contact system it kept 12-19 Krylov iterations
#: per Newton step from 128^2 to 512^2 cells, where PETSc's GAMG needed 40-120 (the rows of
#: active nodes are constraints, not elasticity). The relative tolerance is tight enough for
#: Newton to take the steps of the direct solver.
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
#: with the rigid motions as near-nullspace like BoomerAMG. By default GAMG keeps the
#: prolongation built for the first matrix and only recomputes the Galerkin coarse operators;
#: here each Jacobian has other constraint rows (other active contact nodes) than the first
#: one (t_0's first Newton iteration), and with that stale prolongation the Krylov count grew
#: with the mesh. So it is rebuilt for every Jacobian, as BoomerAMG's set-up is. Graph edges
#: weaker than 0.02 of the diagonal are dropped from the aggregation: the flattest count among
#: the thresholds tried (docs/scaling.md, benchmarks/gamg.py).
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

#: linear_solver = "auto" takes the iterative solver from this many displacement unknowns
#: on (by dimension), where it was measured to beat MUMPS (benchmarks/scaling.py), with
#: BoomerAMG.
AUTO_ITERATIVE = {2: 20_000, 3: 5_000}

#: The same where PETSc has no hypre (GAMG). In 2D MUMPS stayed faster per Newton iteration up
#: to the largest size measured (benchmarks/gamg.py, docs/scaling.md), so auto keeps it up to
#: there. In 3D (block3d) GAMG was faster per Newton iteration from the smallest measured size
#: above this threshold on, and MUMPS at the measured sizes below it.
AUTO_ITERATIVE_GAMG = {2: 530_000, 3: 22_000}


def auto_iterative_size(d: int) -> int:
    """The number of displacement unknowns from which linear_solver = "auto" is iterative."""
    return (AUTO_ITERATIVE if compat.has_hypre() else AUTO_ITERATIVE_GAMG)[d]

#: Scene options (solver.petsc_options) -> the solvers (by number) that were given the option
#: and have not read it, neither at setup nor in any solve so far.
_UNREAD_SCENE_OPTIONS: dict[str, set[int]] = {}
_SOLVER_NUMBERS = itertools.count()


def _petsc_library():
    """The loaded PETSc library, for PetscOptionsUsed (petsc4py 3.18 does not wrap it)."""
    import ctypes
    try:
        with open("/proc/self/maps") as maps:
            paths = sorted({line.split()[-1] for line in maps if "libpetsc" in line})
        return ctypes.CDLL(paths[0]) if paths else None
    except (OSError, IndexError):
        return None


_LIBRARY = []


def option_used(name: str) -> bool | None:
    """Whether PETSc has read the option `name` (without '-'); None if that is unknown."""
    import ctypes
    if not _LIBRARY:
        _LIBRARY.append(_petsc_library())
    library = _LIBRARY[0]
    if library is None:
        return None
    flag = ctypes.c_int(0)
    if library.PetscOptionsUsed(None, name.encode(), ctypes.byref(flag)) != 0:
        return None
    return bool(flag.value)


def unused_options(arguments) -> list[str]:
    """Options of the command line (arguments, e.g. ['-snes_monitor', '-ksp_type', 'cg']) and
    of scenes that no solver read: misspelled, or for a solver that was not used."""
    names = [a.lstrip("-") for a in arguments if a.startswith("-") and len(a) > 1
             and not _is_number(a)]
    unused = [f"-{name}" for name in names if option_used(name) is False]
    unused += [f"-{name} (solver.petsc_options)"
               for name, solvers in sorted(_UNREAD_SCENE_OPTIONS.items()) if solvers]
    return unused


def _is_number(text: str) -> bool:
    try:
        float(text)
        return True
    except ValueError:
        return False


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


class _Newton:
    """The SNES shared by both linear systems: options, monitor, solve, failure report."""

    def __init__(self, comm, functions, scene_options=None, defaults=None):
        self.functions = functions
        self.residuals: list[float] = []
        self.krylov_iterations: list[int] = []
        # Command-line options win over the scene, the scene over the defaults. This solver's
        # options are in PETSc's global database only during its setup and each of its
        # solves (_push_options, _pop_options), so they do not leak into other solvers.
        opts = PETSc.Options()
        merged = dict(DEFAULT_OPTIONS)
        merged.update(defaults or {})
        merged.update(scene_options or {})
        self._scene_options = set(scene_options or {})
        self._options = {key: value for key, value in merged.items()
                         if not opts.hasName(key)}
        self._number = next(_SOLVER_NUMBERS)
        self._scene_read: dict[str, str] = {}    # scene options PETSc read: key -> "-key value"
        self._pushed = False
        self.snes = PETSc.SNES().create(comm)

    def _finish_setup(self):
        self.snes.setMonitor(_weak(self._monitor))
        self._push_options()
        try:
            self.snes.setFromOptions()
            self._check_options()
        except PETSc.Error as err:
            raise self._rejected(err) from None
        finally:                       # also when PETSc rejects an option
            self._pop_options()

    def _check_options(self):
        """Refuse options this linear system cannot follow (raises SceneError); the options
        are still in PETSc's database here."""

    def _origin(self, key: str) -> str:
        """Where option `key` came from, for messages: the scene key or the command line."""
        if key in self._scene_options:
            return f"solver.petsc_options.{key}"
        return f"the option -{key}"

    def _rejected(self, err) -> SceneError:
        """The error for an option value PETSc rejected, naming the given options it had read
        (by scene key where the scene gave it, so that the message gets its origin)."""
        opts = PETSc.Options()
        given = {key: value for key, value in opts.getAll().items()
                 if key in self._scene_options or key not in self._options}
        read = [key for key in given if option_used(key)]
        reason = f"PETSc error {err.ierr}" + (": unknown type" if err.ierr == 86 else "")
        named = ", ".join(f"-{k} {given[k] or ''}".strip() for k in read) or "none"
        scene_keys = [k for k in read if k in self._scene_options]
        if scene_keys:
            return SceneError(f"solver.petsc_options.{scene_keys[0]}: PETSc rejected an "
                              f"option value ({reason}); the given options it had read: "
                              f"{named}", key=f"solver.petsc_options.{scene_keys[0]}")
        return SceneError(f"PETSc rejected a command-line option value ({reason}); the "
                          f"given options it had read: {named}")

    def _push_options(self):
        """Put this solver's options into PETSc's global database: for its setup, and for
        each solve, since PETSc reads some options only while solving (MUMPS its ICNTL and
        CNTL when it first factors the matrix)."""
        opts = PETSc.Options()
        for key, value in self._options.items():
            opts[key] = value
        self._pushed = True

    def _pop_options(self):
        """Take this solver's options out of PETSc's global database again (idempotent),
        noting first which of the scene's options PETSc has read: deleting an option drops
        PETSc's record of its use, so the record is kept here across pushes."""
        if not self._pushed:
            return
        self._note_reads()
        opts = PETSc.Options()
        for key in self._options:
            opts.delValue(key)
        self._pushed = False

    def _note_reads(self):
        """Record the scene options PETSc has read since the push, and keep the scene
        options this solver has never read in _UNREAD_SCENE_OPTIONS (for unused_options)."""
        opts = PETSc.Options()
        for key in self._scene_options & self._options.keys():
            used = option_used(key)
            if used:
                self._scene_read[key] = f"-{key} {opts.getString(key, '')}".strip()
            unread = _UNREAD_SCENE_OPTIONS.setdefault(key, set())
            if used is False and key not in self._scene_read:
                unread.add(self._number)
            else:                      # read now or before, or unknown: not reported
                unread.discard(self._number)

    def destroy(self):
        """Free the SNES and its vectors and matrices (idempotent); the object is unusable
        afterwards."""
        self._pop_options()
        for name in ("snes", "b", "x", "A", "_x_jacobian", "_du"):
            obj = self.__dict__.get(name)
            if obj is not None:
                obj.destroy()

    def _given_read(self) -> list[str]:
        """Options of the scene and of the command line that PETSc has read (at setup or in
        a solve); called while this solver's options are in PETSc's database."""
        self._note_reads()
        command_line = [f"-{key} {value or ''}".strip()
                        for key, value in PETSc.Options().getAll().items()
                        if key not in self._options and option_used(key)]
        return list(self._scene_read.values()) + command_line

    def _monitor(self, snes, it, norm):
        self.residuals.append(float(norm))
        if it > 0:
            self.krylov_iterations.append(snes.getKSP().getIterationNumber())

    def linear_solver(self) -> str:
        """KSP and PC types, e.g. 'preonly/lu' or 'gmres/gamg'."""
        ksp = self.snes.getKSP()
        return f"{ksp.getType()}/{ksp.getPC().getType()}"

    def solve(self) -> int:
        """Newton from the current Functions; returns the iteration count or raises
        NewtonFailure. The Functions hold the converged solution afterwards."""
        self.residuals = []
        self.krylov_iterations = []
        self._from_functions(self.x)
        self._push_options()
        try:
            self.snes.solve(None, self.x)
        except PETSc.Error as err:
            # An option value PETSc checks only when it sets up the solve (a factorization
            # package, a MUMPS parameter): name the given options it had read.
            given = self._given_read()
            if not given:
                raise
            raise SceneError(f"PETSc stopped with error {err.ierr} while setting up the solve "
                             f"(its message is above); given options it had read: "
                             f"{', '.join(given)}") from None
        finally:                       # nothing of this solver stays in the database
            self._pop_options()
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


class BlockSNES(_Newton):
    """SNES over all unknowns `functions` (u and the multipliers) with residual blocks F and
    Jacobian blocks J: the coupled saddle-point system."""

    system_kind = "coupled"

    def __init__(self, F, J, functions, bcs, comm, scene_options=None, defaults=None):
        super().__init__(comm, functions, scene_options, defaults)
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
        self.snes.setFunction(_weak(self._residual), self.b)
        self.snes.setJacobian(_weak(self._jacobian), self.A)
        self._finish_setup()

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

    def _jacobian(self, snes, x, A, P):
        A.zeroEntries()
        compat.assemble_block_matrix(A, self.J, self.bcs, diagonal=1.0)
        A.assemble()


class CondensedSNES(_Newton):
    """SNES over u alone, the nodal multipliers eliminated node by node in every Newton step
    (contactvisco.solver.condensed); they are updated from each displacement step, as the coupled
    Newton step's dl for that du. That holds for full Newton steps with a Jacobian at every
    iterate: options that change this are refused (_check_options), and a residual evaluated
    away from such a step stops the solve with a clear error rather than wrong iterates."""

    system_kind = "condensed"

    def __init__(self, problem, comm, scene_options=None, defaults=None):
        super().__init__(comm, [problem.u], scene_options, defaults)
        self.system = NodalCondensation(problem)
        u_vector = compat.petsc_vector(problem.u)
        self.b = u_vector.copy()
        self.x = u_vector.copy()
        self._x_jacobian = u_vector.copy()   # the iterate of the last Jacobian
        self._du = u_vector.copy()
        self._pending = False            # a step from _x_jacobian awaits its multiplier update
        self._residuals_since_jacobian = 0
        self._broken = None              # why the iterates left the coupled method's, if so
        self.snes.setFunction(_weak(self._residual), self.b)
        self.snes.setJacobian(_weak(self._jacobian), self.system.J_red)
        # Converged when the residual of the coupled problem (u and multiplier rows) is small,
        # as with BlockSNES; the condensed residual alone leaves out the multiplier rows.
        self.snes.setConvergenceTest(_weak(self._converged))
        self.system.J_red.setNearNullSpace(rigid_body_modes(problem.V))
        self._finish_setup()

    def _check_options(self):
        """The multipliers are recovered from each displacement step as the coupled Newton
        step's dl: that needs a Jacobian at every iterate and the full step taken. Options
        that change either (a lagged Jacobian or preconditioner, a line search other than the
        full step, damping, another SNES type, matrix-free or finite-difference Jacobians) are
        refused here by name."""
        opts = PETSc.Options()
        problems = []
        for key, allowed in EQUIVALENCE_OPTIONS.items():
            if opts.hasName(key) and not allowed(opts.getString(key, "").strip()):
                problems.append(f"{self._origin(key)} = {opts.getString(key, '')}")
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
        self._pending = False
        self._broken = None
        self._residuals_since_jacobian = 0
        try:
            return super().solve()
        except (NewtonFailure, SceneError, PETSc.Error):
            if self._broken:
                raise SceneError(self._broken) from None
            raise

    def _monitor(self, snes, it, norm):
        super()._monitor(snes, it, self.system.full_norm)

    def _residual(self, snes, x, b):
        x.ghostUpdate(addv=_INSERT, mode=_FORWARD)
        if self._pending:
            # x = x_J - y, the step from the last Jacobian's iterate: update the multipliers.
            x.copy(self._du)
            self._du.axpy(-1.0, self._x_jacobian)
            self.system.update_multipliers(self._du)
            self._pending = False
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

    def _jacobian(self, snes, x, A, P):
        self.system.jacobian()
        x.copy(self._x_jacobian)
        self._pending = True
        self._residuals_since_jacobian = 0

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


def rigid_body_modes(V) -> PETSc.NullSpace:
    """The rigid motions (2D: 3, 3D: 6) as an orthonormal near-nullspace of elasticity, for
    algebraic multigrid."""
    d = V.dofmap.index_map_bs
    x = V.tabulate_dof_coordinates()[:V.dofmap.index_map.size_local, :d]
    n = x.shape[0]
    modes = []
    for c in range(d):                          # translations
        mode = np.zeros((n, d))
        mode[:, c] = 1.0
        modes.append(mode)
    for a, b in ([(0, 1)] if d == 2 else [(0, 1), (1, 2), (2, 0)]):   # rotations
        mode = np.zeros((n, d))
        mode[:, a], mode[:, b] = -x[:, b], x[:, a]
        modes.append(mode)
    vectors = []
    for mode in modes:
        vec = PETSc.Vec().createMPI((n * d, None), bsize=d, comm=V.mesh.comm)
        vec.array[:] = mode.ravel()
        vectors.append(vec)
    for i, vec in enumerate(vectors):           # modified Gram-Schmidt
        for earlier in vectors[:i]:
            vec.axpy(-earlier.dot(vec), earlier)
        vec.normalize()
    return PETSc.NullSpace().create(vectors=vectors, comm=V.mesh.comm)


def create(problem, comm, scene_options=None) -> _Newton:
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
                else "direct")
    if kind == "iterative" and system == "coupled":
        raise SceneError("solver.linear_solver = 'iterative' needs the displacement-only "
                         "system: solver.linear_system = 'condensed' (nodal contact "
                         "quadrature)", key="solver.linear_solver")
    defaults = iterative_options() if kind == "iterative" else {}
    if system == "condensed":
        newton = CondensedSNES(problem, comm, options, defaults)
    else:
        newton = BlockSNES(problem.F, problem.J, problem.unknowns, problem.bcs, comm,
                           options, defaults)
        if system == "displacement":           # u alone: a block system of one block
            newton.system_kind = system
            newton.A.setNearNullSpace(rigid_body_modes(problem.V))
    return newton
