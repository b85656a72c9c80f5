import gc
import os
import sys

# A pytest-xdist worker is started by the controller process, which has already initialized
# MPI as a singleton: Open MPI and PMIx put that singleton's job into the process environment
# (below Python's os.environ), and the worker inherits it. Left there, the worker and every
# `mpirun` it starts would take themselves for members of the controller's job (the launcher
# then exits 1 without a word). Each worker is a singleton of its own.
if "PYTEST_XDIST_WORKER" in os.environ:
    for key in [key for key in os.environ
                if key.startswith(("PMIX_", "OMPI_MCA_orte_", "OMPI_MCA_ess", "OMPI_MCA_pmix",
                                   "OMPI_APP_CTX_", "OMPI_COMM_WORLD_", "PMI_"))]:
        del os.environ[key]

import pytest  # noqa: E402  (after the environment is cleaned: mpi4py initializes MPI)
from mpi4py import MPI  # noqa: E402
from petsc4py import PETSc

from contactvisco.scene import loader as scene_module
from contactvisco.solver.time_loop import simulate


@pytest.hookimpl(tryfirst=True)
def pytest_configure(config):
    """Under mpirun every rank runs pytest: a JUnit report asked for with --junitxml is
    written by each rank to its own file (`report.xml.rank1`, ...), rank 0 keeping the name
    given, so that the reports of a 2-rank pass do not overwrite each other."""
    rank = MPI.COMM_WORLD.rank
    if rank > 0 and getattr(config.option, "xmlpath", None):
        config.option.xmlpath = f"{config.option.xmlpath}.rank{rank}"


@pytest.hookimpl(tryfirst=True)
def pytest_collection_modifyitems(config, items):
    """Groups for two pytest workers (`pytest -n 2 --dist loadgroup`, `make test`): the tests
    of a module stay in one worker, so that a module's fixtures are built once, and the
    tests marked `processes` (they start the command line or `mpirun` themselves) all go to
    one worker, so that no two of them compete for the cores at once. Runs before
    pytest-xdist reads the groups."""
    if not config.pluginmanager.hasplugin("xdist"):
        return
    for item in items:
        if item.get_closest_marker("xdist_group") is None:
            group = "processes" if item.get_closest_marker("processes") else item.module.__name__
            item.add_marker(pytest.mark.xdist_group(group))


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
