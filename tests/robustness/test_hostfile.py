"""The multi-node recipe of docs/parallel.md on one machine: `mpirun --hostfile` with two slots
on localhost runs the command-line program on 2 ranks; its contact table, probes and status
counts agree with a 1-rank run to 1e-10, its XDMF/HDF5 output holds the whole mesh, each rank
wrote its own checkpoint part, and the figure snapshots (a gather of the whole mesh on rank 0)
are skipped above output.snapshot_max_nodes."""
import csv
import json
import pathlib
import subprocess
import sys

import numpy as np
import pytest
from mpi4py import MPI

from contactvisco.io import launcher
from contactvisco.io.h5read import check_xdmf
from contactvisco.io.output import read_summary
from helpers import mpi_env

pytestmark = [
    pytest.mark.mpi, pytest.mark.slow, pytest.mark.processes,
    pytest.mark.skipif(MPI.COMM_WORLD.size > 1,
                       reason="starts its own (MPI) processes; run on one rank"),
    pytest.mark.skipif(not launcher.mpi_launcher(), reason="no MPI launcher"),
]

CELLS = (16, 12)
# 221 nodes: above output.snapshot_max_nodes, so no rank gathers the whole mesh for figures.
SCENE = ["paper", "--set", f"geometry.cells=[{CELLS[0]}, {CELLS[1]}]", "--set", "time.steps=4",
         "--set", "output.snapshot_max_nodes=100", "--quiet"]
# Two slots in the hostfile: the recipe must run without Open MPI's oversubscription.
ENV = mpi_env(oversubscribe=False)
VALUES = ("x", "y", "u_nu", "gap", "u_tau", "reaction_nu", "reaction_tau", "friction_bound")


def program():
    """The venv's console script, as in the recipe (or the module if it is not installed)."""
    script = pathlib.Path(sys.executable).parent / "contactvisco"
    return [str(script)] if script.exists() else [sys.executable, "-m", "contactvisco"]


def rows(folder):
    with open(folder / "contact_nodes.csv", newline="") as f:
        return list(csv.DictReader(f))


def test_hostfile_run_matches_one_rank(tmp_path):
    hosts = tmp_path / "hosts"
    hosts.write_text(launcher.hostfile_line("localhost", 2) + "\n")
    single, multi = tmp_path / "np1", tmp_path / "np2"
    one = subprocess.run(program() + ["run", *SCENE, "--out", str(single)], env=ENV,
                         capture_output=True, text=True, timeout=300)
    assert one.returncode == 0, one.stderr
    two = subprocess.run([*launcher.mpi_launcher(), "--hostfile", str(hosts), "-n", "2",
                          *program(), "run",
                          *SCENE, "--out", str(multi)], env=ENV, capture_output=True,
                         text=True, timeout=300)
    assert two.returncode == 0, two.stderr

    # The same answer: every contact node of every step, the probes, the status counts.
    a, b = read_summary(multi), read_summary(single)
    assert (a["ranks"], b["ranks"]) == (2, 1)
    assert len(a["steps"]) == len(b["steps"]) == 5
    for sa, sb in zip(a["steps"], b["steps"]):
        assert sa["status_counts"] == sb["status_counts"]
        for pa, pb in zip(sa["probes"], sb["probes"]):
            assert np.max(np.abs(np.array(pa["u"]) - np.array(pb["u"]))) < 1e-10
    ra, rb = rows(multi), rows(single)
    assert len(ra) == len(rb) == 5 * (CELLS[0] + 1)
    for x, y in zip(ra, rb):
        assert x["step"] == y["step"] and x["status"] == y["status"]
        for key in VALUES:
            assert abs(float(x[key]) - float(y[key])) < 1e-10, key

    # The XDMF of the 2-rank run describes the whole mesh at every step, and every array it
    # names reads back from the step's HDF5 file with that shape.
    nodes, cells = (CELLS[0] + 1) * (CELLS[1] + 1), 2 * CELLS[0] * CELLS[1]
    series = check_xdmf(multi / "solution.xdmf")
    assert [t for t, _ in series] == [0.0, 0.25, 0.5, 0.75, 1.0]
    for _, arrays in series:
        assert arrays["topology"].shape == (cells, 3) and arrays["geometry"].shape == (nodes, 2)
        assert arrays["u"].shape == (nodes, 3) and arrays["sigma"].shape == (cells, 9)
    single_series = check_xdmf(single / "solution.xdmf")
    assert [sorted(a) for _, a in single_series] == [sorted(a) for _, a in series]
    # The same displacement field, matched by node position (the node order depends on the
    # partition).
    for (_, a2), (_, a1) in zip(series, single_series):
        key2 = np.lexsort(np.round(a2["geometry"] * 1e6).T)
        key1 = np.lexsort(np.round(a1["geometry"] * 1e6).T)
        assert np.max(np.abs(a2["u"][key2] - a1["u"][key1])) < 1e-10
    # The mesh in the HDF5 file, read back on one process: every node and cell, once.
    from dolfinx import io
    with io.XDMFFile(MPI.COMM_SELF, str(multi / "solution" / "step-000004.xdmf"), "r") as f:
        mesh = f.read_mesh(name="mesh")
    assert mesh.topology.index_map(2).size_global == cells
    assert mesh.geometry.x.shape[0] == nodes
    points = np.round(mesh.geometry.x[:, :2] * np.array(CELLS)).astype(int)
    assert len({tuple(p) for p in points}) == nodes
    assert points.min(axis=0).tolist() == [0, 0] and points.max(axis=0).tolist() == list(CELLS)

    # The figure snapshots were skipped, with a note; the contact figures were drawn.
    assert not (multi / "snapshots.npz").exists()
    assert any("221 nodes > output.snapshot_max_nodes = 100" in note for note in a["notes"])
    assert (multi / "contact_reactions.png").stat().st_size > 0

    # Each rank wrote its own part of the last checkpoint.
    meta = json.loads((multi / "checkpoint" / "meta.json").read_text())
    assert meta["ranks"] == 2 and meta["count"] == 5
    for part in meta["parts"]:
        assert (multi / "checkpoint" / part["file"]).stat().st_size > 0
    assert len({part["file"] for part in meta["parts"]}) == 2
