"""The command line: a short paper run writes every promised file; bad input exits non-zero
with a message and no traceback. Subprocesses are started only on a single rank."""
import csv
import json
import subprocess
import sys

import pytest
from mpi4py import MPI

from contactvisco.io.output import read_summary
from helpers import run_cli

pytestmark = pytest.mark.skipif(MPI.COMM_WORLD.size > 1,
                                reason="starts its own processes; run on one rank")


def cli(*args):
    return run_cli(*args, timeout=600)


def test_run_writes_results(tmp_path):
    out = tmp_path / "paper"
    proc = cli("run", "paper", "--out", str(out), "--set", "geometry.cells=[8, 8]",
               "--set", "time.steps=2", "-snes_max_it", "30")
    assert proc.returncode == 0, proc.stderr
    assert "step    2  t = 1/1" in proc.stdout
    summary = read_summary(out)
    assert [s["t"] for s in summary["steps"]] == [0.0, 0.5, 1.0]
    for step in summary["steps"]:
        assert set(step) >= {"t", "newton_iterations", "residual", "wall_s", "status_counts",
                             "probes"}
        assert set(step["status_counts"]) == {"separated", "compliance", "bound"}
        assert sum(step["status_counts"].values()) == 9     # 9 nodes on an 8-cell edge
        assert len(step["probes"]) == 4 and all(len(p["u"]) == 2 for p in step["probes"])
    assert summary["final"]["t"] == 1.0
    rows = list(csv.DictReader(open(out / "contact_nodes.csv")))
    assert len(rows) == 3 * 9
    assert {r["status"] for r in rows} <= {"separated", "compliance", "bound"}
    for name in ("solution.xdmf", "solution/step-000002.h5", "steps.jsonl", "deformed_mesh.png",
                 "contact_reactions.png", "contact_displacements.png"):
        assert (out / name).stat().st_size > 0, name


@pytest.mark.slow
def test_plot_redraws_every_figure_from_the_files(tmp_path):
    """The run writes its figures from its own output files; `contactvisco plot` redraws
    them (including the pyvista stress rendering, drawn in a child process) after deletion."""
    out = tmp_path / "paper"
    assert cli("run", "paper", "--out", str(out), "--set", "geometry.cells=[6, 6]",
               "--set", "time.steps=2", "--quiet").returncode == 0
    names = {"deformed_mesh.png", "stress.png", "contact_reactions.png",
             "contact_displacements.png", "probes.png"}
    assert names <= {p.name for p in out.glob("*.png")}
    for png in out.glob("*.png"):
        png.unlink()
    proc = cli("plot", str(out))
    assert proc.returncode == 0, proc.stderr
    assert names <= {p.name for p in out.glob("*.png") if p.stat().st_size > 1000}
    assert cli("plot", str(tmp_path)).returncode == 2     # not an output folder


def test_summary_is_strict_json_without_a_bound(tmp_path):
    proc = cli("run", "paper", "--out", str(tmp_path), "--set", "geometry.cells=[4, 4]",
               "--set", "time.steps=1", "--set", "contact.g=inf", "--quiet")
    assert proc.returncode == 0, proc.stderr
    text = (tmp_path / "summary.json").read_text()
    summary = json.loads(text, parse_constant=lambda name: pytest.fail(f"{name} in JSON"))
    assert summary["scene"]["contact"]["g"] == "inf"
    assert summary["final"]["status_counts"]["bound"] == 0


def test_unstable_time_step_is_refused_unless_allowed(tmp_path):
    """k alpha (1 + nu) / E = 2.6 >= 1 with the paper's rule: refused before anything is built
    (exit 2, naming the key); with time.allow_unstable = true it runs, warned."""
    unstable = ["--set", "geometry.cells=[4, 4]", "--set", "time.T=10", "--set", "time.steps=5"]
    proc = cli("run", "paper", "--out", str(tmp_path), *unstable, "--quiet")
    assert proc.returncode == 2 and "unstable here" in proc.stderr and "2.6" in proc.stderr
    assert "time.allow_unstable" in proc.stderr and "Traceback" not in proc.stderr
    assert not (tmp_path / "summary.json").exists()
    proc = cli("run", "paper", "--out", str(tmp_path), *unstable,
               "--set", "time.allow_unstable=true", "--quiet")
    assert proc.returncode == 0, proc.stderr
    assert "unstable here" in proc.stderr and "2.6" in proc.stderr
    assert "unstable" in json.loads((tmp_path / "summary.json").read_text())["warnings"][0]
    proc = cli("run", "paper", "--out", str(tmp_path), *unstable, "--set",
               "time.rule=trapezoid", "--quiet", "--overwrite")
    assert proc.returncode == 0 and "unstable" not in proc.stderr


def test_petsc_options_reach_snes(tmp_path):
    proc = cli("run", "paper", "--out", str(tmp_path), "--set", "geometry.cells=[4, 4]",
               "--set", "time.steps=1", "--quiet", "-snes_monitor")
    assert proc.returncode == 0, proc.stderr
    assert "SNES Function norm" in proc.stdout


@pytest.mark.parametrize("args, words", [
    (("run", "paper", "--set", "contact.stifness=3"), "did you mean 'stiffness'"),
    (("run", "nothing-here"), "not a built-in scene"),
    (("run", "paper", "--set", "material.nu=1.5"), "material.nu must lie in"),
])
def test_bad_input_exits_cleanly(tmp_path, args, words):
    proc = cli(*args, "--out", str(tmp_path))
    assert proc.returncode == 2
    assert words in proc.stderr
    assert "Traceback" not in proc.stderr


def test_show_prints_toml_that_run_reads():
    import tomllib
    proc = cli("show", "hertz", "--set", "time.steps=3")
    assert proc.returncode == 0, proc.stderr
    assert tomllib.loads(proc.stdout)["time"]["steps"] == 3


def test_show_and_check_state_the_time_grid():
    """A logarithmic grid: `show` ends with a comment and `check` prints a line with its
    number of steps and its smallest and largest step (those of the grid itself)."""
    from contactvisco import load_scene
    from contactvisco.model import time_grid
    sets = ["time.grid='logarithmic'", "time.first=0.01", "time.growth=1.5",
            "time.rule='trapezoid'"]
    steps, least, largest = time_grid.summary(load_scene("paper", sets=sets)["time"])
    words = f"{steps} steps, k from {least:.4g} to {largest:.4g}"
    args = [a for m in sets for a in ("--set", m)]
    shown = cli("show", "paper", *args)
    assert shown.returncode == 0, shown.stderr
    assert shown.stdout.rstrip().splitlines()[-1] == f"# time grid (logarithmic): {words}"
    checked = cli("check", "paper", "--set", "geometry.cells=[4, 4]", "--set",
                  "output.probes=[]", *args)
    assert checked.returncode == 0, checked.stderr
    assert f"  time grid: logarithmic, {words}" in checked.stdout.splitlines()
    assert steps == 10 and largest > 30 * least


def test_check_states_what_bounds_the_step_of_each_rule():
    """The paper's rule: its number b; the trapezoid rule: the smallest stiffness of a step
    per mode (lost at k = 1 with alpha = -500); the exponential rule of relaxing terms:
    unconditionally stable."""
    small = ["--set", "geometry.cells=[4, 4]", "--set", "output.probes=[]"]
    lines = {}
    for rule, more in (("paper", []), ("trapezoid", ["memory.alpha=-500.0", "time.steps=1"]),
                       ("exponential", ["memory.kernel='exponential'", "memory.alpha=[-300.0]",
                                        "memory.tau=[0.05]", "time.steps=1"])):
        sets = [a for m in more for a in ("--set", m)]
        proc = cli("check", "paper", *small, "--set", f"time.rule='{rule}'", *sets)
        assert proc.returncode == 0, proc.stderr
        lines[rule] = next(line for line in proc.stdout.splitlines() if "time rule" in line)
    assert "b = k R(0) (1 + nu) / E = 0.13" in lines["paper"]
    assert "b = " not in lines["trapezoid"] and "b = " not in lines["exponential"]
    assert "deviatoric -173 (2 mu = 76.9)" in lines["trapezoid"]
    assert "a step loses its stiffness" in lines["trapezoid"]
    assert "unconditionally stable" in lines["exponential"]


def test_show_into_a_closed_pipe_ends_quietly():
    """`contactvisco show paper | head -1`: no PETSc signal report, no MPI abort."""
    proc = subprocess.run(f"{sys.executable} -m contactvisco show paper --all | head -1",
                          shell=True, capture_output=True, text=True, timeout=120)
    assert proc.stdout == 'name = "paper"\n'
    assert proc.stderr == "", proc.stderr


def test_check_reports_or_refuses_without_solving():
    proc = cli("check", "paper", "--set", "geometry.cells=[8, 8]")
    assert proc.returncode == 0, proc.stderr
    assert "unknowns: u 162, lambda_nu 81, lambda_tau 162" in proc.stdout
    assert "Newton" not in proc.stdout                     # nothing was solved
    bad = cli("check", "paper", "--set", "output.probes=[[2.0, 0.5]]")
    assert bad.returncode == 2
    assert "output.probes[0] = [2.0, 0.5] is outside the body" in bad.stderr
    assert "Traceback" not in bad.stderr
