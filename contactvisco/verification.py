"""Verification against exact solutions: shared by the tests and the benchmarks.

manufactured(): a manufactured solution of the viscoelastic problem without contact. The
solution is u(x, t) = U(x), prescribed on the whole boundary. With the constant kernel
R = alpha I, sigma(t) = A eps(U) + alpha t eps(U), and the body force
f(t) = -div sigma(t) is derived by UFL. Errors at T in L2 and in the H1 seminorm.

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
"""
from __future__ import annotations

import math

import numpy as np
import ufl
from dolfinx import fem
from mpi4py import MPI

from . import geometry as geometry_module
from . import scene as scene_module
from .material import elasticity, lame_constants, strain
from .problem import build
from .run import simulate
from .solver import BlockSNES

#: The manufactured displacement, as scene expressions in x.
U_EXACT = ["0.1 * sin(pi * x[0]) * sin(pi * x[1]) + 0.05 * x[0] * x[1]",
           "0.1 * cos(pi * x[0]) * x[1]**2 - 0.02 * x[0]"]


def manufactured(cells: int, degree: int, rule: str = "trapezoid", steps: int = 4,
                 alpha: float = 50.0, comm=MPI.COMM_WORLD) -> dict:
    """L2 and H1-seminorm errors at T = 1 of the manufactured solution on a cells x cells
    mesh with Lagrange elements of the given degree."""
    raw = {"name": "manufactured",
           "geometry": {"lower": [0.0, 0.0], "upper": [1.0, 1.0], "cells": [cells, cells]},
           "material": {"model": "plane_strain", "E": 100.0, "nu": 0.3},
           "memory": {"kernel": "constant", "alpha": alpha},
           "dirichlet": [{"boundary": b, "components": "all", "value": U_EXACT}
                         for b in ("left", "right", "bottom", "top")],
           "time": {"T": 1.0, "steps": steps, "rule": rule},
           "discretization": {"degree": degree, "contact_quadrature": "gauss"}}
    scene = scene_module.resolve(raw)
    geometry = geometry_module.build(scene, comm)
    problem = build(scene, geometry)
    ctx = problem.context
    U = ctx.vector(U_EXACT, "U_EXACT", 2)
    lmbda, mu = lame_constants("plane_strain", 100.0, 0.3)
    sigma = elasticity(strain(U), lmbda, mu) + alpha * ctx.t * strain(U)
    v = problem.F[0].arguments()[0]
    F = [problem.F[0] + ufl.dot(ufl.div(sigma), v) * ufl.dx] + problem.F[1:]
    snes = BlockSNES(F, problem.J, problem.unknowns, problem.bcs, comm)
    T, N = scene["time"]["T"], steps
    for n in range(N + 1):
        problem.set_time(n * T / N)
        if n > 0:
            problem.update_history()
        snes.solve()
    error = problem.u - U
    quadrature = {"quadrature_degree": 2 * degree + 4}
    l2 = fem.assemble_scalar(fem.form(ufl.inner(error, error) * ufl.dx(metadata=quadrature)))
    h1 = fem.assemble_scalar(fem.form(ufl.inner(ufl.grad(error), ufl.grad(error))
                                      * ufl.dx(metadata=quadrature)))
    return {"cells": cells, "degree": degree, "h": 1.0 / cells,
            "L2": math.sqrt(comm.allreduce(l2, MPI.SUM)),
            "H1": math.sqrt(comm.allreduce(h1, MPI.SUM))}


def orders(errors: list[float], sizes: list[float]) -> list[float]:
    """Observed orders log(e_i / e_{i+1}) / log(h_i / h_{i+1})."""
    return [math.log(a / b) / math.log(h / k)
            for a, b, h, k in zip(errors, errors[1:], sizes, sizes[1:])]


def hertz(overrides=(), comm=MPI.COMM_WORLD) -> dict:
    """The hertz scene against the closed form: the contact half-width (midway between the last
    node in contact and the next) and the pressure at the centre, with their relative errors."""
    scene = scene_module.load("hertz", list(overrides))
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


def uniaxial_exact(kernel: str, t: float, q: float = 10.0, E: float = 100.0, nu: float = 0.3):
    lmbda, mu = lame_constants("plane_strain", E, nu)
    M = lmbda + 2 * mu
    if kernel == "constant":
        return -(q / M) * math.exp(-100.0 * t / M)
    alpha, tau = 300.0, 0.2
    beta = 1 / tau + alpha / M
    return -(q / M) * (1 / (tau * beta) + (1 - 1 / (tau * beta)) * math.exp(-beta * t))


def uniaxial(kernel: str, rule: str, T: float, steps: int, q: float = 10.0,
             comm=MPI.COMM_WORLD) -> np.ndarray:
    """u_y at the top (= e(t)) at every step of the uniaxial block."""
    raw = {"name": "uniaxial",
           "geometry": {"lower": [0.0, 0.0], "upper": [1.0, 1.0], "cells": [1, 1]},
           "material": {"model": "plane_strain", "E": 100.0, "nu": 0.3},
           "memory": UNIAXIAL_KERNELS[kernel],
           "dirichlet": [{"boundary": "bottom", "components": [1]},
                         {"boundary": "left", "components": [0]},
                         {"boundary": "right", "components": [0]}],
           "traction": [{"boundary": "top", "value": [0.0, -q]}],
           # the stability study runs the paper's rule past its limit on purpose
           "time": {"T": T, "steps": steps, "rule": rule, "allow_unstable": True},
           "output": {"probes": [[0.5, 1.0]]}}
    result = simulate(scene_module.resolve(raw), comm=comm, progress=False)
    return np.array([s["probes"][0]["u"][1] for s in result.steps])
