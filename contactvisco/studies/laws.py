"""Verification of the prescribed contact laws and of a nonlinear elasticity operator.

compliant_column(): a column in uniaxial strain (rollers on its sides) on a compliant
foundation p_nu(s) = c s^m with a bound g, its top moved down by w(t). The state is
one-dimensional and P1 holds it exactly: s is the same at every contact node, the stress is
-q with q = p_nu(s) + R_nu, and the column shortens by q H / M, M = lambda + 2 mu. The top
displacement is prescribed as

    w(t) = sigma(t) + c sigma(t)^m H / M,      sigma(t) = s_1 t,

so that before the bound the penetration is s(t) = s_1 t and the force q(t) = c (s_1 t)^m in
closed form; the bound is reached at t* = g / s_1 under the load q* = c g^m, and after it
s = g and q = (w - g) M / H, the bound's reaction R_nu = q - c g^m.

quadratic_orders(): the ratios log(r_{k+1}/r_0) / log(r_k/r_0) of a Newton residual history,
2 for a quadratic method once it is near the solution.
"""
from __future__ import annotations

import math

import numpy as np
from mpi4py import MPI

from contactvisco.model.material import lame_constants
from contactvisco.scene import loader as scene_module
from contactvisco.solver.time_loop import simulate

#: The column of compliant_column: height, Young's modulus, Poisson's ratio.
COLUMN = {"H": 1.0, "E": 100.0, "nu": 0.3}


def compliant_column_scene(c: float = 2000.0, m: float = 1.5, g: float = 0.01,
                           s_1: float = 0.0125, steps: int = 10, cells=(2, 4),
                           p_tau: str | None = None) -> dict:
    """The scene of the compliant column (module description), unresolved.

    Parameters
    ----------
    c, m : float, optional
        The foundation p_nu(s) = c s^m.
    g : float, optional
        The bound.
    s_1 : float, optional
        The penetration rate: s(t) = s_1 t before the bound (t* = g / s_1).
    steps : int, optional
        Time steps on [0, 1].
    cells : tuple of int, optional
        Cells across and along the column.
    p_tau : str, optional
        A friction bound contact.p_tau (no tangential load: sigma_tau stays 0).

    Returns
    -------
    dict
        The scene as a raw TOML-like dict.
    """
    H, E, nu = COLUMN["H"], COLUMN["E"], COLUMN["nu"]
    lam, mu = lame_constants("plane_strain", E, nu)
    M = lam + 2 * mu
    sigma = f"min({s_1} * t, {g})"
    # Before the bound w = sigma + c sigma^m H/M; after it the same formula with sigma = g
    # plus the shortening under the bound's reaction, (s_1 t - g) (the overshoot) as extra w.
    top = (f"-({sigma} + {c} * ({sigma})**{m} * {H / M!r} + max({s_1} * t - {g}, 0))")
    contact = {"boundary": "bottom", "g": g, "p_nu": f"{c} * s**{m}", "augmentation": c * g}
    if p_tau is not None:
        contact["p_tau"] = p_tau
    return {"name": "compliant-column",
            "geometry": {"lower": [0.0, 0.0], "upper": [0.2, H], "cells": list(cells)},
            "material": {"model": "plane_strain", "E": E, "nu": nu},
            "dirichlet": [{"boundary": "left", "components": [0], "value": 0.0},
                          {"boundary": "right", "components": [0], "value": 0.0},
                          {"boundary": "top", "components": [1], "value": top}],
            "contact": contact,
            "time": {"T": 1.0, "steps": steps},
            "output": {"probes": []}}


def compliant_column_exact(t, c: float = 2000.0, m: float = 1.5, g: float = 0.01,
                           s_1: float = 0.0125) -> dict:
    """The closed form of the compliant column at times t (module description).

    Parameters
    ----------
    t : array_like
        Times.
    c, m, g, s_1 : float, optional
        As in compliant_column_scene.

    Returns
    -------
    dict
        Arrays ``s`` (the penetration), ``p_nu`` (c min(s, g)^m), ``R_nu`` (the bound's
        reaction) and ``q`` (the total normal force per area, p_nu + R_nu), and the floats
        ``t_bound`` = g / s_1 and ``q_bound`` = c g^m.
    """
    H, E, nu = COLUMN["H"], COLUMN["E"], COLUMN["nu"]
    lam, mu = lame_constants("plane_strain", E, nu)
    M = lam + 2 * mu
    t = np.asarray(t, dtype=float)
    s = np.minimum(s_1 * t, g)
    p = c * s**m
    # After the bound: w = g + c g^m H/M + (s_1 t - g) = g + q H/M.
    over = np.maximum(s_1 * t - g, 0.0)
    R = over * M / H
    return {"s": s, "p_nu": p, "R_nu": R, "q": p + R, "t_bound": g / s_1,
            "q_bound": c * g**m}


def compliant_column(comm=MPI.COMM_WORLD, linear_system: str = "coupled",
                     predictor: str = "extrapolate", **parameters):
    """Run the compliant column and compare with its closed form at every step.

    Parameters
    ----------
    comm : mpi4py.MPI.Comm, optional
        The communicator (collective).
    linear_system : str, optional
        ``solver.linear_system``: ``"coupled"`` or ``"condensed"``.
    predictor : str, optional
        ``solver.predictor``: ``"none"`` starts every step from the last accepted state (the
        extrapolated start lands on the column's solution, linear in t before the bound).
    **parameters
        Passed to compliant_column_scene (c, m, g, s_1, steps, cells, p_tau).

    Returns
    -------
    dict
        ``t``, the computed ``s``, ``q`` (p_nu + R_nu, the mean over the contact nodes),
        ``R_nu``, the closed form ``exact`` (compliant_column_exact), the largest errors
        ``error_s`` and ``error_q`` (relative to g and to the largest q), the Newton counts
        ``newton`` and residual histories ``residuals``, the tables.
    """
    raw = compliant_column_scene(**parameters)
    scene = scene_module.resolve(raw)
    scene["solver"]["linear_system"] = linear_system
    scene["solver"]["predictor"] = predictor
    result = simulate(scene, comm=comm, progress=False, keep_tables=True)
    t = np.array([s["t"] for s in result.steps])
    tables = result.tables
    s = np.array([np.mean(tab["penetration"]) for tab in tables])
    spread = max(float(np.ptp(tab["penetration"])) for tab in tables)
    q = np.array([np.mean(tab["reaction_nu"]) for tab in tables])
    R = np.array([np.mean(-tab["lambda_nu"]) for tab in tables])
    keys = ("c", "m", "g", "s_1")
    exact = compliant_column_exact(t, **{k: v for k, v in parameters.items() if k in keys})
    g = raw["contact"]["g"]
    return {"t": t, "s": s, "q": q, "R_nu": R, "exact": exact, "spread": spread,
            "error_s": float(np.max(np.abs(s - exact["s"]))) / g,
            "error_q": float(np.max(np.abs(q - exact["q"]))) / float(np.max(exact["q"])),
            "newton": [st["newton_iterations"] for st in result.steps],
            "residuals": [st["residual_history"] for st in result.steps], "tables": tables}


def quadratic_orders(residuals, floor: float = 1e-11) -> list[float]:
    """The convergence orders of a Newton residual history.

    Parameters
    ----------
    residuals : list of float
        |F| at each iterate, r_0 first.
    floor : float, optional
        Pairs whose newer residual is below floor * r_0 are left out (round-off).

    Returns
    -------
    list of float
        log(r_{k+1}/r_0) / log(r_k/r_0) for the pairs with r_k < r_0 (2 for quadratic
        convergence near the solution, 1 for linear).
    """
    r0 = residuals[0]
    out = []
    for a, b in zip(residuals[1:], residuals[2:]):
        if a < r0 and b > floor * r0:
            out.append(math.log(b / r0) / math.log(a / r0))
    return out
