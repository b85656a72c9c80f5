"""The tradeoff study's options at their edges (zero, tiny, negative, not finite, too many
levels): a TradeoffError naming the option before any run, and exit 2 on the command line."""
import math

import pytest
from mpi4py import MPI

from contactvisco.studies import tradeoff
from helpers import run_cli

GOOD = dict(target=0.01, levels=3, coarsest=0.25, degrees=(1, 2), budget=math.inf)

EDGES = [
    ("target", 0.0, "--target must be > 0"),
    ("target", -0.01, "--target must be > 0"),
    ("target", math.nan, "--target must be > 0"),
    ("target", math.inf, "--target must be a relative error between 0 and 1"),
    ("target", 1.0, "--target must be a relative error between 0 and 1"),
    ("levels", 1, "--levels must be an integer from 2 to 8"),
    ("levels", 0, "--levels must be an integer from 2 to 8"),
    ("levels", -2, "--levels must be an integer from 2 to 8"),
    ("levels", 1000, "--levels must be an integer from 2 to 8"),
    ("levels", True, "--levels must be an integer from 2 to 8"),
    ("coarsest", 0.0, "--coarsest must be a finite mesh factor > 0"),
    ("coarsest", -0.25, "--coarsest must be a finite mesh factor > 0"),
    ("coarsest", math.nan, "--coarsest must be a finite mesh factor > 0"),
    ("coarsest", math.inf, "--coarsest must be a finite mesh factor > 0"),
    ("coarsest", 1e-300, "--coarsest: mesh levels 1 and 2 of the ladder are the same mesh"),
    ("coarsest", 1e6, "of the ladder cannot run: geometry.cells"),
    ("degrees", (1, 1), "--degrees must list 1 and/or 2, each once"),
    ("degrees", (), "--degrees must list 1 and/or 2, each once"),
    ("degrees", (3,), "--degrees must list 1 and/or 2, each once"),
    ("budget", 0.0, "--budget must be a number of seconds > 0"),
    ("budget", -1.0, "--budget must be a number of seconds > 0"),
    ("budget", math.nan, "--budget must be a number of seconds > 0"),
]


@pytest.mark.parametrize("option, value, words", EDGES,
                         ids=[f"{o}={v!r}" for o, v, _ in EDGES])
def test_an_option_at_its_edge_is_refused_before_any_run(tmp_path, option, value, words):
    args = dict(GOOD, **{option: value})
    with pytest.raises(tradeoff.TradeoffError, match=words.replace("(", r"\(")):
        tradeoff.tradeoff("paper", out=tmp_path / "t", **args)
    assert not (tmp_path / "t").exists()


def test_the_options_inside_their_edges_pass():
    tradeoff.check_options(1e-12, 2, 1e-3, (2,), 1e-9)
    tradeoff.check_options(0.999, tradeoff.MAX_LEVELS, 4.0, (1, 2), math.inf)


@pytest.mark.skipif(MPI.COMM_WORLD.size > 1, reason="starts its own process; run on one rank")
@pytest.mark.parametrize("args", [["--target", "0"], ["--target", "0.01", "--levels", "0"],
                                  ["--target", "0.01", "--coarsest", "-1"],
                                  ["--target", "0.01", "--budget", "nan"],
                                  ["--target", "0.01", "--degrees", "2,2"]])
def test_the_command_line_exits_2_with_one_line(tmp_path, args):
    proc = run_cli("tradeoff", "paper", "--out", tmp_path / "t", *args, timeout=120)
    assert proc.returncode == 2, proc.stderr
    assert "Traceback" not in proc.stderr and len(proc.stderr.strip().splitlines()) == 1


def test_given_times_are_refused_before_any_run(tmp_path):
    """The ladder scales a grid's density: given times are data it cannot scale, so they
    are refused naming the key, not run on the same grid at every rung."""
    overrides = ["time.grid='times'", "time.times=[0.1, 0.5, 1.0]", "time.rule='trapezoid'"]
    with pytest.raises(tradeoff.TradeoffError, match="time.grid = 'times'"):
        tradeoff.tradeoff("paper", overrides=overrides, out=tmp_path / "t", **GOOD)
    assert not (tmp_path / "t").exists()


def test_the_ladder_scales_a_logarithmic_grids_density():
    """Half, once and twice as dense: first step k_1 / f and f m steps per decade; the rung
    counts the steps of its grid."""
    from contactvisco.model import time_grid
    from contactvisco.scene import loader
    scene = loader.load("paper", ["time.grid='logarithmic'", "time.first=0.01",
                                  "time.per_decade=8", "time.rule='trapezoid'"])
    rungs = [r for r in tradeoff.rungs(scene, 2, 0.5, degrees=(1,)) if r["level"] == 0]
    assert [r["density"] for r in rungs] == [0.5, 1.0, 2.0]
    for rung in rungs:
        given = [line for line in rung["set"] if line.startswith("time.")]
        assert given == [] if rung["density"] == 1.0 else given == [
            f"time.first={0.01 / rung['density']!r}",
            f"time.per_decade={8 * rung['density']!r}"]
        scaled = loader.load("paper", ["time.grid='logarithmic'", "time.first=0.01",
                                       "time.per_decade=8", "time.rule='trapezoid'",
                                       *rung["set"]])
        assert len(time_grid.steps(scaled["time"])) == rung["steps"]
    assert rungs[0]["steps"] < rungs[1]["steps"] < rungs[2]["steps"]
