"""Paths and records of an output folder, tried as a hostile user would: real symbolic and
hard links planted where a run or `plot` writes (its files, their temporary names, the field
and checkpoint files, the folders that hold them), FIFOs where a record file should be, record
files cut, removed or edited after a kill -9, a restart onto another mesh through the Python
interface, a run started inside another run's folder, damaged files given to `plot`.

Every case ends with a refusal naming the path (exit 2 on the command line) or an exact
restoration; nothing outside the folder is written or removed, nothing waits for ever."""
import json
import os
import pathlib
import shutil
import subprocess
import time
import zipfile

import numpy as np
import pytest
from mpi4py import MPI

from contactvisco.errors import SceneError
from contactvisco.io import files, lock
from contactvisco.io.output import read_summary
from contactvisco.scene import loader as scene_module
from contactvisco.solver.time_loop import simulate
from helpers import (ENV, EXIT_S, check_folder, cli_command, kill_a_rank, run_cli, run_paper,
                     start_paper)

pytestmark = [pytest.mark.processes,
              pytest.mark.skipif(MPI.COMM_WORLD.size > 1,
                                 reason="starts its own (MPI) processes; run on one rank")]

SELF = MPI.COMM_SELF
#: The small finished run the link and plot cases start from (5 records, 0..4).
SMALL = ["geometry.cells=[4, 4]", "time.steps=4", "output.figure_times=[0.5]"]
LAST = "000004"           # the last step's field files
STATE = "state-000005"    # its checkpoint


def sets(overrides):
    return [a for o in overrides for a in ("--set", o)]


@pytest.fixture(scope="module")
def finished(tmp_path_factory):
    """A finished run of SMALL with figures, snapshots, XDMF and its final checkpoint."""
    out = tmp_path_factory.mktemp("paths") / "finished"
    done = run_cli("run", "paper", *sets(SMALL), "--quiet", "--out", out)
    assert done.returncode == 0, done.stderr
    return out


@pytest.fixture
def copy(finished, tmp_path):
    """A copy of the finished run, and an outside folder with a file that must stay as it
    is ('keep')."""
    run, outside = tmp_path / "run", tmp_path / "outside"
    shutil.copytree(finished, run, symlinks=True)
    outside.mkdir()
    (outside / "victim").write_text("keep")
    return run, outside


def listing(folder: pathlib.Path) -> dict:
    """{relative path: content} of every file below folder (links not followed), but the
    lock file (its content names the last process that took the folder)."""
    return {str(p.relative_to(folder)): (p.read_bytes() if p.is_file() else None)
            for p in sorted(folder.rglob("*")) if p.name != lock.LOCK}


def restart_in_process(run):
    scene = scene_module.load("paper", SMALL)
    return simulate(scene, run, comm=SELF, progress=False, restart=True, overwrite=False)


# ---- the low-level opener ----------------------------------------------------------------


def test_opener_refuses_links_fifos_directories_and_hard_links_for_writing(tmp_path):
    target = tmp_path / "target"
    target.write_text("keep")
    (tmp_path / "link").symlink_to(target)
    os.mkfifo(tmp_path / "fifo")
    (tmp_path / "dir").mkdir()
    os.link(target, tmp_path / "hard")
    tick = time.monotonic()
    for name, mode, words in [("link", "a", "symbolic link"), ("link", "r", "symbolic link"),
                              ("fifo", "r", "FIFO"), ("fifo", "a", "FIFO"),
                              ("dir", "r", "directory"), ("dir", "a", "directory"),
                              ("hard", "a", "hard links"), ("hard", "c", "hard links")]:
        with pytest.raises(files.UnsafeEntry, match=words) as caught:
            files.open_fd(tmp_path / name, mode)
        assert str(tmp_path / name) in str(caught.value)
    assert time.monotonic() - tick < 5                  # nothing waited on the FIFO
    assert files.read_bytes(tmp_path / "hard") == b"keep"  # reading a hard link is harmless
    assert target.read_text() == "keep"
    # A link (or FIFO) under the temporary name is removed, not followed; the file replaced.
    (tmp_path / "new.tmp").symlink_to(target)
    files.replace(tmp_path / "new", "data")
    assert target.read_text() == "keep" and (tmp_path / "new").read_text() == "data"
    assert not os.path.lexists(tmp_path / "new.tmp")
    # A link at the name itself is replaced by the file, its target untouched.
    (tmp_path / "named").symlink_to(target)
    files.replace(tmp_path / "named", "data")
    assert not (tmp_path / "named").is_symlink() and target.read_text() == "keep"


# ---- 1. no write through a planted link: --restart -----------------------------------------

LINKED_FILES = ["summary.json", "summary.json.tmp", "steps.jsonl", "steps.jsonl.tmp",
                "contact_nodes.csv", "contact_nodes.csv.tmp", "solution.xdmf",
                "solution.xdmf.tmp", "snapshots.npz", "snapshots.tmp.npz", "stress.png",
                "contactvisco.io.lock", f"solution/step-{LAST}.h5",
                f"solution/step-{LAST}.xdmf", "checkpoint/meta.json",
                "checkpoint/meta.tmp.json", f"checkpoint/{STATE}/part-0.npz",
                f"checkpoint/{STATE}/part-0.tmp.npz"]


@pytest.mark.parametrize("name", LINKED_FILES + ["solution", f"checkpoint/{STATE}",
                                                 "checkpoint"])
def test_restart_refuses_a_planted_link_and_writes_nothing_outside(copy, name):
    run, outside = copy
    path = run / name
    if path.is_dir():                   # the folder moved outside, a link left in its place
        shutil.move(path, outside / "moved")
        path.symlink_to(outside / "moved")
    else:
        path.unlink(missing_ok=True)
        path.symlink_to(outside / "victim")
    before = listing(outside)
    with pytest.raises(SceneError) as caught:
        restart_in_process(run)
    assert name in str(caught.value) and "symbolic link" in str(caught.value)
    assert listing(outside) == before


def test_restart_refusal_is_exit_2_on_the_command_line(copy):
    run, outside = copy
    (run / "steps.jsonl.tmp").symlink_to(outside / "victim")
    (run / f"solution/step-{LAST}.h5").unlink()
    (run / f"solution/step-{LAST}.h5").symlink_to(outside / "victim")
    done = run_cli("run", "paper", *sets(SMALL), "--quiet", "--out", run, "--restart")
    assert done.returncode == 2 and done.stderr.startswith("contactvisco: error:")
    assert "steps.jsonl.tmp" in done.stderr and f"step-{LAST}.h5" in done.stderr
    assert "Traceback" not in done.stderr and (outside / "victim").read_text() == "keep"


def test_restart_refuses_a_record_file_with_a_second_name(copy):
    """A hard link to steps.jsonl from outside: appending would change the outside name."""
    run, outside = copy
    os.link(run / "steps.jsonl", outside / "steps-copy")
    before = (outside / "steps-copy").read_bytes()
    with pytest.raises(SceneError, match="hard links"):
        restart_in_process(run)
    assert (outside / "steps-copy").read_bytes() == before


def test_links_planted_during_a_run_are_not_written_through(tmp_path):
    """After each step, a link to an outside file is planted where the next step's HDF5
    file goes: the run stops naming it; a link at summary.json.tmp is only removed."""
    outside = tmp_path / "outside"
    outside.mkdir()
    (outside / "victim").write_text("keep")
    out = tmp_path / "run"

    def plant(record):
        n = record["step"] + 1
        (out / "summary.json.tmp").unlink(missing_ok=True)
        (out / "summary.json.tmp").symlink_to(outside / "victim")
        if n == 3:
            (out / f"solution/step-{n:06d}.h5").symlink_to(outside / "victim")

    scene = scene_module.load("paper", SMALL + ["output.figures=false"])
    with pytest.raises(SceneError, match="step-000003.h5.*symbolic link"):
        simulate(scene, out, comm=SELF, progress=False, on_step=plant)
    assert listing(outside) == {"victim": b"keep"}
    # Without the HDF5 link the run ends: summary.json is a regular file, the victim kept.
    shutil.rmtree(out)
    scene = scene_module.load("paper", SMALL + ["output.figures=false", "time.steps=2"])
    simulate(scene, out, comm=SELF, progress=False,
             on_step=lambda record: plant({"step": 5}))
    assert read_summary(out)["final"] is not None
    assert not (out / "summary.json").is_symlink()
    assert listing(outside) == {"victim": b"keep"}


# ---- 1. no write through a planted link: plot ---------------------------------------------


@pytest.mark.parametrize("name, options", [
    ("stress.png", []), ("contact_reactions.png", []), ("probes.png", []),
    ("stress.pdf", ["--format", "pdf"]), ("stress_t0.5.png", ["--times", "0.5"]),
    ("contact_displacements_t1.svg", ["--format", "svg", "--times", "1"])])
def test_plot_refuses_a_link_where_a_figure_goes_before_writing_any(copy, name, options):
    from contactvisco.cli import main
    run, outside = copy
    (run / name).unlink(missing_ok=True)
    (run / name).symlink_to(outside / "victim")
    before = listing(run)
    assert main(["plot", str(run), "--dpi", "20", *options]) == 2
    assert listing(outside) == {"victim": b"keep"}
    assert listing(run) == before                    # no figure written at all


def test_plot_removes_a_link_at_a_temporary_name(copy):
    from contactvisco.cli import main
    run, outside = copy
    (run / "stress.png.tmp").symlink_to(outside / "victim")
    assert main(["plot", str(run), "--dpi", "20"]) == 0
    assert (outside / "victim").read_text() == "keep"
    assert not (run / "stress.png").is_symlink() and (run / "stress.png").stat().st_size > 0


# ---- 2. no hang on a FIFO ------------------------------------------------------------------

FIFO_RESTART = ["steps.jsonl", "contact_nodes.csv", "summary.json", "checkpoint/meta.json",
                f"checkpoint/{STATE}/part-0.npz", "solution/step-000002.xdmf",
                f"solution/step-{LAST}.h5", "snapshots.npz", "contactvisco.io.lock"]


def fifo(path: pathlib.Path):
    path.unlink(missing_ok=True)
    os.mkfifo(path)


@pytest.mark.parametrize("name", FIFO_RESTART)
def test_restart_refuses_a_fifo_at_once(copy, name):
    run, _ = copy
    fifo(run / name)
    tick = time.monotonic()
    done = run_cli("run", "paper", *sets(SMALL), "--quiet", "--out", run, "--restart",
                   timeout=60)
    assert done.returncode == 2 and name in done.stderr and "FIFO" in done.stderr
    assert time.monotonic() - tick < EXIT_S


@pytest.mark.mpi
@pytest.mark.parametrize("name, make", [
    ("steps.jsonl", fifo), (f"checkpoint/{STATE}/part-0.npz", fifo),
    ("contact_nodes.csv", lambda path: (path.unlink(), path.mkdir()))])
def test_restart_refuses_a_fifo_or_folder_on_two_ranks(copy, name, make):
    """Refused by every rank at once, one message (a folder in place of the CSV, which only
    rank 0 writes, ended the job through MPI_Abort before)."""
    run, _ = copy
    make(run / name)
    tick = time.monotonic()
    done = run_cli("run", "paper", *sets(SMALL), "--quiet", "--out", run, "--restart",
                   ranks=2, timeout=60)
    assert done.returncode == 2 and done.stderr.count(name) == 1, done.stderr
    assert time.monotonic() - tick < EXIT_S


@pytest.mark.parametrize("name", ["summary.json", "steps.jsonl", "contact_nodes.csv",
                                  "snapshots.npz"])
def test_plot_refuses_a_fifo_at_once(copy, name):
    run, _ = copy
    fifo(run / name)
    done = subprocess.run(cli_command(["plot", run, "--dpi", "20"]), env=ENV, timeout=60,
                          capture_output=True, text=True)
    assert done.returncode == 2 and name in done.stderr and "FIFO" in done.stderr
    assert "Traceback" not in done.stderr


# ---- 3. restart checks its records against the checkpoint ----------------------------------

KILL_STEPS, KILL_AT = 60, 14


@pytest.fixture(scope="module")
def killed(request, tmp_path_factory):
    """(ranks, a run of the paper scene killed by kill -9 of its last rank after KILL_AT
    steps, checkpoints every 5 steps so that the records run past the checkpoint); the
    tests give the rank count (indirect parametrization), one run per count and module."""
    ranks = request.param
    out = tmp_path_factory.mktemp(f"killed{ranks}") / "run"
    proc = start_paper(ranks, out, KILL_STEPS, 16, "--set", "output.checkpoint_every=5")
    kill_a_rank(out, proc, ranks, ranks - 1, KILL_AT)
    return ranks, out


def restart_killed(ranks, run):
    return run_paper(ranks, run, KILL_STEPS, 16, "--set", "output.checkpoint_every=5",
                     "--restart", timeout=120)


def _cut_lines(path, keep_fraction):
    lines = path.read_bytes().splitlines(keepends=True)
    path.write_bytes(b"".join(lines[:max(1, int(len(lines) * keep_fraction))]))


def _edit_first_digit(path):
    data = bytearray(path.read_bytes())
    at = data.index(b"1")
    data[at] = ord("2")
    path.write_bytes(bytes(data))


DAMAGE = {
    "steps.jsonl cut": ("steps.jsonl", lambda run: _cut_lines(run / "steps.jsonl", 0.5)),
    "steps.jsonl removed": ("steps.jsonl", lambda run: (run / "steps.jsonl").unlink()),
    "steps.jsonl emptied": ("steps.jsonl", lambda run: (run / "steps.jsonl").write_bytes(b"")),
    "steps.jsonl edited": ("steps.jsonl", lambda run: _edit_first_digit(run / "steps.jsonl")),
    "contact_nodes.csv cut mid-row": ("contact_nodes.csv", lambda run: os.truncate(
        run / "contact_nodes.csv", (run / "contact_nodes.csv").stat().st_size // 2 + 7)),
    "contact_nodes.csv removed": ("contact_nodes.csv",
                                  lambda run: (run / "contact_nodes.csv").unlink()),
    "solution.xdmf cut": ("solution.xdmf", lambda run: os.truncate(run / "solution.xdmf", 300)),
    "a listed step file removed": ("step-000003.h5",
                                   lambda run: (run / "solution/step-000003.h5").unlink()),
}


# Every damage on 1 rank; on 2 ranks the two whose refusal reads a file on rank 0 partly (the
# other cases take the same path on rank 0 as on one rank).
KILLED_CASES = [pytest.param(1, case, id=f"1-{case}") for case in sorted(DAMAGE)] + [
    pytest.param(2, case, id=f"2-{case}", marks=pytest.mark.mpi)
    for case in ("contact_nodes.csv cut mid-row", "steps.jsonl cut")]
KILLED_RANKS = [1, pytest.param(2, marks=pytest.mark.mpi)]


@pytest.mark.slow
@pytest.mark.parametrize("killed, case", KILLED_CASES, indirect=["killed"])
def test_restart_after_a_kill_refuses_records_with_holes(killed, tmp_path, case):
    ranks, out = killed
    run = tmp_path / "run"
    shutil.copytree(out, run)
    name, damage = DAMAGE[case]
    damage(run)
    kept = listing(run)
    done = restart_killed(ranks, run)
    assert done.returncode == 2, done.stderr
    assert name in done.stderr and "Traceback" not in done.stderr
    assert listing(run) == kept                       # nothing changed by the refusal


@pytest.mark.slow
@pytest.mark.parametrize("killed", KILLED_RANKS, indirect=True)
def test_restart_after_a_kill_cuts_records_back_exactly(killed, tmp_path):
    """Records past the checkpoint (a step written after it, and a cut line) are cut back
    to the checkpoint exactly: the restarted series has every step once."""
    ranks, out = killed
    run = tmp_path / "run"
    shutil.copytree(out, run)
    meta = json.loads((run / "checkpoint/meta.json").read_text())
    records = meta["records"]
    assert records["steps.jsonl"]["bytes"] <= (run / "steps.jsonl").stat().st_size
    with open(run / "steps.jsonl", "a") as f:
        f.write('{"step": 999, "t": 9.0, "probes": []}\n{"step": 1000, "t"')
    with open(run / "contact_nodes.csv", "a") as f:
        f.write("999,9.0,0.1,0.2")
    done = restart_killed(ranks, run)
    assert done.returncode == 0, done.stderr
    left = check_folder(run, complete_steps=KILL_STEPS + 1, k=1.0 / KILL_STEPS)
    assert left["records"] == KILL_STEPS + 1
    steps = read_summary(run)["steps"]
    assert [s["step"] for s in steps] == list(range(KILL_STEPS + 1))
    assert not any(line.startswith(b"999,")
                   for line in (run / "contact_nodes.csv").read_bytes().splitlines())


# ---- 4. a restart onto another mesh through the Python interface ---------------------------


def unit_square(n):
    """The unit square of the paper scene made by a caller, tagged left 1, right 2,
    bottom 3, top 4."""
    from dolfinx import mesh as dmesh
    domain = dmesh.create_unit_square(SELF, n, n, dmesh.CellType.triangle)
    fdim = domain.topology.dim - 1
    facets, values = [], []
    for tag, (axis, position) in enumerate([(0, 0.0), (0, 1.0), (1, 0.0), (1, 1.0)], 1):
        found = dmesh.locate_entities_boundary(
            domain, fdim, lambda x, a=axis, p=position: np.isclose(x[a], p))
        facets.append(found)
        values.append(np.full(found.size, tag, dtype=np.int32))
    facets, values = np.concatenate(facets), np.concatenate(values)
    order = np.argsort(facets)
    return domain, dmesh.meshtags(domain, fdim, facets[order], values[order])


def test_api_restart_onto_another_mesh_is_refused(tmp_path):
    """Without memory the unknowns are keyed by node position only: the nodes of a 2 x 2
    mesh are all nodes of the 4 x 4 mesh, and the restart was taken before. Now the mesh is
    checked as the command line checks the scene; the same mesh still restarts."""
    from contactvisco import load_scene, solve
    scene = load_scene("paper", memory={"kernel": "none"}, time={"steps": 3},
                       output={"figures": False, "xdmf": False})
    names = {"left": 1, "right": 2, "bottom": 3, "top": 4}
    out = tmp_path / "run"
    domain, tags = unit_square(4)
    solve(scene, out, mesh=domain, facet_tags=tags, boundaries=names, comm=SELF)
    coarse, coarse_tags = unit_square(2)
    with pytest.raises(SceneError, match="mesh differs.*cells: 32 -> 8"):
        solve(scene, out, mesh=coarse, facet_tags=coarse_tags, boundaries=names, comm=SELF,
              restart=True)
    moved, moved_tags = unit_square(4)
    moved.geometry.x[:, 0] = moved.geometry.x[:, 0] ** 2      # same counts, other positions
    with pytest.raises(SceneError, match="node positions"):
        solve(scene, out, mesh=moved, facet_tags=moved_tags, boundaries=names, comm=SELF,
              restart=True)
    again = solve(scene, out, mesh=domain, facet_tags=tags, boundaries=names, comm=SELF,
                  restart=True)
    assert len(read_summary(out)["steps"]) == 4 and again.final["t"] == 1.0


# ---- 5. a run inside another run's folder --------------------------------------------------


@pytest.mark.parametrize("inner", ["inner", "solution/inner", "checkpoint/deep/inner"])
def test_a_run_inside_another_runs_folder_is_refused(copy, inner):
    run, _ = copy
    before = listing(run)
    scene = scene_module.load("paper", SMALL + ["output.figures=false"])
    with pytest.raises(lock.FolderError, match="inside the output folder of another run"):
        simulate(scene, run / inner, comm=SELF, progress=False)
    assert listing(run) == before


def test_inside_another_run_is_exit_2_on_the_command_line(copy):
    run, _ = copy
    done = run_cli("run", "paper", *sets(SMALL), "--quiet", "--out", run / "solution" / "x")
    assert done.returncode == 2 and "inside the output folder of another run" in done.stderr


def test_overwrite_never_removes_another_runs_folder(tmp_path):
    """Run B lives in y/checkpoint/b (y was no run's folder then); a run into y with
    overwrite would remove y/checkpoint: refused, B intact."""
    y = tmp_path / "y"
    scene = scene_module.load("paper", SMALL + ["output.figures=false"])
    simulate(scene, y / "checkpoint" / "b", comm=SELF, progress=False)
    before = listing(y)
    with pytest.raises(lock.FolderError, match="holds another run's output folder"):
        simulate(scene, y, comm=SELF, progress=False, overwrite=True)
    assert listing(y) == before


# ---- 6. plot on damaged files --------------------------------------------------------------


def _npz_declaring(path, shape):
    """An .npz whose one array declares `shape` (float64) but holds 16 bytes."""
    header = {"descr": "<f8", "fortran_order": False, "shape": shape}
    text = repr(header).encode()
    text += b" " * (63 - (len(text) + 10) % 64) + b"\n"
    data = b"\x93NUMPY\x01\x00" + len(text).to_bytes(2, "little") + text + b"\0" * 16
    with zipfile.ZipFile(path, "w") as archive:
        for name in ("times", "points", "cells", "displacements", "von_mises"):
            archive.writestr(f"{name}.npy", data)


def _deep(n=100000):
    return "[" * n + "]" * n


def _csv_cut_in_middle(run):
    lines = (run / "contact_nodes.csv").read_text().splitlines(keepends=True)
    lines[10] = lines[10][:15] + "\n"
    (run / "contact_nodes.csv").write_text("".join(lines))


def _csv_field(run, index, value):
    """Field `index` of the CSV's third row set to `value`."""
    lines = (run / "contact_nodes.csv").read_text().splitlines(keepends=True)
    fields = lines[3].rstrip("\n").split(",")
    fields[index] = value
    lines[3] = ",".join(fields) + "\n"
    (run / "contact_nodes.csv").write_text("".join(lines))


def _summary_scene(run, value):
    summary = json.loads((run / "summary.json").read_text())
    summary["scene"] = value
    (run / "summary.json").write_text(json.dumps(summary))


def _steps_line(run, text):
    lines = (run / "steps.jsonl").read_text().splitlines(keepends=True)
    lines[1] = text + "\n"
    (run / "steps.jsonl").write_text("".join(lines))


PLOT_DAMAGE = {
    "summary is a list": ("summary.json", lambda r: (r / "summary.json").write_text("[1, 2]")),
    "summary is a number": ("summary.json", lambda r: (r / "summary.json").write_text("3")),
    "summary nested deeply": ("summary.json",
                              lambda r: (r / "summary.json").write_text(_deep())),
    "summary cut": ("summary.json", lambda r: os.truncate(r / "summary.json", 40)),
    "scene is a string": ("summary.json", lambda r: _summary_scene(r, "paper")),
    "a step line nested deeply": ("steps.jsonl", lambda r: _steps_line(r, _deep())),
    "a step line not an object": ("steps.jsonl", lambda r: _steps_line(r, "[1]")),
    "a step line of garbage": ("steps.jsonl", lambda r: _steps_line(r, "{\"step\": 1, \"t")),
    "a CSV row cut in the middle": ("contact_nodes.csv", _csv_cut_in_middle),
    "a CSV value not a number": ("contact_nodes.csv", lambda r: _csv_field(r, 3, "abc")),
    "a CSV status unknown": ("contact_nodes.csv", lambda r: _csv_field(r, -2, "glued")),
    "snapshots declaring 8 TB": ("snapshots.npz",
                                 lambda r: _npz_declaring(r / "snapshots.npz", (10**6, 10**6))),
    "snapshots not a zip": ("snapshots.npz",
                            lambda r: (r / "snapshots.npz").write_bytes(b"PK\x03\x04" * 9)),
    "snapshots without points": ("snapshots.npz", lambda r: np.savez(
        r / "snapshots.npz", times=np.array([1.0]))),
}


@pytest.mark.parametrize("case", sorted(PLOT_DAMAGE))
def test_plot_on_a_damaged_file_is_one_line_naming_it(copy, case, capsys):
    from contactvisco.cli import main
    run, _ = copy
    name, damage = PLOT_DAMAGE[case]
    damage(run)
    capsys.readouterr()
    tick = time.monotonic()
    assert main(["plot", str(run), "--dpi", "20"]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and name in err, err
    assert time.monotonic() - tick < 20


def test_plot_draws_a_folder_cut_by_a_kill(copy, capsys):
    """The last CSV row and the last step line cut as a kill -9 leaves them: drawn from the
    complete steps."""
    from contactvisco.cli import main
    run, _ = copy
    with open(run / "contact_nodes.csv", "a") as f:
        f.write("5,1.25,0.3,1.0,-0.01")
    with open(run / "steps.jsonl", "a") as f:
        f.write('{"step": 5, "t": 1.2')
    assert main(["plot", str(run), "--dpi", "20"]) == 0
    assert (run / "contact_reactions.png").stat().st_size > 0
