"""A fast subset of benchmarks/robustness/extremes.py (the full table is in docs/extremes.md):
parameters at their ends converge with the contact conditions holding; the one known failure
(friction with an augmentation parameter far above the stiffness where the body separates)
stops with a clear message instead of a wrong answer."""
import pytest
from helpers import assert_contact_conditions
from mpi4py import MPI

from contactvisco.scene import loader as scene_module
from contactvisco.solver.time_loop import simulate
from contactvisco.solver.newton import NewtonFailure

BASE = ["geometry.cells=[8, 8]", "output.probes=[]", "time.steps=3"]
LIFT = ["traction.0.value=[0.0, 'conditional(x[0] > 0.5, 24.0, -20.0)']"]


@pytest.mark.parametrize("overrides", [
    ["contact.stiffness=1e8"], ["contact.stiffness=1e-4"], ["contact.augmentation=1e8"],
    ["contact.augmentation=1e-4"], ["contact.g=1e-8"], ["contact.mu=2.0"],
    ["material.model='plane_strain'", "material.nu=0.4999"], ["geometry.cells=[2, 2]"],
    ["time.T=1e-5"], ["time.T=100.0", "time.rule='trapezoid'", "memory.alpha=1e5"],
    LIFT, LIFT + ["contact.mu=0", "contact.augmentation=1e6"],
], ids=lambda o: " ".join(o))
def test_extreme_values_converge(overrides):
    scene = scene_module.load("paper", BASE + overrides)
    result = simulate(scene, comm=MPI.COMM_SELF, progress=False, keep_tables=True)
    scale = max(1.0, max(abs(t["reaction_nu"]).max() for t in result.tables))
    for table in result.tables:
        roller = table["x"][:, 0] > 1.0 - 1e-12
        assert_contact_conditions(table, scene["contact"]["g"], 1e-9 * scale, roller,
                                  direction_tol=1e-6 * scale)


def test_known_failure_stops_clearly():
    """docs/extremes.md: friction, separation and r = 1e6 (stiffness 100) make Newton cycle;
    the run must stop with the step and a likely cause, not return a wrong answer."""
    scene = scene_module.load("paper", ["geometry.cells=[16, 16]", "output.probes=[]",
                                        "contact.augmentation=1e6"] + LIFT)
    with pytest.raises(NewtonFailure) as err:
        simulate(scene, comm=MPI.COMM_SELF, progress=False)
    assert "step to t =" in str(err.value) and "likely cause" in str(err.value)
