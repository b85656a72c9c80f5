"""The scene is checked where it is used: `solve` and `check` refuse a scene changed in Python
after `load_scene` with load_scene's messages (and say the value was changed in Python);
repeated entries of list-valued keys, integers beyond a double and deeply nested TOML are
scene errors that name the key or the file; probes and steps have stated limits."""
import copy
import math

import pytest

from contactvisco import api
from contactvisco.errors import SceneError
from contactvisco.scene import loader
from contactvisco.scene.tables import MAX_PROBES, MAX_STEPS

CHANGED = "changed in Python after load_scene"
#: The [[dirichlet]] tables of the paper scene, as a TOML list's first entries.
PAPER_DIRICHLET = "{boundary = 'left', components = 'all'}, {boundary = 'right', components = [0]}"


def small(name="paper", **overrides):
    """A scene that builds and solves in a fraction of a second."""
    cells = {"paper": [6, 6], "creep": [4, 4]}[name]
    return api.load_scene(name, geometry={"cells": cells}, time={"steps": 2},
                          output={"figures": False}, **overrides)


# ---- a scene changed in Python after load_scene ----

CHANGES = [
    ("time", "rule", "trapeziod", "time.rule must be paper, trapezoid or exponential"),
    ("material", "model", "plane_strian", "material.model must be plane_stress"),
    ("memory", "kernel", "exponentail", "memory.kernel must be none, constant"),
    ("discretization", "contact_quadrature", "gaus", "contact_quadrature must be nodal or"),
    ("contact", "friction_law", "columb", "contact.friction_law must be compliance or coulomb"),
    ("contact", "stiffness", math.nan, "contact.stiffness must be a finite number >= 0"),
    ("contact", "stiffness", -1.0, "contact.stiffness must be a finite number >= 0"),
    ("contact", "g", math.nan, "contact.g must be >= 0"),
    ("contact", "g", -0.5, "contact.g must be >= 0"),
    ("contact", "mu", math.nan, "contact.mu must be a finite number >= 0"),
    ("contact", "mu", -0.1, "contact.mu must be a finite number >= 0"),
    ("time", "T", math.nan, "time.T must be > 0"),
    ("time", "T", -1.0, "time.T must be > 0"),
    ("time", "steps", 2.5, "time.steps must be an integer >= 1"),
    ("material", "E", math.inf, "material.E must be > 0"),
    ("material", "nu", 1.0, "material.nu must lie in (-1, 1.0) for plane_stress"),
    ("time", "stpes", 3, "unknown scene key 'time.stpes' (did you mean 'steps'?)"),
    ("contact", "boundary", ["bottom", "bottom"], "contact.boundary lists the boundary 'bottom'"),
]


@pytest.mark.parametrize("table, key, value, words", CHANGES,
                         ids=[f"{t}.{k}={v!r}" for t, k, v, _ in CHANGES])
@pytest.mark.parametrize("use", ["solve", "check"])
def test_a_scene_changed_in_python_is_refused_where_it_is_used(use, table, key, value, words):
    scene = small()
    scene[table][key] = value
    with pytest.raises(SceneError) as err:
        getattr(api, use)(scene)
    assert words in str(err.value) and CHANGED in str(err.value), str(err.value)


def test_a_changed_value_keeps_the_origin_of_the_others(tmp_path):
    """Only the changed key is said to be changed; a key of the file keeps its line."""
    path = tmp_path / "s.toml"
    path.write_text('name = "s"\n[time]\nT = 2.0\nsteps = 3\n[[dirichlet]]\nboundary = "left"\n')
    scene = api.load_scene(str(path))
    scene["time"]["rule"] = "paper"            # unchanged in value: not "changed"
    scene["time"]["T"] = -2.0
    with pytest.raises(SceneError, match="time.T must be > 0, got -2.0 .changed in Python"):
        api.check(scene)
    scene = api.load_scene(str(path))
    scene["output"]["probes"] = [[0.5, 0.5], [0.5, 0.5]]
    with pytest.raises(SceneError, match=r"output.probes lists the point \[0.5, 0.5\] twice"):
        api.check(scene)


def test_a_changed_valid_value_is_the_one_solved():
    scene = small()
    scene["time"]["steps"] = 3
    result = api.solve(scene)
    assert [r["step"] for r in result.steps] == [0, 1, 2, 3]
    assert result.steps[-1]["t"] == pytest.approx(scene["time"]["T"])


@pytest.mark.parametrize("preset", [None, "fast", "accurate"])
def test_an_unchanged_scene_passes_unchanged(preset):
    """Checking again changes nothing: the preset is not applied twice, E and nu stay."""
    for name in api.builtin_scenes():
        scene = api.load_scene(name, preset=preset)
        again = loader.check_given(scene)
        assert again == scene, name
        assert loader.check_given(copy.deepcopy(scene)) == scene


def test_a_plain_dict_is_checked_as_given():
    scene = small()
    plain = loader.plain_copy(scene)              # no provenance, no record of the load
    assert loader.check_given(plain) == scene
    plain["contact"]["friction_law"] = "columb"
    with pytest.raises(SceneError, match="friction_law must be compliance or coulomb, got "
                                         "'columb' .given to solve."):
        api.check(plain)
    with pytest.raises(SceneError, match="a scene must be a dict"):
        api.check([("time", {})])


def test_lame_parameters_and_e_nu_changed_in_python(tmp_path):
    """lambda changed alone: E and nu follow it; E changed next to lambda and mu: refused
    (it would be overwritten without a word)."""
    path = tmp_path / "lame.toml"
    path.write_text('name = "lame"\n[material]\nlambda = 1.0\nmu = 1.0\n'
                    '[[dirichlet]]\nboundary = "left"\n')
    scene = api.load_scene(str(path))
    assert scene["material"]["E"] == pytest.approx(2.5)
    scene["material"]["lambda"] = 2.0
    again = loader.check_given(scene)
    assert again["material"]["E"] == pytest.approx(8 / 3) and \
        again["material"]["nu"] == pytest.approx(1 / 3)
    scene["material"]["E"] = 5.0
    with pytest.raises(SceneError, match="material.E = 5.0 and material.nu = 0.25 disagree"):
        loader.check_given(scene)


# ---- repeated entries of list-valued keys ----

REPEATS = [
    ("paper", ["contact.boundary=['bottom', 'bottom']"], "contact.boundary",
     "the boundary 'bottom' twice"),
    ("paper", ["output.probes=[[0.5, 0.5], [0.25, 0.5], [0.5, 0.5]]"], "output.probes",
     "the point [0.5, 0.5] twice (entries 0 and 2)"),
    ("paper", ["output.probes=[[0.5, 0.5], [0.5, 0.5e0]]"], "output.probes", "twice"),
    ("paper", ["output.fields=['u', 'sigma', 'u']"], "output.fields", "'u' twice"),
    ("paper", ["output.figure_times=[0.5, 0.5]"], "output.figure_times", "0.5 twice"),
    ("paper", ["output.field_times=[0.25, 0.5, 0.25]"], "output.field_times", "0.25 twice"),
    ("paper", [f"dirichlet=[{PAPER_DIRICHLET}, {{boundary = 'left', components = [1], "
               "value = 0.1}]"], "dirichlet[2].boundary",
     "dirichlet[0] and dirichlet[2] both act on the boundary 'left' (component 1)"),
    ("paper", [f"dirichlet=[{PAPER_DIRICHLET}, {{boundary = 'right'}}]"], "dirichlet[2].boundary",
     "dirichlet[1] and dirichlet[2] both act on the boundary 'right' (component 0)"),
    ("creep", ["traction=[{boundary = 'right', value = [0.1, 0.0]}, "
               "{boundary = 'right', value = [0.0, '0.1*t']}]"], "traction[1].boundary",
     "traction[0] and traction[1] both act on the boundary 'right': give one [[traction]]"),
    ("creep", ["memory.kernel='exponential'", "memory.alpha=[0.1, 0.2]", "memory.tau=[1.0, 1.0]"],
     "memory.tau", "the time scale 1.0 twice"),
    ("creep", ["memory.kernel='prony'", "memory.terms=[{alpha = 0.1, tau = 2.0}, "
               "{alpha = 0.3, tau = 2.0, part = 'full'}]"], "memory.terms[1]",
     "tau = 2.0, part = 'full' twice"),
]


@pytest.mark.parametrize("scene, sets, key, words", REPEATS,
                         ids=[f"{s}:{k}" for s, _, k, _ in REPEATS])
def test_repeated_entries_are_refused_naming_the_key(scene, sets, key, words):
    with pytest.raises(SceneError) as err:
        api.load_scene(scene, sets=sets)
    assert err.value.key == key and words in str(err.value), str(err.value)
    assert "(from --set" in str(err.value)
    given = api.load_scene(scene)                    # the same, set in Python after the load
    for path, value in map(loader.parse_assignment, sets):
        loader._apply_set(given, path, value)
    with pytest.raises(SceneError) as err:
        api.check(given)
    assert err.value.key == key and words in str(err.value), str(err.value)


@pytest.mark.parametrize("sets", [
    [f"dirichlet=[{PAPER_DIRICHLET}, {{boundary = 'right', components = [1]}}]"],
    ["contact.boundary=['bottom']"],
    ["output.probes=[[0.5, 0.5], [0.5, 0.25]]"],
    ["output.figure_times=[0.25, 0.5]"],
    ["creep", "traction=[{boundary = 'right', value = [0.1, 0.0]}, "
              "{boundary = 'top', value = [0.0, -0.1]}]"],
])
def test_distinct_entries_stay_allowed(sets):
    sets = list(sets)
    name = sets.pop(0) if sets[0] == "creep" else "paper"
    scene = api.load_scene(name, sets=sets)
    path, value = loader.parse_assignment(sets[0])
    node = scene
    for key in path:
        node = node[key]
    assert len(node) == len(value)


# ---- numbers beyond a double, nesting, limits ----

NUMERIC_KEYS = [
    "time.T", "time.steps", "material.E", "material.nu", "material.lambda", "material.mu",
    "contact.stiffness", "contact.g", "contact.mu", "contact.gap", "contact.augmentation",
    "memory.alpha", "memory.tau", "memory.beta", "memory.tolerance", "geometry.rotation",
    "geometry.cells", "geometry.lower", "geometry.upper", "solver.max_cuts",
    "output.snapshot_max_nodes", "output.field_every", "output.checkpoint_every",
    "output.checkpoint_seconds", "output.figure_times", "output.field_times", "output.probes",
    "dirichlet.0.value", "body_force.value", "discretization.degree",
    "solver.petsc_options.snes_max_it", "name", "description",
]
HUGE = 10 ** 400


@pytest.mark.parametrize("form", ["int", "negative", "in a list", "in a nested list"])
@pytest.mark.parametrize("key", NUMERIC_KEYS)
def test_an_integer_beyond_a_double_is_a_scene_error_naming_the_key(tmp_path, key, form):
    value = {"int": str(HUGE), "negative": str(-HUGE), "in a list": f"[{HUGE}, 0]",
             "in a nested list": f"[[{HUGE}, 0]]"}[form]
    with pytest.raises(SceneError) as err:
        api.load_scene("paper", sets=[f"{key}={value}"])
    message = str(err.value)
    assert "does not fit a floating-point number" in message, message
    assert err.value.key.replace("[", ".").replace("]", "").startswith(key), err.value.key
    assert len(message) < 400                  # the 401 digits are not printed


def test_an_integer_beyond_a_double_in_a_file_and_in_python(tmp_path):
    path = tmp_path / "big.toml"
    path.write_text(f'name = "big"\n[time]\nsteps = {HUGE}\n[[dirichlet]]\nboundary = "left"\n')
    with pytest.raises(SceneError, match=r"time.steps = 100000\.\.\. \(401 digits\) does not "
                                         r"fit .* \(big.toml, line 3"):
        api.load_scene(str(path))
    scene = small()
    scene["contact"]["stiffness"] = HUGE
    with pytest.raises(SceneError, match=f"contact.stiffness = .* does not fit .*{CHANGED}"):
        api.solve(scene)
    scene = small()
    scene["time"]["steps"] = 10 ** 300               # a double, but a bound run
    with pytest.raises(SceneError, match=f"is more than {MAX_STEPS} steps"):
        api.check(scene)


@pytest.mark.parametrize("text", [
    "[output]\nprobes = " + "[" * 100_000 + "]" * 100_000,
    "[geometry]\nparameters = " + "{a = " * 100_000 + "1" + "}" * 100_000,
    "x = " + "[{a = " * 50_000 + "1" + "}]" * 50_000,
])
def test_very_deep_toml_is_a_scene_error_naming_the_file(tmp_path, text):
    path = tmp_path / "deep.toml"
    path.write_text('name = "deep"\n' + text + "\n")
    with pytest.raises(SceneError, match=f"{path}: arrays or tables nested too deeply"):
        api.load_scene(str(path))


def test_deep_values_given_otherwise_are_scene_errors():
    with pytest.raises(SceneError, match="--set output.probes: the value nests"):
        api.load_scene("paper", sets=["output.probes=" + "[" * 100_000 + "]" * 100_000])
    with pytest.raises(SceneError, match="output.probes: arrays or tables nested more than 32"):
        api.load_scene("paper", sets=["output.probes=" + "[" * 40 + "]" * 40])
    with pytest.raises(SceneError, match="solver.petsc_options.a: arrays or tables nested"):
        api.load_scene("paper", sets=["solver.petsc_options.a=" + "{a = " * 40 + "1"
                                      + "}" * 40])


def test_probes_and_steps_have_limits():
    points = [[0.5, i / (2 * MAX_PROBES)] for i in range(MAX_PROBES + 1)]
    with pytest.raises(SceneError, match=f"output.probes lists {MAX_PROBES + 1} points, at "
                                         f"most {MAX_PROBES}"):
        api.load_scene("paper", output={"probes": points})
    assert len(api.load_scene("paper", output={"probes": points[:MAX_PROBES]})
               ["output"]["probes"]) == MAX_PROBES
    with pytest.raises(SceneError, match=f"time.steps = {MAX_STEPS + 1} is more than"):
        api.load_scene("paper", time={"steps": MAX_STEPS + 1, "rule": "trapezoid"})
    assert api.load_scene("paper", time={"steps": MAX_STEPS})["time"]["steps"] == MAX_STEPS
