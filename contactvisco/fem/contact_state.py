"""The contact table: the values at the contact nodes of the whole mesh (u_nu, u_tau, the
reactions, the friction bound), the contact status of each node (separated, in normal
compliance, at the bound) and its stick/slip state, gathered on every rank and sorted by
position, so that it does not depend on the rank count."""
from __future__ import annotations

import math

import numpy as np
from dolfinx import fem

from contactvisco.fem.contact_terms import corner_values
from contactvisco.model import contact_law as law

STATUSES = ("separated", "compliance", "bound")


def contact_table(problem, comm) -> dict[str, np.ndarray] | None:
    """Values at the contact nodes of the whole mesh, on every rank, sorted by position.

    Keys: x (n, d), normal (n, d), u_nu, gap (h), penetration (s = u_nu - h),
    u_tau (2D: along t = (-nu_y, nu_x); 3D: |u_tau|),
    lambda_nu, p_nu (compliance traction p_nu(min(s, g))), reaction_nu (-sigma_nu),
    contact_pressure (the same -sigma_nu, positive in compression, under the name a reader
    looks for),
    reaction_tau (sigma_tau, same convention as u_tau), radius (the friction bound: mu p_nu,
    or mu (p_nu + R_nu) with contact.friction_law = "coulomb"), slip_vector (u_tau, or the
    step's u_tau - u_tau(t_{n-1}) with contact.slip = "increment"), status (0, 1, 2 as in
    STATUSES), friction (the stick/slip state: 0, 1, 2 as in STICK_SLIP_STATES). With an
    obstacle, normal and gap are the obstacle's and u_nu, u_tau, slip_vector are those of
    u - d, the displacement relative to the obstacle. With another body of the mesh as the
    obstacle (fem.body_contact) also facet (the master facet of the node's closest point),
    force (the node's contact force) and master: a table of the master boundary's nodes, x
    and force (what they receive, Pi^T c), sorted by position.
    """
    if problem.contact is None:
        return None
    nodes = problem.contact.nodes
    contact = problem.scene["contact"]
    d = problem.geometry.mesh.geometry.dim
    own = nodes.nodes[nodes.owned]
    normals = nodes.normals[nodes.owned]
    fields = _node_fields(problem, own)
    law_values = _law_at_nodes(problem, own, normals, fields)
    u_tau, reaction_tau = _tangential_values(problem, law_values["u_tau_vector"],
                                             fields["sigma_tau_vector"], normals)
    # The rigid part's reaction is the one the multiplier carries, R_nu = -lambda_nu (the
    # law's R_nu(lambda_nu, u_nu) at the converged state).
    lam_nu, p_nu = fields["lambda_nu"], law_values["p_nu"]
    radius = (law_values["radius"] if "radius" in law_values else
              law.friction_radius(friction_coefficient(problem, own), p_nu, -lam_nu,
                                  contact["friction_law"]))
    local = dict(x=problem.contact.Q_coordinates[own][:, :d], normal=normals,
                 u_nu=law_values["u_nu"], gap=fields["gap"],
                 penetration=law_values["penetration"], u_tau=u_tau, lambda_nu=lam_nu,
                 p_nu=p_nu, reaction_nu=p_nu - lam_nu, reaction_tau=reaction_tau,
                 radius=radius, u_tau_vector=law_values["u_tau_vector"],
                 sigma_tau_vector=fields["sigma_tau_vector"],
                 slip_vector=law_values["slip_vector"], weight=nodes.weights[nodes.owned])
    body = getattr(problem.contact.obstacle, "interface_values", None)
    if body is not None:                  # another body of the mesh as the obstacle
        local.update(body(own))
    table = _gather_sorted(local, comm, problem.length_scale)
    if body is not None:
        table["master"] = _gather_sorted(problem.contact.obstacle.master_values(), comm,
                                         problem.length_scale)
    # The name a reader looks for: -sigma_nu, positive in compression.
    table["contact_pressure"] = table["reaction_nu"].copy()
    table["status"] = classify(table["penetration"], contact["g"], problem.length_scale)
    table["friction"] = stick_slip(table)             # the stick/slip state
    table["status_name"] = state_names(table["status"], STATUSES)
    table["friction_name"] = state_names(table["friction"], STICK_SLIP_STATES)
    return table


def friction_coefficient(problem, own: np.ndarray):
    """The friction coefficient at the owned contact nodes `own`: the number contact.mu, or
    the values of its P1 field when it is an expression in x and t (0 without friction).

    Parameters
    ----------
    problem : contactvisco.fem.problem.Problem
        The problem.
    own : numpy.ndarray
        Local P1 node indices.

    Returns
    -------
    float or numpy.ndarray
        mu, or mu at each node of `own`.
    """
    mu = problem.constants.get("mu")
    if mu is None:
        value = problem.scene["contact"]["mu"]
        return 0.0 if isinstance(value, str) else value
    if isinstance(mu, fem.Function):
        return mu.x.array[own]
    return float(mu.value)


def state_names(codes: np.ndarray, names: tuple[str, ...]) -> np.ndarray:
    """The names of integer state codes (names[code]) as a numpy string array."""
    return np.asarray(names)[np.asarray(codes, dtype=int)]


def _node_fields(problem, own: np.ndarray) -> dict[str, np.ndarray | None]:
    """The fields at the owned contact nodes `own`: u (n, d), gap h, lambda_nu (zero without
    a bound), sigma_tau_vector = lambda_tau (zero without friction) and u_previous (None
    unless the slip is an increment); with an obstacle, u and u_previous relative to it
    (u - d, u_previous - d(t_{n-1})). P1: node i of the multiplier spaces is dof block i of
    V."""
    d = problem.geometry.mesh.geometry.dim
    part = problem.contact
    u = _nodal_displacement(problem)[own]
    u_previous = (part.u_previous.x.array.reshape(-1, d)[own]
                  if part.u_previous is not None else None)
    if part.obstacle is not None:           # the law acts on u relative to the obstacle
        u = u - part.obstacle.D.x.array.reshape(-1, d)[own]
        if u_previous is not None:
            u_previous = u_previous - part.obstacle.D_previous.x.array.reshape(-1, d)[own]
    return dict(
        u=u, gap=part.gap.x.array[own],
        lambda_nu=(part.lambda_nu.x.array[own] if part.lambda_nu is not None
                   else np.zeros(len(own))),
        sigma_tau_vector=(part.lambda_tau.x.array.reshape(-1, d)[own]
                          if part.lambda_tau is not None else np.zeros_like(u)),
        u_previous=u_previous)


def _law_at_nodes(problem, own: np.ndarray, normals: np.ndarray, fields: dict) -> dict:
    """The law of the forms (contactvisco.model.contact_law) evaluated at the nodes: penetration
    s_nu, u_nu, u_tau_vector, p_nu (zero without compliance) and slip_vector. At corners of
    Gamma_C the forms use each facet's normal: the values there are the law's as the forms
    see them (the facets' weighted mean), not at the mean normal. With a prescribed p_nu or
    p_tau (expressions, not numpy functions) p_nu and the friction bound (radius) come from
    the forms at every node."""
    contact = problem.scene["contact"]
    u = fields["u"]
    constants = {key: float(c.value) for key, c in problem.constants.items()
                 if key in ("r", "g", "stiffness") and c is not None}
    if "mu" in problem.constants:
        constants["mu"] = friction_coefficient(problem, own)
    terms = law.law_terms(law.NUMPY, u, normals, fields["gap"], None, None,
                          fields["u_previous"], constants, contact["friction_law"])
    u_nu = law.normal_part(u, normals, law.NUMPY)
    values = dict(penetration=terms["s_nu"], u_nu=u_nu,
                  u_tau_vector=law.tangential_part(u, normals, law.NUMPY),
                  p_nu=terms["p_nu"] if terms["p_nu"] is not None else np.zeros_like(u_nu),
                  slip_vector=terms["slip"])
    if problem.contact.corner_forms is not None:
        # A prescribed p_nu or p_tau (contact_laws) is read from the forms at every node.
        general = contact.get("p_nu") is not None or contact.get("p_tau") is not None
        at = (np.ones(len(own), dtype=bool) if general
              else np.isin(own, problem.contact.nodes.corners))
        corner = corner_values(problem, own[at])
        if "radius" in corner:
            values["radius"] = np.zeros(len(own))
        for key, corner_key in (("penetration", "s_nu"), ("u_nu", "u_nu"),
                                ("slip_vector", "slip"), ("u_tau_vector", "u_tau"),
                                ("p_nu", "p_nu"), ("radius", "radius")):
            if corner_key in corner:
                values[key] = values[key].copy()
                values[key][at] = corner[corner_key]
    return values


def _tangential_values(problem, u_tau_vector: np.ndarray, sigma_tau_vector: np.ndarray,
                       normals: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """u_tau and the tangential reaction as scalars: in 2D their components along the
    tangent t = (-nu_y, nu_x), in 3D the norms |u_tau| and |sigma_tau - (sigma_tau.nu) nu|."""
    nodes = problem.contact.nodes
    if problem.geometry.mesh.geometry.dim == 2:
        tangents = nodes.tangents[nodes.owned]
        return (np.einsum("ij,ij->i", u_tau_vector, tangents),
                np.einsum("ij,ij->i", sigma_tau_vector, tangents))
    return (np.linalg.norm(u_tau_vector, axis=1),
            np.linalg.norm(law.tangential_part(sigma_tau_vector, normals, law.NUMPY), axis=1))


def _gather_sorted(local: dict, comm, length: float) -> dict:
    """Every rank's rows of a node table, on every rank, sorted by position rounded to 1e-9
    of the body's size `length` (coordinates that are zero can come out as +-1e-17
    depending on the partition)."""
    gathered = comm.allgather(local)
    table = {key: np.concatenate([part[key] for part in gathered]) for key in local}
    rounded = np.round(table["x"] / (1e-9 * length))
    order = np.lexsort(rounded.T[::-1])
    return {key: value[order] for key, value in table.items()}


#: The stick/slip state of a contact node (the table's "friction" column).
STICK_SLIP_STATES = ("none", "stick", "slip")


def stick_slip(table) -> np.ndarray:
    """Per node: 0 no friction (zero bound), 1 stick (|sigma_tau| below the bound, so the
    node's slip is zero), 2 slip (|sigma_tau| at the bound mu times the law's pressure),
    with a tolerance of 1e-8 times the largest bound."""
    radius = table["radius"]
    tol = 1e-8 * max(float(np.max(radius, initial=0.0)), 1e-300)
    force = np.linalg.norm(table["sigma_tau_vector"], axis=1)
    return np.where(radius <= tol, 0, np.where(force < radius - tol, 1, 2))


def classify(s: np.ndarray, g: float, length: float) -> np.ndarray:
    """From the penetration s = u_nu - h: 0 separated (s <= 0: no force), 1 compliance
    (0 < s < g), 2 bound (s = g), with a tolerance of 1e-9 times g (or the body's size when
    g is 0 or infinite)."""
    tol = 1e-9 * (g if 0 < g < math.inf else length)
    status = np.where(s > tol, 1, 0)
    if math.isfinite(g):
        status = np.where(s >= g - tol, 2, status)
    return status


def status_counts(table) -> dict[str, int]:
    if table is None:
        return {s: 0 for s in STATUSES}
    return {name: int(np.sum(table["status"] == i)) for i, name in enumerate(STATUSES)}


def status_at_nodes(problem, table) -> tuple[np.ndarray, np.ndarray]:
    """(the owned contact nodes of this rank, their status codes from the gathered `table`):
    the table's rows matched to the nodes by position, rounded as _gather_sorted rounds."""
    own, rows = rows_at_nodes(problem, table)
    return own, table["status"][rows]


def rows_at_nodes(problem, table) -> tuple[np.ndarray, np.ndarray]:
    """The owned contact nodes of this rank and the rows of the gathered `table` that hold
    them, matched by position (rounded as _gather_sorted rounds).

    Parameters
    ----------
    problem : contactvisco.fem.problem.Problem
        The problem with contact.
    table : dict
        A contact table (contact_table), the same on every rank.

    Returns
    -------
    own : numpy.ndarray
        Local P1 node indices of the owned contact nodes.
    rows : numpy.ndarray
        For each of them, its row of `table`.
    """
    nodes = problem.contact.nodes
    d = problem.geometry.mesh.geometry.dim
    own = nodes.nodes[nodes.owned]
    scale = 1e-9 * problem.length_scale
    row = {tuple(key): i for i, key in enumerate(np.round(table["x"] / scale).astype(np.int64))}
    keys = np.round(problem.contact.Q_coordinates[own][:, :d] / scale).astype(np.int64)
    return own, np.array([row[tuple(key)] for key in keys], dtype=np.int64)


def _nodal_displacement(problem) -> np.ndarray:
    d = problem.geometry.mesh.geometry.dim
    u_p1 = problem.contact.u_p1
    if u_p1 is None:
        return problem.u.x.array.reshape(-1, d)
    u_p1.interpolate(problem.u)
    return u_p1.x.array.reshape(-1, d)
