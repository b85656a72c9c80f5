"""Scenes: defaults, overrides, clear errors, and only the unknowns a scene needs."""
import math

import pytest
from mpi4py import MPI

from contactvisco.model.memory_kernel import memory_terms
from contactvisco.errors import SceneError
from contactvisco.fem import geometry, problem as problem_module
from contactvisco.scene import loader as scene_module


def build(overrides):
    scene = scene_module.load("paper", ["geometry.cells=[4, 4]"] + overrides)
    return problem_module.build(scene, geometry.build(scene, MPI.COMM_WORLD))


def test_paper_scene_values():
    scene = scene_module.load("paper")
    assert scene["material"] == {"model": "plane_stress", "E": 100.0, "nu": 0.3,
                                 "lambda": None, "mu": None, "law": "linear", "energy": None,
                                 "hencky_exponent": 1.0, "hencky_strain": 0.01}
    assert scene["contact"]["g"] == 0.05 and scene["contact"]["mu"] == 0.2
    assert scene["contact"]["augmentation"] == 100.0       # defaults to the stiffness
    assert memory_terms(scene) == [(100.0, math.inf, "full")]
    assert scene["time"] == {"T": 1.0, "steps": 10, "rule": "paper", "allow_unstable": False,
                             "grid": "uniform", "first": None, "growth": None,
                             "per_decade": None, "segments": None, "times": None,
                             "times_file": None, "times_column": None,
                             "tolerance": None, "min_step": None, "max_step": None,
                             "landing_times": None}


def test_set_overrides():
    scene = scene_module.load("paper", ["time.steps=40", "contact.g=inf",
                                        "contact.augmentation=1e4", "material.model=plane_strain"])
    assert scene["time"]["steps"] == 40 and math.isinf(scene["contact"]["g"])
    assert scene["contact"]["augmentation"] == 1e4
    assert scene["material"]["model"] == "plane_strain"


@pytest.mark.parametrize("override, words", [
    ("contact.stiffnes=3", "did you mean 'stiffness'"),
    ("time.steps=0", "time.steps must be an integer >= 1"),
    ("material.nu=1.2", "material.nu must lie in (-1, 1.0) for plane_stress"),
    ("contact.mu=-1", "contact.mu must be a finite number >= 0"),
    ("contact.g=-0.05", "contact.g must be >= 0"),
    ("material.E=0", "material.E must be > 0"),
    ("time.T=-1", "time.T must be > 0"),
    ("contact.g=0", "contact.mu = 0.2 has no effect"),
])
def test_bad_values_are_named(override, words):
    with pytest.raises(SceneError) as err:
        scene_module.load("paper", [override])
    assert words in str(err.value)


def test_poisson_ratio_limit_depends_on_the_model():
    with pytest.raises(SceneError, match=r"\(-1, 0.5\) for plane_strain"):
        scene_module.load("paper", ["material.model=plane_strain", "material.nu=0.5"])


def test_unknown_scene():
    with pytest.raises(SceneError, match="not a built-in scene"):
        scene_module.load("no-such-scene")


def test_unknown_boundary_is_named():
    with pytest.raises(SceneError, match="no boundary named 'floor'"):
        build(["contact.boundary='floor'"])


@pytest.mark.parametrize("overrides, unknowns, history", [
    ([], {"u", "lambda_nu", "lambda_tau"}, True),
    (["contact.mu=0"], {"u", "lambda_nu"}, True),
    (["contact.g=inf"], {"u", "lambda_tau"}, True),
    (["contact.g=inf", "contact.mu=0", "memory.kernel='none'"], {"u"}, False),
    (["memory.alpha=0"], {"u", "lambda_nu", "lambda_tau"}, False),
])
def test_only_needed_terms_are_built(overrides, unknowns, history):
    problem = build(overrides)
    assert set(problem.count_unknowns()) == unknowns
    assert (problem.memory is not None) == history
    assert (problem.memory is not None and problem.memory.H is not None) == history
    # the residual depends on exactly these unknowns
    assert len(problem.F) == len(unknowns)


def test_presets_scale_the_scene():
    base = scene_module.load("paper")
    fast = scene_module.load("paper", ["preset='fast'"])
    accurate = scene_module.load("paper", ["preset='accurate'"])
    assert fast["geometry"]["cells"] == [16, 16] and fast["time"]["steps"] == 10
    assert accurate["geometry"]["cells"] == [64, 64] and accurate["time"]["steps"] == 10
    assert base["time"]["rule"] == "paper" and accurate["time"]["rule"] == "trapezoid"
    # --set after the preset still wins, whatever the order on the command line
    both = scene_module.load("paper", ["time.steps=7", "preset='accurate'"])
    assert both["time"]["steps"] == 7 and both["geometry"]["cells"] == [64, 64]
    hertz = scene_module.load("hertz", ["preset='fast'"])
    assert hertz["geometry"]["parameters"]["h_contact"] == pytest.approx(0.0054)
    assert hertz["geometry"]["parameters"]["radius"] == 1.0       # not a mesh size
    with pytest.raises(SceneError, match="did you mean 'fast'"):
        scene_module.load("paper", ["preset='fats'"])


def test_every_declared_key_is_documented():
    """docs/scenes.md has a row for every key the tables declare, under its table's heading."""
    from contactvisco.scene import tables
    from helpers import ROOT
    text = (ROOT / "docs" / "scenes.md").read_text()
    sections = {}
    for block in text.split("\n## ")[1:]:
        heading, _, body = block.partition("\n")
        names = [part.strip("[]") for part in heading.split("`")[1::2]] or ["top"]
        sections.update({name: body for name in names})
    declared = dict(tables.TABLES, **tables.TABLE_LISTS, top=tables.Scene)
    missing = [f"{name}.{key}" for name, table in declared.items() for key in table.KEYS
               if not any(f"{form}`" in sections.get(name, "")
                          for form in (f"`{key}", f".{key}"))]
    assert not missing, f"keys without a row in docs/scenes.md: {missing}"


def test_a_table_checks_itself_and_names_its_origin(tmp_path):
    """A table refuses a bad value by itself (no whole-scene check), with the dotted key and
    the line of the scene file it came from; the same table from a --set names the --set."""
    from contactvisco.scene import table, tables
    path = tmp_path / "mine.toml"
    path.write_text('name = "mine"\n[contact]\nstiffness = 10.0\ng = 0.1\n'
                    'mu = -0.5   # a negative friction coefficient\n')
    text = path.read_text()
    provenance = table.Provenance(path, text)
    scene = scene_module.load("paper")
    contact = tables.Contact(dict(scene["contact"], mu=-0.5), "contact", provenance)
    with pytest.raises(SceneError) as err:
        contact.validate(scene)
    assert err.value.key == "contact.mu"
    assert "contact.mu must be a finite number >= 0, got -0.5" in str(err.value)
    assert "mine.toml, line 5: mu = -0.5" in str(err.value)
    with pytest.raises(SceneError) as err:
        scene_module.load(str(path))
    assert err.value.key == "contact.mu" and "mine.toml, line 5" in str(err.value)
    with pytest.raises(SceneError) as err:
        scene_module.load(str(path), ["contact.mu=0.3", "contact.g=-1"])
    assert err.value.key == "contact.g" and "(from --set contact.g=-1)" in str(err.value)
    # A valid table passes, and the values of the scene are those of its tables.
    good = scene_module.load(str(path), ["contact.mu=0.3"])
    assert isinstance(good["contact"], tables.Contact) and good["contact"]["mu"] == 0.3
    assert good["contact"].origin("g") == " (mine.toml, line 4: g = 0.1)"
    assert good["time"].origin("steps") == " (a default value)"


def test_an_error_found_while_building_names_its_origin(tmp_path):
    """A boundary name is checked against the mesh only when the mesh exists: the error, raised
    by the geometry, still names the scene line through the scene's provenance."""
    from contactvisco import api
    path = tmp_path / "wrong.toml"
    path.write_text('name = "wrong"\n[geometry]\ncells = [2, 2]\n[[dirichlet]]\n'
                    'boundary = "lef"\n')
    with pytest.raises(SceneError) as err:
        api.solve(scene_module.load(str(path)))
    assert err.value.key == "dirichlet[0].boundary"
    assert "no boundary named 'lef'" in str(err.value)
    assert "wrong.toml, line 5: boundary = \"lef\"" in str(err.value)


def test_a_scene_survives_copy_and_pickle():
    """Scenes are copied (tradeoff ladders, demos) and pickled (MPI): the tables, their values
    and the origins of the Python API's overrides come through."""
    import copy
    import pickle

    from contactvisco import load_scene
    scene = load_scene("paper", contact={"mu": 0.3}, time={"steps": 12})
    for other in (copy.deepcopy(scene), pickle.loads(pickle.dumps(scene))):
        assert other == scene and type(other["contact"]) is type(scene["contact"])
        assert other["contact"].origin("mu") == " (from load_scene contact.mu=0.3)"
        other["time"]["steps"] = 0
        with pytest.raises(SceneError, match="load_scene time.steps=12"):
            other.validate()
