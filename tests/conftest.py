import pytest
from mpi4py import MPI

from contactvisco import scene as scene_module
from contactvisco.run import simulate


@pytest.fixture(scope="session")
def paper_run():
    """The paper scene as shipped, every step's contact table kept."""
    scene = scene_module.load("paper")
    return scene, simulate(scene, comm=MPI.COMM_WORLD, progress=False, keep_tables=True)
