"""Forward sensitivities of a run: the derivative of every step's converged state with respect
to the scene's material and contact parameters, through the time loop (docs/identification.md).

At the converged state of step n the residual of the coupled unknowns w = (u, lambda) and,
under force control, the obstacle's force equation hold:

    F(w_n, d_n; c(theta), H_n, u_{n-1}, d_{n-1}) = 0,      G(w_n, d_n; c(theta)) = 0,

c the Constants of the forms (the Lame constants, the memory's implicit weight w(k), the
contact law's r, g, stiffness, mu), H_n the history stress of eq (19) prepared from the
committed strains, and u_{n-1}, d_{n-1} the origin of the step's slip. Differentiating with
respect to a parameter theta gives the bordered linear system of the step's own Newton matrix
at the converged state (contactvisco.solver.bordered),

    [ K        B + B' ] [w']     [dF/dtheta]
    [ c^T      E + E' ] [d']  = -[dG/dtheta],

    dF/dtheta = sum_c dF/dc c' + dF/dH [H'_n] + dF/du_{n-1} [u'_{n-1}] + dF/dd_{n-1} [d'_{n-1}],

solved with the condensed system (contactvisco.solver.condensed: K^-1 applied through the
node-wise elimination, the multipliers recovered node by node): one solve with K per
parameter and step, plus one per force-controlled component for the bordering. B' and E' are
the derivatives through the curved obstacle's normal and gap, evaluated at the converged
position d_ref = d (fem.obstacle: a curved obstacle is placed again at its equilibrium), by
central differences of that placement (nodal interpolation of closed forms). The derivative
forms dF/dc are built once: UFL cannot differentiate with respect to a Constant, so each
Constant is replaced by a DG0 stand-in, differentiated, and put back.

The history is linear in the strains with coefficients that depend on theta (History:
P_{n+1} = D(theta) P_n + W0(theta) e_n + W1(theta) e_{n+1}, H_{n+1} = explicit(P_n, e_n)),
so its tangent P'_n is carried per parameter by the same recursion applied to the tangent
strains e'_n = eps(u'_n), plus the recursion's own derivative at the primal state,

    P'_{n+1} = [D P'_n + W0 e'_n + W1 e'_{n+1}] + [D' P_n + W0' e_n + W1' e_{n+1}],
    H'_{n+1} = explicit(P'_n, e'_n) + explicit'(P_n, e_n),

the second brackets taken by central differences in theta of the recursion's coefficients
(History objects at theta +- h fed with the primal state: O(h^2) in the coefficients only,
no solve involved), as are the derivatives c' of the Constants from the scene's conversion
of theta (Prony moduli to A and R: contactvisco.scene.viscoelastic_table).

`ForwardModel` builds a scene's problem and solver once and runs it again for other values of
the parameters (the Constants and the Prony terms set, nothing rebuilt or compiled, no file
written), with the sensitivities when asked.
"""
from __future__ import annotations

import math

import numpy as np
import ufl
from dolfinx import fem
from dolfinx.fem.petsc import assemble_vector
from mpi4py import MPI
from petsc4py import PETSc

from contactvisco.errors import SceneError
from contactvisco.fem import compat
from contactvisco.fem import geometry as geometry_module
from contactvisco.fem.problem import build
from contactvisco.model import time_grid
from contactvisco.model.material import lame_constants
from contactvisco.model.memory import History, ReducedTimeHistory
from contactvisco.model.viscoelastic import inverse_shift
from contactvisco.model.kernels import PowerTerms
from contactvisco.model.memory_kernel import memory_power, memory_terms
from contactvisco.solver import newton as solver_module
from contactvisco.solver import predictor
from contactvisco.solver.condensed import condense_rhs, recover
from contactvisco.solver.newton import NewtonFailure

_ADD, _REVERSE = PETSc.InsertMode.ADD, PETSc.ScatterMode.REVERSE

#: The Constants of the forms a parameter may move (scene_constants), and the scene keys
#: whose changes they carry: a parameter outside these is refused (unsupported_key).
SUPPORTED_KEYS = ("viscoelastic.shear.", "viscoelastic.bulk.", "viscoelastic.young",
                  "viscoelastic.nu", "viscoelastic.C1", "viscoelastic.C2",
                  "viscoelastic.activation_energy", "viscoelastic.T_ref", "material.E",
                  "material.nu", "memory.", "contact.mu", "contact.stiffness",
                  "contact.augmentation")

#: Relative displacement of a curved obstacle (of the body's size) in the central differences
#: of its normal and gap (module description).
PLACEMENT_STEP = 1e-6


def unsupported_key(key: str) -> str | None:
    """Why the sensitivities do not cover the scene key `key` (None if they do).

    Parameters
    ----------
    key : str
        A dotted scene key.

    Returns
    -------
    str or None
        The reason, or None.
    """
    if any(key == p.rstrip(".") or key.startswith(p) for p in SUPPORTED_KEYS):
        return None
    return (f"{key!r}: forward sensitivities cover the keys under "
            f"{', '.join(SUPPORTED_KEYS)} (moduli, relaxation times, friction, contact "
            "compliance)")


def scene_constants(scene: dict) -> dict:
    """The values of the forms' Constants that the parameters move, from a resolved scene:
    the Lame constants of A (material.E, nu after the [viscoelastic] conversion), the contact
    law's augmentation r, bound g, stiffness and friction coefficient mu (numbers only).

    Returns
    -------
    dict
        name (as in Problem.constants) -> value.
    """
    mat = scene["material"]
    lam, mu = lame_constants(mat["model"], mat["E"], mat["nu"])
    out = {"lame_lambda": lam, "lame_mu": mu}
    contact = scene.get("contact")
    if contact is not None:
        out["r"] = float(contact["augmentation"])
        if math.isfinite(contact["g"]):
            out["g"] = float(contact["g"])
        out["stiffness"] = float(contact["stiffness"])
        if not isinstance(contact["mu"], str):
            out["mu"] = float(contact["mu"])
    return out


def _prony_terms(scene: dict, reference: list | None = None, power=None) -> list:
    """The Prony terms of a scene, checked against the built problem's (same parts, same
    count: a modulus set to zero drops its term, which a built problem cannot follow). For a
    power kernel, `power` (model.kernels.PowerTerms of the built fit) gives its sum of
    exponentials with the built rates at the scene's alpha, beta and tau."""
    if power is not None:
        mem = scene["memory"]
        c, taus = power(float(mem["alpha"]), float(mem["beta"]), float(mem["tau"]))
        terms = [(float(a), float(tau), mem["part"]) for a, tau in zip(c, taus)]
    else:
        terms = [(float(a), float(tau), part) for a, tau, part in memory_terms(scene)]
    if reference is not None and [p for *_, p in terms] != [p for *_, p in reference]:
        raise SceneError("viscoelastic: the parameters changed the number or the parts of the "
                         f"Prony terms ({len(reference)} -> {len(terms)}); a modulus or "
                         "fraction of 0 removes its term: keep the bounds above 0",
                         key="viscoelastic")
    return terms


def constant_derivative(form, constant, direction, space):
    """d form / d constant [direction]: the derivative of a UFL form with respect to a scalar
    Constant in the direction of another Constant (None if the form does not depend on it).
    UFL differentiates with respect to Coefficients only, so the Constant is replaced by a
    DG0 stand-in, the derivative taken in the direction of a DG0 unit, and both put back.

    Parameters
    ----------
    form : ufl.Form
    constant, direction : dolfinx.fem.Constant
    space : dolfinx.fem.FunctionSpace
        A scalar DG0 space of the mesh.
    """
    stand_in, unit = fem.Function(space), fem.Function(space)
    derivative = ufl.algorithms.expand_derivatives(
        ufl.derivative(ufl.replace(form, {constant: stand_in}), stand_in, unit))
    if derivative.empty():
        return None
    return ufl.replace(derivative, {stand_in: constant, unit: direction})


def _function_derivative(form, function, direction):
    if function is None:
        return None
    derivative = ufl.algorithms.expand_derivatives(ufl.derivative(form, function, direction))
    return None if derivative.empty() else derivative


def _total(pieces):
    pieces = [p for p in pieces if p is not None]
    return sum(pieces[1:], pieces[0]) if pieces else None


def _form(a):
    return None if a is None else fem.form(a)


class StepSensitivity:
    """The linear algebra of the sensitivities at a step's converged state (module
    description): the derivative forms built and compiled once, the step's Newton matrix
    reassembled at the converged state and factorized (the factors kept while the matrix
    stays the same, as it does over steps of one size and one contact state), the bordering
    of force control, and one solve per parameter.

    Parameters
    ----------
    problem : contactvisco.fem.problem.Problem
    newton : contactvisco.solver.newton.CondensedSNES
        The problem's solver; its condensed system is used at the converged states.
    """

    def __init__(self, problem, newton):
        if getattr(newton, "system_kind", "") != "condensed" or \
                type(newton.system).__name__ != "NodalCondensation":
            raise SceneError(
                "forward sensitivities need the condensed Newton system of one body with "
                "nodal contact multipliers (a finite contact.g or friction, nodal contact "
                "quadrature); use fit.jacobian = 'finite-differences'",
                key="solver.linear_system")
        self.problem, self.newton, self.system = problem, newton, newton.system
        mesh = problem.V.mesh
        self.comm = mesh.comm
        scalar0 = compat.scalar_space(mesh, "DG", 0)
        self.names = [name for name, c in problem.constants.items()
                      if isinstance(c, fem.Constant) and name != "t"
                      and np.ndim(c.value) == 0]
        self.dots = {name: fem.Constant(mesh, PETSc.ScalarType(0.0)) for name in self.names}
        memory = problem.memory
        # the implicit weights of a history in reduced time: one value per point (Functions)
        self.weights = {name: f for name, f in problem.constants.items()
                        if name.startswith("memory_implicit_") and isinstance(f, fem.Function)}
        self.weight_dots = {name: fem.Function(f.function_space)
                            for name, f in self.weights.items()}
        self.H_dot = fem.Function(memory.tensor_space) if memory is not None else None
        self.u_dot = fem.Function(problem.V)
        contact = problem.contact
        self.previous_dot = (fem.Function(problem.V) if contact and contact.u_previous
                             is not None else None)
        self.obstacle = contact and contact.obstacle
        self.D_previous_dot = (fem.Function(self.obstacle.D.function_space)
                               if self.obstacle is not None else None)

        def derivative(form):
            pieces = [constant_derivative(form, problem.constants[n], self.dots[n], scalar0)
                      for n in self.names]
            pieces += [_function_derivative(form, f, self.weight_dots[name])
                       for name, f in self.weights.items()]
            if memory is not None:
                pieces.append(_function_derivative(form, memory.H, self.H_dot))
            if self.previous_dot is not None:
                pieces.append(_function_derivative(form, contact.u_previous,
                                                   self.previous_dot))
            if self.obstacle is not None:
                pieces.append(_function_derivative(form, self.obstacle.D_previous,
                                                   self.D_previous_dot))
            return _total(pieces)

        dF = [derivative(F) for F in problem.F]
        self.dF = [_form(a) for a in dF]
        self.controlled = bool(self.obstacle is not None and self.obstacle.controlled)
        self.reaction = None
        if self.obstacle is not None and not self.controlled:
            self._reaction_forms(dF[0])
        self.eps_expression = None
        if memory is not None:
            self.eps_expression = compat.expression(problem.kinematics.strain(self.u_dot),
                                                    memory.tensor_space)
            self.eps_dot = fem.Function(memory.tensor_space)
        if self.controlled:
            forms = self.obstacle.force_forms
            force = newton.force
            self.k = len(self.obstacle.controlled)
            self.dG = [_form(derivative(g)) for g in forms["g"]]
            self.curved = self.problem.scene["obstacle"]["shape"] != "plane"
            if self.curved:
                Q, W = self.obstacle.gap.function_space, self.obstacle.normal.function_space
                self.normal_dot = [fem.Function(W) for _ in range(self.k)]
                self.gap_dot = [fem.Function(Q) for _ in range(self.k)]

                def placement(form, j):
                    return _total([
                        _function_derivative(form, self.obstacle.normal, self.normal_dot[j]),
                        _function_derivative(form, self.obstacle.gap, self.gap_dot[j])])
                self.B_extra = [[_form(placement(F, j)) for F in problem.F]
                                for j in range(self.k)]
                self.E_extra = [[_form(placement(g, j)) for j in range(self.k)]
                                for g in forms["g"]]
            self.force = force
        s = self.system
        self.P = s.A.duplicate()
        self._factorized = None
        self.ksp = PETSc.KSP().create(self.comm)
        self.ksp.setType("preonly")
        pc = self.ksp.getPC()
        pc.setType("lu")
        try:
            pc.setFactorSolverType("mumps")
        except PETSc.Error:        # a PETSc without MUMPS: its own LU
            pass
        self.ksp.setOperators(self.P)
        self.rhs = s.A.createVecLeft()
        self.y = s.A.createVecRight()
        self.b = compat.petsc_vector(problem.u).copy()
        self.owned = problem.V.dofmap.index_map.size_local
        self.fixed = problem.u_fixed[:self.owned] > 0
        self.factorizations = 0

    def destroy(self):
        for obj in (self.ksp, self.P, self.rhs, self.y, self.b):
            obj.destroy()

    def _reaction_forms(self, dF_u):
        """Under displacement control, the obstacle's force along each axis j as the residual
        F_u tested with the uniform unit field e_j, g_j = F_u(w; e_j): the bulk term vanishes
        on a rigid translation (eps(e_j) = 0; not the radial one of a body of revolution), so
        g_j is the contact terms' resultant minus the loads', and the force on the body is
        f_j = -g_j up to the loads, which do not depend on the parameters. Its derivative,
        dg_j/dtheta + sum_k dg_j/dw_k [w_k'], with w' in Functions set per parameter."""
        problem = self.problem
        V = problem.V
        dim = V.mesh.geometry.dim
        (v,) = problem.F[0].arguments()
        self.w_dots = [fem.Function(f.function_space) for f in problem.unknowns]
        self.reaction = []
        for j in range(dim):
            unit = fem.Function(V)
            unit.x.array.reshape(-1, dim)[:, j] = 1.0
            g = ufl.replace(problem.F[0], {v: unit})
            through_w = _total([_function_derivative(g, w, w_dot)
                                for w, w_dot in zip(problem.unknowns, self.w_dots)])
            self.reaction.append({
                "unit": unit, "g": fem.form(g), "dtheta": _form(
                    None if dF_u is None else ufl.replace(dF_u, {v: unit})),
                "dw": _form(through_w)})

    def reaction_force(self, j: int) -> float:
        """-g_j at the current state (the obstacle's force on the body along j, up to the
        loads' resultant)."""
        return -self._scalar(self.reaction[j]["g"])

    def reaction_tangent(self, j: int, x, l) -> float:
        """d(-g_j)/dtheta for the tangent (u' owned entries x, multipliers' l at the owned
        contact nodes) of the parameter whose derivative Functions tangent() set last."""
        s = self.system
        u_dot = self.w_dots[0]
        u_dot.x.array[:x.size] = x
        u_dot.x.scatter_forward()
        for a, f in enumerate(self.w_dots[1:]):
            f.x.array[:] = 0.0
            f.x.array.reshape(-1, s.bs[a])[s.own] = l[:, s.offsets[a]:s.offsets[a + 1]]
            f.x.scatter_forward()
        forms = self.reaction[j]
        return -(self._scalar(forms["dtheta"]) + self._scalar(forms["dw"]))

    # ---------------------------------------------------------------- linear algebra

    def linearize(self):
        """The Newton matrix at the converged state (the Functions hold it): the condensed
        system's node blocks and J_red, factorized unless equal to the last factorized one;
        with force control the bordering X = K^-1 (B + B'), c, E + E', S."""
        s, problem = self.system, self.problem
        x = compat.petsc_vector(problem.u)
        s.residual(x, self.b)
        s.jacobian()
        _, _, values = s.A.getValuesCSR()
        same = self._factorized is not None and len(values) == len(self._factorized) \
            and np.array_equal(values, self._factorized)
        if not self.comm.allreduce(same, op=MPI.LAND):
            s.A.copy(self.P, structure=PETSc.Mat.Structure.SAME_NONZERO_PATTERN)
            self.ksp.setOperators(self.P)
            self._factorized = values.copy()
            self.factorizations += 1
        if self.controlled:
            self._border()

    def _vector(self, form):
        vec = assemble_vector(form)
        vec.ghostUpdate(addv=_ADD, mode=_REVERSE)
        values = vec.array.copy()
        vec.destroy()
        return values

    def _scalar(self, form) -> float:
        return 0.0 if form is None else self.comm.allreduce(fem.assemble_scalar(form), MPI.SUM)

    def _node_rows(self, forms) -> np.ndarray:
        """(n, m): the multiplier rows of per-multiplier forms at the owned contact nodes."""
        s = self.system
        out = np.zeros((len(s.own), s.m))
        for a, form in enumerate(forms):
            if form is not None:
                out[:, s.offsets[a]:s.offsets[a + 1]] = \
                    self._vector(form).reshape(-1, s.bs[a])[s.own]
        return out * s.free

    def solve(self, r_u: np.ndarray, r_l: np.ndarray):
        """The coupled system [J B; C D] (x, l) = (r_u, r_l) at the converged state, by the
        condensed one: J_red x = (r_u off the contact nodes, condense_rhs(r_u, r_l) on them),
        then l node by node (contactvisco.solver.condensed.recover with F = -r_u, G = -r_l).

        Parameters
        ----------
        r_u : numpy.ndarray
            The u rows, owned entries (Dirichlet rows are set to zero: the prescribed values
            do not depend on the parameters).
        r_l : numpy.ndarray
            (n, m) multiplier rows at the owned contact nodes.

        Returns
        -------
        tuple
            x (owned u entries) and l (n, m).
        """
        s, d = self.system, self.system.d
        parts = s.parts
        rows = r_u.reshape(-1, d).copy()
        rows[self.fixed] = 0.0
        F = rows[s.own].copy()
        G = r_l * s.free
        rows[s.own] = condense_rhs(parts, F, G)
        self.rhs.array[:] = rows.ravel()
        self.ksp.solve(self.rhs, self.y)
        if self.ksp.getConvergedReason() <= 0:
            raise NewtonFailure("the sensitivity solve failed (KSP reason "
                                f"{self.ksp.getConvergedReason()})", -6, [])
        x = self.y.array.copy()
        s.J_contact.mult(self.y, s._Jdu)
        l = recover(parts, parts["B"], parts["C"], -F, -G, x.reshape(-1, d)[s.own],
                    s._Jdu.array.reshape(-1, d))
        return x, l

    def _placement_derivatives(self):
        """d nu / d d_j and d h / d d_j of the curved obstacle at its converged position, by
        central differences of its placement (fem.obstacle.ObstaclePart.place); the obstacle
        is left as it was."""
        obstacle = self.obstacle
        saved = (obstacle.normal.x.array.copy(), obstacle.gap.x.array.copy(),
                 np.array(obstacle.reference.value, copy=True), obstacle.D.x.array.copy(),
                 obstacle.nodes.normals.copy(),
                 None if obstacle.nodes.tangents is None else obstacle.nodes.tangents.copy())
        d0 = obstacle.displacement()
        step = PLACEMENT_STEP * self.problem.length_scale
        for j, comp in enumerate(obstacle.controlled):
            values = []
            for sign in (1.0, -1.0):
                d = d0.copy()
                d[comp] += sign * step
                obstacle.place(d)
                values.append((obstacle.normal.x.array.copy(), obstacle.gap.x.array.copy()))
            (n_plus, h_plus), (n_minus, h_minus) = values
            self.normal_dot[j].x.array[:] = (n_plus - n_minus) / (2 * step)
            self.gap_dot[j].x.array[:] = (h_plus - h_minus) / (2 * step)
        normal, gap, reference, D, normals, tangents = saved
        obstacle.normal.x.array[:] = normal
        obstacle.gap.x.array[:] = gap
        obstacle.reference.value[:] = reference
        obstacle.D.x.array[:] = D
        obstacle.nodes.normals[:] = normals
        if tangents is not None:
            obstacle.nodes.tangents[:] = tangents

    def _border(self):
        """X = K^-1 (B + B'), c, E + E' and S = E + E' - c^T X at the converged state."""
        force, s = self.force, self.system
        if self.curved:
            self._placement_derivatives()
        self.X = []
        for j in range(self.k):
            r_u = np.zeros(self.owned * s.d)
            if force.B[j][0] is not None:
                r_u += self._vector(force.B[j][0])[:self.owned * s.d]
            forms = list(force.B[j][1:])
            r_l = self._node_rows(forms)
            if self.curved:
                if self.B_extra[j][0] is not None:
                    r_u += self._vector(self.B_extra[j][0])[:self.owned * s.d]
                r_l = r_l + self._node_rows(self.B_extra[j][1:])
            self.X.append(self.solve(r_u, r_l))
        self.c = []
        for j in range(self.k):
            c_u = self._vector(force.C[j][0])[:self.owned * s.d].copy()
            c_u.reshape(-1, s.d)[self.fixed] = 0.0
            self.c.append((c_u, self._node_rows(force.C[j][1:])))
        E = np.array([[force._scalar(e) for e in row] for row in force.E])
        if self.curved:
            E = E + np.array([[self._scalar(e) for e in row] for row in self.E_extra])
        self.S = E - np.array([[self._dot(self.c[j], self.X[i]) for i in range(self.k)]
                               for j in range(self.k)])

    def _dot(self, c, x) -> float:
        (c_u, c_l), (x_u, x_l) = c, x
        return self.comm.allreduce(float(c_u @ x_u + np.sum(c_l * x_l)), MPI.SUM)

    def tangent(self, dots: dict, H_dot, previous_dot, D_previous_dot):
        """(u', lambda' at the owned contact nodes, d') for one parameter: the derivatives of
        its Constants `dots` (name -> c'), of the history stress H' (array or None), of
        u_{n-1} and d_{n-1} (arrays or None); linearize() first.

        Returns
        -------
        tuple
            u' (owned entries), lambda' (n, m), d' (controlled components; empty without
            force control).
        """
        for name in self.names:
            self.dots[name].value = dots.get(name, 0.0)
        for name, f in self.weight_dots.items():
            f.x.array[:] = dots.get(name, 0.0)
        if self.H_dot is not None:
            self.H_dot.x.array[:] = 0.0 if H_dot is None else H_dot
        if self.previous_dot is not None:
            self.previous_dot.x.array[:] = 0.0 if previous_dot is None else previous_dot
        if self.D_previous_dot is not None:
            dim = self.obstacle.dim
            self.D_previous_dot.x.array.reshape(-1, dim)[:] = (
                0.0 if D_previous_dot is None else D_previous_dot)
        s = self.system
        n = self.owned * s.d
        r_u = -self._vector(self.dF[0])[:n] if self.dF[0] is not None else np.zeros(n)
        r_l = -self._node_rows(self.dF[1:])
        x, l = self.solve(r_u, r_l)
        if not self.controlled:
            return x, l, np.zeros(0)
        dG = np.array([self._scalar(g) for g in self.dG])
        cw = np.array([self._dot(self.c[j], (x, l)) for j in range(self.k)])
        dd = np.linalg.solve(self.S, -dG - cw)
        for j in range(self.k):
            x = x - self.X[j][0] * dd[j]
            l = l - self.X[j][1] * dd[j]
        return x, l, dd

    def strain(self, u_owned: np.ndarray) -> np.ndarray:
        """eps(u') at the history's points, for the tangent of the history."""
        self.u_dot.x.array[:self.owned * self.system.d] = u_owned
        self.u_dot.x.scatter_forward()
        self.eps_dot.interpolate(self.eps_expression)
        return self.eps_dot.x.array.copy()


class HistoryTangent:
    """The tangent of the Prony history of eq (19) for one parameter (module description):
    a History of the same terms holding P'_n, and two at theta +- h for the recursion's
    derivative at the primal state. A history in reduced time (a temperature with a shift,
    ReducedTimeHistory) has per point the rates 1/a_T at the step's two ends: the twin takes
    the primal's, the two at theta +- h their own from the shift at theta +- h (WLF C1, C2,
    an Arrhenius energy, T_ref)."""

    def __init__(self, history, plus: list, minus: list, two_h: float, shifts=(None, None)):
        self.two_h = two_h
        self.reduced = isinstance(history, ReducedTimeHistory)
        base = history.history if self.reduced else history

        def make(terms):
            made = History(terms, base.k, base.rule, base.d)
            return ReducedTimeHistory(made, history.block) if self.reduced else made
        self.twin, self.plus, self.minus = make(base.terms), make(plus), make(minus)
        self.shifts = shifts

    def _sums(self, h):
        return (h.history if self.reduced else h).sums

    def prepare(self, primal, state, before, now):
        """Before the step's stress and weights: the histories at theta +- h at the primal
        state `state`; in reduced time their rates at the temperatures `before` (the
        committed time's; None at t_0) and `now` (the staged time's), and the twin's the
        primal's."""
        if not self.reduced:
            for h in (self.plus, self.minus):
                if state:
                    h.restore(state)
            return
        self.twin.committed = None if primal.committed is None else primal.committed.copy()
        self.twin.stage(primal.staged)
        for h, shift in zip((self.plus, self.minus), self.shifts):
            if state:
                h.restore(state)
            if before is not None:
                h.committed = inverse_shift(shift, before)[0]
            h.stage(inverse_shift(shift, now)[0])

    def stress(self, k: float | None):
        """H'_{n+1} of a step of size k (None at t_0); prepare() first."""
        if k is None or self._sums(self.twin) is None:
            return None
        return self.twin.explicit(k) + (self.plus.explicit(k)
                                        - self.minus.explicit(k)) / self.two_h

    def weights(self, k: float | None) -> dict:
        """The derivatives of the implicit weights, name -> w' (memory_implicit_<part>:
        numbers, or arrays per point in reduced time); prepare() first."""
        if k is None:
            return {}
        plus, minus = self.plus.implicit(k), self.minus.implicit(k)
        return {f"memory_implicit_{part}": (plus[part] - minus[part]) / self.two_h
                for part in plus}

    def commit(self, state, eps: np.ndarray, eps_dot: np.ndarray, k: float | None):
        """P'_{n+1} from the primal state before the step (prepare() for this step first),
        its strain eps_{n+1} and the tangent strain eps'_{n+1}."""
        self.twin.commit(eps_dot, k)
        if k is None or not state:
            return
        self.plus.commit(eps, k)
        self.minus.commit(eps, k)
        for total, p, m in zip(self._sums(self.twin), self._sums(self.plus),
                               self._sums(self.minus)):
            total += (p - m) / self.two_h


class ForwardModel:
    """A scene's problem and solver, built once and run again for other values of its
    material and contact parameters (module description).

    Parameters
    ----------
    scene : dict
        The resolved scene (its grid, loads and obstacle stay those of every run).
    comm : mpi4py.MPI.Comm
    """

    def __init__(self, scene: dict, comm=MPI.COMM_WORLD, component: int | None = None):
        self.scene, self.comm, self.component = scene, comm, component
        geometry = geometry_module.build(scene, comm)
        self.problem = build(scene, geometry)
        self.newton = solver_module.create(self.problem, comm)
        memory = self.problem.memory
        history = memory and memory.history
        self.reduced = isinstance(history, ReducedTimeHistory) and \
            type(history.history) is History
        self.base = history.history if self.reduced else history
        if memory is not None and type(history) is not History and not self.reduced:
            self.memory_reason = ("forward sensitivities follow a Prony history (in time, or "
                                  "in reduced time with a shift) or a power kernel's sum of "
                                  "exponentials only, not a power kernel summed directly, a "
                                  "table or fractional kernel or two bodies")
            self.base = None
        else:
            self.memory_reason = None
        self.terms = list(self.base.terms) if self.base is not None else None
        # a power kernel's sum of exponentials: its rates kept, its coefficients refitted
        # for the parameters' alpha, beta, tau (model.kernels.PowerTerms)
        self.power = None
        power = memory_power(scene) if self.base is not None else None
        if power is not None and power["kernel"] == "power" and \
                getattr(self.base, "fit", None) is not None:
            span = getattr(self.base, "span", None)
            self.power = PowerTerms(self.base.fit, float(power["alpha"]),
                                    float(power["beta"]), float(power["tau"]),
                                    float(scene["time"]["T"] if span is None else span))
        self.built = scene_constants(scene)
        self.sensitivity = None
        self.runs = 0

    def destroy(self):
        if self.sensitivity is not None:
            self.sensitivity.destroy()
        self.newton.destroy()
        self.newton = None
        self.problem.release_garbage()

    def apply(self, scene: dict):
        """The Constants and Prony terms of `scene` into the built problem."""
        constants = self.problem.constants
        built = self.built
        for name, value in scene_constants(scene).items():
            c = constants.get(name)
            if isinstance(c, fem.Constant):
                c.value = value
            elif value != built.get(name):
                # e.g. contact.mu from 0: the built problem has no friction terms
                raise SceneError(f"{name} = {value!r}: the problem was built with "
                                 f"{built.get(name)!r}, which has no term of it; start the "
                                 "parameter away from 0", key=f"contact.{name}")
        if self.terms is not None:
            self.base.terms = _prony_terms(scene, self.terms, self.power)
        if self.reduced:
            # the shift of the stage (fem.problem) reads the built scene's table: updated in
            # place
            self.scene["viscoelastic"].update(scene["viscoelastic"])

    def _reset(self):
        problem = self.problem
        for f in problem.unknowns:
            f.x.array[:] = 0.0
        time = problem.time
        time.committed = time.staged = None
        contact = problem.contact
        if contact is not None and contact.u_previous is not None:
            contact.u_previous.x.array[:] = 0.0
        if contact is not None and contact.obstacle is not None:
            contact.obstacle.committed = None
        memory = problem.memory
        if memory is not None:
            memory.H.x.array[:] = 0.0
            for constant, _ in memory.implicit_terms:
                if isinstance(constant, fem.Function):     # a weight per point
                    constant.x.array[:] = 0.0
                else:
                    constant.value = 0.0
            self.base.sums = self.base.last = self.base.previous = None
            if self.reduced:
                history = memory.history
                history.committed = history.staged = history.temperature = None
                history.reduced_time = None
                history._cached = None

    def run(self, scene: dict, tangents=()) -> dict:
        """Run the scene's grid with the parameters of `scene`.

        Parameters
        ----------
        scene : dict
            The resolved scene at the parameters' values (only its Constants and Prony terms
            are taken; the rest is the built scene's).
        tangents : sequence of (dict, dict, float)
            Per parameter theta_i: the scene at theta_i + h_i, at theta_i - h_i, and 2 h_i;
            the derivatives of the Constants and the Prony terms are their central
            differences. Empty: no sensitivities.

        Returns
        -------
        dict
            ``t`` (the grid's times), ``depth`` (-d_c of the first force-controlled component
            c, or None), and with tangents ``d_depth`` (times x parameters); under
            displacement control with a `component`, ``force`` (the obstacle's force on the
            body along it, -g_c: StepSensitivity._reaction_forms) and ``d_force``.
        """
        problem = self.problem
        if tangents and self.memory_reason:
            raise SceneError(self.memory_reason, key="viscoelastic.temperature")
        if tangents and self.sensitivity is None:
            self.sensitivity = StepSensitivity(problem, self.newton)
        self.apply(scene)
        self._reset()
        self.runs += 1
        grid = time_grid.times(self.scene["time"])
        predict = predictor.create(self.scene, problem)
        obstacle = problem.contact and problem.contact.obstacle
        component = (obstacle.controlled[0] if obstacle is not None and obstacle.controlled
                     else None)
        held = (self.component if obstacle is not None and not obstacle.controlled
                else None)             # displacement control: the force is observed
        force, d_force = [], []
        if held is not None and self.sensitivity is None:
            self.sensitivity = StepSensitivity(problem, self.newton)
        dots = [{name: (a - b) / two_h for (name, a), b in
                 zip(scene_constants(plus).items(), scene_constants(minus).values())}
                for plus, minus, two_h in tangents]
        histories = []
        if tangents and self.terms is not None:
            histories = [HistoryTangent(problem.memory.history,
                                        _prony_terms(plus, self.terms, self.power),
                                        _prony_terms(minus, self.terms, self.power), two_h,
                                        (plus["viscoelastic"], minus["viscoelastic"]))
                         for plus, minus, two_h in tangents]
        state = {"u": [None] * len(tangents), "d": [None] * len(tangents),
                 "force": [None] * len(tangents)}
        depth, d_depth = [], []
        for t in grid:
            for accepted in self._advance(float(t), predict, tangents, dots, histories,
                                          state, 0):
                pass
            if component is not None:
                depth.append(-obstacle.displacement()[component])
                if tangents:
                    d_depth.append([-d[component] for d in state["d"]])
            if held is not None:
                force.append(self.sensitivity.reaction_force(held))
                if tangents:
                    d_force.append(list(state["force"]))
        return {"t": np.asarray(grid, float), "depth": np.array(depth) if depth else None,
                "d_depth": np.array(d_depth) if tangents and depth else None,
                "force": np.array(force) if force else None,
                "d_force": np.array(d_force) if tangents and force else None}

    def _advance(self, t_to, predict, tangents, dots, histories, state, cuts):
        """One step to t_to (in halves when Newton fails, as the time loop cuts), with the
        sensitivities of each accepted state before it is committed."""
        from contactvisco.solver.time_loop import _restore, _solve
        problem = self.problem
        t_from = problem.time.committed
        first = t_from is None
        k = None if first else t_to - t_from
        saved = [f.x.array.copy() for f in problem.unknowns]
        history = problem.memory and problem.memory.history
        before = ({key: value.copy() for key, value in history.state().items()}
                  if histories and not first else {})
        temperature = getattr(history, "temperature", None)
        temperature = None if temperature is None or first else temperature.copy()
        problem.time.stage(t_to)
        try:
            _solve(problem, self.newton, saved, predict, t_to)
        except NewtonFailure:
            _restore(problem, saved)
            if first or cuts >= self.scene["solver"]["max_cuts"]:
                raise
            middle = t_from + 0.5 * (t_to - t_from)
            yield from self._advance(middle, predict, tangents, dots, histories, state,
                                     cuts + 1)
            yield from self._advance(t_to, predict, tangents, dots, histories, state,
                                     cuts + 1)
            return
        results = []
        if tangents:
            step = self.sensitivity
            step.linearize()
            for i in range(len(tangents)):
                constant_dots = dict(dots[i])
                H_dot = None
                if histories:
                    histories[i].prepare(history, before, temperature,
                                         getattr(history, "temperature", None))
                    constant_dots.update(histories[i].weights(k))
                    H_dot = histories[i].stress(k)
                results.append(step.tangent(constant_dots, H_dot, state["u"][i],
                                            state["d"][i]))
                if step.reaction is not None and self.component is not None:
                    x, l, _ = results[-1]
                    state["force"][i] = step.reaction_tangent(self.component, x, l)
        problem.time.commit()
        if predict is not None:
            predict.record(t_to)
        step = self.sensitivity
        for i, (x, _, dd) in enumerate(results):
            # u' with its ghosts: the next step's u_{n-1}' (slip = "increment")
            step.u_dot.x.array[:x.size] = x
            step.u_dot.x.scatter_forward()
            state["u"][i] = step.u_dot.x.array.copy()
            if step.obstacle is not None:
                # d' of every component: the prescribed ones do not depend on theta
                state["d"][i] = np.zeros(step.obstacle.dim)
                state["d"][i][step.obstacle.controlled] = dd
            if histories:
                eps = problem.memory.eps_function.x.array
                histories[i].commit(before, eps, self.sensitivity.strain(x), k)
        yield t_to
