"""Verification of the relaxation-modulus form ([viscoelastic]) on a homogeneous block.

Every boundary of a box follows u(x, t) = f(t) E x for a fixed strain tensor E, so the P1
solution is u itself and the strain eps = f(t) E is homogeneous: the stress the solver
computes is then the generalized Maxwell stress of that strain history, in closed form
(contactvisco.model.viscoelastic.response, Boltzmann's superposition):

    3D             sigma = 2 (G * f) dev3 E + 3 (K * f) vol3 E
    plane strain   the in-plane part of the 3D stress of the strain E with eps_33 = 0
    plane stress   sigma = (g * f) A0 E  (proportional G, K; A0 the instantaneous operator)

with (phi * f)(t) = int_0-^t phi(t - s) df(s). Space is exact, so the difference is the error
of the time rule of eq (19) alone.
"""
from __future__ import annotations

import numpy as np
from mpi4py import MPI

from contactvisco.fem import geometry as geometry_module
from contactvisco.fem.problem import build
from contactvisco.model import time_grid
from contactvisco.model import viscoelastic as ve
from contactvisco.model.material import lame_constants
from contactvisco.scene import loader
from contactvisco.solver.newton import create
from contactvisco.solver import step_control

#: The strain histories f(t) as scene expressions in t (hold: a ramp to t = hold, then held;
#: smooth: the smooth ramp-and-hold 1 - exp(-t/hold), its rate 1/hold at 0, held at 1).
HISTORIES = {"step": "1.0", "ramp": "{rate} * t", "sine": "sin({omega} * t)",
             "hold": "{rate} * min(t, {hold})", "smooth": "1.0 - exp(-t / {hold})"}


def block_scene(viscoelastic: dict, model: str, strain, history: str, T: float, steps: int,
                rule: str = "trapezoid", rate: float = 1.0, omega: float = 1.0,
                cells: int = 1, hold: float = 1.0, grid: dict | None = None) -> dict:
    """The raw scene of the homogeneous block (module description).

    Parameters
    ----------
    viscoelastic : dict
        The [viscoelastic] table.
    model : str
        ``plane_strain``, ``plane_stress`` or ``3d``.
    strain : array_like
        The d x d strain tensor E.
    history : str
        ``step``, ``ramp``, ``sine``, ``hold`` or ``smooth`` (HISTORIES).
    T : float
        The end time.
    steps : int
        The number of time steps.
    rule : str, optional
        ``time.rule``.
    rate, omega : float, optional
        The ramp's rate and the sine's angular frequency.
    cells : int, optional
        Boxes per side.
    hold : float, optional
        The end of the ramp of the ``hold`` history; the time scale of ``smooth``.
    grid : dict, optional
        More [time] keys: a grid other than `steps` uniform steps (time.grid, first, ...).

    Returns
    -------
    dict
        The raw scene, every boundary on u = f(t) E x.
    """
    E = np.asarray(strain, float)
    d = E.shape[0]
    f = HISTORIES[history].format(rate=repr(rate), omega=repr(omega), hold=repr(hold))
    value = [f"({f}) * (" + " + ".join(f"{float(E[i, j])!r} * x[{j}]" for j in range(d)) + ")"
             for i in range(d)]
    boundaries = ("left", "right", "bottom", "top") + (("front", "back") if d == 3 else ())
    return {"name": "relaxation_block",
            "geometry": {"lower": [0.0] * d, "upper": [1.0] * d, "cells": [cells] * d},
            "material": {"model": model},
            "viscoelastic": viscoelastic,
            "dirichlet": [{"boundary": b, "value": value} for b in boundaries],
            "time": {"T": T, "steps": steps, "rule": rule, **(grid or {})},
            "output": {"xdmf": False, "figures": False, "checkpoint": False}}


def block_stress(raw: dict, comm=MPI.COMM_WORLD, per_point: bool = False):
    """Run a raw scene step by step and return the mean stress of the body at each step.

    Parameters
    ----------
    raw : dict
        A raw scene (e.g. :func:`block_scene`).
    comm : mpi4py.MPI.Comm, optional
        The communicator (collective).
    per_point : bool, optional
        True: the stress at each point of the stress space this rank owns, not the mean.

    Returns
    -------
    tuple of numpy.ndarray
        The times t_n of the scene's grid and the stresses, shape (N + 1, d, d) (d = 3 for an
        axisymmetric body: the hoop component included): the mean
        over the cells of the stress's values (the stress of a homogeneous state); with per_point, shape
        (N + 1, points, d, d), then the points' coordinates (points, 3).
    """
    scene = loader.resolve(raw)
    geometry = geometry_module.build(scene, comm)
    problem = build(scene, geometry)
    snes = create(problem, comm)
    d = problem.kinematics.tensor_dim          # the stress's: 3 x 3 in axisymmetry
    from dolfinx import fem
    sigma = fem.Function(problem.tensor_space)
    owned = problem.tensor_space.dofmap.index_map.size_local
    bs = problem.tensor_space.dofmap.index_map_bs
    times, out = [], []
    control = None
    grid = time_grid.times(scene["time"])
    if time_grid.adaptive(scene["time"]):       # the steps of the controller, as it goes
        control = step_control.Controller(scene["time"], problem, comm)
        grid = control.times()
    try:
        for t in grid:
            before = problem.time.committed
            problem.time.stage(float(t))
            snes.solve()
            problem.time.commit()
            if control is not None:
                control.accepted(float(t), None if before is None else float(t) - before)
            sigma.interpolate(problem.sigma_expression)
            values = sigma.x.array[:owned * bs].reshape(-1, d, d)
            times.append(float(t))
            if per_point:
                out.append(values.copy())
                continue
            total = comm.allreduce(values.sum(axis=0), MPI.SUM)
            count = comm.allreduce(values.shape[0], MPI.SUM)
            out.append(total / count)
    finally:
        snes.destroy()
        snes = None
    problem.release_garbage()
    if per_point:
        points = problem.tensor_space.tabulate_dof_coordinates()[:owned]
        return np.array(times), np.array(out), points
    return np.array(times), np.array(out)


def maxwell_stress(model: str, shear: ve.PronySeries, bulk: ve.PronySeries, strain,
                   history: str, t, rate: float = 1.0, omega: float = 1.0,
                   hold: float = 1.0) -> np.ndarray:
    """The closed-form stress of the homogeneous block (module description).

    Parameters
    ----------
    model : str
        ``plane_strain``, ``plane_stress`` or ``3d``.
    shear, bulk : PronySeries
        G(t) and K(t) (proportional in plane stress).
    strain : array_like
        The d x d strain tensor E.
    history : str
        ``step``, ``ramp``, ``sine``, ``hold`` or ``smooth``.
    t : array_like
        Times.
    rate, omega, hold : float, optional
        As in :func:`block_scene`.

    Returns
    -------
    numpy.ndarray
        sigma(t), shape (len(t), d, d).
    """
    E = np.asarray(strain, float)
    d = E.shape[0]
    t = np.atleast_1d(np.asarray(t, float))
    Gf, Kf = (_response(phi, history, t, rate, omega, hold) for phi in (shear, bulk))
    if model == "plane_stress":
        E0, nu0 = ve.young_poisson(shear.instantaneous, bulk.instantaneous)
        lam, mu = lame_constants(model, E0, nu0)
        A0E = lam * np.trace(E) * np.eye(d) + 2.0 * mu * E
        g = Gf / shear.instantaneous
        return g[:, None, None] * A0E
    E3 = np.zeros((3, 3))
    E3[:d, :d] = E
    dev = E3 - np.trace(E3) / 3.0 * np.eye(3)
    sigma = (2.0 * Gf[:, None, None] * dev
             + Kf[:, None, None] * np.trace(E3) * np.eye(3))
    return sigma[:, :d, :d]


def _response(phi, history: str, t, rate: float, omega: float, hold: float):
    """(phi * f)(t). The ramp-and-hold by superposition: a ramp from 0 minus the same ramp
    from t = hold, r(t) - r(t - hold) with r(s) = 0 for s <= 0. The smooth one,
    f = 1 - exp(-t/h) (h = hold), term by term:

        phi_inf f(t) + sum_i phi_i (exp(-t/h) - exp(-t/tau_i)) / (h/tau_i - 1),

    and phi_i (t/h) exp(-t/h) for tau_i = h (the limit)."""
    if history == "smooth":
        t = np.asarray(t, float)
        out = phi.long_term * -np.expm1(-t / hold)
        for m, tau in zip(phi.moduli, phi.taus):
            c = hold / tau - 1.0
            if abs(c) < 1e-6:            # the difference quotient's limit
                out = out + m * t / hold * np.exp(-t / hold)
            else:
                out = out + m * (np.exp(-t / hold) - np.exp(-t / tau)) / c
        return out
    if history != "hold":
        return ve.response(phi, history, t, rate, omega)
    ramp = ve.response(phi, "ramp", t, rate)
    return ramp - ve.response(phi, "ramp", np.maximum(t - hold, 0.0), rate)


def creep_compliance(scene: dict, t, function: str = "young") -> np.ndarray:
    """The creep compliance J(t) of a relaxation function of a scene's [viscoelastic] table as
    entered: the strain of a unit stress applied at t = 0 and held, the solution of
    int_0-^t phi(t - s) dJ(s) = 1 (Boltzmann's superposition), in closed form from the
    retardation rates of the Prony series (``studies.relaxation.prony_compliance``).

    Parameters
    ----------
    scene : dict
        A resolved scene with a [viscoelastic] table.
    t : array_like
        Times >= 0.
    function : str, optional
        ``"young"`` (E(t): the strain of a uniaxial stress), ``"shear"`` or ``"bulk"``.

    Returns
    -------
    numpy.ndarray
        J(t), shaped like t; J(0) = 1/phi(0), J(inf) = 1/phi_inf.

    Raises
    ------
    SceneError
        When the scene has no such relaxation function.
    """
    from contactvisco.errors import SceneError
    table = scene.get("viscoelastic")
    functions = getattr(table, "functions", None) or {}
    if function not in functions:
        raise SceneError(f"the creep compliance of {function!r} needs a scene whose "
                         f"[viscoelastic] table gives it (it gives {sorted(functions) or 'none'})",
                         key="viscoelastic")
    return prony_compliance(functions[function], t)


def prony_compliance(phi: ve.PronySeries, t) -> np.ndarray:
    """The creep compliance J(t) of a relaxation function phi (Prony series, phi_inf > 0): the
    strain of a unit stress applied at t = 0 and held, (phi * dJ)(t) = 1.

    In Laplace variables s phi~(s) s J~(s) = 1 with

        f(s) = s phi~(s) = phi_inf + sum_i phi_i s / (s + r_i),   r_i = 1/tau_i,

    so J~(s) = 1 / (s f(s)). f increases between its poles -r_i and has one zero lambda_k in
    each interval between neighbouring poles and in (-r_min, 0), all real and negative (the
    retardation rates), found by bisection in those brackets; the residues give

        J(t) = 1/phi_inf + sum_k exp(lambda_k t) / (lambda_k f'(lambda_k)),
        f'(s) = sum_i phi_i r_i / (s + r_i)^2,

    with J(0) = 1/phi(0) and J(inf) = 1/phi_inf.

    Parameters
    ----------
    phi : PronySeries
        The relaxation function (its moduli > 0, distinct relaxation times).
    t : array_like
        Times >= 0.

    Returns
    -------
    numpy.ndarray
        J(t), shaped like t.
    """
    t = np.asarray(t, float)
    moduli = np.asarray(phi.moduli, float)
    r = 1.0 / np.asarray(phi.taus, float)

    def f(s):
        return phi.long_term + np.sum(moduli * s / (s + r))

    out = np.full_like(t, 1.0 / phi.long_term)
    edges = np.concatenate([-np.sort(r)[::-1], [0.0]])     # -r_max < ... < -r_min < 0
    for lo, hi in zip(edges, edges[1:]):
        a, b = lo, hi                    # f -> -inf just above a pole, f(hi) > 0
        for _ in range(200):             # bisection to round-off on the bracket
            middle = 0.5 * (a + b)
            if middle in (a, b):
                break
            a, b = (middle, b) if f(middle) < 0 else (a, middle)
        root = 0.5 * (a + b)
        out = out + np.exp(root * t) / (root * np.sum(moduli * r / (root + r) ** 2))
    return out
