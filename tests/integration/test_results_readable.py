"""Results a reader can follow without the code list: the contact states by name in the
contact table and in contact_nodes.csv, with the columns docs/running.md lists."""
import csv
import re

import numpy as np
import pytest
from mpi4py import MPI

from contactvisco import load_scene, solve
from contactvisco.fem.contact_state import STATUSES, STICK_SLIP_STATES
from helpers import ROOT

COMM = MPI.COMM_WORLD
OVERRIDES = dict(contact={"mu": 0.4}, time={"steps": 3}, geometry={"cells": [8, 8]},
                 output={"figures": False, "checkpoint": False})


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """The paper's scene with friction, written to a folder shared by the ranks."""
    out = COMM.bcast(str(tmp_path_factory.mktemp("readable")) if COMM.rank == 0 else None)
    result = solve(load_scene("paper", **OVERRIDES), out=out)
    return result, out


def test_contact_states_have_names_next_to_their_codes(run):
    result, _ = run
    table = result.contact[-1]
    # The integer codes stay (demos and tests compare them with numbers).
    assert table["status"].dtype.kind == "i" and table["friction"].dtype.kind == "i"
    assert list(table["status_name"]) == [STATUSES[c] for c in table["status"]]
    assert list(table["friction_name"]) == [STICK_SLIP_STATES[c] for c in table["friction"]]
    # A real check: the final state has nodes separated, in compliance and at the bound,
    # and the counts of the names are the run's status counts.
    counts = {name: int(np.sum(table["status_name"] == name)) for name in STATUSES}
    assert counts == result.final["status_counts"] and min(counts.values()) > 0
    assert "slip" in set(table["friction_name"])


def test_contact_csv_has_the_documented_columns_and_state_names(run):
    result, out = run
    if COMM.rank != 0:
        return
    with open(f"{out}/contact_nodes.csv", newline="") as f:
        rows = list(csv.reader(f))
    header, body = rows[0], rows[1:]
    # docs/running.md's output-folder row lists the columns in order.
    doc = (ROOT / "docs" / "running.md").read_text()
    line = next(text for text in doc.splitlines() if text.startswith("| `contact_nodes.csv`"))
    columns = line.split("in the columns")[1].split(":")[0]
    documented = re.findall(r"`([a-z_]+)`", columns)
    assert [c for c in documented if c != "z"] == header        # a 2D scene: no z
    last = [row for row in body if int(row[0]) == len(result.steps) - 1]
    table = result.contact[-1]
    assert [row[header.index("status")] for row in last] == list(table["status_name"])
    assert [row[header.index("friction")] for row in last] == list(table["friction_name"])
    assert np.allclose([float(row[header.index("u_nu")]) for row in last], table["u_nu"],
                       rtol=0, atol=1e-15)
