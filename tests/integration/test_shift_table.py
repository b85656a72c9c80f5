"""viscoelastic.shift = "table" through the Python routes (load_scene, check, solve), from the
docs' own example (docs/scenes.md: its TOML block and the points in its comment) and from
inline lists: the scene built again for check and solve reads its points as load did."""
import pathlib

import numpy as np
import pytest
from mpi4py import MPI

from contactvisco import api
from shift_example import POINTS, write_scene

COMM = MPI.COMM_WORLD


@pytest.fixture
def scene_file(tmp_path_factory):
    """The docs' example as a scene file in a folder of its own, with its shift.csv."""
    folder = COMM.bcast(tmp_path_factory.mktemp("shift") if COMM.rank == 0 else None, root=0)
    if COMM.rank == 0:
        write_scene(pathlib.Path(folder))
    COMM.barrier()
    return pathlib.Path(folder) / "scene.toml"


def _solved_temperature_shift(scene) -> list:
    checked = api.check(scene)
    assert checked is not None
    run = api.solve(scene)
    assert [round(r["t"], 12) for r in run.steps] == [0.0, 0.5, 1.0]
    return [r["newton_iterations"] for r in run.steps]


@pytest.mark.mpi
def test_docs_shift_file_example_loads_checks_and_solves(scene_file, monkeypatch):
    # from another folder: the CSV is found relative to the scene file
    monkeypatch.chdir(scene_file.parent.parent)
    scene = api.load_scene(str(scene_file))
    visco = scene["viscoelastic"]
    from contactvisco.model import viscoelastic as ve
    assert np.allclose(ve.log10_shift(visco, np.array(POINTS[0])), POINTS[1], atol=1e-12)
    _solved_temperature_shift(scene)


@pytest.mark.mpi
def test_inline_shift_table_loads_checks_and_solves(scene_file):
    scene = api.load_scene(str(scene_file), viscoelastic={
        "shift_file": None, "shift_temperatures": POINTS[0], "shift_log10_aT": POINTS[1]})
    _solved_temperature_shift(scene)
