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

What the systems share (the solver class with its PETSc options, failures, kept
factorizations and the near-nullspace of elasticity) is in contactvisco.solver.newton_base,
which contactvisco.solver.interface_newton (two bodies of one mesh) imports too; its public
names are available from this module as well.
"""
from __future__ import annotations

import numpy as np
import ufl
from dolfinx import fem
from petsc4py import PETSc

from contactvisco.errors import SceneError
from contactvisco.fem import compat, parts
from contactvisco.solver import floating, linear
from contactvisco.solver.bordered import ObstacleForce
from contactvisco.solver.condensed import NodalCondensation
from contactvisco.solver.interface_newton import InterfaceCondensation, InterfaceSNES
from contactvisco.solver.newton_base import (  # noqa: F401 (the solvers' public names)
    DEFAULT_OPTIONS, NEARBY_BUDGET, NEARBY_MAX_IT, PREFIX, STALE_ATOL, STALE_KRYLOV,
    STALE_MAX_IT, STALE_ROWS, STALE_RTOL, NewtonFailure, NewtonSolver, SlidingLimit,
    SolverOptions, _FORWARD, _INSERT, _is_number, _weak, matrix_fingerprint, near_nullspace,
    option_read, residual_summary, rigid_body_modes, unused_options)


#: The iterative linear solver: GMRES preconditioned by BoomerAMG (hypre), HMIS coarsening with
#: extended+i interpolation, Chebyshev smoothing on the way down and up (a V-cycle at half the
#: cost of PETSc's default hybrid symmetric Gauss-Seidel for a few more Krylov iterations);
#: the relative tolerance is tight enough for Newton to take the steps of the direct solver.
#: Iteration counts against PETSc's GAMG, and the smoothers measured: docs/scaling.md.
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
    "pc_hypre_boomeramg_relax_type_down": "Chebyshev",
    "pc_hypre_boomeramg_relax_type_up": "Chebyshev",
}

#: Where PETSc has no hypre: GMRES preconditioned by PETSc's smoothed-aggregation AMG (GAMG),
#: with the rigid motions as near-nullspace; the aggregation threshold is the one chosen in
#: docs/scaling.md (benchmarks/performance/gamg.py). Whether a set-up builds a new
#: prolongation or keeps the first one: GAMG_REUSE_INTERPOLATION.
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

#: GAMG's pc_gamg_reuse_interpolation by dimension: True keeps the prolongation of the first
#: set-up for the run, and a later set-up (a new Newton matrix) recomputes only the Galerkin
#: coarse operators. In 2D the Jacobians' other constraint rows made the Krylov counts grow
#: with a kept prolongation and a new one per set-up is as fast (the paper scene at 256^2:
#: 5 % more Newton time kept); in 3D a set-up costs about an elastic solve, and keeping the
#: prolongation took 35 and 39 % less Newton time on block3d at 22k and 52k unknowns
#: (docs/scaling.md). After a solve that does not converge, every set-up of the run builds a
#: new prolongation (newton_base.NewtonSolver._fresh_prolongation).
GAMG_REUSE_INTERPOLATION = {2: False, 3: True}

#: linear_solver = "auto" takes the iterative solver from this many displacement unknowns on
#: (by dimension), with BoomerAMG; where the measurements put the switch: docs/scaling.md
#: (in 2D 20000: with the front rule, linear.FrontRule, BoomerAMG is even with MUMPS and its
#: kept factors at 18818 unknowns and ahead from 33282 on).
AUTO_ITERATIVE = {2: 20_000, 3: 5_000}

#: The same where PETSc has no hypre (GAMG): docs/scaling.md (in 3D 6000: with the kept
#: prolongation, GAMG_REUSE_INTERPOLATION, GAMG is even with MUMPS at 4014 unknowns on block3d
#: and ahead from 7998 on).
AUTO_ITERATIVE_GAMG = {2: 530_000, 3: 6_000}

#: linear_solver = "auto" where it chose the iterative solver: the states after the first take
#: the direct solver below this many displacement unknowns (by dimension; 0: never), where the
#: Newton matrix changes only in the contact rows from one step to the next (for_later_states).
#: The first state, from u = 0, changes the state of most contact nodes and pays a
#: factorization per Newton iteration; a later step keeps the factors of a factorized matrix
#: for nearby ones (newton_base, low_rank). Measured in docs/scaling.md.
AUTO_DIRECT_LATER = {2: 60_000, 3: 0}

#: The direct solver of AUTO_DIRECT_LATER gives way to the iterative one for the rest of the
#: run once its factorizations exceed LATER_FACTORIZATIONS per solve (a step) beyond the
#: first two: where the contact zone moves, each step changes more rows than the kept
#: factors serve (a factorization in nearly every Newton iteration; docs/scaling.md).
LATER_FACTORIZATIONS = 1.0


#: Off: every new matrix is factorized (the measurement's reference).
NEARBY = True


def auto_iterative_size(d: int) -> int:
    """The number of displacement unknowns from which linear_solver = "auto" is iterative."""
    return (AUTO_ITERATIVE if compat.has_hypre() else AUTO_ITERATIVE_GAMG)[d]


#: Options whose values keep the condensed iterates the coupled method's, as a test of the
#: value PETSc reads: any other value is refused by CondensedSNES.
EQUIVALENCE_OPTIONS = {
    "snes_type": lambda value: value.lower() == "newtonls",
    "snes_linesearch_type": lambda value: value.lower() in ("basic", "none"),
    "snes_linesearch_damping": lambda value: _is_number(value) and float(value) == 1.0,
    "snes_lag_jacobian": lambda value: _is_number(value) and float(value) == 1.0,
    "snes_lag_preconditioner": lambda value: _is_number(value) and float(value) == 1.0,
}


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

#: The condensed system's line search (CondensedSNES._line_search): the sufficient decrease
#: of the merit phi = |F|^2 of the coupled residual (Armijo's constant c in
#: phi(lambda) <= (1 - 2 c lambda) max of the last LINE_SEARCH_MEMORY accepted phi), the most
#: trial steps before the best of them is taken, and the bounds of each reduction of lambda.
LINE_SEARCH_ARMIJO = 1e-4
LINE_SEARCH_MEMORY = 5
LINE_SEARCH_TRIALS = 12
LINE_SEARCH_SHRINK = (0.1, 0.5)


#: contact_law.ZERO_BALL = "guarded": the free side's solve is given up for the stick side's
#: when the coupled residual found no new minimum in this many iterations (a single rise at
#: a change of contact state is common and harmless: block3d's steps 3 and 4).
GUARD_WINDOW = 3


def _condensation(problem):
    """The condensed system of a problem: NodalCondensation, or for a contact boundary that
    meets another body of the mesh its InterfaceCondensation."""
    if hasattr(problem.contact.obstacle, "pairing"):
        return InterfaceCondensation(problem)
    return NodalCondensation(problem)


def line_search_on(scene) -> bool:
    """Whether the condensed Newton system backtracks (solver.line_search): "nonmonotone"
    always, "none" never, "auto" where the bulk law is nonlinear (material.law "hencky" or
    "energy"). With the linear law the Newton matrix changes only with the contact nodes'
    branches, and the full generalized Newton step (an active-set method on the contact
    conditions) is kept as it is: measured in benchmarks/results/line_search.md, a line
    search there changes no answer but can add an iteration at a change of contact state."""
    choice = scene["solver"]["line_search"]
    if choice == "auto":
        return scene["material"]["law"] != "linear"
    return choice == "nonmonotone"


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
        self._tripped = False            # the free side's residual rose (_guarded_solve)
        obstacle = problem.contact.obstacle
        # The iterative solver's preconditioner is built from an operator of its own, copied
        # from J_red only when linear.KeptPreconditioner says so.
        nodal = type(self.system) is NodalCondensation and not (
            obstacle is not None and obstacle.controlled)
        if (linear.KEEP or linear.FRONT) and not reuse and nodal:
            self.kept = linear.KeptPreconditioner(self.system.bulk_stamp,
                                                  self.system.varying_rows())
        # The front rule: loose solves while the iterations change the contact state.
        # (iterative solver only: with MUMPS an iteration on the last factors is already a
        # back-substitution, and loose ones added Newton iterations without saving time)
        self.front = linear.FrontRule() if linear.FRONT and nodal and not reuse else None
        #: Per Newton iteration of the last solve (front rule): (the relative tolerance
        #: asked, the relative residual the Krylov method reached, None without one: LU
        #: alone; a solve stopped by the absolute tolerance counts as reaching the asked one;
        #: whether the solve was a loose one).
        self.linear_log: list[tuple[float, float | None, bool]] = []
        self._before = None              # (|F|, asked tolerance) of the last iteration
                                         # (None after a loose one: linear.AFTER_LOOSE_PCS)
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
        # Whether the nonlinear-remainder rule may follow a loose solve (its preconditioner)
        self._remainder_after_loose = (self.snes.getKSP().getPC().getType()
                                       in linear.AFTER_LOOSE_PCS)
        if self.front is not None:
            self.snes.getKSP().setConvergenceHistory(reset=True)
        if self.force is None:           # the bordered solves need P's exact factors
            self.enable_stale()
        # The line search on the coupled residual (none with force control, whose bordered
        # step moves the obstacle with u).
        self.line_search = self.force is None and line_search_on(problem.scene)
        self.step_lengths: list[float] = []     # lambda of each Newton step of a solve
        self._trial = u_vector.copy()           # the line search's trial iterate
        self._trial_b = u_vector.copy()         # and its condensed residual
        self._trial_norm = None                 # its coupled residual norm (None: no trial)
        if self.line_search:
            # Each trial's merit needs its own residual's node blocks, now.
            self.system.defer = False
            self.snes.setLineSearchPreCheck(_weak(self._line_search))

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
        self._trial_norm = None
        self.step_lengths = []
        self.linear_log = []
        self._before = None              # (|F|, asked tolerance) of the last iteration
        if self.front is not None:
            self.front.reset()
        try:
            iterations = self._guarded_solve()
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
        flag = self.system.problem.constants.get("free_ball")
        if (flag is not None and float(flag.value) > 0.5 and it >= GUARD_WINDOW
                and min(self.residuals[-GUARD_WINDOW:]) >= min(self.residuals[:-GUARD_WINDOW])):
            self._tripped = True              # _converged stops the solve
        if it > 0 and self.front is not None:
            ksp = snes.getKSP()
            history = ksp.getConvergenceHistory()
            reached = (float(history[-1] / history[0])
                       if len(history) > 1 and history[0] > 0 else None)
            # Reached the absolute tolerance instead (a small right-hand side): exact too.
            if ksp.getConvergedReason() == PETSc.KSP.ConvergedReason.CONVERGED_ATOL:
                reached = min(reached or 0.0, self._asked)
            self.linear_log.append((self._asked, reached, self._loose))

    def _guarded_solve(self) -> int:
        """Newton; with contact_law.ZERO_BALL = "guarded" (the Constant free_ball of the
        forms) first with the free side of a ball of radius 0, and, if the coupled residual
        finds no new minimum in GUARD_WINDOW iterations (a cycle) or that solve fails, again
        from the same first iterate with the stick side (the residual's value is the same on
        either side, only the Newton matrix changes). The iterations of both attempts are
        counted."""
        flag = self.system.problem.constants.get("free_ball")
        if flag is None:
            return super().solve()
        unknowns = self.system.problem.unknowns
        saved = [f.x.array.copy() for f in unknowns]
        flag.value = 1.0
        try:
            return super().solve()
        except NewtonFailure:
            spent = max(len(self.residuals) - 1, 0)
        finally:
            self._tripped = False
            flag.value = 0.0                  # the stick side outside this solver's solves
        for f, values in zip(unknowns, saved):
            f.x.array[:] = values
        self._pending = False
        self._residuals_since_jacobian = 0
        self._trial_norm = None
        self.step_lengths = []
        self._before = None
        return spent + super().solve()

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
        if self._trial_norm is not None:
            # The iterate the line search accepted (x_J - lambda y, evaluated last): its
            # residual, Functions and node blocks are those of the trial.
            trial, self._trial_norm = self._trial_norm, None
            if np.array_equal(x.getArray(readonly=True), self._trial.getArray(readonly=True)):
                self._trial_b.copy(b)
                self.system.full_norm = trial
                self._residuals_since_jacobian += 1
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

    def _line_search(self, X, Y):
        """Backtracking along the Newton step of the coupled system, called by SNES before
        it takes the step x = X - Y (a line-search pre-check that may shorten Y).

        The condensed step du = -Y and the multipliers' step dl (recovered node by node) are
        the coupled Newton step, so x_J + lambda (du, dl) is the coupled method's damped
        iterate for every lambda. The merit is the coupled residual's phi = |F(u, l)|^2 (the
        norm Newton's convergence test reads): the condensed residual's own norm weighs a
        contact node's constraint rows by s_i and jumps at changes of contact state.
        A trial is accepted under the non-monotone Armijo condition of Grippo, Lampariello
        and Lucidi (SIAM J. Numer. Anal. 23, 1986, 707-716),

            phi(lambda) <= (1 - 2 c lambda) max(phi_k, ..., phi_{k-M+1}),

        with c = LINE_SEARCH_ARMIJO and M = LINE_SEARCH_MEMORY, using the generalized Newton
        step's slope d phi / d lambda = -2 phi_k at lambda = 0; otherwise lambda becomes the
        minimizer of the quadratic through phi_k, that slope and phi(lambda), kept within
        LINE_SEARCH_SHRINK times lambda. A semismooth Newton step whose residual grows at a
        change of contact state is thus still taken in full when it stays below the recent
        maximum, so the iterates of a run whose full steps are accepted are those of the
        full-step method.

        Parameters
        ----------
        X : petsc4py.PETSc.Vec
            The iterate of the last Jacobian, x_J.
        Y : petsc4py.PETSc.Vec
            The Newton update (x = X - Y), scaled in place by the accepted lambda.

        Returns
        -------
        bool
            Whether Y was shortened.
        """
        trial = self._trial
        X.copy(trial)
        trial.axpy(-1.0, Y)                  # the full step, as SNES forms it
        trial.copy(self._du)
        self._du.axpy(-1.0, self._x_jacobian)
        dl = self.system.update_multipliers(self._du)     # l = l_J + dl
        self._pending = False
        phi0 = self.residuals[-1] ** 2 if self.residuals else self.system.full_norm ** 2
        reference = max(r * r for r in self.residuals[-LINE_SEARCH_MEMORY:]) \
            if self.residuals else phi0
        lam, taken = 1.0, 1.0
        best = (np.inf, 1.0)                 # (phi, lambda) of the best trial
        for attempt in range(LINE_SEARCH_TRIALS + 1):
            if lam != taken:                 # x_J + lam du, l_J + lam dl
                X.copy(trial)
                trial.axpy(-lam, Y)
                self.system.add_to_multipliers((lam - taken) * dl)
                taken = lam
            trial.ghostUpdate(addv=_INSERT, mode=_FORWARD)
            self._to_functions(trial)
            self.system.residual(trial, self._trial_b)
            phi = self.system.full_norm ** 2
            if (np.isfinite(phi) and phi <= (1.0 - 2.0 * LINE_SEARCH_ARMIJO * lam) * reference) \
                    or attempt == LINE_SEARCH_TRIALS:
                break
            if phi < best[0]:
                best = (phi, lam)
            if attempt == LINE_SEARCH_TRIALS - 1:
                # No trial decreased the merit enough: the best one is taken (evaluated
                # again, as the last), and Newton's iteration limit decides.
                lam = best[1]
                continue
            low, high = LINE_SEARCH_SHRINK
            if np.isfinite(phi):
                # phi(s) ~ phi0 - 2 phi0 s + a s^2 through phi(lam): minimizer phi0 / a
                curvature = (phi - phi0 + 2.0 * phi0 * lam) / lam ** 2
                fit = phi0 / curvature if curvature > 0 else high * lam
            else:
                fit = low * lam
            lam = float(np.clip(fit, low * lam, high * lam))
        self._trial_norm = self.system.full_norm
        self.step_lengths.append(taken)
        if taken != 1.0:
            Y.scale(taken)
            X.copy(trial)                    # bit for bit the iterate SNES forms next
            trial.axpy(-1.0, Y)
        return taken != 1.0

    def _jacobian(self, snes, x, A, P):
        self.system.jacobian()
        if self.front is not None:
            self._state = linear.contact_state(self.system.parts)
            self._loose = self.front.loose(self._state, self.system.V.mesh.comm)
            # (the rule is the iterative solver's only: self.front is None with MUMPS)
            # (a matrix unchanged at a fixed state: the law is linear there, and the
            # step's residual was its linear one; the read serves build_next too)
            moved = self.kept.moved(self.system.J_red)
            self._asked = linear.front_tolerance(self._loose, self._ksp_rtol,
                                                 self.system.full_norm, self._target(snes),
                                                 self._before if moved else None)
            self._before = (None if self._loose and not self._remainder_after_loose
                            else (self.system.full_norm, self._asked))
            snes.getKSP().setTolerances(rtol=self._asked)
        self._to_operator(self.system.J_red)
        if linear.INEXACT and not self.reuse and self.front is None:   # iterative solver
            snes.getKSP().setTolerances(rtol=linear.forcing(
                self._ksp_rtol, self.system.full_norm, self._target(snes)))
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

    def _target(self, snes) -> float:
        """The coupled residual at which _converged stops: max(atol, rtol |F_0|)."""
        atol, rtol, _, _ = snes.getTolerances()
        return max(atol, rtol * self._norm0)

    def _converged(self, snes, it, norms):
        norm = self.system.full_norm
        atol, rtol, _, max_it = snes.getTolerances()
        if self._tripped:                     # _guarded_solve tries the stick side
            return PETSc.SNES.ConvergedReason.DIVERGED_MAX_IT
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


def iterative_options(dimension: int = 2) -> dict:
    """GMRES with BoomerAMG where PETSc has hypre, else with GAMG (its prolongation kept
    across set-ups by GAMG_REUSE_INTERPOLATION of the mesh's `dimension`)."""
    if compat.has_hypre():
        return ITERATIVE_OPTIONS
    return {**GAMG_OPTIONS, "pc_gamg_reuse_interpolation": GAMG_REUSE_INTERPOLATION[dimension]}


def create(problem, comm, scene_options=None, later=False) -> NewtonSolver:
    """The Newton solver a Problem's scene asks for (solver.linear_system, .linear_solver).

    Parameters
    ----------
    problem : contactvisco.fem.problem.Problem
        The discrete problem and its scene.
    comm : mpi4py.MPI.Comm
        The mesh's communicator.
    scene_options : dict, optional
        PETSc options instead of the scene's solver.petsc_options.
    later : bool, optional
        For the states after the first (a restart's included): linear_solver = "auto" may
        then take the direct solver where it takes the iterative one for the first state
        (AUTO_DIRECT_LATER, for_later_states).

    Returns
    -------
    NewtonSolver
        Its `later` attribute is the argument.
    """
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
    first_kind, later_kind = solver_kinds(problem, system)
    kind = later_kind if later else first_kind
    if kind == "iterative" and system == "coupled":
        raise SceneError("solver.linear_solver = 'iterative' needs the displacement-only "
                         "system: solver.linear_system = 'condensed' (nodal contact "
                         "quadrature)", key="solver.linear_solver")
    newton = _create(problem, comm, options, system, kind)
    newton.later = later
    newton.auto_direct = kind != first_kind     # AUTO_DIRECT_LATER's direct solver
    return newton


def solver_kinds(problem, system) -> tuple[str, str]:
    """The linear solvers of the first state and of the states after it (AUTO_DIRECT_LATER):
    the scene's solver.linear_solver, or auto's choice.

    Parameters
    ----------
    problem : contactvisco.fem.problem.Problem
        The discrete problem and its scene.
    system : str
        The linear system: "condensed", "coupled" or "displacement".

    Returns
    -------
    tuple of str
        ("direct" or "iterative") for the first state and for the later ones.
    """
    kind = problem.scene["solver"]["linear_solver"]
    if kind != "auto":
        return kind, kind
    d = problem.V.mesh.geometry.dim
    size = problem.count_unknowns()["u"]
    if system == "coupled" or size < auto_iterative_size(d) or _held_by_contact(problem):
        return "direct", "direct"
    return "iterative", "direct" if _direct_later(problem, system, d, size) else "iterative"


def _create(problem, comm, options, system, kind) -> NewtonSolver:
    """The solver of `system` ("condensed", "coupled" or "displacement") with the linear
    solver `kind` ("direct" or "iterative")."""
    defaults = (iterative_options(problem.V.mesh.geometry.dim) if kind == "iterative"
                else {})
    obstacle = problem.contact and problem.contact.obstacle
    if obstacle is not None and obstacle.controlled and system != "condensed":
        raise SceneError("obstacle.force_components: force control is solved with the "
                         f"condensed Newton system, not the {system} one (it needs nodal "
                         "contact multipliers: a finite contact.g or friction)",
                         key="obstacle.force_components")
    if hasattr(obstacle, "pairing"):           # another body of the mesh (fem.body_contact)
        if len(problem.unknowns) == 1:          # u alone: no contact multipliers
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


def for_later_states(problem, comm, newton: NewtonSolver) -> NewtonSolver:
    """The solver of the states after the first, called after every state: `newton` itself,
    or in its place (destroyed) the one create(later=True) gives when that differs
    (AUTO_DIRECT_LATER), or once that one has factorized too often (LATER_FACTORIZATIONS),
    the iterative solver for the rest of the run. The same on every rank (the set-up counts
    are global). Collective when it replaces `newton`."""
    if newton.later:
        if not (newton.auto_direct
                and newton.all_setups > 2 + LATER_FACTORIZATIONS * newton.solves):
            return newton
        newton.destroy()
        newton = create(problem, comm)          # the first state's choice, iterative
        newton.later = True
        return newton
    newton.later = True
    first_kind, later_kind = solver_kinds(problem, newton.system_kind)
    if later_kind == first_kind:
        return newton
    newton.destroy()
    return create(problem, comm, later=True)


def _direct_later(problem, system, d, size) -> bool:
    """Whether the direct solver's kept factors serve the states after the first better than
    the iterative solver (AUTO_DIRECT_LATER): the condensed system of one body against an
    obstacle under displacement control, below the size bound, with a Newton matrix that
    stays the same from step to step where the contact state does (a linear bulk law, the
    same step size throughout: a uniform time grid)."""
    scene = problem.scene
    obstacle = problem.contact and problem.contact.obstacle
    return (system == "condensed" and size < AUTO_DIRECT_LATER[d]
            and not hasattr(obstacle, "pairing")
            and not (obstacle is not None and obstacle.controlled)
            and scene["material"]["law"] == "linear"
            and scene["time"]["grid"] == "uniform")


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
