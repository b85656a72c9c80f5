"""The discrete problem (20)-(21) of a scene: spaces, unknowns, UFL residual and Jacobian.

Only the terms a scene needs are built: no lambda_tau without friction, no lambda_nu without a
finite bound g, no compliance term when g = 0 (pure Signorini), no history without memory, no
previous-step displacement unless friction acts on the slip per step.

Residual, with sigma_n = A eps(u_n) + H_n (H_n the history stress of eq 19) and
R_nu = (lambda_nu - r (u_nu - g))_-, sigma_tau = P_B(lambda_tau - r u_tau), B of radius
mu p_nu(u_nu) (contact.friction_law = "compliance", the paper's) or mu (p_nu(u_nu) + R_nu)
("coulomb": the total normal pressure); with contact.slip = "increment", u_tau is replaced by
the slip of the step, u_tau - u_tau(t_{n-1}):

    F_u   = (sigma_n, eps(v)) - (f, v) + int_C (p_nu(u_nu) + R_nu) v_nu - int_C sigma_tau . v_tau
    F_nu  = -1/r int_C (lambda_nu + R_nu) gamma_nu
    F_tau = -1/r int_C (lambda_tau - sigma_tau) . gamma_tau

Here u_nu = u . nu - h, the penetration past the initial gap h, and nu is the averaged nodal normal
(a P1 field); with an [obstacle] (contactvisco.fem.obstacle) nu and h are the obstacle's normal
and distance at the nodes (P1 fields) and u is replaced by u - d, d the obstacle's
displacement. lambda_nu and lambda_tau are P1 fields whose dofs off Gamma_C are fixed to zero,
because DOLFINx 0.5 has no boundary-only spaces. With the vertex quadrature on Gamma_C the
conditions hold node by node, on curved boundaries too. F_tau uses the full vector gamma_tau,
which also forces lambda_tau . nu = 0.
"""
from __future__ import annotations

import gc
import math
from dataclasses import dataclass

import numpy as np
import ufl
from dolfinx import fem
from dolfinx.fem.petsc import assemble_vector
from mpi4py import MPI
from petsc4py import PETSc

from contactvisco.fem import compat
from contactvisco.model import contact_law as law
from contactvisco.fem import obstacle as obstacle_module
from contactvisco.fem import rigid
from contactvisco.fem import prescribed
from contactvisco.fem import geometry as geometry_module
from contactvisco.fem.geometry import Geometry
from contactvisco.fem.kinematics import kinematics
from contactvisco.model.material import (elasticity, energy_stress, hencky_energy,
                                         invariants, lame_constants)
from contactvisco.fem.tangent import TangentCheck
from contactvisco.scene.expressions import Context
from contactvisco.model.memory import (DirectHistory, FractionalHistory, History,
                                       ReducedFractionalHistory, ReducedTimeHistory,
                                       table_kernel)
from contactvisco.errors import SceneError
from contactvisco.model.memory_kernel import memory_power, memory_table, memory_terms
from contactvisco.model import kernels
from contactvisco.model import time_grid


def nodal_rule(d: int) -> dict:
    """Quadrature metadata for the vertex rule on a facet (trapezoid rule for intervals): the
    contact conditions then hold node by node. FFCx 0.5's own "vertex" rule fails on
    intervals, so the rule is given as a custom one (tuples keep the form signature exact)."""
    if d == 2:
        points, weights = ((0.0,), (1.0,)), (0.5, 0.5)
    else:
        points, weights = ((0.0, 0.0), (1.0, 0.0), (0.0, 1.0)), (1 / 6, 1 / 6, 1 / 6)
    return {"quadrature_rule": "custom", "quadrature_points": points,
            "quadrature_weights": weights}


@dataclass
class ContactNodes:
    """Nodes of Gamma_C in the P1 node numbering (local, ghosts included)."""
    nodes: np.ndarray          # local P1 node indices on Gamma_C
    owned: np.ndarray          # bool: owned by this rank
    normals: np.ndarray        # (len(nodes), d) unit nodal normals
    tangents: np.ndarray | None  # (len(nodes), d) unit tangent (2D only)
    corners: np.ndarray | None = None  # nodes at corners of Gamma_C (facet normals used)
    weights: np.ndarray | None = None  # nodal quadrature weight (the node's share of Gamma_C)


@dataclass(frozen=True)
class MemoryPart:
    """The history of eq (19): the integrator, the history stress H it sets (a known DG
    field), eps(u) interpolated for its commits, and the (Constant, part) weights of the
    implicit term of the trapezoid rule."""
    history: History
    H: fem.Function
    eps_function: fem.Function
    eps_expression: fem.Expression
    tensor_space: fem.FunctionSpace
    implicit_terms: list
    constants: dict                            # memory_implicit_<part>


@dataclass(frozen=True)
class ContactPart:
    """The unknowns and node data of Gamma_C: the multipliers (None where the scene needs
    none), the contact nodes, the initial gap h at the P1 nodes, u(t_{n-1}) for
    slip = "increment", the P1 node coordinates and u's P1 interpolant (degree > 1)."""
    nodes: ContactNodes
    lambda_nu: fem.Function | None
    lambda_tau: fem.Function | None
    gap: fem.Function
    u_previous: fem.Function | None
    Q_coordinates: np.ndarray
    u_p1: fem.Function | None
    constants: dict                            # r, g, stiffness, mu (those the law needs)
    corner_forms: dict | None = None           # corner_forms() (None without corners)
    obstacle: object | None = None             # fem.obstacle.ObstaclePart (None: none)


@dataclass
class TimeState:
    """What a time step stages before its solve and commits after it (like an ODE
    integrator's stage and update): the time t of the scene's expressions with the data that
    follow it (loads, Dirichlet values, the gap), the history stress H of eq (19) with the
    implicit weights of the step, prepared from the committed strains, and the origin of the
    step's slip (slip = "increment").

    stage(t) takes the problem from the committed time to t, a step of size k = t - committed
    (the first state, t_0, has no step and nothing to prepare); a step that failed is staged
    again with another t. commit() takes the converged state into the history and makes the
    staged time the committed one. A restart sets `committed` to the checkpoint's time."""
    t: fem.Constant                            # the time of the expressions (Context.t)
    updates: list                              # callables that follow t (interpolations)
    u: fem.Function
    memory: MemoryPart | None
    u_previous: fem.Function | None            # the slip's origin (slip = "increment")
    committed: float | None = None             # the last committed time (None: none yet)
    staged: float | None = None
    obstacle: object | None = None             # fem.obstacle.ObstaclePart (None: none)

    def stage(self, t: float):
        """Move to time t and prepare the step from the committed state."""
        self.move_to(t)
        if self.committed is not None:
            self.prepare(t - self.committed)
        self.staged = t

    def commit(self):
        """Take the converged state at the staged time into the history."""
        self.record(None if self.committed is None else self.staged - self.committed)
        self.committed = self.staged
        if self.obstacle is not None:
            self.obstacle.commit()

    def move_to(self, t: float):
        """Move time-dependent data (loads, Dirichlet values, gap) to time t."""
        self.t.value = t
        for update in self.updates:
            update()

    def prepare(self, k: float):
        """Set the history stress H of a step of size k from the committed state, and the
        implicit weight k/2 R(0) of the trapezoid rule (0 at t_0, where nothing is prepared).
        A failed step can be prepared again with a smaller k.

        With slip = "increment" the current u, the converged state of t_{n-1}, becomes the
        origin of the step's slip; it stays so until the next step is prepared, so that the
        step's output still sees it."""
        if self.u_previous is not None:
            self.u_previous.x.array[:] = self.u.x.array
        if self.obstacle is not None:
            self.obstacle.prepare(self.committed)
        if self.memory is None:
            return
        for memory in getattr(self.memory, "parts", (self.memory,)):
            weights = memory.history.implicit(k)
            for constant, part in memory.implicit_terms:
                if isinstance(constant, fem.Function):  # a weight per point (reduced time)
                    constant.x.array[:] = weights[part]
                else:
                    constant.value = weights[part]
            memory.H.x.array[:] = memory.history.explicit(k)
        if isinstance(self.memory, BodyMemory):
            self.memory.combine()

    def record(self, k: float | None):
        """Take eps of the current, converged u (reached by a step of size k; None at t_0)
        into the history."""
        if self.memory is None:
            return
        for memory in getattr(self.memory, "parts", (self.memory,)):
            memory.eps_function.interpolate(memory.eps_expression)
            memory.history.commit(memory.eps_function.x.array, k)


@dataclass
class Problem:
    """The discrete problem, complete when built (build()); afterwards only the values of
    its Functions and Constants change (time, history, iterates), through `time` between
    steps and the solver within them."""
    scene: dict
    geometry: Geometry
    V: fem.FunctionSpace                      # displacement
    u: fem.Function
    F: list
    J: list
    bcs: list                                 # on every unknown
    bcs_u: list                               # on u only
    u_fixed: np.ndarray                       # (nodes, d) 1 where u's component is prescribed
    multiplier_free: list                     # per multiplier: (nodes, bs) bool
    constants: dict                           # every Constant of the forms, by name
    context: Context                          # x and t of the scene's expressions
    time: TimeState                           # staged and committed between steps
    loads: object                             # the linear form of the external loads (UFL)
    tensor_space: fem.FunctionSpace           # the stress output's tensor space
    sigma_expression: fem.Expression
    length_scale: float
    kinematics: object = None                 # fem.kinematics: eps(u), weights, tensor size
    memory: MemoryPart | None = None
    contact: ContactPart | None = None
    tangent: object | None = None              # fem.tangent.TangentCheck (nonlinear A)

    def load_resultant(self) -> np.ndarray:
        """The resultant of the external loads at the current time, int f + int_N f_N
        (collective; compiles its forms on first use)."""
        d = self.V.mesh.geometry.dim
        if self.loads is None:
            return np.zeros(d)
        if "_resultant" not in self.__dict__:
            units = [fem.Function(self.V) for _ in range(d)]
            for j, e in enumerate(units):
                e.x.array.reshape(-1, d)[:, j] = 1.0
            self._resultant = [fem.form(ufl.action(self.loads, e)) for e in units]
        comm = self.V.mesh.comm
        return np.array([comm.allreduce(fem.assemble_scalar(f), MPI.SUM)
                         for f in self._resultant])

    @property
    def multipliers(self) -> dict[str, fem.Function]:
        """The multipliers the scene needs, by name, in the order lambda_nu, lambda_tau."""
        contact = self.contact
        if contact is None:
            return {}
        return {name: f for name, f in (("lambda_nu", contact.lambda_nu),
                                        ("lambda_tau", contact.lambda_tau)) if f is not None}

    @property
    def unknowns(self) -> list[fem.Function]:
        return [self.u, *self.multipliers.values()]

    def spaces(self) -> list:
        """Every function space of the problem's forms (unknowns, multipliers, coefficients:
        history, obstacle, normals, gap) and its stress output space."""
        spaces = {id(self.V): self.V, id(self.tensor_space): self.tensor_space}
        forms = list(self.F) + [a for row in self.J for a in row if a is not None]
        for form in forms:
            for term in (*form.coefficients(), *form.arguments()):
                space = getattr(term, "function_space", None)
                if space is not None and hasattr(space, "dofmap"):
                    spaces.setdefault(id(space), space)
        return list(spaces.values())

    def release_garbage(self) -> None:
        """Destroy the PETSc objects that Python dropped on this problem's communicators
        (collective; fem.compat.release_petsc_garbage), the solver's included once the
        caller holds it no more. Called when a run ends; a caller that builds problems and
        solvers itself calls it after dropping the solver, before dropping the problem."""
        if self.V.mesh.comm.size == 1:
            return                     # petsc4py destroys the objects of one rank at once
        gc.collect()                   # objects in reference cycles become garbage now
        compat.release_petsc_garbage(self.spaces())

    def count_unknowns(self) -> dict:
        """Global dof counts per unknown."""
        out = {}
        for name, f in (("u", self.u), *self.multipliers.items()):
            imap = f.function_space.dofmap.index_map
            out[name] = imap.size_global * f.function_space.dofmap.index_map_bs
        return out

    def count_contact_nodes(self) -> int:
        """Global number of contact nodes (0 without contact)."""
        if self.contact is None:
            return 0
        return self.V.mesh.comm.allreduce(int(self.contact.nodes.owned.sum()))


def _scalar(mesh, value):
    return fem.Constant(mesh, PETSc.ScalarType(value))


def _block_jacobian(F, unknowns, spaces):
    """J[i][j] = dF_i/dw_j, None where the block is empty."""
    J = []
    for Fi in F:
        row = []
        for unknown, space in zip(unknowns, spaces):
            a = ufl.algorithms.expand_derivatives(
                ufl.derivative(Fi, unknown, ufl.TrialFunction(space)))
            row.append(None if a.empty() else a)
        J.append(row)
    return J


def build(scene: dict, geometry: Geometry) -> Problem:
    """The Problem of a scene on a geometry, built complete in one call: elasticity with the
    memory part (eq 19), the external loads, the Dirichlet conditions, and the contact part
    (eqs 20-21) with its multipliers, residual blocks F and Jacobian blocks J."""
    mesh = geometry.mesh
    geometry_module.check_ranks(mesh)
    compat.settle_coordinate_element(mesh)
    d = mesh.geometry.dim
    degree = scene["discretization"]["degree"]
    context = Context(mesh)
    updates = []                               # run at each new time
    kin = kinematics(scene, mesh)

    V = compat.vector_space(mesh, "CG", degree)
    u, v = fem.Function(V, name="u"), ufl.TestFunction(V)
    if scene.get("body"):
        sigma, constants, memory = body_stress(scene, geometry, u, context, updates, kin)
    else:
        sigma, constants, memory = _stress(scene, mesh, u, context, updates, kin)
    constants["t"] = context.t

    ds = ufl.Measure("ds", domain=mesh, subdomain_data=geometry.facet_tags)
    loads = _loads(scene, geometry, context, v, ds, kin)
    F_u = kin.integral(ufl.inner(sigma, kin.strain(v)), ufl.dx)
    if loads is not None:
        F_u -= loads
    bcs, fixed_components = _dirichlet(scene, geometry, V, context, updates, kin)

    unknowns, spaces, F_extra = [u], [V], []
    contact = None
    if scene["contact"] is not None:
        contact, contact_terms, multipliers = _contact(scene, geometry, u, v, ds, context,
                                                       updates, kin)
        constants.update(contact.constants)
        if contact_terms is not None:
            F_u += contact_terms
        for function, residual in multipliers:
            unknowns.append(function)
            spaces.append(function.function_space)
            F_extra.append(residual)
    multiplier_bcs, multiplier_free = _multiplier_bcs(
        contact and contact.nodes, contact and contact.lambda_nu,
        contact and contact.lambda_tau, fixed_components, d)

    F = [F_u] + F_extra
    tensor_space = memory.tensor_space if memory else kin.tensor_space("DG", degree - 1)
    problem = Problem(
        scene=scene, geometry=geometry, V=V, u=u, F=F, J=_block_jacobian(F, unknowns, spaces),
        bcs=bcs + multiplier_bcs, bcs_u=list(bcs), u_fixed=fixed_components,
        multiplier_free=multiplier_free, constants=constants, context=context,
        time=TimeState(context.t, updates, u, memory, contact and contact.u_previous,
                       obstacle=contact and contact.obstacle),
        loads=loads, tensor_space=tensor_space,
        sigma_expression=compat.expression(sigma, tensor_space),
        length_scale=_length_scale(mesh), kinematics=kin, memory=memory, contact=contact,
        tangent=constants.pop("tangent", None))
    rigid.check(problem)
    return problem


def _stress(scene, mesh, u, context=None, updates=None, kin=None):
    """sigma(u) = A eps(u) + H + sum_part w_part P_part eps(u) (eq 19: the elastic stress,
    the history stress of the memory part and its implicit weights, none without memory),
    eps the strain of the kinematics `kin` (fem.kinematics; the scene's when None).
    Returns sigma, the Constants it uses by name (the Lame constants lame_lambda, lame_mu
    and the memory part's; with a nonlinear A also "tangent", its TangentCheck) and the
    MemoryPart (None without memory)."""
    kin = kin or kinematics(scene, mesh)
    strain = kin.strain
    mat = scene["material"]
    lame_lambda, lame_mu = lame_constants(mat["model"], mat["E"], mat["nu"])
    constants = {"lame_lambda": _scalar(mesh, lame_lambda), "lame_mu": _scalar(mesh, lame_mu)}
    if mat.get("law", "linear") == "linear":
        sigma = elasticity(strain(u), constants["lame_lambda"], constants["lame_mu"])
    else:
        energy = material_energy(mat, constants, context or Context(mesh))
        sigma, C = energy_stress(strain(u), energy)
        constants["tangent"] = TangentCheck(C, u, lame_mu)
    memory = _memory(scene, mesh, u, context, updates, kin)
    if memory is not None:
        sigma = sigma + memory.H
        for constant, part in memory.implicit_terms:
            sigma = sigma + constant * _strain_part(strain(u), part)
        constants.update(memory.constants)
    return sigma, constants, memory


def material_energy(mat: dict, constants: dict, context: Context):
    """The strain energy W of a nonlinear A (material.law "hencky" or "energy").

    Parameters
    ----------
    mat : dict
        The resolved [material] table.
    constants : dict
        The Constants lame_lambda and lame_mu (lambda* in plane stress).
    context : contactvisco.scene.expressions.Context
        The position and time symbols of material.energy.

    Returns
    -------
    callable
        eps -> W(eps), a UFL expression: hencky_energy, or material.energy in the
        invariants tr_eps, eps2, dev_eps2 with lmbda and mu_lame.
    """
    lmbda, mu = constants["lame_lambda"], constants["lame_mu"]
    if mat["law"] == "hencky":
        return lambda eps: hencky_energy(eps, lmbda, mu, mat["hencky_exponent"],
                                         mat["hencky_strain"])
    text = mat["energy"]
    return lambda eps: context.scalar(text, "material.energy",
                                      dict(invariants(eps), lmbda=lmbda, mu_lame=mu))


def _strain_part(eps, part):
    """The part of the strain eps a memory term acts on: full, deviatoric or volumetric
    (tr(eps)/d I, d the dimension of the strain tensor: 3 for an axisymmetric body)."""
    d = eps.ufl_shape[0]
    if part == "deviatoric":
        return ufl.dev(eps)
    if part == "volumetric":
        return ufl.tr(eps) / d * ufl.Identity(d)
    return eps


def _length_scale(mesh) -> float:
    """The largest extent of the mesh's bounding box (collective)."""
    d = mesh.geometry.dim
    x = mesh.geometry.x[:, :d]
    upper, lower = np.empty(d), np.empty(d)
    mesh.comm.Allreduce(x.max(axis=0), upper, op=MPI.MAX)
    mesh.comm.Allreduce(x.min(axis=0), lower, op=MPI.MIN)
    return float(np.max(upper - lower))


def _loads(scene, geometry, context, v, ds, kin):
    """(f, v) + sum (f_N, v)_Gamma_N: the linear form of the external loads, None without
    (integrals weighted as the kinematics `kin` weighs them: 2 pi r in axisymmetry)."""
    d = geometry.mesh.geometry.dim
    loads = []
    body = scene["body_force"]["value"]
    if body is not None:
        loads.append(kin.integral(ufl.dot(context.vector(body, "body_force.value", d), v),
                                  ufl.dx))
    for i, traction in enumerate(scene["traction"]):
        geometry.facets(traction["boundary"], f"traction[{i}].boundary")   # checks the name
        fN = context.vector(traction["value"], f"traction[{i}].value", d)
        loads.append(kin.integral(ufl.dot(fN, v), ds(geometry.names[traction["boundary"]])))
    return sum(loads[1:], loads[0]) if loads else None


def _contact_measure(scene, geometry, ds):
    """ds restricted to Gamma_C with the contact quadrature (nodal: the vertex rule)."""
    disc = scene["discretization"]
    d = geometry.mesh.geometry.dim
    if disc["contact_quadrature"] == "nodal":
        if disc["degree"] != 1:
            raise SceneError("discretization.contact_quadrature = 'nodal' needs degree 1; "
                             "use 'gauss' for degree 2", key="discretization.contact_quadrature")
        metadata = nodal_rule(d)
    else:
        metadata = {"quadrature_degree": 2 * disc["degree"] + 2}
    names = scene["contact"]["boundary"]
    names = [names] if isinstance(names, str) else list(names)
    for name in names:
        geometry.facets(name, "contact.boundary")     # checks the name
    return ds(tuple(geometry.names[name] for name in names), metadata=metadata)


def _contact(scene, geometry, u, v, ds, context, updates, kin):
    """The contact part (eqs 20-21): returns the ContactPart, the terms it adds to F_u and
    the (multiplier, its residual F_nu or F_tau) pairs, in the order lambda_nu, lambda_tau.
    The law itself is contactvisco.model.contact_law.law_terms. The kinematics `kin` weighs
    the terms node by node (kin.contact_weight: the ring areas in axisymmetry)."""
    mesh = geometry.mesh
    contact = scene["contact"]
    degree = scene["discretization"]["degree"]
    dsc = _contact_measure(scene, geometry, ds)
    # P1 spaces for the multipliers and for the node tables of the output.
    Q = compat.scalar_space(mesh, "CG", 1)
    # Its own space object, even for P1: block assembly keys boundary conditions and
    # diagonals on space identity, so sharing V would put u's onto lambda_tau's rows.
    W = compat.vector_space(mesh, "CG", 1)
    nodes = _contact_nodes(mesh, Q, W, dsc)
    omega, nodes.weights = _node_weights(kin, Q, dsc, nodes)
    if degree == 1 and not np.allclose(u.function_space.tabulate_dof_coordinates(),
                                       W.tabulate_dof_coordinates()):
        raise RuntimeError("displacement and multiplier node numberings differ")
    obstacle = _obstacle(scene, Q, W, nodes, context, updates, geometry, u.function_space)
    if obstacle is None:
        normal = _contact_normal(mesh, Q, W, dsc, nodes)
        gap_value, gap_function = _gap(contact["gap"], Q, context, updates)
    else:
        normal, gap_value, gap_function = obstacle.normal, obstacle.gap, obstacle.gap

    constants, lambda_nu, lambda_tau, u_previous = _contact_unknowns(contact, u, Q, W,
                                                                      context, updates)
    laws = contact_laws(contact, context)
    check = prescribed.NodeCheck(contact, Q, nodes.nodes, context)
    if check:                                   # at every staged time, before its solve
        check()
        updates.append(check)
    relative, previous = _relative_motion(u, u_previous, obstacle)
    terms = law.law_terms(law.UFL, relative, normal, gap_value, lambda_nu, lambda_tau,
                          previous, constants, contact["friction_law"], laws=laws)
    F_u = None
    pairs = []

    def weighted(integrand):
        return (integrand if omega is None else omega * integrand) * dsc

    if terms["normal_force"] is not None:
        F_u = weighted(terms["normal_force"] * law.normal_part(v, normal))
    if lambda_nu is not None:
        r = constants["r"]
        pairs.append((lambda_nu, weighted(-1.0 / r * (lambda_nu + terms["R_nu"])
                                          * ufl.TestFunction(Q))))
    if lambda_tau is not None:
        r, sigma_tau = constants["r"], terms["sigma_tau"]
        tangential = weighted(-ufl.dot(sigma_tau, law.tangential_part(v, normal)))
        F_u = tangential if F_u is None else F_u + tangential
        pairs.append((lambda_tau, weighted(-1.0 / r * ufl.dot(lambda_tau - sigma_tau,
                                                               ufl.TestFunction(W)))))
    if (scene.get("obstacle") or {}).get("shape") == "body":
        obstacle.contact_form = F_u            # the master's share (fem.body_contact)
    if obstacle is not None and obstacle.controlled:
        obstacle.force_forms = obstacle_module.force_forms(
            obstacle, F_u, v, [u] + [f for f, _ in pairs], [F_u] + [r for _, r in pairs])
    corners = mesh.comm.allreduce(nodes.corners.size, MPI.SUM) > 0
    part = ContactPart(nodes=nodes, lambda_nu=lambda_nu, lambda_tau=lambda_tau,
                       gap=gap_function, u_previous=u_previous,
                       Q_coordinates=Q.tabulate_dof_coordinates(),
                       u_p1=fem.Function(W) if degree > 1 else None, constants=constants,
                       corner_forms=_corner_forms(terms, u, normal, Q, W, dsc,
                                                  with_radius="p_tau" in laws)
                       if corners or laws else None, obstacle=obstacle)
    return part, F_u, pairs


def _node_weights(kin, Q, dsc, nodes):
    """The contact terms' weight (None: none) and each contact node's weight, the area its
    force acts on (kin.contact_weight; the node's share of Gamma_C without a weight)."""
    shares = np.zeros(Q.dofmap.index_map.size_local + Q.dofmap.index_map.num_ghosts)
    shares[nodes.nodes] = nodes.weights
    omega, weights = kin.contact_weight(Q, dsc, shares)
    return omega, weights[nodes.nodes]


def _obstacle(scene, Q, W, nodes, context, updates, geometry=None, V=None):
    """The scene's rigid obstacle (contactvisco.fem.obstacle; None without one): its normal nu
    and gap h at the contact nodes, re-evaluated at each time when it moves. The contact
    nodes' normals become the obstacle's; no node is a corner (one normal per node)."""
    table = scene.get("obstacle")
    if table is None or table["shape"] == "none":
        return None
    if table["shape"] == "body":
        from contactvisco.fem import body_contact
        return body_contact.build(scene, geometry, V, Q, W, nodes,
                                  _length_scale(geometry.mesh))
    part = obstacle_module.build(scene, Q, W, nodes, context.t)
    nodes.corners = np.zeros(0, dtype=nodes.nodes.dtype)
    if table["displacement"] is not None and context.depends_on_time(table["displacement"]):
        updates.append(part.move_to)
    return part


def _relative_motion(u, u_previous, obstacle):
    """What the law acts on: u and u(t_{n-1}) relative to the obstacle, u - d and
    u(t_{n-1}) - d(t_{n-1}) (u and u_previous themselves without an obstacle)."""
    if obstacle is None:
        return u, u_previous
    previous = None if u_previous is None else u_previous - obstacle.D_previous
    return u - obstacle.D, previous


def has_friction(mu) -> bool:
    """Whether contact.mu asks for friction: a number > 0, or an expression (in x and t).

    Parameters
    ----------
    mu : float or str
        The scene's contact.mu.

    Returns
    -------
    bool
        True for mu > 0 or an expression.
    """
    return isinstance(mu, str) or mu > 0


def _friction_coefficient(mu, Q, context, updates):
    """contact.mu for the forms: a Constant, or for an expression in x and t its P1
    interpolant max(mu(x, t), 0), kept up to date in time (a node's friction coefficient is
    its value at the node, as the nodal contact quadrature sees it)."""
    if not isinstance(mu, str):
        return _scalar(Q.mesh, mu)
    value = context.scalar(mu, "contact.mu")
    function = fem.Function(Q, name="mu")
    update = _interpolator(function, ufl.max_value(value, 0.0)
                           if not isinstance(value, fem.Constant) else value, Q)
    update()
    if context.depends_on_time(mu):
        updates.append(update)
    return function


def _contact_unknowns(contact: dict, u, Q, W, context=None, updates=None):
    """What the law of the [contact] table needs: its Constants by name (r, g when finite,
    stiffness when the compliance term acts, mu when friction acts), the
    multiplier lambda_nu in Q (a finite bound g only), lambda_tau in W (mu > 0 and a pressure
    to bound it: compliance, or Coulomb with a bound) and u(t_{n-1}) for slip = "increment"
    (None where absent)."""
    mesh = Q.mesh
    g = contact["g"]
    constants = {"r": _scalar(mesh, contact["augmentation"]),
                 "g": _scalar(mesh, g) if math.isfinite(g) else None}
    if contact["stiffness"] > 0 and g > 0:
        constants["stiffness"] = _scalar(mesh, contact["stiffness"])
    lambda_nu = fem.Function(Q, name="lambda_nu") if math.isfinite(g) else None
    compliance = "stiffness" in constants or (contact.get("p_nu") is not None and g > 0)
    has_pressure = (compliance
                    or (contact["friction_law"] == "coulomb" and lambda_nu is not None))
    lambda_tau = u_previous = None
    friction = has_friction(contact["mu"]) or (contact.get("p_tau") is not None
                                               and compliance)
    if friction and has_pressure:
        if has_friction(contact["mu"]):
            constants["mu"] = _friction_coefficient(contact["mu"], Q, context, updates)
        lambda_tau = fem.Function(W, name="lambda_tau")
        if contact["slip"] == "increment":
            # Slip measured from the previous step's state: u_tau - u_tau(t_{n-1}).
            u_previous = fem.Function(u.function_space, name="u_previous")
    return constants, lambda_nu, lambda_tau, u_previous


def contact_laws(contact: dict, context: Context) -> dict:
    """The prescribed functions of the [contact] table as callables of the saturated
    penetration sigma = max(0, min(s, g)) (contactvisco.model.contact_law.law_terms): "p_nu"
    (contact.p_nu, an expression in s, x, t; built when the compliance term acts, g > 0) and
    "p_tau" (contact.p_tau, in s, p_nu, x, t); none for the linear law (stiffness, mu).

    Parameters
    ----------
    contact : dict
        The resolved [contact] table.
    context : contactvisco.scene.expressions.Context
        The position and time symbols of the mesh.

    Returns
    -------
    dict
        name -> callable giving the UFL value of p_nu(sigma) or p_tau(sigma, p_nu).
    """
    laws = {}
    if contact.get("p_nu") is not None and contact["g"] > 0:
        text = contact["p_nu"]
        laws["p_nu"] = lambda sigma: context.scalar(text, "contact.p_nu", {"s": sigma})
    if contact.get("p_tau") is not None:
        text_tau = contact["p_tau"]
        laws["p_tau"] = lambda sigma, p: context.scalar(text_tau, "contact.p_tau",
                                                        {"s": sigma, "p_nu": p})
    return laws


def _corner_forms(terms, u, normal, Q, W, dsc, with_radius=False):
    """Forms whose assembled vectors, divided by the node's weight, are the law's node values
    as the forms see them: with the vertex rule, node i gets sum_f w_f value_f(x_i) over its
    facets f. Where the normal is one P1 field this is the value at the node; at a corner of
    Gamma_C, where the forms use each facet's normal, it is their weighted mean, which is what
    the node's single multiplier and force act on. Keys: weight, u_nu, s_nu, p_nu (if any),
    slip, u_tau (vectors), and radius with with_radius (a prescribed p_tau)."""
    d = Q.mesh.geometry.dim
    vertex = dsc.reconstruct(metadata=nodal_rule(d))
    scalar_test, vector_test = ufl.TestFunction(Q), ufl.TestFunction(W)
    scalars = {"weight": 1.0, "u_nu": law.normal_part(u, normal), "s_nu": terms["s_nu"],
               "p_nu": terms["p_nu"], "radius": terms["radius"] if with_radius else None}
    vectors = {"slip": terms["slip"], "u_tau": law.tangential_part(u, normal)}
    forms = {key: fem.form(value * scalar_test * vertex) for key, value in scalars.items()
             if value is not None}
    forms.update({key: fem.form(ufl.dot(value, vector_test) * vertex)
                  for key, value in vectors.items()})
    return forms


def assembled_values(form) -> np.ndarray:
    """The assembled vector of a linear form at every local dof, ghosts included (their
    contributions summed on the owner, then sent back; collective). The PETSc vector is
    destroyed here: dropped on several ranks, it would wait for a collective clean-up."""
    vec = assemble_vector(form)
    vec.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
    vec.ghostUpdate(addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)
    with vec.localForm() as local:
        values = local.array.copy()
    vec.destroy()
    return values


def corner_values(problem, nodes_local) -> dict:
    """The law's values at the local P1 nodes `nodes_local` from corner_forms (collective):
    a dict of (n,) or (n, d) arrays, keys as in corner_forms but the weight."""
    d = problem.V.mesh.geometry.dim
    out = {}
    for key, form in problem.contact.corner_forms.items():
        values = assembled_values(form)
        out[key] = values.reshape(-1, d)[nodes_local] if key in ("slip", "u_tau") \
            else values[nodes_local]
    weight = out.pop("weight")
    return {key: value / (weight[:, None] if value.ndim == 2 else weight)
            for key, value in out.items()}


def _gap(expression, Q, context, updates):
    """The initial gap h: its UFL value and its P1 interpolant (kept up to date in time)."""
    value = context.scalar(expression, "contact.gap")
    function = fem.Function(Q, name="gap")
    update = _interpolator(function, value, Q)
    update()
    if context.depends_on_time(expression):
        updates.append(update)
    return value, function


def _memory(scene, mesh, u, context=None, updates=None, kin=None) -> MemoryPart | None:
    """The history of eq (19) (None without memory): H, a known DG field, and for the
    trapezoid rule the implicit weights w of w P eps(u) (w = k/2 R(0), or the
    product-integration weight of the fractional kernel: history.implicit), as Constants
    that are zero at t_0, where there is no history yet; prepare(k) sets them."""
    terms, table, power = memory_terms(scene), memory_table(scene), memory_power(scene)
    if not terms and table is None and power is None:
        return None
    time = scene["time"]
    dt = float(time_grid.steps(time).max())      # the uniform step of `advance` (tests)
    kin = kin or kinematics(scene, mesh)
    d = kin.tensor_dim                          # the strain's: 3 in axisymmetry
    tensor_space = kin.tensor_space("DG", kin.history_degree(scene["discretization"]["degree"]))
    visco = scene.get("viscoelastic")
    thermal = visco is not None and visco["temperature"] is not None
    if table is not None:
        history = DirectHistory(table_kernel(*table), dt, time["rule"])
    elif power is not None:
        least, span = _reduced_range(scene, mesh, context) if thermal else (1.0, None)
        history = kernels.history(power, time, scene["solver"]["max_cuts"], d, span=span,
                                  least=least)
    else:
        history = History(terms, dt, time["rule"], d)
    if thermal:
        return _reduced_time_memory(scene, mesh, u, history, tensor_space, context, updates,
                                    kin)
    weights = {part: _scalar(mesh, 0.0) for part in history.implicit(dt)}
    return _memory_part(history, weights, kin.strain(u), tensor_space)


def _temperature_field(scene, mesh, context):
    """The temperature as a DG field at the stress's points: (space, Function, a callable
    that interpolates viscoelastic.temperature at the context's time)."""
    scalars = compat.scalar_space(mesh, "DG", scene["discretization"]["degree"] - 1)
    theta = fem.Function(scalars, name="temperature")
    follow = _interpolator(theta, context.scalar(scene["viscoelastic"]["temperature"],
                                                 "viscoelastic.temperature"), scalars)
    return scalars, theta, follow


#: Margin of the reduced-time span of a fitted kernel over its bound from the step times.
SPAN_MARGIN = 1.1


def _reduced_range(scene, mesh, context) -> tuple[float, float]:
    """(least, span) that the fit of a power or fractional kernel must cover in reduced time:
    the reduced end time xi(T) (the span) and the least 1/a_T, which scales the shortest
    reduced step (least k / 2^max_cuts). At a constant temperature, 1/a_T and T / a_T (exactly
    the T_ref run of T / a_T); for an expression, over the points and the step times
    t_n of the grid, min(1, 1/a_T) / SPAN_MARGIN and SPAN_MARGIN T max(1, 1/a_T) (xi(T) <=
    T max 1/a_T; the run stops if a step would pass the span)."""
    from contactvisco.model.viscoelastic import inverse_shift, log10_shift
    visco, T = scene["viscoelastic"], scene["time"]["T"]
    theta = visco["temperature"]
    if isinstance(theta, (int, float)) and not isinstance(theta, bool):
        inverse = 10.0 ** -float(log10_shift(visco, theta))
        return inverse, T * inverse
    _, field, follow = _temperature_field(scene, mesh, context)
    start, least, largest = float(context.t.value), 1.0, 1.0
    for t in time_grid.times(scene["time"]):
        context.t.value = t
        follow()
        inverse, error = inverse_shift(visco, field.x.array)
        if error is None and inverse.size:     # an error stops the run at its step
            least = min(least, float(inverse.min()))
            largest = max(largest, float(inverse.max()))
    context.t.value = start
    return (mesh.comm.allreduce(least, op=MPI.MIN) / SPAN_MARGIN,
            SPAN_MARGIN * T * mesh.comm.allreduce(largest, op=MPI.MAX))


def _reduced_time_memory(scene, mesh, u, history, tensor_space, context, updates, kin):
    """The memory part of a scene with a temperature: the Prony history advanced in reduced
    time (ReducedTimeHistory), 1/a_T(theta) taken at each point whenever the time moves, and
    the implicit weights as fields (one value per point)."""
    from contactvisco.model.viscoelastic import inverse_shift
    d = kin.tensor_dim
    fractional = isinstance(history, FractionalHistory)
    reduced = (ReducedFractionalHistory if fractional else ReducedTimeHistory)(history, d * d)
    visco = scene["viscoelastic"]
    scalars, theta, follow = _temperature_field(scene, mesh, context)
    reduced.owned = scalars.dofmap.index_map.size_local    # points of this rank (then ghosts)
    span = getattr(history, "span", None)
    dt = float(time_grid.steps(scene["time"]).max())     # the largest step of the grid
    staged = []                                 # the last staged time (none yet)
    moving = context.depends_on_time(visco["temperature"])

    def stage():
        owned = reduced.owned                   # ghosts: taken along, never an error
        now = float(context.t.value)
        error = (_between_steps(visco, theta, follow, context, staged[0], now, owned)
                 if moving and staged else None)
        staged[:] = [now]
        follow()
        inverse, at_time = inverse_shift(visco, theta.x.array[:owned])
        if error is None and at_time:
            error = (f"{_at_point(at_time, visco, theta.x.array[:owned], scalars)} "
                     f"(at t = {now:g})")
        elif error is None and span is not None and reduced.reduced_time is not None and owned:
            # a step (at most dt) from the committed state: xi_n + dt max 1/a_T bounds xi_n+1
            reach = float(np.max(reduced.reduced_time[:owned]
                                 + dt * np.maximum(reduced.committed[:owned], inverse)))
            if reach > span * (1.0 + 1e-9):
                error = (f"viscoelastic.temperature: the reduced time would reach {reach:.6g}, "
                         f"beyond {span:.6g}, the span of the kernel's sum of exponentials "
                         f"(fitted from the temperature at the step times) (at t = {now:g})")
        inverse = np.concatenate([inverse, inverse_shift(visco, theta.x.array[owned:])[0]])
        error = next((e for e in mesh.comm.allgather(error) if e), None)   # every rank stops
        if error:
            raise SceneError(error, key="viscoelastic.temperature")
        reduced.stage(inverse, theta.x.array)

    updates.append(stage)
    weights = {part: fem.Function(scalars) for part in reduced.implicit(0.0)}
    return _memory_part(reduced, weights, kin.strain(u), tensor_space)


def _memory_part(history, weights, eps, tensor_space) -> MemoryPart:
    """The MemoryPart of a history whose implicit weights (by part) are the Constants or
    point fields `weights`, of the strain eps(u) (UFL)."""
    return MemoryPart(
        history=history, H=fem.Function(tensor_space, name="history_stress"),
        eps_function=fem.Function(tensor_space),
        eps_expression=compat.expression(eps, tensor_space),
        tensor_space=tensor_space,
        constants={f"memory_implicit_{part}": c for part, c in weights.items()},
        implicit_terms=[(c, part) for part, c in weights.items()])


#: The times inside a step at which a temperature in t is checked against its shift's range.
BETWEEN_STEPS = 16


def _between_steps(visco, theta, follow, context, before: float, now: float, owned: int):
    """Why the shift cannot be taken at a time strictly between two staged times (WLF's
    C2 + T - T_ref crossing zero inside a step, which the step times alone do not see): the
    temperature at BETWEEN_STEPS times inside the interval, at this rank's points; None if
    none. The reduced time integrates 1/a_T over the whole step."""
    from contactvisco.model.viscoelastic import inverse_shift
    error = None
    for j in range(1, BETWEEN_STEPS + 1):
        context.t.value = before + (now - before) * j / (BETWEEN_STEPS + 1)
        follow()
        _, error = inverse_shift(visco, theta.x.array[:owned])
        if error:
            error = (f"{_at_point(error, visco, theta.x.array[:owned], theta.function_space)}"
                     f" (at t = {float(context.t.value):g}, between the step times "
                     f"{before:g} and {now:g})")
            break
    context.t.value = now
    return error


def _at_point(error: str, visco, values, space) -> str:
    """The shift error with the point where it arises (its coordinates)."""
    from contactvisco.model.viscoelastic import first_error_point, shift_error
    i = first_error_point(visco, values)
    if i is None:
        return error
    error = shift_error(visco, values[i])
    x = space.tabulate_dof_coordinates()[i]
    where = ", ".join(f"{c:.6g}" for c in x[:space.mesh.geometry.dim])
    return f"{error} at the point x = ({where})"


def _interpolator(function, value, space):
    """A callable that sets `function` to the UFL value or Constant `value`."""
    if isinstance(value, fem.Constant):
        return lambda: function.x.array.__setitem__(slice(None), value.value)
    if ufl.domain.extract_unique_domain(value) is None:
        # A value in t alone (e.g. [d * t, -w]) has no mesh: fem.Expression needs one. A zero
        # Constant times x gives it one (a float zero would be simplified away).
        x = ufl.SpatialCoordinate(space.mesh)
        zero = _scalar(space.mesh, 0.0)
        value = value + zero * (x[0] if value.ufl_shape == ()
                                else ufl.as_vector([x[0]] * value.ufl_shape[0]))
    expression = compat.expression(value, space)
    return lambda: function.interpolate(expression)


def _dirichlet(scene, geometry, V, context, updates, kin=None):
    """Dirichlet conditions and, per displacement dof, whether it is prescribed (0/1 array,
    consistent over ranks, ghosts included). Values may depend on x and t. An axisymmetric
    body (kin) also gets u_r = 0 at its nodes on the axis (kin.axis_dofs)."""
    mesh = geometry.mesh
    d = mesh.geometry.dim
    fdim = d - 1
    bcs = []
    fixed = fem.Function(V)
    for i, item in enumerate(scene["dirichlet"]):
        where = f"dirichlet[{i}]"          # keys and values checked by tables.Dirichlet
        facets = geometry.facets(item["boundary"], f"{where}.boundary")
        comps = item.get("components", "all")
        value = item.get("value", 0.0)
        if comps == "all":
            vals = value if isinstance(value, (list, tuple)) else [value] * d
            dofs = fem.locate_dofs_topological(V, fdim, facets)
            vector = context.vector(vals, f"{where}.value", d)
            if isinstance(vector, fem.Constant):
                bcs.append(fem.dirichletbc(vector.value, dofs, V))
            else:
                g = fem.Function(V)
                update = _interpolator(g, vector, V)
                update()
                if context.depends_on_time(vals):
                    updates.append(update)
                bcs.append(fem.dirichletbc(g, dofs))
            fixed.x.array[(dofs[:, None] * d + np.arange(d)).ravel()] = 1.0
            continue
        bcs += _component_bcs(item, where, comps, facets, V, context, updates, fixed)
    axis = None if kin is None else kin.axis_dofs(V)
    if axis is not None:
        bcs.append(fem.dirichletbc(PETSc.ScalarType(0.0), axis, V.sub(0)))
        fixed.x.array[axis] = 1.0
    # A rank may hold a prescribed node as a ghost without the facet that prescribes it.
    fixed_vector = compat.petsc_vector(fixed)
    fixed_vector.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
    fixed_vector.ghostUpdate(addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)
    return bcs, fixed.x.array.reshape(-1, V.dofmap.index_map_bs)


def _component_bcs(item, where, comps, facets, V, context, updates, fixed):
    """The conditions of one dirichlet entry on the listed components; marks their dofs in
    the Function `fixed`."""
    d = V.mesh.geometry.dim
    value = item.get("value", 0.0)
    vals = value if isinstance(value, (list, tuple)) else [value] * len(comps)
    bcs = []
    for comp, val in zip(comps, vals):
        scalar = context.scalar(val, f"{where}.value")
        if isinstance(scalar, fem.Constant):
            dofs = fem.locate_dofs_topological(V.sub(comp), d - 1, facets)
            bcs.append(fem.dirichletbc(scalar.value, dofs, V.sub(comp)))
        else:
            Vc, _ = V.sub(comp).collapse()
            g = fem.Function(Vc)
            update = _interpolator(g, scalar, Vc)
            update()
            if context.depends_on_time(val):
                updates.append(update)
            pair = fem.locate_dofs_topological((V.sub(comp), Vc), d - 1, facets)
            bcs.append(fem.dirichletbc(g, pair, V.sub(comp)))
            dofs = pair[0]
        fixed.x.array[dofs] = 1.0
    return bcs


def _contact_nodes(mesh, Q, W, dsc) -> ContactNodes:
    """Nodes of Gamma_C with their normals, found by assembly so that every rank knows every
    contact node it holds, ghosts included."""
    d = mesh.geometry.dim
    scalar_test, vector_test = ufl.TestFunction(Q), ufl.TestFunction(W)
    facet_normal = ufl.FacetNormal(mesh)
    weights = assembled_values(fem.form(scalar_test * dsc))
    normals = assembled_values(fem.form(ufl.dot(facet_normal, vector_test) * dsc))
    normals = normals.reshape(-1, d)
    if not np.allclose(Q.tabulate_dof_coordinates(),
                       W.tabulate_dof_coordinates()):
        raise RuntimeError("scalar and vector P1 node numberings differ")
    nodes = np.flatnonzero(weights > 0)
    normals = normals[nodes]
    normals /= np.linalg.norm(normals, axis=1)[:, None]
    tangents = np.column_stack([-normals[:, 1], normals[:, 0]]) if d == 2 else None
    owned = nodes < Q.dofmap.index_map.size_local
    return ContactNodes(nodes=nodes, owned=owned, normals=normals, tangents=tangents,
                        weights=weights[nodes])


def _contact_normal(mesh, Q, W, dsc, nodes, corner_angle=15.0):
    """The normal nu of the contact terms: the averaged nodal normal (a P1 field), so that
    where two facets of a curved boundary meet each node has one normal and its conditions
    hold exactly; but the facet normal at corners of the contact boundary (adjacent facet
    normals more than corner_angle degrees from the average), where no average is right."""
    d = mesh.geometry.dim
    nodal = fem.Function(W, name="normal")
    nodal.x.array.reshape(-1, d)[nodes.nodes] = nodes.normals
    facet = ufl.FacetNormal(mesh)
    scalar_test = ufl.TestFunction(Q)
    deviation = assembled_values(
        fem.form((1.0 - ufl.dot(facet, nodal)) * scalar_test * dsc))
    weight = assembled_values(fem.form(scalar_test * dsc))
    mean = deviation[nodes.nodes] / weight[nodes.nodes]
    corners = nodes.nodes[mean > 1.0 - np.cos(np.deg2rad(corner_angle))]
    nodes.corners = corners
    if mesh.comm.allreduce(corners.size, MPI.SUM) == 0:
        return nodal
    indicator = fem.Function(Q)
    indicator.x.array[corners] = 1.0
    return ufl.conditional(ufl.gt(indicator, 0.5), facet, nodal)


def _multiplier_bcs(nodes, lambda_nu, lambda_tau, fixed, d):
    """Fix multiplier dofs to zero off Gamma_C, and where the displacement they act on is
    prescribed (their Newton rows would be empty: MUMPS then stops with INFOG(1) = -3).
    Returns the conditions and, per multiplier, its free dofs as a (nodes, bs) bool array."""
    bcs, free_masks = [], []
    if nodes is None:
        return bcs, free_masks
    zero = PETSc.ScalarType(0.0)
    if lambda_nu is not None:
        Q = lambda_nu.function_space
        n_local = Q.dofmap.index_map.size_local + Q.dofmap.index_map.num_ghosts
        free = np.zeros(n_local, dtype=bool)
        # u_nu is prescribed when every component that nu involves is.
        involved = np.abs(nodes.normals) > 1e-8
        prescribed = np.all(~involved | (fixed[nodes.nodes] > 0), axis=1)
        free[nodes.nodes[~prescribed]] = True
        dofs = np.flatnonzero(~free).astype(np.int32)
        bcs.append(fem.dirichletbc(zero, dofs, Q))
        free_masks.append(free[:, None])
    if lambda_tau is not None:
        L = lambda_tau.function_space
        n_local = L.dofmap.index_map.size_local + L.dofmap.index_map.num_ghosts
        free = np.zeros((n_local, d), dtype=bool)
        free[nodes.nodes] = fixed[nodes.nodes] == 0
        # One condition per component: on a sub-space, dofs are unrolled parent indices.
        for comp in range(d):
            dofs = (np.flatnonzero(~free[:, comp]) * d + comp).astype(np.int32)
            bcs.append(fem.dirichletbc(zero, dofs, L.sub(comp)))
        free_masks.append(free)
    return bcs, free_masks


# ------------------------------------------------------------------ bodies

class BodyHistory:
    """The histories of eq (19) of several bodies seen as one by checkpoints and reports:
    state() holds each body's arrays under its key with the suffix _body<b>."""

    def __init__(self, histories: list):
        self.histories = histories
        self.direct = any(getattr(h, "direct", False) for h in histories)
        self.terms = [term for h in histories for term in getattr(h, "terms", [])]

    def state(self) -> dict:
        """Every body's history arrays (restore() takes them back)."""
        return {f"{key}_body{b}": value for b, history in enumerate(self.histories)
                for key, value in history.state().items()}

    def restore(self, state: dict):
        """Each body's arrays of state() back into its history."""
        for b, history in enumerate(self.histories):
            suffix = f"_body{b}"
            history.restore({key[:-len(suffix)]: value for key, value in state.items()
                             if key.endswith(suffix)})


@dataclass
class BodyMemory:
    """The memory parts of the bodies that have one ([[body]] tables): each a MemoryPart on
    the whole tensor space, of which the stress takes its body's cells only; H, the history
    stress of the output, is the body's H_b on each body's cells (combine())."""
    parts: list                                # MemoryPart of each body with memory
    masks: list                                # per part: 1.0 on its body's tensor dofs
    history: BodyHistory
    H: fem.Function
    tensor_space: fem.FunctionSpace
    bodies: list | None = None                 # per part: its [[body]] table

    def combine(self):
        """H = sum_b mask_b H_b."""
        self.H.x.array[:] = sum(mask * part.H.x.array for mask, part in zip(self.masks,
                                                                           self.parts))


def body_cells(scene: dict, geometry: Geometry) -> list[np.ndarray]:
    """The local cells (ghosts included) of each [[body]] table, checked: a cell tag name or
    region that names no cell, or a cell in no body or in two, is a SceneError naming the key.

    Parameters
    ----------
    scene : dict
        The resolved scene, with its list ``body`` of [[body]] tables.
    geometry : contactvisco.fem.geometry.Geometry
        The mesh with its cell tags and cell tag names.

    Returns
    -------
    list of numpy.ndarray
        Per body, the local cell indices c with tag(c) = the body's tag, or with r(x_c) > 0 for
        a region r in x, x_c the cell's midpoint.
    """
    from contactvisco.scene.expressions import value_at
    mesh = geometry.mesh
    tdim, d = mesh.topology.dim, mesh.geometry.dim
    cell_map = mesh.topology.index_map(tdim)
    local = cell_map.size_local + cell_map.num_ghosts
    names = geometry.cell_names or {}
    midpoints = None
    out = []
    for b, body in enumerate(scene["body"]):
        where, cells = f"body[{b}].cells", body["cells"]
        if cells in names:
            found = geometry.cell_tags.find(names[cells])
        else:
            try:
                value_at(cells, where, d, [0.0] * d, 0.0)
            except SceneError as err:
                raise SceneError(
                    f"{where} = {cells!r} is neither a cell tag of this mesh (it has "
                    f"{', '.join(sorted(names)) or 'none'}) nor a region in x: {err}",
                    key=where) from None
            if midpoints is None:
                nodes = compat.geometry_nodes(mesh)[:local]
                midpoints = mesh.geometry.x[nodes][:, :, :d].mean(axis=1)
            found = np.flatnonzero([value_at(cells, where, d, x, 0.0) > 0 for x in midpoints])
        found = np.asarray(found, dtype=np.int32)
        if mesh.comm.allreduce(found.size, MPI.SUM) == 0:
            raise SceneError(f"{where} = {cells!r} holds no cell of the mesh", key=where)
        out.append(found)
    count = np.zeros(local, dtype=int)
    for found in out:
        count[found] += 1
    owned = count[:cell_map.size_local]
    for what, bad in (("no", owned == 0), ("two", owned > 1)):
        if mesh.comm.allreduce(int(bad.sum()), MPI.SUM):
            raise SceneError(f"body: some cells of the mesh lie in {what} [[body]]; every "
                             "cell must lie in exactly one (body[i].cells)", key="body")
    return out


def _indicator(mesh, cells):
    """The DG0 field 1 on `cells` (local indices), 0 elsewhere."""
    chi = fem.Function(compat.scalar_space(mesh, "DG", 0))
    dofs = compat.cell_dofs(chi.function_space.dofmap)[cells].ravel()
    chi.x.array[dofs] = 1.0
    return chi


def _tensor_mask(space, cells):
    """1.0 on the dofs (all components) of `cells` in a blocked DG space, 0 elsewhere."""
    bs = space.dofmap.index_map_bs
    mask = np.zeros_like(fem.Function(space).x.array)
    nodes = compat.cell_dofs(space.dofmap)[cells].ravel()
    mask[(nodes[:, None] * bs + np.arange(bs)).ravel()] = 1.0
    return mask


def body_stress(scene: dict, geometry: Geometry, u, context=None, updates=None, kin=None):
    """The stress of several bodies, each with its own A and memory kernel:
    sigma = sum_b chi_b sigma_b(u), chi_b the DG0 indicator of body b's cells and sigma_b
    eq (19) with the body's [material] and [memory] (_stress).

    Parameters
    ----------
    scene : dict
        The resolved scene with its [[body]] tables.
    geometry : contactvisco.fem.geometry.Geometry
        The mesh and its cell tags.
    u : dolfinx.fem.Function
        The displacement.
    context, updates
        The expressions' x and t, and the callables run at each new time.
    kin : Cartesian or Axisymmetric, optional
        The kinematics (fem.kinematics; the scene's when None).

    Returns
    -------
    tuple
        sigma (UFL), the Constants by name (``<body>.<name>``), and a BodyMemory (None if no
        body has memory).
    """
    if scene.get("viscoelastic") is not None:
        raise SceneError("viscoelastic: a scene with [[body]] tables gives each body its "
                         "material and memory in its own tables; leave out [viscoelastic]",
                         key="viscoelastic")
    mesh = geometry.mesh
    sigma, constants, parts, masks, owners = 0, {}, [], [], []
    for body, cells in zip(scene["body"], body_cells(scene, geometry)):
        own = dict(scene, material=body["material"], memory=body["memory"])
        sigma_b, constants_b, memory_b = _stress(own, mesh, u, context, updates, kin)
        sigma = sigma + _indicator(mesh, cells) * sigma_b
        constants.update({f"{body['name']}.{name}": c for name, c in constants_b.items()})
        if memory_b is not None:
            parts.append(memory_b)
            masks.append(_tensor_mask(memory_b.tensor_space, cells))
            owners.append(body)
    if not parts:
        return sigma, constants, None
    space = parts[0].tensor_space
    memory = BodyMemory(parts=parts, masks=masks,
                        history=BodyHistory([part.history for part in parts]),
                        H=fem.Function(space, name="history_stress"), tensor_space=space,
                        bodies=owners)
    return sigma, constants, memory
