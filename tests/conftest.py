import pytest
from mpi4py import MPI

from contactvisco.scene import loader as scene_module
from contactvisco.solver.time_loop import simulate


@pytest.fixture(scope="session")
def paper_run():
    """The paper scene as shipped, every step's contact table kept."""
    scene = scene_module.load("paper")
    return scene, simulate(scene, comm=MPI.COMM_WORLD, progress=False, keep_tables=True)


@pytest.fixture
def hard_newton_steps(monkeypatch):
    """Newton's derivative at the bound taken on the bound side, slope 0 at s = g
    (contact_law.BOUND_TIE = "bound", ufl.min_value's choice; the default is the compliance
    side): the ironing scene's 5 large steps then need up to 29 Newton iterations and the
    paper scene's first state on 4 x 4 cells more than 3, the hard steps that step cutting
    and the failure reports are tested on (on the compliance side they take at most 7)."""
    from contactvisco.model import contact_law
    monkeypatch.setattr(contact_law, "BOUND_TIE", "bound")
