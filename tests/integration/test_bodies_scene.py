"""A TOML scene of two bodies ([[body]] tables, an array of tables, each with its own
[material] and [memory]) through every path that walks a scene's keys: the command line's
run and show (written back and read again), a restart's scene comparison, the Python API's
overrides and the re-check of a scene changed in Python, and the scene digest the ranks
compare. Subprocesses are started only on a single rank."""
import json

import pytest
from mpi4py import MPI

from contactvisco import api
from contactvisco.errors import SceneError
from contactvisco.io import checkpoint
from contactvisco.scene import loader
from helpers import ROOT, run_cli

pytestmark = [pytest.mark.processes,
              pytest.mark.skipif(MPI.COMM_WORLD.size > 1,
                                 reason="starts its own processes; run on one rank")]

#: Two blocks (meshes/two_blocks.py) pressed together, the upper one creeping with its own
#: kernel, the lower one elastic with the scene's material.
SCENE = """\
name = "two_bodies"

[geometry]
type = "gmsh"
script = "two_blocks"
parameters = { h_slave = 0.077, h_master = 0.1 }

[material]
model = "plane_strain"
E = 1.0
nu = 0.3

[[dirichlet]]
boundary = "bottom"
components = [1]

[[dirichlet]]
boundary = "master_sides"
components = [0]

[[dirichlet]]
boundary = "slave_sides"
components = [0]

[[traction]]
boundary = "top"
value = [0.0, "-0.01 * min(2 * t, 1)"]

[[body]]
name = "upper"
cells = "slave_body"
material = { E = 2.0 }
memory = { kernel = "exponential", alpha = [-0.5], tau = [1.0] }

[[body]]
name = "lower"
cells = "master_body"

[contact]
boundary = "slave"
stiffness = 100.0
pairing = "mortar"

[obstacle]
shape = "body"
boundary = "master"

[time]
T = 1.0
steps = 3
rule = "trapezoid"

[output]
probes = []
"""


@pytest.fixture
def scene_file(tmp_path):
    path = tmp_path / "two_bodies.toml"
    path.write_text(SCENE)
    return path


def body_values(scene) -> list:
    """Each body's name, cells, E, nu and memory kernel with its terms."""
    return [(b["name"], b["cells"], b["material"]["E"], b["material"]["nu"],
             b["memory"]["kernel"], b["memory"]["alpha"], b["memory"]["tau"])
            for b in scene["body"]]


def test_version_names_the_package_run():
    """`--version` says where the package it runs was imported from: a run that reads a
    scene key this checkout knows ([[body]]) with an older installed copy would refuse it as
    an unknown key; the line shows which copy answered."""
    proc = run_cli("--version")
    assert proc.returncode == 0, proc.stderr
    assert f"(from {ROOT / 'contactvisco'})" in proc.stdout.splitlines()[0]


def test_show_writes_back_the_same_bodies(scene_file, tmp_path):
    """`show` of the scene, read back: the same scene key for key ([[body]] included), and
    `show` of that text gives the same text again."""
    first = run_cli("show", scene_file)
    assert first.returncode == 0, first.stderr
    assert first.stdout.count("[[body]]") == 2
    written = tmp_path / "written.toml"
    written.write_text(first.stdout)
    again = run_cli("show", written)
    assert again.returncode == 0, again.stderr
    assert again.stdout == first.stdout
    a, b = loader.load(str(scene_file)), loader.load(str(written))
    assert checkpoint.scene_values(a) == checkpoint.scene_values(b)
    assert body_values(b) == [("upper", "slave_body", 2.0, 0.3, "exponential", [-0.5], [1.0]),
                              ("lower", "master_body", 1.0, 0.3, "none", 0.0, [])]


@pytest.mark.parametrize("setting, expected", [
    ("body.1.material.E=3.0", ("lower", 3.0)),      # a body with no [material] of its own
    ("body.0.material.nu=0.2", ("upper", 0.2)),     # a key the file's table does not give
])
def test_set_a_key_of_a_body(scene_file, setting, expected):
    """--set reaches a key of a body's [material], given in the file or not."""
    scene = loader.load(str(scene_file), [setting])
    j = 0 if expected[0] == "upper" else 1
    key = setting.split("=")[0].split(".")[-1]
    assert scene["body"][j]["name"] == expected[0]
    assert scene["body"][j]["material"][key] == expected[1]
    assert scene["body"][1 - j]["material"][key] == (0.3 if key == "nu" else
                                                     (2.0 if j == 1 else 1.0))


@pytest.mark.parametrize("setting, words", [
    ("body.0.material.Ee=3.0", "unknown scene key 'body.0.material.Ee' (did you mean 'E'?)"),
    ("body.0.colour=1", "unknown scene key 'body.0.colour'"),
    ("body.2.name=x", "'body' is a list of 2 table(s); the index must be 0..1"),
])
def test_set_refuses_a_wrong_body_key(scene_file, setting, words):
    with pytest.raises(SceneError) as err:
        loader.load(str(scene_file), [setting])
    assert words in str(err.value)


def test_run_and_restart_from_the_command_line(scene_file, tmp_path):
    """`run` of the two-body scene to its end (its checkpoint included), `run --restart` of
    the same scene accepted, and of a scene whose body differs refused naming that key."""
    out = tmp_path / "out"
    proc = run_cli("run", scene_file, "--out", out, "-q", timeout=600)
    assert proc.returncode == 0, proc.stderr
    steps = [json.loads(line) for line in (out / "steps.jsonl").read_text().splitlines()]
    assert [s["t"] for s in steps][-1] == 1.0
    assert steps[-1]["status_counts"]["compliance"] > 0          # the blocks are pressed
    again = run_cli("run", scene_file, "--out", out, "-q", "--restart", timeout=600)
    assert again.returncode == 0, again.stderr
    changed = run_cli("run", scene_file, "--out", out, "-q", "--restart",
                      "--set", "body.0.material.E=3.0", timeout=600)
    assert changed.returncode == 2
    assert "body.0.material.E: 2.0 -> 3.0" in changed.stderr
    assert "Traceback" not in changed.stderr


def test_api_overrides_and_changes_in_python(scene_file):
    """load_scene's keyword overrides reach a body's tables; a scene changed in Python after
    load_scene is checked again by solve/check with the body's key named."""
    scene = api.load_scene(scene_file, body={"1": {"memory": {"kernel": "constant",
                                                              "alpha": -0.1}}},
                           sets=["body.0.material.E=4.0"])
    assert body_values(scene)[0][2] == 4.0
    assert body_values(scene)[1][4:6] == ("constant", -0.1)
    checked = loader.check_given(scene)
    assert checkpoint.scene_values(checked) == checkpoint.scene_values(scene)
    scene["body"][1]["material"]["E"] = 5.0
    assert loader.check_given(scene)["body"][1]["material"]["E"] == 5.0
    scene["body"][1]["material"]["E"] = -5.0
    with pytest.raises(SceneError, match=r"body\[1\]\.material\.E.*changed in Python"):
        loader.check_given(scene)


@pytest.mark.mpi
def test_two_ranks_run_the_two_body_scene(scene_file, tmp_path):
    """Two ranks compare the digest of the two-body scene and solve it to the one-rank
    answer's contact status."""
    runs = {}
    for ranks in (1, 2):
        out = tmp_path / f"ranks{ranks}"
        proc = run_cli("run", scene_file, "--out", out, "-q", ranks=ranks, timeout=600)
        assert proc.returncode == 0, proc.stderr
        runs[ranks] = [json.loads(line)["status_counts"]
                       for line in (out / "steps.jsonl").read_text().splitlines()]
    assert runs[2] == runs[1]
