"""The multi-node recipe of docs/parallel.md on one machine: `mpirun --hostfile` with two slots
on localhost runs the command-line program on 2 ranks; its contact table, probes and status
counts agree with a 1-rank run to 1e-10, its XDMF/HDF5 output holds the whole mesh, each rank
wrote its own checkpoint part, and the figure snapshots (a gather of the whole mesh on rank 0)
are skipped above output.snapshot_max_nodes."""
import csv
import json
import os
import pathlib
import shutil
import subprocess
import sys
import xml.etree.ElementTree as ElementTree

import numpy as np
import pytest
from mpi4py import MPI

from contactvisco.output import read_summary

pytestmark = [
    pytest.mark.skipif(MPI.COMM_WORLD.size > 1,
                       reason="starts its own (MPI) processes; run on one rank"),
    pytest.mark.skipif(shutil.which("mpirun") is None, reason="no mpirun"),
]

CELLS = (16, 12)
# 221 nodes: above output.snapshot_max_nodes, so no rank gathers the whole mesh for figures.
SCENE = ["paper", "--set", f"geometry.cells=[{CELLS[0]}, {CELLS[1]}]", "--set", "time.steps=4",
         "--set", "output.snapshot_max_nodes=100", "--quiet"]
ENV = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1")
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
    hosts.write_text("localhost slots=2\n")
    single, multi = tmp_path / "np1", tmp_path / "np2"
    one = subprocess.run(program() + ["run", *SCENE, "--out", str(single)], env=ENV,
                         capture_output=True, text=True, timeout=300)
    assert one.returncode == 0, one.stderr
    two = subprocess.run(["mpirun", "--hostfile", str(hosts), "-n", "2", *program(), "run",
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

    # The XDMF of the 2-rank run describes the whole mesh at every step, and the HDF5 file
    # is large enough to hold every array it names (8 bytes per number).
    nodes, cells = (CELLS[0] + 1) * (CELLS[1] + 1), 2 * CELLS[0] * CELLS[1]
    root = ElementTree.parse(multi / "solution.xdmf").getroot()
    grid = root.find("Domain/Grid")
    assert grid.find("Topology").get("NumberOfElements") == str(cells)
    assert grid.find("Geometry/DataItem").get("Dimensions") == f"{nodes} 2"
    items = root.findall(".//DataItem")
    times = {t.get("Value") for t in root.iter("Time")}
    assert times == {"0", "0.25", "0.5", "0.75", "1"}
    for item in items:
        assert item.get("Dimensions").split()[0] in (str(nodes), str(cells)), item.text
        assert item.text.startswith("solution.h5:")
    size = sum(8 * np.prod([int(n) for n in item.get("Dimensions").split()]) for item in items)
    assert (multi / "solution.h5").stat().st_size >= size
    assert len(items) == len(ElementTree.parse(single / "solution.xdmf").findall(".//DataItem"))
    # The mesh in the HDF5 file, read back on one process: every node and cell, once.
    from dolfinx import io
    with io.XDMFFile(MPI.COMM_SELF, str(multi / "solution.xdmf"), "r") as f:
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
