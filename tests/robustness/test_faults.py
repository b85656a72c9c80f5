"""Faults on 1 and 2 ranks: kill -9 of a real rank process, SIGTERM, an error on one rank
only, a full disk, a second run into a folder in use. Every run ends (2 ranks: within 30 s)
with a clear message and a non-zero exit, leaves every completed step readable, and a restart
completes the time series once. The whole campaign is benchmarks/robustness/reliability.py."""
import os
import signal
import time

import pytest
from mpi4py import MPI

from helpers import (EXIT_S, block_rank0_file, check_folder, end, grow_tmpfs, kill_a_rank,
                     mount_tmpfs, rank_pids, run_paper, start_paper, steps_done, unmount,
                     vtk_read, wait_for)

pytestmark = [pytest.mark.processes,
              pytest.mark.skipif(MPI.COMM_WORLD.size > 1,
                                 reason="starts its own (MPI) processes; run on one rank")]

STEPS = 60
K = 1.0 / STEPS


@pytest.mark.slow
@pytest.mark.parametrize("ranks, victim, at", [
    (1, 0, 7), pytest.param(2, 1, 12, marks=pytest.mark.mpi),
    pytest.param(2, 0, 25, marks=pytest.mark.mpi)])
def test_kill9_of_a_rank_keeps_every_completed_step(tmp_path, ranks, victim, at):
    """kill -9 of one real rank after `at` steps: the job ends, every completed step is in
    the files, and --restart completes the series once."""
    out = tmp_path / "run"
    proc = start_paper(ranks, out, STEPS)
    kill_a_rank(out, proc, ranks, victim, at)
    left = check_folder(out)
    assert left["records"] >= at
    restarted = run_paper(ranks, out, STEPS, 16, "--restart")
    assert restarted.returncode == 0, restarted.stderr
    check_folder(out, complete_steps=STEPS + 1, k=K)
    if ranks == 1:             # the whole series as ParaView's XDMF reader sees it
        seen = vtk_read(out / "solution.xdmf")
        assert seen is None or seen == (STEPS + 1, 1.0, 17 * 17, 17 * 17)


@pytest.mark.slow
@pytest.mark.parametrize("ranks", [1, pytest.param(2, marks=pytest.mark.mpi)])
def test_sigterm_stops_after_a_whole_step_and_a_second_run_is_refused(tmp_path, ranks):
    """While a run holds its folder a second run into it stops at once (exit 2, naming the
    holder); SIGTERM to one rank stops every rank after the same step (exit 143 from the
    ranks, one message), and --restart completes the series."""
    out = tmp_path / "run"
    steps = 400        # still running when the second run has started, even on a loaded machine
    proc = start_paper(ranks, out, steps)
    pids = rank_pids(out, proc, ranks)
    assert wait_for(out, proc, 5)
    tick = time.time()
    second = run_paper(1, out, steps)
    assert second.returncode == 2 and time.time() - tick < EXIT_S
    assert "in use by another run" in second.stderr and str(pids[0]) in second.stderr
    os.kill(pids[-1], signal.SIGTERM)
    code, seconds = end(proc)
    err = (out.parent / "run.err").read_text()
    assert seconds < EXIT_S and code != 0
    if ranks == 1:
        assert code == 128 + signal.SIGTERM
    assert err.count("stopped by SIGTERM after step") == 1, err
    left = check_folder(out)
    assert left["checkpoint"] == left["records"] == left["fields"]   # the step was finished
    restarted = run_paper(ranks, out, steps, 16, "--restart")
    assert restarted.returncode == 0, restarted.stderr
    check_folder(out, complete_steps=steps + 1, k=1.0 / steps)


@pytest.mark.mpi
@pytest.mark.slow
def test_error_on_one_rank_ends_both(tmp_path):
    """A file only rank 0 reads is damaged while rank 1 waits in a collective: rank 0
    prints the error once and aborts the job."""
    out = tmp_path / "run"
    assert run_paper(1, out, 3, 8).returncode == 0
    block_rank0_file(out)
    tick = time.time()
    proc = run_paper(2, out, 3, 8, "--restart")
    assert proc.returncode != 0 and time.time() - tick < EXIT_S + 15   # start-up included
    assert proc.stderr.count("not a readable .npz archive") == 1, proc.stderr
    assert "snapshots.npz" in proc.stderr


@pytest.fixture
def small_disk(tmp_path):
    """A 400 kB tmpfs (root only)."""
    disk = tmp_path / "disk"
    disk.mkdir()
    if not mount_tmpfs(disk, "400k"):
        pytest.skip("cannot mount a tmpfs here (needs root)")
    yield disk
    unmount(disk, check=True)


@pytest.mark.parametrize("ranks", [
    1, pytest.param(2, marks=[pytest.mark.mpi, pytest.mark.slow])])
def test_full_disk_stops_cleanly_and_restarts_after_space_is_freed(small_disk, ranks):
    out = small_disk / "run"
    tick = time.time()
    full = run_paper(ranks, out, 40, 8)
    assert full.returncode == 1 and time.time() - tick < EXIT_S + 15
    assert full.stderr.count("No space left on device") == 1, full.stderr
    left = check_folder(out)
    assert 0 < left["records"] < 41
    grow_tmpfs(small_disk, "20m")
    restarted = run_paper(ranks, out, 40, 8, "--restart")
    assert restarted.returncode == 0, restarted.stderr
    check_folder(out, complete_steps=41, k=1.0 / 40)


def test_earlier_files_need_overwrite_which_never_follows_a_symlink(tmp_path):
    out, outside = tmp_path / "run", tmp_path / "precious"
    outside.mkdir()
    (outside / "data.txt").write_text("keep")
    out.mkdir()
    (out / "checkpoint").symlink_to(outside)
    (out / "notes.txt").write_text("not ours")
    refused = run_paper(1, out, 2, 4)
    assert refused.returncode == 2 and "--overwrite" in refused.stderr
    assert run_paper(1, out, 2, 4, "--overwrite").returncode == 0
    assert (outside / "data.txt").read_text() == "keep"
    assert (out / "notes.txt").read_text() == "not ours"
    assert not (out / "checkpoint").is_symlink()
    check_folder(out, complete_steps=3, k=0.5)
    assert steps_done(out) == 3
