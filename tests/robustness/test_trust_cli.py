"""Issue 35's classes on the command line (run and check), as a user meets them: a surface
without a direction, a law negative away from x = 0, a key without a meaning, a repeated
component, and the docs' shift table run from another folder. Each refusal exits 2 naming the
key, without a traceback, and nothing is written outside --out."""
import os
import pathlib

import pytest
from mpi4py import MPI

from helpers import run_cli
from shift_example import write_scene

pytestmark = [pytest.mark.processes,
              pytest.mark.skipif(MPI.COMM_WORLD.size > 1,
                                 reason="starts its own (MPI) processes; run on one rank")]

SMALL = ["geometry.cells=[8, 4]", "time.steps=4"]
SURFACE = ["contact.gap=0", "obstacle.shape='surface'", "obstacle.distance='abs(x[1])'",
           "obstacle.displacement=[0.0, '1e-3 * t']"]


def sets(overrides):
    return [a for o in overrides for a in ("--set", o)]


def listing(folder: pathlib.Path) -> set:
    return {str(p.relative_to(folder)) for p in folder.rglob("*")}


@pytest.mark.parametrize("scene, overrides, key, words, steps", [
    ("hertz", SURFACE, "obstacle.distance", "|grad phi| = 0", 0),
    ("paper", SMALL + ["contact.stiffness=0", "contact.g=0.01",
                       "contact.p_nu='2e3 * s * (1 - 6 * x[0] * t)'"],
     "contact.p_nu", "t = 0.25", 1),
    ("paper", SMALL + ["material.hencky_exponent=0.5"], "material.hencky_exponent",
     "law = 'hencky'", None),
    ("paper", SMALL + ["dirichlet.0.components=[0, 0]", "dirichlet.0.value=[0.0, 1.0]"],
     "dirichlet[0].components", "the component 0 twice", None),
])
def test_refused_on_the_command_line(tmp_path, scene, overrides, key, words, steps):
    """run and check: exit 2, the key and the words, no traceback; the run keeps the steps
    before the refused time; nothing is written outside --out."""
    work = tmp_path / "work"
    work.mkdir()
    before = listing(tmp_path)
    out = work / "out"
    proc = run_cli("run", scene, "--out", out, *sets(overrides), cwd=work)
    assert proc.returncode == 2, proc.stderr
    assert key in proc.stderr and words in proc.stderr, proc.stderr
    assert "Traceback" not in proc.stderr
    outside = listing(tmp_path) - before
    assert all(p == "work/out" or p.startswith("work/out/") for p in outside), outside
    if steps is not None and steps > 0:
        records = (out / "steps.jsonl").read_text().splitlines()
        assert len(records) == steps          # t = 0 kept, the run stopped at t = 0.25
    check = run_cli("check", scene, *sets(overrides), cwd=work)
    if steps is None or steps == 0:              # what check can see: before any step
        assert check.returncode == 2 and key in check.stderr, check.stderr
    assert "Traceback" not in check.stderr


def test_docs_shift_table_runs_from_another_folder(tmp_path):
    """The docs' shift_file example through run and check, started from a folder other than
    the scene's."""
    folder = tmp_path / "scene"
    folder.mkdir()
    write_scene(folder)
    check = run_cli("check", folder / "scene.toml", cwd=tmp_path)
    assert check.returncode == 0, check.stderr
    proc = run_cli("run", folder / "scene.toml", "--out", tmp_path / "out", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert len((tmp_path / "out" / "steps.jsonl").read_text().splitlines()) == 3
    assert not os.path.exists(folder / "out")


def test_more_ranks_than_cells_is_refused_once(tmp_path):
    """3 ranks for a mesh of 2 cells: run and check exit 2 with one scene error naming the
    counts, not an internal error."""
    for args in (["check", "paper"], ["run", "paper", "--out", tmp_path / "out"]):
        proc = run_cli(*args, "--set", "geometry.cells=[1, 1]", ranks=3, cwd=tmp_path)
        assert proc.returncode == 2, proc.stderr
        assert "2 cell(s) for 3 MPI ranks" in proc.stderr, proc.stderr
        assert "Traceback" not in proc.stderr and "ValueError" not in proc.stderr
