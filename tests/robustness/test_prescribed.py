"""Prescribed functions checked where the forms use them (issue 35): an obstacle's distance
and its gradient, contact.p_nu, contact.p_tau and an expression contact.mu at the contact nodes
and at every staged time. A violation stops the run with the key, the node and the time, on
every rank alike, and the steps before it are kept."""
import json
import pathlib

import pytest
from helpers import layer_on_surface
from mpi4py import MPI

from contactvisco.errors import SceneError
from contactvisco.scene import loader as scene_module
from contactvisco.solver.time_loop import simulate

COMM = MPI.COMM_WORLD
SMALL = ["geometry.cells=[8, 4]", "time.steps=4"]


@pytest.mark.mpi
@pytest.mark.parametrize("distance, value", [
    ("abs(x[1])", "|grad phi| = 0"),          # a true distance, its gradient 0 on the surface
    ("x[1]**2", "|grad phi| = 0"),
    ("1.0", "|grad phi| = 0"),                # constant: no direction at all
    ("sqrt(x[1] - 0.5)", "nan"),              # undefined below 0.5
    ("1e-4 * x[1]", "|grad phi| = 0.0001"),   # a level set too flat to give a distance
])
def test_surface_without_a_direction_is_refused(distance, value):
    with pytest.raises(SceneError, match="obstacle's distance is not defined") as err:
        simulate(scene_module.resolve(layer_on_surface(distance), []), comm=COMM,
                 progress=False)
    assert err.value.key == "obstacle.distance"
    assert value in str(err.value) and "x = (" in str(err.value) and "t = 0" in str(err.value)


def test_level_set_that_is_not_a_distance_still_runs():
    """A scaled, curved level set keeps |grad phi| within the bounds: solved, in contact."""
    result = simulate(scene_module.resolve(
        layer_on_surface("2 * x[1] + 0.01 * (x[0] - 1)**2"), []), comm=COMM, progress=False,
        keep_tables=True)
    assert (result.tables[-1]["status"] == 2).sum() >= 1


@pytest.mark.mpi
@pytest.mark.parametrize("sets, key, words, t", [
    # negative away from x = 0 once t > 0: the scene check at x = 0 cannot see it
    (["contact.stiffness=0", "contact.g=0.01", "contact.p_nu='2e3 * s * (1 - 6 * x[0] * t)'"],
     "contact.p_nu", "must be >= 0", "t = 0.25:"),
    (["contact.stiffness=0", "contact.g=0.01", "contact.mu=0",
      "contact.p_nu='2e3 * s'", "contact.p_tau='0.3 * p_nu * (1 - 6 * x[0] * t)'"],
     "contact.p_tau", "must be >= 0", "t = 0.25:"),
    # decreasing in s at x > 0.5 only
    (["contact.stiffness=0", "contact.g=0.01",
      "contact.p_nu='conditional(x[0] > 0.5, 2e3 * s * (1.1 - 100 * s), 2e3 * s)'"],
     "contact.p_nu", "non-decreasing", "t = 0:"),
    # not zero at s = 0 away from x = 0
    (["contact.stiffness=0", "contact.g=0.01", "contact.p_nu='2e3 * s + 1e-3 * x[0]'"],
     "contact.p_nu", "must vanish at s = 0", "t = 0:"),
    (["contact.mu='0.2 / (t - 0.5)'"], "contact.mu", "must be finite", "t = 0.5:"),
    (["contact.mu='0.2 / (x[0] - 0.5)'"], "contact.mu", "must be finite", "t = 0:"),
])
def test_prescribed_law_checked_at_the_nodes_and_times(tmp_path_factory, sets, key, words, t):
    out = tmp_path_factory.mktemp("law") if COMM.rank == 0 else None
    out = COMM.bcast(out, root=0)
    scene = scene_module.load("paper", SMALL + sets)
    with pytest.raises(SceneError, match=words) as err:
        simulate(scene, comm=COMM, progress=False, out=out)
    assert err.value.key == key
    assert t in str(err.value) and "contact node x = (" in str(err.value)
    if t != "t = 0:":
        # the states before the refused time are kept: t = 0 (and 0.25)
        records = (pathlib.Path(out) / "steps.jsonl").read_text().splitlines()
        times = [json.loads(line)["t"] for line in records]
        assert times and max(times) < float(t[4:-1])


@pytest.mark.mpi
def test_wlf_pole_between_two_step_times_is_refused(tmp_path_factory):
    """C2 + T - T_ref > 0 at every step time (0.5 and 1.0 here) but < 0 at t = 0.75: the
    reduced time of that step would integrate through the WLF pole."""
    folder = COMM.bcast(tmp_path_factory.mktemp("wlf") if COMM.rank == 0 else None, root=0)
    raw = {"name": "wlf_dip",
           "geometry": {"lower": [0.0, 0.0], "upper": [2.0, 1.0], "cells": [4, 2]},
           "material": {"model": "plane_strain"},
           "viscoelastic": {"shear": {"instantaneous": 30.0, "tau": [1.0], "moduli": [10.0]},
                            "bulk": {"long_term": 50.0}, "shift": "wlf", "T_ref": 50.0,
                            "C1": 17.44, "C2": 51.6,
                            "temperature": "50 - 60 * exp(-((t - 0.75) / 0.05)**2)"},
           "dirichlet": [{"boundary": "left", "components": [0]}],
           "traction": [{"boundary": "top", "value": [0.0, -1.0]}],
           "contact": {"boundary": "bottom", "stiffness": 100.0, "g": 0.03},
           "time": {"T": 4.0, "steps": 8}, "output": {"probes": []}}
    with pytest.raises(SceneError, match="between the step times 0.5 and 1") as err:
        simulate(scene_module.resolve(raw, []), comm=COMM, progress=False, out=folder)
    assert err.value.key == "viscoelastic.temperature"
    assert "C2 + T - T_ref" in str(err.value) and "x = (" in str(err.value)
    times = [json.loads(line)["t"]
             for line in (pathlib.Path(folder) / "steps.jsonl").read_text().splitlines()]
    assert times == [0.0, 0.5]


@pytest.mark.parametrize("scene, sets, key, meaning", [
    ("paper", ["material.hencky_exponent=0.5"], "material.hencky_exponent", "law = 'hencky'"),
    ("paper", ["material.hencky_strain=0.05"], "material.hencky_strain", "law = 'hencky'"),
    ("paper", ["contact.pairing='node_to_segment'"], "contact.pairing", "shape = 'body'"),
    ("paper", ["contact.sliding_limit=0.2"], "contact.sliding_limit", "shape = 'body'"),
    ("paper", ["contact.search_distance=0.1"], "contact.search_distance", "shape = 'body'"),
    ("hertz", ["contact.gap=0", "obstacle.shape='cylinder'", "obstacle.centre=[0.0, -1.0]",
               "obstacle.radius=1.0", "obstacle.axis=[0.0, 1.0]"], "obstacle.axis",
     "'cylinder' in 3D"),
    ("hertz", ["contact.gap=0", "obstacle.shape='plane'", "obstacle.point=[0.0, 0.0]",
               "obstacle.normal=[0.0, 1.0]", "obstacle.radius=1.0"], "obstacle.radius",
     "'cylinder' or 'sphere'"),
])
def test_key_without_a_meaning_is_refused(scene, sets, key, meaning):
    """One rule (Table.MEANINGFUL_WHEN): the key, 'no meaning' and what would give it one,
    through the loader (the CLI's and check's route) and the API's load_scene."""
    from contactvisco import api
    with pytest.raises(SceneError, match="has no meaning in this scene") as err:
        scene_module.load(scene, sets)
    assert err.value.key == key and meaning in str(err.value)
    with pytest.raises(SceneError, match="has no meaning in this scene") as err:
        api.load_scene(scene, sets=sets)
    assert err.value.key == key and meaning in str(err.value)


def test_key_without_a_meaning_is_refused_from_keyword_overrides():
    from contactvisco import api
    with pytest.raises(SceneError, match="law = 'hencky'") as err:
        api.load_scene("paper", material={"hencky_strain": 0.05})
    assert err.value.key == "material.hencky_strain"


@pytest.mark.parametrize("sets", [["material.law='hencky'", "material.hencky_exponent=0.5"],
                                  ["material.hencky_exponent=1.0"]])
def test_key_with_its_meaning_or_its_default_is_accepted(sets):
    assert scene_module.load("paper", sets)["material"]["hencky_exponent"] in (0.5, 1.0)


# ---- duplicates and contradictions in list-valued keys; a master on the slave's body ----

@pytest.mark.parametrize("sets, key, words", [
    (["dirichlet.0.components=[0, 0]", "dirichlet.0.value=[0.0, 1.0]"],
     "dirichlet[0].components", "the component 0 twice"),
    (["contact.boundary=['bottom', 'bottom']"], "contact.boundary", "'bottom' twice"),
])
def test_repeated_entry_is_refused(sets, key, words):
    from contactvisco import api
    for load in (scene_module.load, lambda name, s: api.load_scene(name, sets=s)):
        with pytest.raises(SceneError, match=words) as err:
            load("paper", sets)
        assert err.value.key == key


def test_repeated_force_component_is_refused():
    with pytest.raises(SceneError, match="the component 1 twice") as err:
        scene_module.load("hertz", [
            "contact.gap=0", "obstacle.shape='plane'", "obstacle.point=[0.0, 0.0]",
            "obstacle.normal=[0.0, 1.0]", "obstacle.force_components=[1, 1]",
            "obstacle.force=[-0.1, -0.1]"])
    assert err.value.key == "obstacle.force_components"


@pytest.mark.mpi
@pytest.mark.parametrize("master", ["top", "slave_sides"])
def test_master_on_the_slave_body_is_refused(master):
    """obstacle.boundary names a face of the slave's own block (two_blocks: the slave block's
    top and sides): refused naming obstacle.boundary before anything is solved."""
    from contactvisco.fem import geometry as geometry_module
    from contactvisco.fem.problem import build
    raw = {"name": "patch",
           "geometry": {"type": "gmsh", "script": "two_blocks",
                        "parameters": {"h_slave": 0.077, "h_master": 0.1}},
           "material": {"model": "plane_strain", "E": 1.0, "nu": 0.3},
           "dirichlet": [{"boundary": "bottom", "components": [1]}],
           "contact": {"boundary": "slave", "stiffness": 100.0},
           "obstacle": {"shape": "body", "boundary": master},
           "time": {"T": 1.0, "steps": 1}, "output": {"probes": []}}
    scene = scene_module.resolve(raw)
    with pytest.raises(SceneError, match="same body") as err:
        build(scene, geometry_module.build(scene, COMM))
    assert err.value.key == "obstacle.boundary"
