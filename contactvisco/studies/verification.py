"""Verification against exact solutions: shared by the tests and the benchmarks.

manufactured(): a manufactured solution of the viscoelastic problem without contact. The
solution is u(x, t) = U(x), prescribed on the boundary. With the constant kernel R = alpha I,
sigma(t) = A eps(U) + alpha t eps(U), and the body force f(t) = -div sigma(t) enters in its weak
form: int f . v dx = int sigma(t) : eps(v) dx for every v vanishing where U is prescribed
(integration by parts), so that the kinematics' strain and weight give it in every body model
(in axisymmetry eps has the hoop strain v_r / r and dx carries 2 pi r). In axisymmetry the
meridian square (r, z) in [0, 1]^2 has U prescribed on r = 1, z = 0 and z = 1; the axis r = 0
is no boundary of the body (its weight 2 pi r vanishes there), u_r = 0 holds on it, and U is
smooth about it in 3D (U_r odd in r, U_z even). Errors at T in L2 and in the H1 seminorm of
the body (weighted by 2 pi r in axisymmetry, with the hoop component u_r / r of the gradient).

hertz(): the cylinder scene against the closed form of Hertz contact (plane strain, on a rigid
plane): half-width a = sqrt(4 P R / (pi E*)) and peak pressure p0 = 2 P / (pi a), with
E* = E / (1 - nu^2).

uniaxial(): time discretization against a closed form. A block in uniaxial strain (rollers on
the sides, u_y = 0 at the bottom) under a constant pressure q has e = eps_yy(t) with
M e(t) + int_0^t R(t - s) e(s) ds = -q, M = lambda + 2 mu:
    R = alpha:                  e(t) = -(q/M) exp(-alpha t / M)
    R = alpha exp(-t/tau):      e(t) = -(q/M) (1/(tau beta) + (1 - 1/(tau beta)) exp(-beta t)),
                                beta = 1/tau + alpha/M.
Space is exact for this state, so the error at T is the time error.

Power-law kernels in the same block (the full part, so the equation stays scalar):
    fractional, R = alpha t^(-beta)/Gamma(1 - beta): the memory term is alpha I^(1-beta) e,
        I^g the Riemann-Liouville integral of order g = 1 - beta. In Laplace variables
        (M + alpha z^(-g)) e^(z) = -q/z, so e^(z) = -(q/M) z^(g-1) / (z^g + alpha/M), the
        transform of e(t) = -(q/M) E_g(-(alpha/M) t^g), E_g the Mittag-Leffler function
        (kernels.mittag_leffler). At t = 0, e = -q/M; for t -> inf, e -> 0 like t^(-g).
    power, R = alpha (1 + t/tau)^(-beta): no elementary closed form. The kernel is replaced
        by its sum of exponentials sum_j a_j exp(-s_j t) fitted to 1e-12 on [0, T]; for it
        e^(z) = -q / (z D(z)), D(z) = M + sum_j a_j/(z + s_j), whose poles are z = 0 and one
        root zeta_i of D between consecutive -s_j (and one below -s_N), so
        e(t) = -q (1/D(0) + sum_i exp(zeta_i t) / (zeta_i D'(zeta_i))) (partial fractions).
        Its difference to the exact kernel's creep is of the order of the fit's 1e-12.
"""
from __future__ import annotations

import copy
import math

import numpy as np
import ufl
from dolfinx import fem
from mpi4py import MPI

from contactvisco.fem import geometry as geometry_module
from contactvisco.model import kernels
from contactvisco.scene import loader as scene_module
from contactvisco.fem.kinematics import AXISYMMETRIC
from contactvisco.model.material import elasticity, energy_stress, lame_constants
from contactvisco.fem.problem import build
from contactvisco.fem.stress import material_energy
from contactvisco.solver.time_loop import simulate
from contactvisco.solver.newton import BlockSNES

#: The manufactured displacement, as scene expressions in x.
U_EXACT = ["0.1 * sin(pi * x[0]) * sin(pi * x[1]) + 0.05 * x[0] * x[1]",
           "0.1 * cos(pi * x[0]) * x[1]**2 - 0.02 * x[0]"]
#: The axisymmetric manufactured displacement (u_r, u_z) in (r, z) = (x[0], x[1]): u_r odd in r
#: and u_z even, so that the field is smooth across the axis in 3D.
U_EXACT_AXISYMMETRIC = [
    "0.1 * x[0] * sin(pi * x[1]) * cos(0.5 * pi * x[0]) + 0.05 * x[0] * x[1]",
    "0.1 * cos(pi * x[0]) * x[1]**2 - 0.02 * x[0]**2"]


def manufactured(cells: int, degree: int, rule: str = "trapezoid", steps: int = 4,
                 alpha: float = 50.0, comm=MPI.COMM_WORLD, material=None,
                 model: str = "plane_strain") -> dict:
    """Errors at T = 1 of the manufactured solution (module description).

    Parameters
    ----------
    cells : int
        The unit square is meshed with cells x cells squares (two triangles each).
    degree : int
        The Lagrange degree.
    rule : str, optional
        ``time.rule``: ``"paper"`` or ``"trapezoid"``.
    steps : int, optional
        The number of time steps.
    alpha : float, optional
        The constant memory kernel ``R = alpha I``.
    comm : mpi4py.MPI.Comm, optional
        The communicator (collective).
    material : dict, optional
        Further [material] keys, e.g. a nonlinear A (``{"law": "hencky", ...}``): the body
        force is then -div (dW/deps(U) + alpha t eps(U)), W the scene's energy.
    model : str, optional
        ``material.model``: ``"plane_strain"`` on the unit square, or ``"axisymmetric"`` on
        the meridian square (module description).

    Returns
    -------
    dict
        ``cells``, ``degree``, ``h`` and the errors ``L2`` and ``H1`` (seminorm).
    """
    exact = U_EXACT_AXISYMMETRIC if model == AXISYMMETRIC else U_EXACT
    sides = ("right", "bottom", "top") if model == AXISYMMETRIC else \
        ("left", "right", "bottom", "top")
    raw = {"name": "manufactured",
           "geometry": {"lower": [0.0, 0.0], "upper": [1.0, 1.0], "cells": [cells, cells]},
           "material": {"model": model, "E": 100.0, "nu": 0.3, **(material or {})},
           "memory": {"kernel": "constant" if alpha else "none", "alpha": alpha},
           "dirichlet": [{"boundary": b, "components": "all", "value": exact}
                         for b in sides],
           "time": {"T": 1.0, "steps": steps, "rule": rule},
           "discretization": {"degree": degree, "contact_quadrature": "gauss"}}
    scene = scene_module.resolve(raw)
    geometry = geometry_module.build(scene, comm)
    problem = build(scene, geometry)
    ctx, kin = problem.context, problem.kinematics
    U = ctx.vector(exact, "U_EXACT", 2)
    lmbda, mu = lame_constants(model, 100.0, 0.3)
    if scene["material"]["law"] == "linear":
        elastic = elasticity(kin.strain(U), lmbda, mu)
    else:
        energy = material_energy(scene["material"], problem.constants, ctx)
        elastic = energy_stress(kin.strain(U), energy)[0]
    sigma = elastic + alpha * ctx.t * kin.strain(U)
    v = problem.F[0].arguments()[0]
    F = [problem.F[0] - kin.integral(ufl.inner(sigma, kin.strain(v)), ufl.dx)] + problem.F[1:]
    snes = BlockSNES(F, problem.J, problem.unknowns, problem.bcs, comm)
    T, N = scene["time"]["T"], steps
    try:
        for n in range(N + 1):
            problem.time.stage(n * T / N)
            snes.solve()
            problem.time.commit()
    finally:
        snes.destroy()
        snes = None
    error = problem.u - U
    dx = ufl.dx(metadata={"quadrature_degree": 2 * degree + 4})
    l2 = fem.assemble_scalar(fem.form(kin.integral(ufl.inner(error, error), dx)))
    grad = kin.gradient(error)
    h1 = fem.assemble_scalar(fem.form(kin.integral(ufl.inner(grad, grad), dx)))
    problem.release_garbage()
    return {"cells": cells, "degree": degree, "h": 1.0 / cells,
            "L2": math.sqrt(comm.allreduce(l2, MPI.SUM)),
            "H1": math.sqrt(comm.allreduce(h1, MPI.SUM))}


def orders(errors: list[float], sizes: list[float]) -> list[float]:
    """Observed orders of convergence ``log(e_i / e_{i+1}) / log(h_i / h_{i+1})``.

    Parameters
    ----------
    errors : list of float
        Errors, coarsest first.
    sizes : list of float
        The mesh sizes (or time steps) of the errors.

    Returns
    -------
    list of float
        One order per consecutive pair.
    """
    return [math.log(coarse / fine) / math.log(h_coarse / h_fine)
            for coarse, fine, h_coarse, h_fine in zip(errors, errors[1:], sizes, sizes[1:])]


def hertz(overrides=(), comm=MPI.COMM_WORLD, scene=None) -> dict:
    """The ``hertz`` scene against Hertz's closed form: the contact half-width (midway between
    the last node in contact and the next) and the pressure at the centre.

    Parameters
    ----------
    overrides : sequence of str, optional
        ``"key=value"`` texts applied to the built-in scene, as ``--set``.
    comm : mpi4py.MPI.Comm, optional
        The communicator of the run (collective).
    scene : dict, optional
        A resolved scene to run instead of the built-in one (not modified).

    Returns
    -------
    dict
        ``a``, ``a_exact``, ``a_error`` (relative), ``a_bracket`` (the last node in contact
        and the next), ``p0``, ``p0_exact``, ``p0_error`` (relative), ``unknowns`` and
        ``wall_s`` (of the time steps).
    """
    scene = copy.deepcopy(scene) if scene is not None else \
        scene_module.load("hertz", list(overrides))
    scene["output"]["probes"] = []
    result = simulate(scene, comm=comm, progress=False, keep_tables=True)
    table = result.tables[-1]
    mat = scene["material"]
    radius = scene["geometry"]["parameters"].get("radius", 1.0)
    q = -scene["traction"][0]["value"][1]
    P = 2 * q * radius                             # per unit length, both quarters
    a = math.sqrt(4 * P * radius / (math.pi * mat["E"] / (1 - mat["nu"]**2)))
    p0 = 2 * P / (math.pi * a)
    x = table["x"][:, 0]
    touching = table["status"] == 2
    last = x[touching].max()
    following = x[x > last].min()
    half_width = 0.5 * (last + following)
    peak = table["reaction_nu"][np.argmin(x)]
    return {"a": half_width, "a_exact": a, "a_error": abs(half_width - a) / a,
            "a_bracket": (last, following), "p0": peak, "p0_exact": p0,
            "p0_error": abs(peak - p0) / p0,
            "unknowns": sum(result.problem.count_unknowns().values()),
            "wall_s": sum(s["wall_s"] for s in result.steps)}


UNIAXIAL_KERNELS = {"constant": {"kernel": "constant", "alpha": 100.0},
                    "exponential": {"kernel": "exponential", "alpha": [300.0], "tau": [0.2]}}
POWER_KERNELS = {"power": {"kernel": "power", "alpha": 300.0, "tau": 0.05, "beta": 0.7},
                 "fractional": {"kernel": "fractional", "alpha": 100.0, "beta": 0.5}}


def prony_creep(M: float, weights, rates, q: float, t) -> np.ndarray:
    """The creep ``e(t)`` of ``M e + int_0^t sum_j a_j exp(-s_j (t - s)) e(s) ds = -q``
    (``a_j > 0``), by partial fractions (module description); the roots of D are found by
    bisection, one per bracket.

    Parameters
    ----------
    M : float
        The modulus of the instantaneous response.
    weights : array_like
        The weights ``a_j`` of the exponentials.
    rates : array_like
        Their rates ``s_j``.
    q : float
        The constant pressure.
    t : float or array_like
        Times.

    Returns
    -------
    numpy.ndarray
        e at each time.
    """
    order = np.argsort(rates)
    a, s = np.asarray(weights)[order], np.asarray(rates)[order]

    def D(z):
        return M + np.sum(a / (z[:, None] + s), axis=1)

    left = np.concatenate([-s[1:], [-s[-1] - a.sum() / M]])
    right = -s.copy()
    lo, hi = left.copy(), right.copy()           # D > 0 at lo, D < 0 at hi (D decreases)
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        positive = D(mid) > 0
        lo, hi = np.where(positive, mid, lo), np.where(positive, hi, mid)
    zeta = 0.5 * (lo + hi)
    dD = -np.sum(a / (zeta[:, None] + s) ** 2, axis=1)
    t = np.atleast_1d(np.asarray(t, float))
    return -q * (1.0 / D(np.zeros(1))[0]
                 + np.exp(np.multiply.outer(t, zeta)) @ (1.0 / (zeta * dD)))


def uniaxial_exact(kernel: str, t: float, q: float = 10.0, E: float = 100.0, nu: float = 0.3):
    """The exact creep of the uniaxial block (module description).

    Parameters
    ----------
    kernel : str
        ``"constant"``, ``"exponential"``, ``"power"`` or ``"fractional"``.
    t : float
        The time.
    q : float, optional
        The pressure on the top.
    E, nu : float, optional
        Young's modulus and Poisson's ratio (plane strain).

    Returns
    -------
    float
        ``e(t) = eps_yy(t)``, equal to u_y at the top of the unit block.
    """
    lmbda, mu = lame_constants("plane_strain", E, nu)
    M = lmbda + 2 * mu
    if kernel == "constant":
        return -(q / M) * math.exp(-100.0 * t / M)
    if kernel == "fractional":
        mem = POWER_KERNELS[kernel]
        g = 1.0 - mem["beta"]
        return -(q / M) * float(kernels.mittag_leffler(g, mem["alpha"] / M * t**g)[0])
    if kernel == "power":
        mem = POWER_KERNELS[kernel]
        fit = kernels.power_soe(mem["alpha"], mem["beta"], mem["tau"], max(t, 1e-3), 1e-12)
        return float(prony_creep(M, fit.weights, fit.rates, q, t)[0])
    alpha, tau = 300.0, 0.2
    beta = 1 / tau + alpha / M
    return -(q / M) * (1 / (tau * beta) + (1 - 1 / (tau * beta)) * math.exp(-beta * t))


def uniaxial(kernel: str, rule: str, T: float, steps: int, q: float = 10.0,
             comm=MPI.COMM_WORLD, memory: dict = None, time: dict = None) -> np.ndarray:
    """The uniaxial block under constant pressure, solved (module description).

    Parameters
    ----------
    kernel : str
        ``"constant"``, ``"exponential"``, ``"power"`` or ``"fractional"`` (the kernels of
        ``UNIAXIAL_KERNELS`` and ``POWER_KERNELS``).
    rule : str
        ``time.rule``: ``"paper"`` or ``"trapezoid"`` (the paper's rule runs past its
        stability limit too).
    T : float
        The final time.
    steps : int
        The number of time steps.
    q : float, optional
        The pressure on the top.
    comm : mpi4py.MPI.Comm, optional
        The communicator (collective).
    memory : dict, optional
        Extra keys of the memory table, e.g. ``{"tolerance": 1e-8}``.
    time : dict, optional
        Extra keys of the time table: another grid than `steps` uniform steps, e.g.
        ``{"grid": "logarithmic", "first": 1e-3, "per_decade": 10}``.

    Returns
    -------
    numpy.ndarray
        u_y at the top (= e(t)) at every step, t = 0 included.
    """
    raw = {"name": "uniaxial",
           "geometry": {"lower": [0.0, 0.0], "upper": [1.0, 1.0], "cells": [1, 1]},
           "material": {"model": "plane_strain", "E": 100.0, "nu": 0.3},
           "memory": {**{**UNIAXIAL_KERNELS, **POWER_KERNELS}[kernel], **(memory or {})},
           "dirichlet": [{"boundary": "bottom", "components": [1]},
                         {"boundary": "left", "components": [0]},
                         {"boundary": "right", "components": [0]}],
           "traction": [{"boundary": "top", "value": [0.0, -q]}],
           # the stability study runs the paper's rule past its limit on purpose
           "time": {"T": T, "steps": steps, "rule": rule, "allow_unstable": True,
                    **(time or {})},
           "output": {"probes": [[0.5, 1.0]]}}
    result = simulate(scene_module.resolve(raw), comm=comm, progress=False)
    return np.array([s["probes"][0]["u"][1] for s in result.steps])
