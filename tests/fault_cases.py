"""Running the command under faults (kill -9 of a real rank, signals, full disk, a second run)
and checking what it leaves: shared by tests/test_faults.py (a fast subset) and
benchmarks/reliability.py (the whole campaign)."""
from __future__ import annotations

import csv
import json
import os
import pathlib
import signal
import subprocess
import sys
import time

from contactvisco.io import launcher
from contactvisco.io.h5read import check_xdmf
from contactvisco.io.output import read_summary

ENV = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
           OMPI_MCA_rmaps_base_oversubscribe="1",
           PYTHONPATH=str(pathlib.Path(__file__).resolve().parents[1]))
#: Every 2-rank failure must end the job within this many seconds.
EXIT_S = 30


def command(ranks, out, steps=60, cells=16, *extra):
    base = [sys.executable, "-m", "contactvisco", "run", "paper",
            "--set", f"geometry.cells=[{cells}, {cells}]", "--set", f"time.steps={steps}",
            "--set", "output.figures=false", "--quiet", "--out", str(out), *extra]
    return ([*launcher.mpi_launcher(), "-n", str(ranks)] if ranks > 1 else []) + base


def start(ranks, out, steps=60, cells=16, *extra, log=None):
    """The run as a child process in a session of its own (stdout, stderr to files)."""
    log = pathlib.Path(log or f"{out}.log")
    return subprocess.Popen(command(ranks, out, steps, cells, *extra), env=ENV,
                            start_new_session=True, stdout=open(log.with_suffix(".out"), "w"),
                            stderr=open(log.with_suffix(".err"), "w"))


def run(ranks, out, steps=60, cells=16, *extra, timeout=300):
    return subprocess.run(command(ranks, out, steps, cells, *extra), env=ENV,
                          capture_output=True, text=True, timeout=timeout)


def rank_pids(out, proc, ranks, timeout=120) -> list[int]:
    """The pids of the rank processes, from the lock file the run writes when it starts."""
    deadline = time.time() + timeout
    while time.time() < deadline and proc.poll() is None:
        try:
            pids = json.loads((pathlib.Path(out) / "contactvisco.io.lock").read_text())["pids"]
            if len(pids) == ranks:
                return pids
        except (OSError, ValueError, KeyError):
            pass
        time.sleep(0.02)
    raise RuntimeError(f"the run in {out} did not start (exit {proc.poll()})")


def alive(pid: int, wait_s: float = 5.0) -> bool:
    """Whether process pid still runs (a zombie awaiting its parent does not) after up to
    wait_s seconds."""
    deadline = time.time() + wait_s
    while True:
        try:
            state = pathlib.Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
        except OSError:
            return False
        if state in ("Z", "X"):
            return False
        if time.time() > deadline:
            return True
        time.sleep(0.05)


def steps_done(out) -> int:
    """Whole lines in steps.jsonl (records of completed steps)."""
    try:
        return (pathlib.Path(out) / "steps.jsonl").read_bytes().count(b"\n")
    except OSError:
        return 0


def wait_for(out, proc, steps, timeout=300) -> bool:
    deadline = time.time() + timeout
    while time.time() < deadline and proc.poll() is None:
        if steps_done(out) >= steps:
            return True
        time.sleep(0.005)
    return False


def end(proc, timeout=EXIT_S) -> tuple[int, float]:
    """Wait for the run to end: (exit code, seconds). Kills it (and fails) after timeout."""
    tick = time.time()
    try:
        code = proc.wait(timeout=timeout)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
        raise AssertionError(f"the run did not end within {timeout} s") from None
    return code, time.time() - tick


VTK_READ = """
import sys, vtk
reader = vtk.vtkXdmfReader()
reader.SetFileName(sys.argv[1])
reader.UpdateInformation()
times = reader.GetOutputInformation(0).Get(vtk.vtkStreamingDemandDrivenPipeline.TIME_STEPS())
reader.UpdateTimeStep(times[-1])
grid = reader.GetOutputDataObject(0)
print(len(times), times[-1], grid.GetNumberOfPoints(),
      grid.GetPointData().GetArray("u").GetNumberOfTuples())
"""


def vtk_read(path) -> tuple[int, float, int, int] | None:
    """What VTK's XDMF reader (the one ParaView offers) finds in `path`: number of times, the
    last time, points and u values at it; None without VTK. In a child process: VTK aborts in
    a process that has loaded DOLFINx."""
    proc = subprocess.run([sys.executable, "-c", VTK_READ, str(path)], capture_output=True,
                          text=True, timeout=120)
    if "No module named 'vtk'" in proc.stderr:
        return None
    n, t, points, values = proc.stdout.split()
    return int(n), float(t), int(points), int(values)


def check_folder(out, complete_steps=None, k=None) -> dict:
    """What a run (stopped at any moment) left in `out` is consistent and readable:
    every step record is whole and numbered 0..m-1; solution.xdmf lists each of them once,
    in order, at its time (and at most the one step after them), and every dataset it names
    reads back with its shape; contact_nodes.csv has whole rows of the same steps; the
    checkpoint is at most one step behind the records. With complete_steps, all of them must
    be there, at t = n k."""
    out = pathlib.Path(out)
    if not (out / "summary.json").exists():       # stopped during set-up: nothing written
        assert complete_steps is None and steps_done(out) == 0
        assert not (out / "checkpoint" / "meta.json").exists()
        return {"records": 0, "fields": 0, "csv_steps": 0, "checkpoint": None}
    records = read_summary(out)["steps"]
    m = len(records)
    assert [r["step"] for r in records] == list(range(m)), "step records out of order"
    series = check_xdmf(out / "solution.xdmf") if (out / "solution.xdmf").exists() else []
    times = [t for t, _ in series]
    assert len(times) in (m, m + 1), f"{len(times)} fields for {m} step records"
    assert times[:m] == [r["t"] for r in records], "XDMF times differ from the records"
    assert all(a < b for a, b in zip(times, times[1:])), "a step listed twice"
    for t, arrays in series:
        assert set(arrays) >= {"u", "sigma"}, f"t = {t}: fields {sorted(arrays)}"
    rows = []
    if (out / "contact_nodes.csv").exists():
        with open(out / "contact_nodes.csv", newline="") as f:
            rows = list(csv.DictReader(f))
    steps_in_csv = sorted({int(r["step"]) for r in rows})
    assert steps_in_csv[:m] == list(range(m)) and len(steps_in_csv) <= m + 1
    counts = {}
    for r in rows:
        counts[r["step"]] = counts.get(r["step"], 0) + 1
        assert None not in r.values() and r["status"] in ("separated", "compliance", "bound")
    assert len(set(counts.values())) <= 1, "a step with missing contact rows"
    checkpoint = None
    if (out / "checkpoint" / "meta.json").exists():
        checkpoint = json.loads((out / "checkpoint" / "meta.json").read_text())["count"]
        assert checkpoint in (m - 1, m), (checkpoint, m)
    if complete_steps is not None:
        assert m == complete_steps and len(times) == m
        assert max(abs(t - n * k) for n, t in enumerate(times)) < 1e-12
    return {"records": m, "fields": len(times), "csv_steps": len(steps_in_csv),
            "checkpoint": checkpoint}
