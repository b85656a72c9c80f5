"""Normal and tangential parts come from the facet normal: a scene rotated by an angle (mesh and
loads) gives the same frame-invariant contact values as the unrotated one."""
import numpy as np
import pytest
from mpi4py import MPI

from contactvisco.scene import loader as scene_module
from contactvisco.solver.time_loop import simulate


def rotated(angle):
    c, s = np.cos(np.deg2rad(angle)), np.sin(np.deg2rad(angle))

    def turn(v):
        return [c * v[0] - s * v[1], s * v[0] + c * v[1]]

    raw = {
        "name": f"tilted-{angle}",
        "geometry": {"lower": [0.0, 0.0], "upper": [1.0, 0.5], "cells": [16, 8],
                     "rotation": angle},
        "material": {"model": "plane_strain", "E": 100.0, "nu": 0.3},
        "memory": {"kernel": "constant", "alpha": 40.0},
        "dirichlet": [{"boundary": "left", "components": "all"}],
        "traction": [{"boundary": "top", "value": turn([4.0, -20.0])}],
        "body_force": {"value": turn([0.0, -10.0])},
        "contact": {"boundary": "bottom", "stiffness": 100.0, "g": 0.05, "mu": 0.3},
        "time": {"T": 1.0, "steps": 3},
    }
    return scene_module.resolve(raw)


@pytest.mark.parametrize("angle", [30.0, -115.0])
def test_rotated_scene_gives_the_same_contact_state(angle):
    flat = simulate(rotated(0.0), comm=MPI.COMM_WORLD, progress=False, keep_tables=True)
    tilted = simulate(rotated(angle), comm=MPI.COMM_WORLD, progress=False, keep_tables=True)
    c, s = np.cos(np.deg2rad(angle)), np.sin(np.deg2rad(angle))
    for a, b in zip(flat.tables, tilted.tables):
        # match nodes by their unrotated positions
        x_back = np.column_stack([c * b["x"][:, 0] + s * b["x"][:, 1],
                                  -s * b["x"][:, 0] + c * b["x"][:, 1]])
        order = np.lexsort(x_back.T[::-1])
        assert np.allclose(x_back[order], a["x"], atol=1e-12)
        for key in ("u_nu", "u_tau", "reaction_nu", "reaction_tau", "lambda_nu"):
            assert np.max(np.abs(b[key][order] - a[key])) < 1e-9, key
        assert np.array_equal(b["status"][order], a["status"])
        assert np.allclose(b["normal"], [s, -c], atol=1e-12)     # the rotated (0, -1)
    counts = flat.steps[-1]["status_counts"]
    assert counts["compliance"] > 0 and counts["bound"] > 0
