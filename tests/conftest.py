import pytest
from mpi4py import MPI

from contactvisco.scene import loader as scene_module
from contactvisco.solver.time_loop import simulate


@pytest.fixture(scope="session")
def paper_run():
    """The paper scene as shipped, every step's contact table kept."""
    scene = scene_module.load("paper")
    return scene, simulate(scene, comm=MPI.COMM_WORLD, progress=False, keep_tables=True)
