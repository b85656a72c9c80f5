"""A rigid cone and a rigid flat punch pressed into an axisymmetric block (elastic,
frictionless), against Sneddon's closed forms (Sneddon 1965; Johnson, Contact Mechanics, 1985,
sec 5.2-5.3), on the graded block of test_axisymmetric_hertz (80 R wide and high, h = a/n at
the contact, a = 0.1):

- cone of half-angle alpha: P = (2/pi) E* tan(alpha) delta^2, a = 2 delta tan(alpha) / pi.
  Sneddon's geometry (the gap r cot(alpha) - delta along the vertical) is posed through
  contact.gap. Measured (alpha = 70.3 deg): P/P_S - 1 = +1.7 %, +0.52 %, +0.16 % for n = 4, 8,
  16. The exact cone (obstacle.shape = "cone", its closest-point normal, tilted by 90 - alpha
  from the vertical) is a different problem: its vertical force exceeds Sneddon's by +5.9 %,
  +4.6 %, +4.2 % (n = 4, 8, 16), as the sphere's exceeds Hertz's by its slope;
- flat punch of radius a (obstacle.shape = "punch"): P = 2 E* a delta. Measured P/P_F - 1 =
  +8.0 %, +3.7 %, +1.9 % for n = 4, 8, 16: order 1 in h, the pressure being singular at the
  edge as (a - r)^(-1/2).
"""
import math

import numpy as np
import pytest
from mpi4py import MPI

from contactvisco.scene import loader as scene_module
from contactvisco.solver.time_loop import simulate
from helpers import axisymmetric_blocks

COMM = MPI.COMM_WORLD
E, NU, A = 1.0, 0.3, 0.1
E_STAR = E / (1 - NU**2)
SIZE = 800.0 * A
ALPHA = 70.3                                   # degrees: Berkovich's equivalent cone
TAN = math.tan(math.radians(ALPHA))
DELTA_CONE = math.pi * A / (2 * TAN)           # the depth at which a = A
P_CONE = 2 / math.pi * E_STAR * TAN * DELTA_CONE**2
DELTA_PUNCH = 1e-3
P_PUNCH = 2 * E_STAR * A * DELTA_PUNCH


@pytest.fixture(scope="module")
def meshes(tmp_path_factory):
    """n -> the .msh file of the block with h = a/n at the contact (made on rank 0)."""
    return axisymmetric_blocks(tmp_path_factory.mktemp("axi_indenters"), A, SIZE)


def run(mesh, n, obstacle=None, gap=0.0):
    raw = {"name": "indenter", "geometry": {"type": "gmsh", "file": str(mesh)},
           "material": {"model": "axisymmetric", "E": E, "nu": NU},
           "dirichlet": [{"boundary": "bottom", "components": [1]}],
           "contact": {"boundary": "top", "g": 0.0, "mu": 0.0, "augmentation": E * n / A,
                       "gap": gap},
           "time": {"T": 1.0, "steps": 1}, "output": {"probes": []}}
    if obstacle:
        raw["obstacle"] = obstacle
    result = simulate(scene_module.resolve(raw), comm=COMM, progress=False, keep_tables=True)
    table = result.tables[-1]
    return float((table["reaction_nu"] * table["weight"]).sum()), result.steps[-1]


def test_sneddon_cone_force_and_radius_fall_with_h(meshes):
    errors = {}
    for n in (8, 16):
        P, record = run(meshes[n], n, gap=f"x[0] / {TAN!r} - {DELTA_CONE!r} * t")
        errors[n] = abs(P / P_CONE - 1.0)
        assert record["contact_radius"]["interpolated"] == pytest.approx(A, rel=1.5 / n)
    assert errors[16] < 3e-3 and errors[16] < errors[8] / 2.5, errors


def test_exact_cone_under_displacement_and_force_control(meshes):
    """The cone obstacle: its vertical force exceeds Sneddon's (vertical gap) by the flank's
    slope effect (measured +4.6 % at n = 8, cot(alpha) = 0.36), and is the sum of the normal
    ring forces times cos(90 - alpha) on the flank; pressed by that force, the cone reaches
    the same depth."""
    n = 8
    cone = {"shape": "cone", "point": [0.0, 0.0], "angle": ALPHA,
            "displacement": [0.0, f"-{DELTA_CONE!r} * t"]}
    P, record = run(meshes[n], n, cone)
    vertical = -record["obstacle"]["force"][1]
    assert 0.02 < vertical / P_CONE - 1.0 < 0.07
    assert record["obstacle"]["force"][0] == 0.0
    assert vertical == pytest.approx(P * math.sin(math.radians(ALPHA)), rel=1e-2)
    # A cone touching the block at its tip alone carries no force change at first: it starts
    # pressed by delta/10 under a hundredth of the force (P grows as delta^2).
    force = record["obstacle"]["force"][1]
    pushed = dict(cone, displacement=[0.0, -0.1 * DELTA_CONE], force_components=[1],
                  force=[f"{force!r} * (0.01 + 0.99 * t)"])
    _, moved = run(meshes[n], n, pushed)
    assert moved["obstacle"]["displacement"][1] == pytest.approx(-DELTA_CONE, rel=1e-7)


def test_flat_punch_force_falls_with_h(meshes):
    """P = 2 E* a delta at order 1 in h; the contact radius is the punch's to a spacing."""
    errors = {}
    for n in (8, 16):
        punch = {"shape": "punch", "point": [0.0, 0.0], "radius": A,
                 "displacement": [0.0, f"-{DELTA_PUNCH!r} * t"]}
        P, record = run(meshes[n], n, punch)
        errors[n] = P / P_PUNCH - 1.0
        assert abs(record["contact_radius"]["node"] - A) < 1.0 * A / n
    assert 0 < errors[16] < 0.025 and errors[16] < errors[8] / 1.6, errors


def test_plane_strain_die_and_wedge_touch_where_they_reach():
    """In plane strain the same keys give a flat die and a wedge about the vertical line
    through their point: symmetric about it (the nodes in contact mirror each other), the die
    pressing exactly the nodes under its face, the wedge fewer than the die."""
    found = {}
    for shape, extra in (("punch", {"radius": 0.25}), ("cone", {"angle": 80.0})):
        raw = {"name": "die", "geometry": {"lower": [0.0, 0.0], "upper": [2.0, 1.0],
                                           "cells": [16, 8]},
               "material": {"model": "plane_strain", "E": E, "nu": NU},
               "dirichlet": [{"boundary": "bottom", "components": "all"}],
               "contact": {"boundary": "top", "g": 0.0, "mu": 0.0},
               "obstacle": {"shape": shape, "point": [1.0, 1.0],
                            "displacement": [0.0, "-0.01 * t"], **extra},
               "time": {"T": 1.0, "steps": 1}, "output": {"probes": []}}
        result = simulate(scene_module.resolve(raw), comm=COMM, progress=False,
                          keep_tables=True)
        table = result.tables[-1]
        x = table["x"][table["status"] > 0][:, 0]
        assert np.allclose(np.sort(x - 1.0), np.sort(1.0 - x), atol=1e-12)
        assert result.steps[-1]["obstacle"]["force"][1] < 0        # pushes the body down
        found[shape] = x
    assert np.allclose(np.sort(found["punch"]), np.linspace(0.75, 1.25, 5))
    assert 0 < found["cone"].size < found["punch"].size
