"""A body of revolution in axisymmetry and in 3D: the same sphere-on-cylinder problem posed in
the meridian half-plane (material.model = "axisymmetric", meshes/axisymmetric_block.py) and on
a quarter of the cylinder of tetrahedra with its two planes of symmetry on rollers
(material.model = "3d", meshes/quarter_cylinder.py), so that the two discretizations converge
to one solution and the 3D run's discretization error can be measured against a fine
axisymmetric run.

The problem: an elastic cylinder (E = 1, nu = 0.3) of radius and height `size`, on rollers
at its bottom, pressed to the depth delta = a^2 / R by a rigid sphere of radius R = 1 on its
axis, frictionless, in Hertz's parabolic gap g(x) = rho^2 / 2R - delta t (rho the distance from
the axis: r, or sqrt(x^2 + y^2)) with its vertical contact direction. The measured quantity is
the total force P = sum_i p_i w_i over the contact nodes (their ring areas in axisymmetry; four
times the quarter's sum in 3D). Both meshes have the size a/n within 1.5 a of the contact
point, growing by 1.2/n per unit distance up to size/4.
"""
from __future__ import annotations

import time

import numpy as np
from mpi4py import MPI

from contactvisco.scene import loader as scene_module
from contactvisco.solver.time_loop import simulate

#: The sphere's radius, the contact radius a = sqrt(R delta), and the depth.
RADIUS, CONTACT_RADIUS = 1.0, 0.1
DEPTH = CONTACT_RADIUS**2 / RADIUS


def sphere_on_cylinder_scene(model: str, n: int, size: float = 1.0) -> dict:
    """The raw scene of the sphere-on-cylinder problem (module description).

    Parameters
    ----------
    model : str
        ``"axisymmetric"`` or ``"3d"``.
    n : int
        Mesh size a/n at the contact.
    size : float, optional
        The cylinder's radius and height.

    Returns
    -------
    dict
        A raw scene (for scene.loader.resolve).
    """
    a = CONTACT_RADIUS
    parameters = {"radius": size, "height": size, "h_contact": a / n, "h_far": size / 4,
                  "refine": 1.5 * a, "growth": 1.2 / n}
    if model == "3d":
        geometry = {"type": "gmsh", "script": "quarter_cylinder", "parameters": parameters}
        rho2 = "(x[0]**2 + x[1]**2)"
        dirichlet = [{"boundary": "bottom", "components": [2]},
                     {"boundary": "xsym", "components": [0]},
                     {"boundary": "ysym", "components": [1]}]
    else:
        geometry = {"type": "gmsh", "script": "axisymmetric_block", "parameters": parameters}
        rho2 = "x[0]**2"
        dirichlet = [{"boundary": "bottom", "components": [1]}]
    return {"name": f"sphere_on_cylinder_{model}", "geometry": geometry,
            "material": {"model": model, "E": 1.0, "nu": 0.3}, "dirichlet": dirichlet,
            "contact": {"boundary": "top", "g": 0.0, "mu": 0.0, "augmentation": n / a,
                        "gap": f"{rho2} / {2 * RADIUS!r} - {DEPTH!r} * t"},
            "time": {"T": 1.0, "steps": 1}, "output": {"probes": []}}


def sphere_on_cylinder(model: str, n: int, size: float = 1.0, comm=MPI.COMM_WORLD) -> dict:
    """The sphere-on-cylinder problem solved (module description).

    Parameters
    ----------
    model, n, size
        As in sphere_on_cylinder_scene.
    comm : mpi4py.MPI.Comm, optional
        The communicator (collective).

    Returns
    -------
    dict
        ``P`` (the total force), ``unknowns`` (u and the multipliers), ``newton`` (Newton
        iterations), ``wall_s`` (the whole run, mesh and set-up included).
    """
    start = time.perf_counter()
    result = simulate(scene_module.resolve(sphere_on_cylinder_scene(model, n, size)),
                      comm=comm, progress=False, keep_tables=True)
    wall = time.perf_counter() - start
    table = result.tables[-1]
    quarters = 4 if model == "3d" else 1
    return {"P": quarters * float(np.sum(table["reaction_nu"] * table["weight"])),
            "unknowns": sum(result.problem.count_unknowns().values()),
            "newton": sum(step["newton_iterations"] for step in result.steps),
            "wall_s": comm.allreduce(wall, op=MPI.MAX)}
