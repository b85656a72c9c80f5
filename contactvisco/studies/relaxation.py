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
from contactvisco.model import viscoelastic as ve
from contactvisco.model.material import lame_constants
from contactvisco.scene import loader
from contactvisco.solver.newton import create

#: The strain histories f(t) as scene expressions in t.
HISTORIES = {"step": "1.0", "ramp": "{rate} * t", "sine": "sin({omega} * t)"}


def block_scene(viscoelastic: dict, model: str, strain, history: str, T: float, steps: int,
                rule: str = "trapezoid", rate: float = 1.0, omega: float = 1.0,
                cells: int = 1) -> dict:
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
        ``step``, ``ramp`` or ``sine`` (HISTORIES).
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

    Returns
    -------
    dict
        The raw scene, every boundary on u = f(t) E x.
    """
    E = np.asarray(strain, float)
    d = E.shape[0]
    f = HISTORIES[history].format(rate=repr(rate), omega=repr(omega))
    value = [f"({f}) * (" + " + ".join(f"{float(E[i, j])!r} * x[{j}]" for j in range(d)) + ")"
             for i in range(d)]
    boundaries = ("left", "right", "bottom", "top") + (("front", "back") if d == 3 else ())
    return {"name": "relaxation_block",
            "geometry": {"lower": [0.0] * d, "upper": [1.0] * d, "cells": [cells] * d},
            "material": {"model": model},
            "viscoelastic": viscoelastic,
            "dirichlet": [{"boundary": b, "value": value} for b in boundaries],
            "time": {"T": T, "steps": steps, "rule": rule},
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
        The times t_n = n T / N and the stresses, shape (N + 1, d, d): the mean over the cells
        of the stress's values (the stress of a homogeneous state); with per_point, shape
        (N + 1, points, d, d), then the points' coordinates (points, 3).
    """
    scene = loader.resolve(raw)
    geometry = geometry_module.build(scene, comm)
    problem = build(scene, geometry)
    snes = create(problem, comm)
    d = problem.V.mesh.geometry.dim
    from dolfinx import fem
    sigma = fem.Function(problem.tensor_space)
    owned = problem.tensor_space.dofmap.index_map.size_local
    bs = problem.tensor_space.dofmap.index_map_bs
    T, N = scene["time"]["T"], scene["time"]["steps"]
    times, out = [], []
    try:
        for n in range(N + 1):
            problem.time.stage(n * T / N)
            snes.solve()
            problem.time.commit()
            sigma.interpolate(problem.sigma_expression)
            values = sigma.x.array[:owned * bs].reshape(-1, d, d)
            times.append(n * T / N)
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
                   history: str, t, rate: float = 1.0, omega: float = 1.0) -> np.ndarray:
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
        ``step``, ``ramp`` or ``sine``.
    t : array_like
        Times.
    rate, omega : float, optional
        As in :func:`block_scene`.

    Returns
    -------
    numpy.ndarray
        sigma(t), shape (len(t), d, d).
    """
    E = np.asarray(strain, float)
    d = E.shape[0]
    t = np.atleast_1d(np.asarray(t, float))
    Gf = ve.response(shear, history, t, rate, omega)
    Kf = ve.response(bulk, history, t, rate, omega)
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
