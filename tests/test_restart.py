"""A run killed mid-way leaves complete, readable output for the steps it finished, and a
restart from its checkpoint reaches the same final answer as an uninterrupted run, on 1 and
on 2 ranks (history included: the paper scene has a constant memory kernel)."""
import csv
import json
import os
import signal
import subprocess
import sys
import time

import pytest
from mpi4py import MPI

from contactvisco.io import launcher
from contactvisco.io.output import read_summary
from fault_cases import alive

pytestmark = pytest.mark.skipif(MPI.COMM_WORLD.size > 1,
                                reason="starts its own (MPI) processes; run on one rank")

# Enough steps that the run is still going when 20 are written (a step takes about 0.02 s).
STEPS = 200
SCENE = ["paper", "--set", "geometry.cells=[24, 24]", "--set", f"time.steps={STEPS}",
         "--set", "output.figures=false", "--quiet"]
ENV = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1")


def command(ranks, out, *extra):
    base = [sys.executable, "-m", "contactvisco", "run", *SCENE, "--out", str(out), *extra]
    return ([*launcher.mpi_launcher(), "-n", str(ranks)] if ranks > 1 else []) + base


def last_step_rows(path):
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    last = max(int(r["step"]) for r in rows)
    return [r for r in rows if int(r["step"]) == last], rows


@pytest.mark.parametrize("ranks", [1, 2])
def test_killed_run_restarts_to_the_same_answer(tmp_path, ranks):
    reference = tmp_path / "reference"
    subprocess.run(command(ranks, reference), check=True, env=ENV, timeout=600,
                   capture_output=True)
    out = tmp_path / "killed"
    proc = subprocess.Popen(command(ranks, out), env=ENV, start_new_session=True,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.time() + 300
    steps = 0
    while time.time() < deadline and proc.poll() is None:
        # Wait for the checkpoint, not the summary: the summary of a step is written before
        # its checkpoint, and a kill between the two restarts from the step before.
        try:
            steps = json.loads((out / "checkpoint" / "meta.json").read_text())["count"]
        except (OSError, ValueError, KeyError):
            steps = 0
        if steps >= 20:
            break
        time.sleep(0.05)
    assert proc.poll() is None, "the run finished before it could be killed"
    # kill -9 of a real rank process (the last one), not of mpirun: the job must end.
    pids = json.loads((out / "contactvisco.io.lock").read_text())["pids"]
    assert len(pids) == ranks
    os.kill(pids[-1], signal.SIGKILL)
    proc.wait(timeout=30)
    assert not any(alive(pid) for pid in pids)
    # What the killed run left is complete and readable for the steps it finished.
    summary = read_summary(out)
    done = len(summary["steps"])
    assert 20 <= done < STEPS + 1 and summary["final"] is None
    _, rows = last_step_rows(out / "contact_nodes.csv")
    assert {int(r["step"]) for r in rows} >= set(range(done))
    # Restart and compare with the uninterrupted run.
    restart = subprocess.run(command(ranks, out, "--restart"), env=ENV, timeout=600,
                             capture_output=True, text=True)
    assert restart.returncode == 0, restart.stderr
    final = read_summary(out)
    expected = read_summary(reference)
    assert len(final["steps"]) == STEPS + 1 and final["restarts"][0]["from_step"] >= 20
    assert final["final"]["status_counts"] == expected["final"]["status_counts"]
    got, _ = last_step_rows(out / "contact_nodes.csv")
    want, _ = last_step_rows(reference / "contact_nodes.csv")
    assert len(got) == len(want) == 25
    for a, b in zip(got, want):
        for key in ("x", "u_nu", "u_tau", "reaction_nu", "reaction_tau"):
            assert abs(float(a[key]) - float(b[key])) < 1e-10, key
        assert a["status"] == b["status"]


def test_restart_checks_the_scene_and_works_on_another_rank_count(tmp_path):
    """The checkpoint is keyed by position, so a 1-rank checkpoint restarts on 2 ranks; a
    restart with another scene is refused. A table kernel (direct sum) restarts too."""
    out = tmp_path / "run"
    table = ["--set", "memory.kernel='table'", "--set", "memory.times=[0.0, 1.0]",
             "--set", "memory.values=[100.0, 50.0]"]
    subprocess.run(command(1, out, *table), check=True, env=ENV, timeout=600,
                   capture_output=True)
    other = subprocess.run(command(1, out, "--restart", "--set", "contact.mu=0.3", *table),
                           env=ENV, timeout=600, capture_output=True, text=True)
    assert other.returncode == 2 and "scene differs" in other.stderr
    assert "contact.mu: 0.2 -> 0.3" in other.stderr      # the key that differs, and only it
    assert other.stderr.count("->") == 1
    two = subprocess.run(command(2, out, "--restart", *table), env=ENV, timeout=600,
                         capture_output=True, text=True)
    assert two.returncode == 0, two.stderr
    assert read_summary(out)["final"]["t"] == 1.0
