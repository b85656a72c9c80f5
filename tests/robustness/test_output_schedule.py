"""Output on a schedule ([output] field_every, field_times, checkpoint_every,
checkpoint_seconds): the XDMF fields and the checkpoint are written at the scheduled steps and
at the final one, the records and contact rows at every step; a run killed (kill -9 of a real
rank process) between two checkpoints and restarted has every step once, its fields exactly at
the scheduled steps, and the contact values of an uninterrupted run."""
import csv
import json
import os
import pathlib
import signal

import numpy as np
import pytest
from mpi4py import MPI

from helpers import (HARD_IRONING, end, kill_a_rank, newton_limit, read_steps, run_cli, run_paper,
                     start_paper, wait_for)

from contactvisco.errors import SceneError
from contactvisco.io import checkpoint
from contactvisco.io.h5read import check_xdmf
from contactvisco.scene import loader as scene_module
from contactvisco.solver.time_loop import FieldSchedule, simulate

COMM = MPI.COMM_WORLD
one_rank = pytest.mark.skipif(COMM.size > 1,
                              reason="starts its own (MPI) processes; run on one rank")

#: Neither a multiple of FIELD_EVERY nor of CHECKPOINT_EVERY: the final step is written
#: because it is the final one.
STEPS = 62
FIELD_EVERY, CHECKPOINT_EVERY = 3, 4
SCHEDULE = ("--set", f"output.field_every={FIELD_EVERY}",
            "--set", f"output.checkpoint_every={CHECKPOINT_EVERY}")


def field_steps(out, killed=False) -> list[int]:
    """The steps solution.xdmf lists (every dataset read back), by their time in the
    records; and the step files in solution/ must be exactly those (killed: and perhaps the
    file of one step more, written but not yet listed)."""
    by_time = {r["t"]: r["step"] for r in read_steps(out)}
    listed = [by_time[t] for t, arrays in check_xdmf(pathlib.Path(out) / "solution.xdmf")
              if {"u", "sigma"} <= set(arrays)]
    files = sorted(int(p.stem.split("-")[1]) for p in (pathlib.Path(out) / "solution").glob(
        "step-*.h5"))
    assert files[:len(listed)] == listed and len(files) <= len(listed) + killed, (files, listed)
    return listed


def checkpoint_count(out) -> int | None:
    path = pathlib.Path(out) / "checkpoint" / "meta.json"
    return json.loads(path.read_text())["count"] if path.exists() else None


def contact_values(out) -> np.ndarray:
    """The numeric columns of contact_nodes.csv, one row per step and contact node (the
    status names left out)."""
    with open(pathlib.Path(out) / "contact_nodes.csv", newline="") as f:
        rows = list(csv.reader(f))[1:]

    def number(text):
        try:
            return float(text)
        except ValueError:
            return None
    return np.array([[v for v in map(number, row) if v is not None] for row in rows])


def scheduled(every, steps):
    return sorted(set(range(0, steps + 1, every)) | {steps})


@pytest.mark.processes
@pytest.mark.slow
@one_rank
@pytest.mark.parametrize("ranks, victim, at", [
    (1, 0, 17), pytest.param(2, 1, 22, marks=pytest.mark.mpi)])
def test_kill9_between_checkpoints_then_restart_gives_the_uninterrupted_run(
        tmp_path, ranks, victim, at):
    reference = tmp_path / "reference"
    done = run_paper(ranks, reference, STEPS, 16, *SCHEDULE)
    assert done.returncode == 0, done.stderr
    assert field_steps(reference) == scheduled(FIELD_EVERY, STEPS)
    assert checkpoint_count(reference) == STEPS + 1          # the final state, always

    out = tmp_path / "run"
    proc = start_paper(ranks, out, STEPS, 16, *SCHEDULE)
    kill_a_rank(out, proc, ranks, victim, at)
    m = len(read_steps(out))
    assert at <= m < STEPS + 1
    count = checkpoint_count(out)
    # At the last scheduled step before the records' end (its own checkpoint may be the one
    # the kill stopped).
    assert (count - 1) % CHECKPOINT_EVERY == 0 and m - CHECKPOINT_EVERY <= count <= m
    before = field_steps(out, killed=True)
    assert before == [n for n in scheduled(FIELD_EVERY, STEPS) if n <= m][:len(before)]
    assert len(before) >= len([n for n in scheduled(FIELD_EVERY, STEPS) if n < m])

    restarted = run_paper(ranks, out, STEPS, 16, *SCHEDULE, "--restart")
    assert restarted.returncode == 0, restarted.stderr
    records = read_steps(out)
    assert [r["step"] for r in records] == list(range(STEPS + 1))     # each step once
    assert max(abs(r["t"] - n / STEPS) for n, r in enumerate(records)) < 1e-12
    assert field_steps(out) == scheduled(FIELD_EVERY, STEPS)
    assert checkpoint_count(out) == STEPS + 1
    summary = json.loads((out / "summary.json").read_text())
    assert summary["restarts"] == [{"from_step": count}]

    got, want = contact_values(out), contact_values(reference)
    assert got.shape == want.shape and len(got) % (STEPS + 1) == 0   # every step's rows
    assert np.max(np.abs(got - want)) < 1e-10
    final = slice(-(len(got) // (STEPS + 1)), None)
    assert np.max(np.abs(got[final] - want[final])) < 1e-10


@pytest.mark.processes
@pytest.mark.slow
@one_rank
def test_a_restart_with_another_schedule_drops_the_later_field_files(tmp_path):
    """Killed with fields at every step and a checkpoint every 10, restarted with
    field_every = 5: the field files the killed run wrote after its checkpoint are removed,
    not left unlisted (a later restart would list them)."""
    out = tmp_path / "run"
    proc = start_paper(1, out, STEPS, 16, "--set", "output.checkpoint_every=10")
    assert wait_for(out, proc, 25), "the run ended before the kill"
    os.kill(proc.pid, signal.SIGKILL)
    end(proc)
    count, m = checkpoint_count(out), len(read_steps(out))
    assert count < m and field_steps(out, killed=True)[-1] >= m - 1   # fields after it
    restarted = run_paper(1, out, STEPS, 16, "--set", "output.field_every=5", "--restart")
    assert restarted.returncode == 0, restarted.stderr
    assert field_steps(out) == list(range(count)) + [
        n for n in scheduled(5, STEPS) if n >= count]


@pytest.mark.processes
@pytest.mark.slow
@one_rank
def test_sigterm_checkpoints_the_step_it_stops_after(tmp_path):
    """A stop between two scheduled checkpoints writes one at the step it stops after: the
    restart recomputes nothing."""
    out = tmp_path / "run"
    proc = start_paper(1, out, 400, 16, "--set", "output.checkpoint_every=1000",
                       "--set", "output.field_every=1000")
    assert wait_for(out, proc, 5)
    os.kill(proc.pid, signal.SIGTERM)
    code, _ = end(proc)
    assert code == 128 + signal.SIGTERM
    m = len(read_steps(out))
    assert checkpoint_count(out) == m and field_steps(out) == [0]
    restarted = run_paper(1, out, 400, 16, "--restart")        # every step now
    assert restarted.returncode == 0, restarted.stderr
    assert [r["step"] for r in read_steps(out)] == list(range(401))
    assert field_steps(out) == [0] + list(range(m, 401))


def shared_folder(tmp_path) -> pathlib.Path:
    """One output folder for every rank (tmp_path differs between ranks)."""
    return pathlib.Path(COMM.bcast(str(tmp_path) if COMM.rank == 0 else None)) / "run"


def checkpoints_seen(tmp_path, *overrides, steps=9, scene="paper", base=(), comm=COMM):
    """Run the scene in-process with these [output] overrides: (the checkpoint count found
    at each step, before that step's own checkpoint; the final count; the XDMF steps)."""
    out = shared_folder(tmp_path)
    values = (["geometry.cells=[4, 4]"] if scene == "paper" else []) + [
        f"time.steps={steps}", "output.figures=false", *base, *overrides]
    seen = []
    result = simulate(scene_module.load(scene, values), out=out, comm=comm, progress=False,
                      on_step=lambda record: seen.append(checkpoint_count(out)))
    comm.barrier()
    return seen, checkpoint_count(out), field_steps(out), result


@pytest.mark.mpi
@pytest.mark.parametrize("overrides, expected", [
    ((), lambda n: n or None),                                          # every step
    (("output.checkpoint_seconds=0",), lambda n: n or None),            # 0: off
    (("output.checkpoint_every=4",), lambda n: (n - 1) // 4 * 4 + 1 if n else None),
    (("output.checkpoint_seconds=1e9",), lambda n: None),               # only the final
])
def test_checkpoint_schedule(tmp_path, overrides, expected):
    """Seen from the step observer (before a step's own checkpoint): after step n - 1 the
    checkpoint holds count n when every step has one, the last multiple of 4 plus one with
    checkpoint_every = 4, and nothing with a wall-time interval no run reaches. The final
    state always has its checkpoint. On 2 ranks the wall-time decision is rank 0's."""
    seen, final, fields, _ = checkpoints_seen(tmp_path, *overrides)
    assert seen == [expected(n) for n in range(10)]
    assert final == 10 and fields == list(range(10))


def test_wall_time_schedule_with_a_clock():
    """checkpoint_seconds: due once the interval has passed since the last checkpoint, not
    before; the final state always."""
    now = [0.0]
    schedule = checkpoint.Schedule(MPI.COMM_SELF, seconds=10.0, clock=lambda: now[0])
    due = []
    for step in range(8):
        now[0] += 3.0                       # 3 s a step: 10 s passed after steps 3 and 7
        due.append(schedule.due(step))
        if due[-1]:
            schedule.written()
    assert due == [False, False, False, True, False, False, False, True]
    assert schedule.due(8, final=True) and not schedule.due(8)


def test_field_times_land_on_the_nearest_step_and_the_final_one():
    k = 1.0 / 10
    schedule = FieldSchedule(4, [0.23, 0.5, 1.0], {"T": 1.0, "steps": 10})
    due = [n for n in range(11) if schedule.due(n, n * k)]
    assert due == [0, 2, 4, 5, 8, 10]
    assert not schedule.due(3, 0.25)          # a time between steps (a cut step's half)


@pytest.mark.slow
def test_cut_steps_count_as_accepted_states(tmp_path):
    """The ironing load in 5 large steps (HARD_IRONING) with one Newton iteration fewer than
    its hardest step takes uncut (newton_limit): steps are cut, and field_every,
    checkpoint_every count the accepted states (the records' step numbers, the halves
    included); field_times and the final state fall on the 5 steps' ends. One rank: where
    steps are cut depends on the partition."""
    if COMM.size > 1:
        pytest.skip("one rank: where steps are cut depends on the partition")
    uncut = simulate(scene_module.load("ironing", HARD_IRONING), comm=MPI.COMM_SELF,
                     progress=False)
    limit = newton_limit(r["newton_iterations"] for r in uncut.steps)
    seen, final, fields, result = checkpoints_seen(
        tmp_path, "output.field_every=2", "output.checkpoint_every=3", "output.field_times=[0.4]",
        steps=5, scene="ironing", comm=MPI.COMM_SELF,
        base=HARD_IRONING + [f"solver.petsc_options={{snes_max_it={limit}}}"])
    records = result.steps
    last = len(records) - 1
    assert last > 5 and any(r["cuts"] for r in records)
    at_04 = [r["step"] for r in records if r["t"] == 2 * (1.0 / 5)]
    assert fields == sorted(set(range(0, last + 1, 2)) | set(at_04) | {last})
    assert seen == [(n - 1) // 3 * 3 + 1 if n else None for n in range(last + 1)]
    assert final == last + 1


@pytest.mark.parametrize("value, key, words", [
    ("output.field_every=0", "output.field_every", "an integer >= 1"),
    ("output.field_every=2.5", "output.field_every", "an integer >= 1"),
    ("output.checkpoint_every=true", "output.checkpoint_every", "an integer >= 1"),
    ("output.checkpoint_seconds=-1", "output.checkpoint_seconds", "seconds >= 0"),
    ("output.checkpoint_seconds=nan", "output.checkpoint_seconds", "seconds >= 0"),
    ("output.field_times=[0.5, -0.1]", "output.field_times", "times >= 0"),
    ("output.field_times=[0.5, 3.0]", "output.field_times", "[0, time.T] = [0, 1]"),
    ("output.field_times=0.5", "output.field_times", "a list"),
])
def test_bad_schedules_are_refused_naming_the_key(value, key, words):
    with pytest.raises(SceneError) as err:
        scene_module.load("paper", [value])
    assert err.value.key == key and key in str(err.value) and words in str(err.value)


def test_seconds_and_steps_together_are_refused():
    with pytest.raises(SceneError) as err:
        scene_module.load("paper", ["output.checkpoint_seconds=60",
                                    "output.checkpoint_every=10"])
    assert err.value.key == "output.checkpoint_seconds"
    assert "not both" in str(err.value) and "output.checkpoint_every" in str(err.value)


@one_rank
def test_the_command_line_refuses_a_bad_schedule_with_exit_2(tmp_path):
    proc = run_cli("run", "paper", "--set", "output.field_every=0", "--out", tmp_path / "run")
    assert proc.returncode == 2 and "output.field_every" in proc.stderr
    assert "Traceback" not in proc.stderr and not (tmp_path / "run").exists()
