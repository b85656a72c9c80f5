"""Creep indentation over five decades of time on a logarithmic grid: the built-in scene
sphere_creep (a rigid sphere under a force held from t = 0 on an axisymmetric block with one
shear relaxation time tau = 1 s) from t_1 = 1e-2 s to T = 1e3 s at 5 steps per decade (24
steps) against Lee and Radok's closed form (studies.indentation.SphereLeeRadok). Measured: the
depth creeps by 1.44; the creep ratio delta(t)/delta(0) within 0.65 % of the closed form's
(0.69 % at 10 per decade: the mesh's, from the contact radius growing node by node), the
depth within 1.7 % (the exact sphere's departure from Hertz)."""
import math

import numpy as np
import pytest
from mpi4py import MPI

from contactvisco.scene import loader as scene_module
from contactvisco.solver.time_loop import simulate
from contactvisco.studies.indentation import SphereLeeRadok


@pytest.mark.slow
def test_sphere_creep_over_five_decades_on_a_logarithmic_grid_follows_lee_radok():
    scene = scene_module.load("sphere_creep", [
        "time.T=1000", "time.grid='logarithmic'", "time.first=0.01", "time.per_decade=5"])
    result = simulate(scene, comm=MPI.COMM_WORLD, progress=False)
    t = np.array([step["t"] for step in result.steps])
    assert len(t) - 1 == 24 and t[1] <= 0.01 and t[-1] == 1000.0
    depth = -np.array([step["obstacle"]["displacement"][1] for step in result.steps])
    P = -scene["obstacle"]["force"][0]
    shear = scene["viscoelastic"]["shear"]
    exact = SphereLeeRadok(scene["material"]["E"], scene["material"]["nu"],
                           -2.0 * shear["fractions"][0] * shear["instantaneous"], 1.0, 1.0)
    closed = exact.radius(P, t) ** 2
    assert closed[-1] / closed[0] > 1.4
    assert np.max(np.abs((depth / depth[0]) / (closed / closed[0]) - 1.0)) < 1e-2
    assert np.max(np.abs(depth / closed - 1.0)) < 0.25 * math.sqrt(closed[0])
