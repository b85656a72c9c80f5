"""The same scene on all ranks (distributed mesh) and on one rank (MPI.COMM_SELF) gives the same
contact-boundary values. Runs only under mpirun with more than one rank."""
import numpy as np
import pytest
from mpi4py import MPI

from contactvisco.scene import loader as scene_module
from contactvisco.solver.time_loop import simulate

pytestmark = [pytest.mark.mpi,
              pytest.mark.skipif(MPI.COMM_WORLD.size == 1, reason="needs mpirun -n 2 or more")]

KEYS = ("x", "u_nu", "u_tau", "reaction_nu", "reaction_tau", "lambda_nu", "weight")


@pytest.mark.parametrize("name, overrides", [
    ("paper", ["geometry.cells=[24, 16]", "time.steps=4"]),
    ("paper", ["geometry.cells=[24, 16]", "time.steps=4", "contact.g=inf"]),
    ("paper", ["geometry.cells=[24, 16]", "time.steps=4", "geometry.diagonal='crossed'",
               "contact.mu=0.5"]),
    # 3D, gmsh mesh, nonzero prescribed displacements that vary in x and t
    ("block3d", ["time.steps=4"]),
    # a moving load needs steps small enough for Newton to start near the solution: with 4
    # steps the semismooth Newton was seen to end on another discrete solution now and then
    ("ironing", ["geometry.parameters.h=0.1", "time.steps=20"]),
    # axisymmetric: ring weights of the contact nodes, the axis, force control along z
    ("sphere_creep", ["time.steps=4"]),
])
def test_ranks_agree(name, overrides):
    scene = scene_module.load(name, overrides)
    world = simulate(scene, comm=MPI.COMM_WORLD, progress=False, keep_tables=True)
    single = simulate(scene, comm=MPI.COMM_SELF, progress=False, keep_tables=True)
    tdim = world.problem.geometry.mesh.topology.dim
    assert world.problem.geometry.mesh.topology.index_map(tdim).size_local < \
        single.problem.geometry.mesh.topology.index_map(tdim).size_local   # really distributed
    for a, b in zip(world.tables, single.tables):
        for key in KEYS:
            assert np.max(np.abs(a[key] - b[key])) < 1e-10, key
        assert np.array_equal(a["status"], b["status"])
    for a, b in zip(world.steps, single.steps):
        assert a["status_counts"] == b["status_counts"]
        if "obstacle" in a:
            assert np.allclose(a["obstacle"]["displacement"], b["obstacle"]["displacement"],
                               rtol=1e-10, atol=0)
        for pa, pb in zip(a["probes"], b["probes"]):
            assert np.max(np.abs(np.array(pa["u"]) - np.array(pb["u"]))) < 1e-10
