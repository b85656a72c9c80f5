"""Ranks that disagree: an exception raised by a caller's on_step on one rank only ends every
rank within seconds with one message (the other rank waits in a collective that will never
complete); on every rank it reaches the caller; ranks started with different scenes stop
with one message and exit 2 before building anything."""
import re
import subprocess
import sys
import time

import pytest
from mpi4py import MPI

from helpers import ENV, EXIT_S, cli_command

pytestmark = [pytest.mark.mpi, pytest.mark.processes,
              pytest.mark.skipif(MPI.COMM_WORLD.size > 1,
                                 reason="starts its own MPI jobs; run on one rank")]

SCRIPT = """
import sys
from mpi4py import MPI
from contactvisco import api
scene = api.load_scene("paper", time={"steps": 4}, geometry={"cells": [6, 6]},
                       output={"figures": False})
failing = [int(r) for r in sys.argv[1].split(",")]
out = sys.argv[2] if len(sys.argv) > 2 else None

def on_step(record):
    if MPI.COMM_WORLD.rank in failing and record["step"] == 2:
        raise ValueError("the callback refuses step 2")

try:
    api.solve(scene, out=out, on_step=on_step)
except ValueError as err:
    print(f"caught on rank {MPI.COMM_WORLD.rank}: {err}", flush=True)
    sys.exit(0)
print(f"finished on rank {MPI.COMM_WORLD.rank}", flush=True)
"""


def _launch(tmp_path, *args):
    from contactvisco.io.launcher import mpi_launcher
    script = tmp_path / "on_step.py"
    script.write_text(SCRIPT)
    command = [*mpi_launcher(), "-n", "2", sys.executable, str(script), *map(str, args)]
    tick = time.time()
    proc = subprocess.run(command, env=ENV, capture_output=True, text=True, timeout=120)
    return proc, time.time() - tick


@pytest.mark.parametrize("rank", [0, 1])
@pytest.mark.parametrize("write", [False, True])
def test_on_step_raising_on_one_rank_ends_both(tmp_path, rank, write):
    proc, seconds = _launch(tmp_path, rank, *([tmp_path / "out"] if write else []))
    assert proc.returncode != 0 and seconds < EXIT_S + 15, (seconds, proc.stderr)
    assert proc.stderr.count("ValueError: the callback refuses step 2") == 1, proc.stderr
    assert "on_step.py, line" in proc.stderr and "ending all 2 ranks" in proc.stderr
    assert "caught" not in proc.stdout and "finished" not in proc.stdout
    if write:           # the steps before the failing one are on disk, whole
        lines = (tmp_path / "out" / "steps.jsonl").read_text().splitlines(keepends=True)
        assert 2 <= len(lines) <= 3 and all(line.endswith("\n") for line in lines)


def test_on_step_raising_on_every_rank_reaches_the_caller(tmp_path):
    proc, seconds = _launch(tmp_path, "0,1")
    assert proc.returncode == 0, proc.stderr
    # (MPICH's launcher may join the two ranks' lines)
    assert sorted(re.findall(r"caught on rank \d: the callback refuses step 2",
                             proc.stdout)) == [
        "caught on rank 0: the callback refuses step 2",
        "caught on rank 1: the callback refuses step 2"], proc.stdout


@pytest.mark.parametrize("command", ["run", "check"])
@pytest.mark.parametrize("sets, keys", [
    (("time.steps=4", "time.steps=5"), "time.steps"),
    (("contact.mu=0.1", "geometry.cells=[8, 9]"), "contact.mu, geometry.cells.1"),
])
def test_ranks_given_different_scenes_stop_with_one_message(tmp_path, command, sets, keys):
    """Two ranks started by one launcher with different --set values (MPMD syntax)."""
    from contactvisco.io.launcher import mpi_launcher
    out = tmp_path / "out"
    parts = []
    for value in sets:
        args = [command, "paper", "--set", value, "--set", "geometry.cells=[8, 8]"
                if "cells" not in value else value]
        if command == "run":
            args += ["--out", out, "--quiet"]
        parts += [":", "-n", "1", *cli_command(args)]
    tick = time.time()
    proc = subprocess.run([*mpi_launcher(), *parts[1:]], env=ENV, capture_output=True,
                          text=True, timeout=120)
    assert time.time() - tick < EXIT_S + 15
    assert proc.returncode == 2, proc.stderr
    assert proc.stderr.count("the ranks were given different scenes") == 1, proc.stderr
    assert f"rank(s) 1 differ from rank 0 in {keys}" in proc.stderr, proc.stderr
    assert "Traceback" not in proc.stderr
    assert not (out / "steps.jsonl").exists()
