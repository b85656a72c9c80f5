"""Bounded work and signals outside the time loop: the estimated output is said before the
first step and refused above output.max_bytes unless --allow-large-output; SIGINT during
start-up and SIGTERM while the figures are drawn end the command at once with one line and
128 + the signal number, never a traceback."""
import signal
import subprocess
import sys
import time

import pytest
from mpi4py import MPI

from contactvisco import api
from contactvisco.errors import SceneError
from helpers import ENV, read_steps, run_cli

pytestmark = [pytest.mark.processes,
              pytest.mark.skipif(MPI.COMM_WORLD.size > 1, reason="runs the command line")]

SMALL = ["--set", "time.steps=3", "--set", "geometry.cells=[6, 6]"]


def test_output_above_the_limit_is_refused_before_the_first_step(tmp_path):
    out = tmp_path / "run"
    proc = run_cli("run", "paper", "--out", out, *SMALL, "--set", "output.max_bytes=1e4")
    assert proc.returncode == 2, proc.stderr
    assert "output.max_bytes: the run would write about" in proc.stderr
    assert "--allow-large-output" in proc.stderr and "Traceback" not in proc.stderr
    assert not (out / "steps.jsonl").exists()
    allowed = run_cli("run", "paper", "--out", out, *SMALL, "--set", "output.max_bytes=1e4",
                      "--allow-large-output", "--overwrite", "--set", "output.figures=false")
    assert allowed.returncode == 0, allowed.stderr
    header = allowed.stdout.splitlines()[1]
    estimate = float(header.split("output about ")[1].split()[0]) * {
        "kB": 1e3, "MB": 1e6, "GB": 1e9}[header.split("output about ")[1].split()[1]]
    assert len(read_steps(out)) == 4
    written = sum(p.stat().st_size for p in out.rglob("*") if p.is_file()
                  and "checkpoint" not in p.parts and p.suffix not in (".png", ".npz"))
    assert estimate > 1e4 and 0.3 < written / estimate < 3, (written, estimate)


def test_the_limit_applies_to_the_api_and_only_when_writing(tmp_path):
    scene = api.load_scene("paper", time={"steps": 2}, geometry={"cells": [4, 4]},
                           output={"max_bytes": 1000, "figures": False})
    with pytest.raises(SceneError, match="output.max_bytes: the run would write about"):
        api.solve(scene, out=tmp_path / "api")
    assert len(api.solve(scene).steps) == 3          # nothing written: nothing to bound


@pytest.mark.parametrize("value", ["0", "-1", "nan", "'big'", "true"])
def test_output_max_bytes_values(value):
    with pytest.raises(SceneError, match="output.max_bytes must be a number of bytes > 0, "
                                         "or inf"):
        api.load_scene("paper", sets=[f"output.max_bytes={value}"])
    assert api.load_scene("paper", sets=["output.max_bytes=inf"])["output"]["max_bytes"] == \
        float("inf")


def _start(args):
    """The command line in a child whose SIGINT is not ignored (as in a terminal)."""
    return subprocess.Popen([sys.executable, "-m", "contactvisco", *map(str, args)], env=ENV,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))


def _args(command, out):
    return {"run": ["run", "paper", "--out", out, *SMALL, "--quiet"],
            "check": ["check", "paper"], "plot": ["plot", out]}[command]


@pytest.fixture(scope="module")
def durations(tmp_path_factory):
    """Each command's wall time on this machine, measured once: the signals below are sent at
    fractions of it, so that they fall inside the command on an idle machine and a loaded one."""
    out = tmp_path_factory.mktemp("durations") / "run"
    measured = {}
    for command in ("run", "plot", "check"):
        tick = time.monotonic()
        assert run_cli(*_args(command, out)).returncode == 0
        measured[command] = time.monotonic() - tick
    return measured


@pytest.mark.parametrize("command", ["run", "check", "plot"])
@pytest.mark.parametrize("fraction", [0.3, 0.55, 0.8])
def test_sigint_during_start_up_is_one_line_and_130(tmp_path, durations, command, fraction):
    out = tmp_path / "run"
    if command == "plot":
        assert run_cli("run", "paper", "--out", out, *SMALL).returncode == 0
    proc = _start(_args(command, out))
    time.sleep(fraction * durations[command])
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=60)
    if proc.returncode == 0:
        pytest.skip(f"{command} ended before the signal")
    assert proc.returncode == 130, err
    assert "Traceback" not in err and "PETSC ERROR" not in err, err
    lines = err.strip().splitlines()
    # Whether the signal falls in the start-up, the steps or the figures, it ends the command
    # with that phase's one line.
    assert len(lines) == 1 and lines[0].startswith("contactvisco:"), err
    assert "stopped by SIGINT" in lines[0], err


@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGINT])
def test_a_signal_while_drawing_the_figures_stops_them(tmp_path, signum):
    out = tmp_path / "run"
    times = "[" + ", ".join(f"{i / 20:g}" for i in range(1, 20)) + "]"
    proc = _start(["run", "paper", "--out", out, *SMALL, "--set",
                   f"output.figure_times={times}"])
    for line in proc.stdout:
        if line.startswith("done in"):
            break
    time.sleep(0.3)
    tick = time.time()
    proc.send_signal(signum)
    _, err = proc.communicate(timeout=60)
    assert time.time() - tick < 10
    if proc.returncode == 0:
        pytest.skip("the figures were drawn before the signal")
    assert proc.returncode == 128 + signum, err
    assert "Traceback" not in err
    name = signal.Signals(signum).name
    assert err.strip().splitlines() == [
        f"contactvisco: figures stopped by {name}; the results in {out} are complete; draw "
        f"them with 'contactvisco plot {out}'"], err
    assert len(read_steps(out)) == 4 and (out / "summary.json").exists()


def test_check_says_when_the_output_is_above_the_limit():
    above = run_cli("check", "paper", *SMALL, "--set", "output.max_bytes=1e4")
    assert above.returncode == 0 and "above output.max_bytes = 10.0 kB: the run will be " \
        "refused without --allow-large-output" in above.stdout, above.stdout
    within = run_cli("check", "paper", *SMALL)
    assert within.returncode == 0 and "above output.max_bytes" not in within.stdout
