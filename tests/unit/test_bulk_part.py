"""The kept cell part of the condensed Newton matrix (condensed.BulkPart) across a uniform time
grid: the steps t_n - t_(n-1) differ in their last bits, and the memory's implicit weight with
them; within condensed.CONSTANTS_RTOL the bulk operator is kept (one assembly for the whole
run after t_0), and the answer is the one with the operator assembled at every such change.
"""
import numpy as np
import pytest
from mpi4py import MPI

from contactvisco.model import time_grid
from contactvisco.scene import loader as scene_module
from contactvisco.solver import condensed
from contactvisco.solver.time_loop import simulate

#: The creep scene (a Prony kernel: its implicit weight depends on the step size), 12 steps.
CREEP = ["time.T=2.4", "time.steps=12", "solver.linear_solver='direct'", "output.figures=false"]


def _counted_assemblies(monkeypatch) -> list:
    """A list that gets the bulk assemblies of the BulkPart after each of its Jacobians."""
    assemblies = []
    assemble_into = condensed.BulkPart.assemble_into

    def counted(self, A, bcs):
        assemble_into(self, A, bcs)
        assemblies.append(self.assemblies)

    monkeypatch.setattr(condensed.BulkPart, "assemble_into", counted)
    return assemblies


def _run(monkeypatch, rtol):
    """The run with CONSTANTS_RTOL = rtol: (result, the most bulk assemblies of a BulkPart)."""
    monkeypatch.setattr(condensed, "CONSTANTS_RTOL", rtol)
    assemblies = _counted_assemblies(monkeypatch)
    scene = scene_module.load("creep", CREEP)
    scene["output"]["probes"] = []
    result = simulate(scene, comm=MPI.COMM_WORLD, progress=False, keep_tables=True)
    return result, max(assemblies)


@pytest.mark.mpi
def test_a_uniform_grid_keeps_one_bulk_operator(monkeypatch):
    scene = scene_module.load("creep", CREEP)
    steps = np.diff(time_grid.times(scene["time"]))
    assert len(set(steps.tolist())) > 1          # the round-off the tolerance is for
    assert np.ptp(steps) <= 1e-13 * steps[0]
    kept, kept_assemblies = _run(monkeypatch, condensed.CONSTANTS_RTOL)
    exact, exact_assemblies = _run(monkeypatch, 0.0)
    # t_0 (no memory weight) and the steps: two operators; one per distinct k otherwise
    assert kept_assemblies == 2 < exact_assemblies
    setups = [[s["preconditioner_setups"] for s in r.steps] for r in (kept, exact)]
    assert sum(setups[0][1:]) < sum(setups[1][1:])
    for a, b in zip(kept.tables, exact.tables):
        for key in ("u_nu", "u_tau", "reaction_nu", "reaction_tau"):
            scale = max(np.max(np.abs(b[key])), 1e-12)
            assert np.max(np.abs(np.asarray(a[key]) - b[key])) <= 1e-10 * scale, key


def test_a_changed_weight_assembles_the_bulk_operator_again(monkeypatch):
    """Beyond the tolerance (another step size) the operator is assembled again, so that a
    step of another size never reuses the old operator: a logarithmic grid's growth."""
    scene = scene_module.load("creep", ["time.T=2.4", "time.grid='logarithmic'",
                                        "time.first=0.1", "time.growth=1.5",
                                        "solver.linear_solver='direct'",
                                        "output.figures=false"])
    scene["output"]["probes"] = []
    assemblies = _counted_assemblies(monkeypatch)
    result = simulate(scene, comm=MPI.COMM_WORLD, progress=False)
    ks = {round(s["k"], 12) for s in result.steps if s["k"] is not None}
    assert max(assemblies) == 1 + len(ks) and len(ks) > 2
