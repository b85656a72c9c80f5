import gc
import sys

import pytest
from mpi4py import MPI
from petsc4py import PETSc

from contactvisco.scene import loader as scene_module
from contactvisco.solver.time_loop import simulate


@pytest.fixture(scope="session")
def paper_run():
    """The paper scene as shipped, every step's contact table kept."""
    scene = scene_module.load("paper")
    return scene, simulate(scene, comm=MPI.COMM_WORLD, progress=False, keep_tables=True)


@pytest.fixture(autouse=True)
def release_petsc_garbage(request, monkeypatch):
    """The PETSc garbage of every problem a test module builds itself is released when the
    test ends, as a run releases its own (Problem.release_garbage; a test that drops a
    problem or a solver without destroying it would otherwise hold a communicator for ever,
    and MPICH aborts the 2-rank suite once about 2000 are held). The problems are held until
    then, except in tests marked `own_garbage`, which release theirs. Collective: every rank
    runs every test."""
    if MPI.COMM_WORLD.size == 1:       # petsc4py destroys the objects of one rank at once
        yield
        return
    from contactvisco.fem import problem as problem_module
    original, built = problem_module.build, []

    def recorded(*args, **kwargs):
        problem = original(*args, **kwargs)
        built.append(problem)
        return problem

    if request.node.get_closest_marker("own_garbage") is None:
        for name, module in list(sys.modules.items()):   # `from ... import build` included
            if name.split(".")[0] != "contactvisco" \
                    and vars(module).get("build") is original:
                monkeypatch.setattr(module, "build", recorded)
    yield
    gc.collect()
    for problem in built:
        problem.release_garbage()
    PETSc.garbage_cleanup(MPI.COMM_WORLD)
