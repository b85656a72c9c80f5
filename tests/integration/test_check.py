"""`contactvisco show` writes TOML that reads back to the same scene; `contactvisco check`
(api.check) builds a scene, makes the checks a run makes and reports the run's size, without
solving."""
import pathlib
import tomllib

import pytest
from mpi4py import MPI

from contactvisco import api
from contactvisco.errors import SceneError
from contactvisco.io.output import jsonable
from contactvisco.scene import loader as scene_module
from contactvisco.scene.tables import TABLE_LISTS

COMM = MPI.COMM_WORLD


def _normal(scene) -> dict:
    """The scene as plain values, list items with their defaults filled in (they are filled
    on use, so both forms mean the same)."""
    out = jsonable(scene)
    for name, table in TABLE_LISTS.items():
        out[name] = [{**table.defaults(), **item} for item in out[name]]
    return out


def _reload(text: str, folder: pathlib.Path):
    path = folder / f"scene-{COMM.rank}.toml"
    path.write_text(text)
    return scene_module.load(str(path))


@pytest.mark.parametrize("every_value", [False, True], ids=["set", "all"])
@pytest.mark.parametrize("name", scene_module.builtin_names())
def test_show_reads_back_to_the_same_scene(name, every_value, tmp_path):
    scene = api.load_scene(name)
    again = _reload(api.scene_toml(scene, every_value), tmp_path)
    assert _normal(again) == _normal(scene)


def test_show_keeps_overrides_strings_and_special_numbers(tmp_path):
    scene = api.load_scene("paper", contact={"mu": 0.4, "gap": '0.01 * x[0] ** 2'},
                           time={"steps": 7}, solver={"petsc_options": {"ksp_rtol": 1e-12}},
                           description='a "quoted" \u00e9 description')
    text = api.scene_toml(scene)
    again = _reload(text, tmp_path)
    assert _normal(again) == _normal(scene)
    set_only = tomllib.loads(text)
    # what the scene sets, not the defaults it leaves alone
    assert set_only["contact"]["mu"] == 0.4 and "slip" not in set_only["contact"]
    assert "discretization" not in set_only
    assert "slip" in tomllib.loads(api.scene_toml(scene, every_value=True))["contact"]


@pytest.mark.mpi
def test_check_counts_the_unknowns_of_a_box():
    """P1 on an nx x ny box: d (nx+1)(ny+1) displacement unknowns, nx + 1 contact nodes on
    the bottom edge, the multipliers on every vertex (fixed off the contact boundary)."""
    nx, ny = 6, 4
    report = api.check(api.load_scene("paper", geometry={"cells": [nx, ny]}))
    vertices = (nx + 1) * (ny + 1)
    assert report["vertices"] == vertices
    assert report["cells"] == 2 * nx * ny
    assert report["unknowns"] == {"u": 2 * vertices, "lambda_nu": vertices,
                                  "lambda_tau": 2 * vertices}
    assert report["contact_nodes"] == nx + 1
    assert not report["unstable"]


def test_check_assembles_only_what_the_scene_needs():
    """No friction multiplier at mu = 0, no history without memory."""
    report = api.check(api.load_scene("paper", geometry={"cells": [4, 4]}, contact={"mu": 0.0},
                                      memory={"kernel": "none"}))
    assert set(report["unknowns"]) == {"u", "lambda_nu"}
    assert report["history_bytes"] == 0


def test_check_sees_the_memory_grow_only_for_a_direct_sum():
    """A recursive kernel stores a fixed number of strain fields; a table kernel stores every
    step's strain (eq 19 summed directly)."""
    def history(memory, steps):
        scene = api.load_scene("paper", geometry={"cells": [4, 4]}, memory=memory,
                               time={"steps": steps})
        return api.check(scene)["history_bytes"]
    constant = {"kernel": "constant", "alpha": 100.0}
    table = {"kernel": "table", "times": [0.0, 1.0], "values": [100.0, 50.0]}
    assert history(constant, 10) == history(constant, 40) > 0
    assert history(table, 40) / history(table, 10) == pytest.approx(41 / 11)


@pytest.mark.mpi
@pytest.mark.parametrize("every", [1, 3])
def test_check_estimates_the_output_of_a_run(tmp_path, every):
    """The estimated size of the folder's records (fields at the steps of the schedule,
    contact table and step records at every step) within 15 % of what a run writes."""
    scene = api.load_scene("paper", geometry={"cells": [8, 8]}, time={"steps": 6},
                           output={"figures": False, "field_every": every})
    estimate = api.check(scene)["output_bytes"]
    out = tmp_path / "run"
    out = pathlib.Path(COMM.bcast(str(out), root=0))
    api.solve(scene, out=out)
    if COMM.rank == 0:
        written = sum(p.stat().st_size for p in (out / "solution").iterdir())
        written += sum((out / name).stat().st_size
                       for name in ("contact_nodes.csv", "steps.jsonl", "solution.xdmf"))
        assert estimate == pytest.approx(written, rel=0.15)


@pytest.mark.parametrize("change, words", [
    ({"output": {"probes": [[5.0, 5.0]]}}, "output.probes[0] = [5.0, 5.0] is outside the body"),
    ({"contact": {"mu": 0.0}, "dirichlet": [{"boundary": "top", "components": [1]}]},
     "free to move rigidly"),
    ({"solver": {"petsc_options": {"snes_lag_jacobian": 2}}},
     "solver.petsc_options.snes_lag_jacobian = 2"),
], ids=["probe outside", "free rigid motion", "refused option"])
def test_check_refuses_what_a_run_refuses(change, words):
    scene = api.load_scene("paper", geometry={"cells": [4, 4]}, **change)
    with pytest.raises(SceneError, match=words.replace("[", r"\[").replace(".", r"\.")):
        api.check(scene)
