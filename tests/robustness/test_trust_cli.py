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


#: A user's scene file: a layer 1 thick, its top held, on a cylinder of radius 1 below.
LAYER = """name = "layer"
[geometry]
type = "gmsh"
script = "rectangle"
parameters = {{length = 2.0, height = 1.0, h = 0.2, h_bottom = 0.05}}
[material]
model = "plane_strain"
E = 200.0
nu = 0.3
[[dirichlet]]
boundary = "top"
[contact]
boundary = "bottom"
g = 0.0
mu = 0.0
augmentation = 200.0
[obstacle]
shape = "cylinder"
centre = [1.0, {centre}]
radius = 1.0
{motion}
[time]
T = 1.0
steps = 4
[output]
probes = []
xdmf = false
"""


@pytest.mark.parametrize("centre, motion, extra, code, key, words, kept", [
    (-1.0, "force_components = [1]\nforce = ['-0.1 * t']", [], 2, "obstacle.force",
     "pulls the obstacle away", 1),
    (-1.0, "force_components = [1]\nforce = ['400 * t']", [], 2, "obstacle.force",
     "passes through the body", 2),
    (-1.0, "force_components = [1]\nforce = ['80 * t']",
     ["time.steps=1", "solver.max_cuts=0", "solver.petsc_options.snes_max_it=2"], 3,
     "obstacle.force", "did not converge to the prescribed force [80.0] at t = 1", 1),
    (-0.5, "displacement = [0.0, '1e-3 * t']", [], 2, "obstacle.centre",
     "the deepest by 0.5 at (1, 0)", 0),
])
def test_force_control_and_penetration_on_the_command_line(tmp_path, centre, motion, extra,
                                                          code, key, words, kept):
    """A user's scene file run from another folder: the exit code, the key and the cause, no
    traceback, the steps before kept (t = 0, and t = 0.25 when the force was carried there),
    nothing written outside --out; check refuses the penetration too."""
    folder, work = tmp_path / "scene", tmp_path / "work"
    folder.mkdir()
    work.mkdir()
    (folder / "layer.toml").write_text(LAYER.format(centre=centre, motion=motion))
    before = listing(tmp_path)
    out = work / "out"
    proc = run_cli("run", folder / "layer.toml", "--out", out, *sets(extra), cwd=work)
    assert proc.returncode == code, proc.stderr
    assert key in proc.stderr and words in proc.stderr, proc.stderr
    assert "Traceback" not in proc.stderr
    outside = listing(tmp_path) - before
    assert all(p == "work/out" or p.startswith("work/out/") for p in outside), outside
    written = (out / "steps.jsonl").read_text().splitlines() if kept else []
    assert len(written) == kept
    if key == "obstacle.centre":
        check = run_cli("check", folder / "layer.toml", cwd=work)
        assert check.returncode == 2 and words in check.stderr, check.stderr


def test_whole_relaxation_function_on_the_command_line(tmp_path):
    """--set 'viscoelastic.shear={...moduli...}' over a scene whose shear has fractions:
    check passes (it was refused: 'unknown scene key viscoelastic.shear.moduli'), and show
    prints the new table."""
    shear = "viscoelastic.shear={instantaneous=0.4, tau=[1.0], moduli=[0.1]}"
    proc = run_cli("show", "sphere_creep", "--set", shear, cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert "moduli = [0.1]" in proc.stdout and "fractions" not in proc.stdout, proc.stdout
    proc = run_cli("check", "sphere_creep", "--set", shear, "--set",
                   "geometry.parameters.h_contact=0.05", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
