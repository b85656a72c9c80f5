"""A restart trusts nothing it reads: an edited or damaged checkpoint stops with an error that
names the file and what is wrong, also when the forger recomputed the checksums; an intact
one restores the state exactly. A scene change is refused with the keys that differ, an
output change is allowed. (Each rank works on a checkpoint of its own, on COMM_SELF.)"""
import hashlib
import io
import json
import pathlib
import shutil
import tempfile

import numpy as np
import pytest
from mpi4py import MPI

from contactvisco.io import checkpoint
from contactvisco.scene import loader as scene_module
from contactvisco.fem.geometry import build as build_geometry
from contactvisco.fem.problem import build
from contactvisco.solver.time_loop import simulate
from contactvisco.errors import SceneError

SELF = MPI.COMM_SELF
OVERRIDES = ["geometry.cells=[4, 4]", "time.steps=3", "output.figures=false",
             "output.xdmf=false"]


@pytest.fixture(scope="module")
def saved():
    """A run of 3 steps with its checkpoint, and its final unknowns."""
    folder = pathlib.Path(tempfile.mkdtemp(prefix="cv-checkpoint-"))
    scene = scene_module.load("paper", OVERRIDES)
    result = simulate(scene, folder / "run", comm=SELF, progress=False)
    yield scene, folder / "run", [f.x.array.copy() for f in result.problem.unknowns]
    shutil.rmtree(folder)


@pytest.fixture
def copy(saved, tmp_path):
    scene, run, arrays = saved
    target = tmp_path / f"run-{MPI.COMM_WORLD.rank}"
    shutil.copytree(run, target)
    return scene, target, arrays


def restore(scene, folder):
    problem = build(scene, build_geometry(scene, SELF))
    meta = checkpoint.load(folder, problem, SELF)
    return problem, meta


def test_intact_checkpoint_restores_the_state(copy):
    scene, folder, arrays = copy
    problem, meta = restore(scene, folder)
    assert meta["count"] == 4 and meta["t"] == 1.0
    for f, a in zip(problem.unknowns, arrays):
        assert np.array_equal(f.x.array, a)


def _meta(folder):
    return folder / "checkpoint" / "meta.json"


def _part(folder):
    meta = json.loads(_meta(folder).read_text())
    return folder / "checkpoint" / meta["parts"][0]["file"]


def _resign(folder, edit_meta=None, part_arrays=None):
    """Forge: rewrite the part and/or meta with every checksum recomputed."""
    meta = json.loads(_meta(folder).read_text())
    if part_arrays is not None:
        buffer = io.BytesIO()
        np.savez(buffer, **part_arrays)
        _part(folder).write_bytes(buffer.getvalue())
        meta["parts"][0]["sha256"] = hashlib.sha256(buffer.getvalue()).hexdigest()
    if edit_meta:
        edit_meta(meta)
    meta["sha256"] = checkpoint._meta_digest(meta)
    _meta(folder).write_text(json.dumps(meta))


def _edit_json(key, value):
    def edit(folder):
        meta = json.loads(_meta(folder).read_text())
        meta[key] = value
        _meta(folder).write_text(json.dumps(meta))
    return edit


def _flip_byte(folder):
    path = _part(folder)
    data = bytearray(path.read_bytes())
    data[len(data) // 2] ^= 0xFF
    path.write_bytes(bytes(data))


def _part_arrays(folder):
    with np.load(_part(folder)) as data:
        return {name: data[name] for name in data.files}


def _forged_t(folder):
    _resign(folder, edit_meta=lambda meta: meta.update(t=0.5))


def _forged_history(folder):
    arrays = _part_arrays(folder)
    name = next(n for n in arrays if n.startswith("history_") and not n.endswith(".keys"))
    arrays[name] = arrays[name][:-1]
    _resign(folder, part_arrays=arrays)


def _unsigned_history(folder):
    """The checksums removed (meta's and the part's) and the history edited."""
    arrays = _part_arrays(folder)
    name = next(n for n in arrays if n.startswith("history_") and not n.endswith(".keys"))
    arrays[name] = 2 * arrays[name]
    buffer = io.BytesIO()
    np.savez(buffer, **arrays)
    _part(folder).write_bytes(buffer.getvalue())
    meta = json.loads(_meta(folder).read_text())
    del meta["sha256"]
    for entry in meta["parts"]:
        del entry["sha256"]
    _meta(folder).write_text(json.dumps(meta))


def _unsigned_part(folder):
    """Only the part's checksum removed, meta's recomputed: the part is not vouched for."""
    _resign(folder, edit_meta=lambda meta: meta["parts"][0].pop("sha256"))


CASES = {
    "checksums removed, history edited": (_unsigned_history, "meta.json", "no checksum"),
    "part's checksum removed": (_unsigned_part, "part-0.npz", "no checksum"),
    "t edited": (_edit_json("t", 0.5), "meta.json", "checksum mismatch"),
    "count edited": (_edit_json("count", 2), "meta.json", "checksum mismatch"),
    "meta cut": (lambda f: _meta(f).write_text(_meta(f).read_text()[:40]), "meta.json",
                 "not valid JSON"),
    "part byte flipped": (_flip_byte, "part-0.npz", "checksum mismatch"),
    "part truncated": (lambda f: _part(f).write_bytes(_part(f).read_bytes()[:100]),
                       "part-0.npz", "checksum mismatch"),
    "part missing": (lambda f: _part(f).unlink(), "part-0.npz", "cannot be read"),
    "t forged with checksums": (_forged_t, "part-0.npz", "meta.json says t = 0.5"),
    "history forged with checksums": (_forged_history, "part-0.npz", "has shape"),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_damaged_checkpoint_is_refused_naming_file_and_fault(copy, case):
    scene, folder, _ = copy
    damage, file, words = CASES[case]
    damage(folder)
    with pytest.raises(checkpoint.Damaged) as error:
        restore(scene, folder)
    assert file in str(error.value) and words in str(error.value), str(error.value)


def test_scene_change_lists_the_keys_and_output_changes_are_allowed(copy):
    scene, folder, arrays = copy
    other = scene_module.load("paper", OVERRIDES + ["contact.mu=0.3", "material.nu=0.25"])
    with pytest.raises(SceneError) as error:
        restore(other, folder)
    message = str(error.value)
    assert "contact.mu: 0.2 -> 0.3" in message and "material.nu: 0.3 -> 0.25" in message
    assert message.count("->") == 2
    output_only = scene_module.load("paper", OVERRIDES[:2] + ["output.xdmf=true",
                                                              "output.probes=[[0.5, 0.5]]"])
    problem, meta = restore(output_only, folder)
    assert meta["count"] == 4
    assert np.array_equal(problem.u.x.array, arrays[0])
