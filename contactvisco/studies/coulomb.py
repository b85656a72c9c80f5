"""Closed forms of Coulomb friction (contact.friction_law = "coulomb"), shared by the tests, the
benchmark and the demo.

sliding_block(): a block (plane strain, nu = 0) pressed onto a rigid foundation (g = 0) by a
pressure N on its top and sheared by tau. Tractions (0, -+tau) on its sides make the stress
homogeneous, sigma_yy = -N, sigma_xy = tau, sigma_xx = 0, so every contact node carries the
pressure N and the friction force tau:
    stick (tangential load Q = tau < mu N, applied as a traction on the top):
        u = (tau / G y, -N / E y), the elastic solution with zero slip (G = E / 2);
    slip (the top moved by U > mu N H / G, tau = mu N on the sides):
        u = (U - mu N (H - y) / G, -N / E y), friction force mu N at every node.
P1 holds both fields exactly, so the errors are round-off. In 3D the same holds with the pull
along any tangential direction e (u_tau = u_x e, friction on a disc).

cattaneo_mindlin(): a cylinder (radius R, plane strain) pressed onto a rigid plane and then
pulled tangentially through its clamped top (u = (delta t, -w)). With P and Q the normal and
tangential contact resultants, Hertz's half-width a = sqrt(4 P R / (pi E*)) and
p0 = 2 P / (pi a), the Cattaneo-Mindlin solution for Q < mu P has a central stick zone of
half-width c = a sqrt(1 - Q / (mu P)) and the tangential traction
    q(x) = mu p0 sqrt(1 - x^2 / a^2) - [|x| < c] mu p0 (c / a) sqrt(1 - x^2 / c^2).
It assumes the normal and tangential problems do not couple (Dundurs' beta = 0). For an
elastic body on a rigid plane beta = (1 - 2 nu) / (2 (1 - nu)), zero only at nu = 1/2: the
comparison runs at nu close to 1/2 (0.49: beta = 0.0098) and reports the effect of nu = 0.3
(beta = 0.29), where the normal load alone makes the contact nodes slip inwards. The slip is
measured per step (contact.slip = "increment"), so the pull acts from the pressed state, as in
Cattaneo's and Mindlin's loading path.
"""
from __future__ import annotations

import math

import numpy as np
from mpi4py import MPI

from contactvisco.scene import loader as scene_module
from contactvisco.solver.time_loop import simulate


def block_scene(regime: str, N: float = 10.0, mu: float = 0.4, load: float = 0.5,
                cells=(8, 4), slip: str = "total", direction=None) -> tuple[dict, dict]:
    """The sliding block (module description) and its exact fields.

    Parameters
    ----------
    regime : str
        ``"stick"``: a tangential traction ``load * mu * N`` on the top; ``"slip"``: the top
        moved by ``2 mu N H / G``, twice the stick limit.
    N : float, optional
        The pressure on the top.
    mu : float, optional
        The friction coefficient.
    load : float, optional
        The tangential load as a fraction of ``mu N`` (stick regime).
    cells : tuple of int, optional
        Cells of the box; two entries in 2D, three in 3D.
    slip : str, optional
        ``contact.slip``: ``"total"`` or ``"increment"``.
    direction : sequence of float, optional
        The tangential direction of the load (2D: x; 3D: any ``(e_x, e_y)``, normalized).

    Returns
    -------
    raw : dict
        The scene, unresolved (as a TOML file would give it).
    exact : dict
        The exact fields as numbers: ``{"ux": (a, b), "uy": c, "friction_force": f}``
        meaning ``u_tau = (a + b z) direction``, ``u_normal = c z`` (z the height), and the
        friction force per node.
    """
    E, H = 100.0, 0.5
    G = E / 2
    d = len(cells)
    e = np.array(direction if direction is not None else [1.0] + [0.0] * (d - 2), float)
    e /= np.linalg.norm(e)
    tau = load * mu * N if regime == "stick" else mu * N
    # sigma_tau,z = tau e: the tractions sigma n on the sides keep the stress homogeneous.
    sides = [("left", "right"), ("front", "back")][:d - 1]
    tractions = []
    for k, (low, high) in enumerate(sides):
        value = [0.0] * d
        value[-1] = -tau * e[k]
        tractions += [{"boundary": low, "value": list(value)},
                      {"boundary": high, "value": [0.0] * (d - 1) + [tau * e[k]]}]
    if regime == "stick":
        top = {"boundary": "top", "value": [float(tau * c) for c in e] + [-N]}
        dirichlet = []
        exact = {"ux": (0.0, tau / G), "uy": -N / E, "friction_force": tau}
    else:
        U = 2 * tau * H / G
        top = {"boundary": "top", "value": [0.0] * (d - 1) + [-N]}
        dirichlet = [{"boundary": "top", "components": list(range(d - 1)),
                      "value": [float(U * c) for c in e]}]
        exact = {"ux": (U - tau * H / G, tau / G), "uy": -N / E, "friction_force": tau}
    upper = [1.0] * (d - 1) + [H]
    raw = {"name": f"block-{regime}",
           "geometry": {"lower": [0.0] * d, "upper": upper, "cells": list(cells)},
           "material": {"model": "plane_strain" if d == 2 else "3d", "E": E, "nu": 0.0},
           "dirichlet": dirichlet,
           "traction": [top] + tractions,
           "contact": {"boundary": "bottom", "g": 0.0, "mu": mu, "friction_law": "coulomb",
                       "slip": slip},
           "time": {"T": 1.0, "steps": 1}, "output": {"probes": []}}
    return raw, exact


def cattaneo_scene(h_contact: float, nu: float = 0.49, mu: float = 0.3, w: float = 0.005,
                   delta: float = 0.0013, slip: str = "increment") -> dict:
    """The cylinder of radius 1 (E = 200, plane strain) pressed by its clamped top and then
    pulled: Signorini contact (g = 0, gap of the circle) with Coulomb friction.

    Parameters
    ----------
    h_contact : float
        The mesh size at the contact.
    nu : float, optional
        Poisson's ratio (Cattaneo-Mindlin needs it near 1/2).
    mu : float, optional
        The friction coefficient.
    w : float, optional
        The downward displacement of the top, from t = 0.
    delta : float, optional
        The tangential displacement of the top at t = 1.
    slip : str, optional
        ``contact.slip``.

    Returns
    -------
    dict
        The scene, unresolved.
    """
    return {"name": "cattaneo-mindlin",
            "geometry": {"type": "gmsh", "script": "half_disk",
                         "parameters": {"radius": 1.0, "h_contact": h_contact, "h_far": 0.1,
                                        "refine": 0.11}},
            "material": {"model": "plane_strain", "E": 200.0, "nu": nu},
            "dirichlet": [{"boundary": "top", "components": "all",
                           "value": [f"{delta} * t", -w]}],
            "contact": {"boundary": "contact", "g": 0.0, "gap": "x[1]", "mu": mu,
                        "friction_law": "coulomb", "slip": slip, "augmentation": 200.0},
            "time": {"T": 1.0, "steps": 1},
            "output": {"probes": []}}


def cattaneo_obstacle_scene(h_contact: float, P: float, Q: float, nu: float = 0.49,
                            mu: float = 0.3, frictionless_pressing: bool = False) -> dict:
    """The half cylinder of cattaneo_scene with its top clamped, loaded through a rigid plane
    obstacle under force control ([obstacle] force_components = [0, 1]): the normal force P
    (step 1, t = 1/2), then the tangential force Q with P held (step 2, t = 1), Cattaneo's and
    Mindlin's loading path with the normal and the friction plane of the plane itself.

    Parameters
    ----------
    h_contact : float
        The mesh size at the contact.
    P, Q : float
        The normal and tangential forces the plane exerts on the cylinder (Q along +x).
    nu : float, optional
        Poisson's ratio (Cattaneo-Mindlin needs it near 1/2).
    mu : float, optional
        The friction coefficient.
    frictionless_pressing : bool, optional
        Cattaneo's and Mindlin's protocol as written: ``contact.mu = "conditional(t <= 0.5,
        0.0, mu)"``, no friction while P is applied (the plane's tangential position, which
        then carries no force, is held), friction mu under Q.

    Returns
    -------
    dict
        The scene, unresolved.
    """
    raw = cattaneo_scene(h_contact, nu=nu, mu=mu)
    if frictionless_pressing:
        raw["contact"]["mu"] = f"conditional(t <= 0.5, 0.0, {mu!r})"
    raw["dirichlet"] = [{"boundary": "top", "components": "all"}]
    del raw["contact"]["gap"]
    raw["obstacle"] = {"shape": "plane", "point": [0.0, 0.0], "normal": [0.0, 1.0],
                       "force_components": [0, 1],
                       "force": [f"{Q!r} * max(2 * t - 1, 0)", f"{P!r} * min(2 * t, 1)"]}
    raw["time"] = {"T": 1.0, "steps": 2}
    return raw


def cattaneo_traction(x, a, c, p0, mu):
    """Cattaneo-Mindlin's tangential traction
    ``q(x) = mu p0 sqrt(1 - x^2/a^2) - [|x| < c] mu p0 (c/a) sqrt(1 - x^2/c^2)``.

    Parameters
    ----------
    x : array_like
        Positions along the contact, from its centre.
    a : float
        Hertz's contact half-width.
    c : float
        The stick-zone half-width, ``a sqrt(1 - Q/(mu P))`` (0: full slip).
    p0 : float
        Hertz's peak pressure.
    mu : float
        The friction coefficient.

    Returns
    -------
    numpy.ndarray
        q at `x` (zero outside the contact).
    """
    outer = mu * p0 * np.sqrt(np.maximum(0.0, 1 - (x / a) ** 2))
    inner = mu * p0 * (c / a) * np.sqrt(np.maximum(0.0, 1 - (x / c) ** 2)) if c > 0 else 0.0
    return outer - inner


def _zone_half_width(x, inside):
    """Half-width and centre of the run of nodes `inside` (x sorted), each end taken midway
    between the last node inside and the next one outside."""
    idx = np.flatnonzero(inside)
    if idx.size == 0:
        return 0.0, 0.0
    lo, hi = idx.min(), idx.max()
    left = 0.5 * (x[lo] + x[lo - 1]) if lo > 0 else x[lo]
    right = 0.5 * (x[hi] + x[hi + 1]) if hi + 1 < len(x) else x[hi]
    return 0.5 * (right - left), 0.5 * (right + left)


def cattaneo_mindlin(h_contact: float, comm=MPI.COMM_WORLD, raw: dict | None = None,
                     **kwargs) -> dict:
    """Run the pressed and pulled cylinder and compare it with Cattaneo-Mindlin's partial
    slip and with Hertz's pressure.

    Parameters
    ----------
    h_contact : float
        The mesh size at the contact.
    comm : mpi4py.MPI.Comm, optional
        The communicator of the run (collective).
    raw : dict, optional
        A scene to run instead (e.g. ``cattaneo_obstacle_scene``); the pull's direction is
        then the sign of the friction force's resultant.
    **kwargs
        Passed to ``cattaneo_scene``: ``nu``, ``mu``, ``w``, ``delta``, ``slip``.

    Returns
    -------
    dict
        The resultants ``P``, ``Q`` and ``load_ratio`` ``Q/(mu P)``; Hertz's ``a`` and ``p0``;
        the stick-zone half-width ``c`` (exact) and ``c_h`` (computed), ``c_error`` (relative
        to a) and ``stick_centre`` (relative to a); ``q_error`` (pointwise, relative to
        mu p0), ``q_error_l2``, ``F_error`` (the force transmitted left of x, relative to Q),
        ``p_error`` (relative to p0); ``newton``, ``unknowns``; and the node values ``x``,
        ``q``, ``p``, ``stick`` near the contact for plots.
    """
    scene = scene_module.resolve(raw if raw is not None else cattaneo_scene(h_contact, **kwargs))
    result = simulate(scene, comm=comm, progress=False, keep_tables=True)
    table = result.tables[-1]
    mat, mu = scene["material"], scene["contact"]["mu"]
    if isinstance(mu, str):             # mu(x, t): its value at the end, read off the bound
        pressed = table["reaction_nu"] > 0
        mu = float(np.max(table["radius"][pressed] / table["reaction_nu"][pressed]))
    x = table["x"][:, 0]
    order = np.argsort(x)
    x = x[order]
    w = table["weight"][order]
    p = table["reaction_nu"][order]
    direction = math.copysign(1.0, kwargs.get("delta", 1.0))   # the pull's sign (default > 0)
    if raw is not None:                 # the friction force on the cylinder is along the pull
        direction = -math.copysign(1.0, float(np.sum(table["weight"] * table["reaction_tau"])))
    q = -direction * table["reaction_tau"][order]      # the friction force along the pull
    P, Q = float(np.sum(w * p)), float(np.sum(w * q))
    E_star = mat["E"] / (1 - mat["nu"] ** 2)
    a = math.sqrt(4 * P / (math.pi * E_star))
    p0 = 2 * P / (math.pi * a)
    c = a * math.sqrt(max(0.0, 1 - Q / (mu * P)))
    touching = table["status"][order] == 2
    stick = touching & (table["friction"][order] == 1)
    c_h, centre = _zone_half_width(x, stick)
    a_h, _ = _zone_half_width(x, touching)
    near = np.abs(x) < 1.5 * a
    q_exact = cattaneo_traction(x, a, c, p0, mu)
    p_exact = p0 * np.sqrt(np.maximum(0.0, 1 - (x / a) ** 2))
    return {"h": h_contact, "a_over_h": a / h_contact, "nu": mat["nu"], "P": P, "Q": Q,
            "load_ratio": Q / (mu * P), "a": a, "a_h": a_h, "p0": p0, "c": c, "c_h": c_h,
            "c_error": abs(c_h - c) / a, "stick_centre": centre / a,
            "q_error": float(np.max(np.abs(q - q_exact)[near]) / (mu * p0)),
            "q_error_l2": float(math.sqrt(np.sum((w * (q - q_exact) ** 2)[near])
                                          / np.sum((w * q_exact ** 2)[near]))),
            "p_error": float(np.max(np.abs(p - p_exact)[near]) / p0),
            # The force transmitted left of x, sum_{x_i <= x} w_i q_i, against the same sum of
            # the closed form, relative to Q: nodal tractions carry node-to-node noise (P1 in
            # nearly incompressible plane strain locks), their partial sums much less.
            "F_error": float(np.max(np.abs(np.cumsum(w * (q - q_exact)))) / Q),
            "newton": [s["newton_iterations"] for s in result.steps],
            "x": x[near], "q": q[near], "p": p[near], "stick": stick[near],
            "unknowns": result.problem.count_unknowns()["u"]}
