"""contactvisco tradeoff at small sizes: the recommended settings reach the target against a
reference finer than the ladder, the files say what was run, the budget stops the climb."""
import json
import math

import pytest
from mpi4py import MPI

from contactvisco.scene import loader as scene_module
from contactvisco.studies import tradeoff
from contactvisco.cli import main

# The paper scene on 4, 8, 16 cells per side, 2/4/8 steps; reference 32 cells, 16 steps.
SMALL = ["geometry.cells=[16,16]", "time.steps=4"]
TARGET = 0.15


@pytest.fixture(scope="module")
def small_trade(tmp_path_factory):
    out = tmp_path_factory.mktemp("trade")
    result = tradeoff.tradeoff("paper", TARGET, SMALL, measure="contact_pressure", levels=3,
                               coarsest=0.25, degrees=(1,), out=out, say=lambda *a: None)
    return result, out


@pytest.mark.convergence
def test_recommendation_meets_target_against_finer_reference(small_trade):
    result, _ = small_trade
    rec = result["recommended"]
    assert rec is not None and rec["estimated_error"] <= TARGET
    # Not the finest rung: the target is met by a cheaper one.
    assert rec["wall_s"] < max(r["wall_s"] for r in result["ladder"])
    reference = tradeoff.finer_reference("paper", SMALL, levels=3, coarsest=0.25)
    assert reference[0] == "geometry.cells=[32,32]" and "time.steps=16" in reference
    check = tradeoff.verify("paper", SMALL, rec["set"], "contact_pressure", reference)
    assert check["error"] <= TARGET
    # The estimate (difference to the finest + Richardson tail) is an upper estimate here.
    assert check["error"] <= rec["estimated_error"]


@pytest.mark.convergence
def test_ladder_estimates_and_front(small_trade):
    result, _ = small_trade
    rows = result["ladder"]
    assert len(rows) == 9                      # 3 mesh levels x 3 step counts
    ref = [r for r in rows if r["reference"]]
    assert len(ref) == 1 and ref[0]["difference"] == 0.0
    assert ref[0]["estimated_error"] == pytest.approx(result["reference"]["self_error"])
    # Space dominates: at 8 steps the difference to the finest falls with the mesh, at an
    # observed order near 1 (contact pressure, P1).
    column = sorted((r for r in rows if r["steps"] == 8), key=lambda r: r["mesh"])
    assert column[0]["difference"] > column[1]["difference"] > 0
    assert 0.5 <= result["reference"]["order_space"] <= 2.0
    for r in rows:       # the front: the runs no other run beats in both time and error
        beaten = any(o["wall_s"] <= r["wall_s"] and o["estimated_error"] <= r["estimated_error"]
                     and (o["wall_s"], o["estimated_error"]) != (r["wall_s"],
                                                                 r["estimated_error"])
                     for o in rows)
        assert r["pareto"] == (not beaten)


def test_files_and_scene_file_round_trip(small_trade):
    result, out = small_trade
    if MPI.COMM_WORLD.rank != 0:
        return                                   # rank 0 writes the files
    saved = json.loads((out / "tradeoff.json").read_text())
    assert set(saved["recommended"]) >= {"set", "estimated_error", "wall_s", "scene_file"}
    assert saved["recommended"]["set"] == result["recommended"]["set"]
    assert "Richardson" in saved["error_estimate"]
    assert (out / "tradeoff.png").stat().st_size > 0
    from_file = scene_module.load(str(out / saved["recommended"]["scene_file"]))
    from_set = scene_module.load("paper", saved["recommended"]["set"])
    from_file["name"] = from_set["name"]
    assert from_file == from_set


def test_budget_stops_the_climb():
    with pytest.raises(tradeoff.TradeoffError, match="budget"):
        tradeoff.tradeoff("paper", TARGET, ["geometry.cells=[8,8]", "time.steps=2"],
                          levels=3, degrees=(1,), budget=1e-9, say=lambda *a: None)


def test_command(tmp_path, capsys):
    out = tmp_path / "t"
    code = main(["tradeoff", "paper", "--target", "0.5", "--levels", "2", "--degrees", "1",
                 "--measure", "probe", "--set", "geometry.cells=[8,8]", "--set",
                 "time.steps=2", "--out", str(out)])
    assert code == 0
    if MPI.COMM_WORLD.rank == 0:
        text = capsys.readouterr().out
        assert "--set geometry.cells=" in text and "recommended" in text
        saved = json.loads((out / "tradeoff.json").read_text())
        assert saved["measure"] == "probe" and saved["recommended"]["estimated_error"] <= 0.5
        assert math.isfinite(saved["recommended"]["wall_s"])
    assert main(["tradeoff", "hertz", "--target", "0.01", "--measure", "contact_pressure",
                 "--degrees", "3"]) == 2


def test_mesh_scaling_touches_mesh_sizes_only():
    """gmsh scripts: h and h_* are mesh sizes, the strip's height is not (ladder and
    presets alike)."""
    creep = scene_module.load("creep")
    lines = tradeoff.settings_lines(creep, 2.0, 100, 1)
    assert "geometry.parameters.h=0.05" in lines and \
        "geometry.parameters.h_bottom=0.025" in lines
    assert not any("height" in line or "length" in line for line in lines)
    fine = scene_module.load("creep", ["preset=accurate"])["geometry"]["parameters"]
    assert fine == dict(creep["geometry"]["parameters"], h=0.05, h_bottom=0.025)
