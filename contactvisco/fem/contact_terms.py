"""The contact part of the discrete problem (eqs 20-21): the contact nodes of Gamma_C and their
normals, the contact quadrature, the obstacle or the initial gap, the law's terms in F_u and the
multipliers' residuals F_nu and F_tau, the conditions that fix the multipliers off Gamma_C, and
the law's node values read from the forms (corners, prescribed laws)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import ufl
from dolfinx import fem
from mpi4py import MPI
from petsc4py import PETSc

from contactvisco.errors import SceneError
from contactvisco.fem import compat
from contactvisco.fem import obstacle as obstacle_module
from contactvisco.fem import prescribed
from contactvisco.fem.bound_zone import BoundZone
from contactvisco.fem.contact_unknowns import contact_unknowns
from contactvisco.fem.fields import assembled_values, interpolator, length_scale, nodal_rule
from contactvisco.model import contact_law as law
from contactvisco.scene.expressions import Context


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
    bound_zone: object | None = None           # fem.bound_zone.BoundZone (lambda_nu only)


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


def build_contact(scene, geometry, u, v, ds, context, updates, kin):
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

    constants, lambda_nu, lambda_tau, u_previous = contact_unknowns(contact, u, Q, W,
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
                       if corners or laws else None, obstacle=obstacle,
                       bound_zone=BoundZone(Q, dsc) if lambda_nu is not None else None)
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
                                  length_scale(geometry.mesh))
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
    update = interpolator(function, value, Q)
    update()
    if context.depends_on_time(expression):
        updates.append(update)
    return value, function


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


def multiplier_conditions(nodes, lambda_nu, lambda_tau, fixed, d):
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
