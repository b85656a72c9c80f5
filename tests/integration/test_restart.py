"""A run killed mid-way leaves complete, readable output for the steps it finished, and a
restart from its checkpoint reaches the same final answer as an uninterrupted run, on 1 and
on 2 ranks (history included: the paper scene has a constant memory kernel)."""
import csv
import json
import os
import signal
import subprocess
import time

import pytest
from mpi4py import MPI

from contactvisco.io.output import read_summary
from helpers import ENV, alive, cli_command, run_cli

pytestmark = [pytest.mark.slow, pytest.mark.processes,
              pytest.mark.skipif(MPI.COMM_WORLD.size > 1,
                                 reason="starts its own (MPI) processes; run on one rank")]

# Enough steps that the run is still going when 20 are written (a step takes about 0.02 s).
STEPS = 200
SCENE = ["paper", "--set", "geometry.cells=[24, 24]", "--set", f"time.steps={STEPS}",
         "--set", "output.figures=false", "--quiet"]


def run(ranks, out, *extra):
    """The scene run into `out` on `ranks` ranks, to its end."""
    return run_cli("run", *SCENE, "--out", out, *extra, ranks=ranks, timeout=600)


def last_step_rows(path):
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    last = max(int(r["step"]) for r in rows)
    return [r for r in rows if int(r["step"]) == last], rows


@pytest.mark.parametrize("ranks", [1, pytest.param(2, marks=pytest.mark.mpi)])
def test_killed_run_restarts_to_the_same_answer(tmp_path, ranks):
    reference = tmp_path / "reference"
    uninterrupted = run(ranks, reference)
    assert uninterrupted.returncode == 0, uninterrupted.stderr
    out = tmp_path / "killed"
    proc = subprocess.Popen(cli_command(["run", *SCENE, "--out", out], ranks), env=ENV,
                            start_new_session=True, stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)
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
    restart = run(ranks, out, "--restart")
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


@pytest.mark.mpi
def test_restart_checks_the_scene_and_works_on_another_rank_count(tmp_path):
    """The checkpoint is keyed by position, so a 1-rank checkpoint restarts on 2 ranks; a
    restart with another scene is refused. A table kernel (direct sum) restarts too."""
    out = tmp_path / "run"
    table = ["--set", "memory.kernel='table'", "--set", "memory.times=[0.0, 1.0]",
             "--set", "memory.values=[100.0, 50.0]"]
    first = run(1, out, *table)
    assert first.returncode == 0, first.stderr
    other = run(1, out, "--restart", "--set", "contact.mu=0.3", *table)
    assert other.returncode == 2 and "scene differs" in other.stderr
    assert "contact.mu: 0.2 -> 0.3" in other.stderr      # the key that differs, and only it
    assert other.stderr.count("->") == 1
    two = run(2, out, "--restart", *table)
    assert two.returncode == 0, two.stderr
    assert read_summary(out)["final"]["t"] == 1.0
