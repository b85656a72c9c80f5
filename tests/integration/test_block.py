"""A frictionless, memoryless block pressed uniformly onto the compliant layer: closed form.

Rollers on x = 0 and x = 1 (u_x = 0), pressure q on top, contact at y = 0. The state is
uniaxial strain: sigma_yy = -q, eps_xx = 0, eps_yy = -q / M with M = lambda + 2 mu (plane
strain) or E / (1 - nu^2) (plane stress). The layer carries q: u_nu = q / c while q < c g
(normal compliance), else u_nu = g and the rigid part adds R = q - c g (bound). Then
u_y(x, y) = -u_nu - q y / M, which P1 represents exactly.
"""
import math

import numpy as np
import pytest
from mpi4py import MPI

from contactvisco.scene import loader as scene_module
from contactvisco.model.material import lame_constants
from contactvisco.solver.time_loop import simulate


def block_scene(q, stiffness, g, model="plane_strain", cells=(6, 5)):
    raw = {
        "name": "block",
        "geometry": {"lower": [0.0, 0.0], "upper": [1.0, 1.0], "cells": list(cells)},
        "material": {"model": model, "E": 50.0, "nu": 0.3},
        "dirichlet": [{"boundary": "left", "components": [0]},
                      {"boundary": "right", "components": [0]}],
        "traction": [{"boundary": "top", "value": [0.0, -q]}],
        "contact": {"boundary": "bottom", "stiffness": stiffness, "g": g, "mu": 0.0},
        "time": {"T": 1.0, "steps": 1},
        "output": {"probes": [[0.3, 1.0], [0.7, 0.0]]},
    }
    return scene_module.resolve(raw)


@pytest.mark.parametrize("model", ["plane_strain", "plane_stress"])
@pytest.mark.parametrize("q, g, regime", [(2.0, 0.05, "compliance"), (2.0, math.inf, "compliance"),
                                          (8.0, 0.05, "bound")])
def test_uniform_block(model, q, g, regime):
    c = 100.0
    scene = block_scene(q, c, g, model)
    result = simulate(scene, comm=MPI.COMM_WORLD, progress=False, keep_tables=True)
    lmbda, mu = lame_constants(model, 50.0, 0.3)
    M = lmbda + 2 * mu
    u_nu = q / c if regime == "compliance" else g
    table = result.tables[-1]
    assert np.allclose(table["u_nu"], u_nu, rtol=0, atol=1e-12)
    assert np.allclose(table["reaction_nu"], q, rtol=0, atol=1e-10)
    R = -table["lambda_nu"]
    assert np.allclose(R, q - c * g if regime == "bound" else 0.0, atol=1e-10)
    assert set(table["status"]) == {1 if regime == "compliance" else 2}
    for probe in result.steps[-1]["probes"]:
        x, y = probe["x"]
        assert probe["u"][0] == pytest.approx(0.0, abs=1e-12)
        assert probe["u"][1] == pytest.approx(-u_nu - q * y / M, abs=1e-12)
    # no friction, no memory: neither lambda_tau nor a history is built
    assert result.problem.contact.lambda_tau is None and result.problem.memory is None
    assert (result.problem.contact.lambda_nu is None) == (not math.isfinite(g))


def test_block_separates_under_tension():
    """Pulled up (q < 0) against the rollers only, a block cannot stay in equilibrium; held
    at the top instead, a layer with nothing to push on gives no contact force."""
    raw = block_scene(1.0, 100.0, 0.05).copy()
    raw["dirichlet"] = [{"boundary": "top", "components": "all", "value": [0.0, 0.01]}]
    raw["traction"] = []
    scene = scene_module.resolve(raw)
    result = simulate(scene, comm=MPI.COMM_WORLD, progress=False, keep_tables=True)
    table = result.tables[-1]
    assert np.all(table["status"] == 0)
    assert np.allclose(table["reaction_nu"], 0.0, atol=1e-12)
    assert np.all(table["u_nu"] < 0)


def test_block_in_a_corner_of_two_layers():
    """Contact on two boundaries: pressures q on top and p on the right push the block onto
    compliant layers at the bottom and on the left. Homogeneous stress sigma = diag(-p, -q):
    u = (-p/c + eps_xx x, -q/c + eps_yy y) with plane-strain eps from Hooke's law."""
    q, p, c, E, nu = 3.0, 1.0, 100.0, 50.0, 0.3
    raw = {
        "name": "corner",
        "geometry": {"lower": [0.0, 0.0], "upper": [1.0, 1.0], "cells": [5, 5]},
        "material": {"model": "plane_strain", "E": E, "nu": nu},
        "traction": [{"boundary": "top", "value": [0.0, -q]},
                     {"boundary": "right", "value": [-p, 0.0]}],
        "contact": {"boundary": ["bottom", "left"], "stiffness": c, "g": 1.0, "mu": 0.0},
        "time": {"T": 1.0, "steps": 1},
        "output": {"probes": [[1.0, 1.0], [0.4, 0.6]]},
    }
    result = simulate(scene_module.resolve(raw), comm=MPI.COMM_WORLD, progress=False,
                      keep_tables=True)
    s_xx, s_yy = -p, -q
    e_xx = ((1 - nu**2) * s_xx - nu * (1 + nu) * s_yy) / E
    e_yy = ((1 - nu**2) * s_yy - nu * (1 + nu) * s_xx) / E
    for probe in result.steps[-1]["probes"]:
        x, y = probe["x"]
        assert probe["u"] == pytest.approx([-p / c + e_xx * x, -q / c + e_yy * y], abs=1e-12)
    table = result.tables[-1]
    on_bottom = (table["x"][:, 1] < 1e-12) & (table["x"][:, 0] > 1e-12)
    on_left = (table["x"][:, 0] < 1e-12) & (table["x"][:, 1] > 1e-12)
    assert np.allclose(table["reaction_nu"][on_bottom], q, atol=1e-10)
    assert np.allclose(table["reaction_nu"][on_left], p, atol=1e-10)
