"""A 3D block pressed and sheared on the layer: friction is a projection onto a disc, and the
nodal vertex rule on triangular facets makes the conditions hold node by node."""
import numpy as np
import pytest
from helpers import assert_contact_conditions
from mpi4py import MPI

from contactvisco.scene import loader as scene_module
from contactvisco.solver.time_loop import simulate

pytestmark = pytest.mark.mpi


def test_block3d_conditions():
    raw = {
        "name": "block3d-test",
        "geometry": {"lower": [0.0, 0.0, 0.0], "upper": [1.0, 1.0, 0.5], "cells": [5, 5, 2]},
        "material": {"model": "3d", "E": 100.0, "nu": 0.3},
        "memory": {"kernel": "exponential", "alpha": [50.0], "tau": [0.5]},
        "dirichlet": [{"boundary": "left", "components": "all"}],
        "traction": [{"boundary": "top", "value": [5.0, 2.0, -20.0]}],
        "body_force": {"value": [0.0, 0.0, -10.0]},
        "contact": {"boundary": "bottom", "stiffness": 100.0, "g": 0.05, "mu": 0.3},
        "time": {"T": 1.0, "steps": 2},
    }
    scene = scene_module.resolve(raw)
    result = simulate(scene, comm=MPI.COMM_WORLD, progress=False, keep_tables=True)
    sliding = 0
    for step, table in zip(result.steps, result.tables):
        assert step["residual"] < 1e-10
        clamped = table["x"][:, 0] < 1e-12
        sliding += assert_contact_conditions(table, 0.05, 1e-10, clamped)
        assert np.all(table["normal"][:, 2] == -1.0)
    counts = result.steps[-1]["status_counts"]
    assert counts["bound"] > 0 and counts["compliance"] > 0
    assert sliding > 20
    # shear in x and y: sliding directions really are 2D vectors in the plane
    ut = result.tables[-1]["u_tau_vector"]
    assert np.max(np.abs(ut[:, 0])) > 1e-3 and np.max(np.abs(ut[:, 1])) > 1e-3


def test_prescribed_displacement_uniaxial_closed_form():
    """3D uniaxial stress by a nonzero prescribed displacement on top, rollers on three faces
    and a compliant layer below: s = delta / (1 + c H / E) at every contact node and
    u = (nu e x, nu e y, ...) inside. Nonzero Dirichlet values cross process boundaries here,
    so on 2 ranks this checks the ghost update of the Newton iterate."""
    delta, c, H, E, nu = 0.01, 100.0, 0.5, 100.0, 0.3
    raw = {"name": "uniaxial3d", "material": {"model": "3d", "E": E, "nu": nu},
           "geometry": {"lower": [0, 0, 0], "upper": [1, 1, H], "cells": [4, 4, 2]},
           "dirichlet": [{"boundary": "top", "components": [2], "value": -delta},
                         {"boundary": "left", "components": [0]},
                         {"boundary": "front", "components": [1]}],
           "contact": {"boundary": "bottom", "stiffness": c, "g": 0.02, "mu": 0.0},
           "time": {"T": 1.0, "steps": 1},
           "output": {"probes": [[1.0, 1.0, H], [0.25, 0.75, 0.25]]}}
    result = simulate(scene_module.resolve(raw), comm=MPI.COMM_WORLD, progress=False,
                      keep_tables=True)
    s = delta / (1 + c * H / E)
    strain = (delta - s) / H
    assert np.allclose(result.tables[-1]["u_nu"], s, atol=1e-13)
    for probe in result.steps[-1]["probes"]:
        x, y, z = probe["x"]
        assert np.allclose(probe["u"], [nu * strain * x, nu * strain * y, -s - strain * z],
                           atol=1e-13)
    assert result.steps[0]["newton_iterations"] <= 2
