"""Keys without a meaning for an axisymmetric body are refused before anything is built,
each with a SceneError naming the key."""
import pytest

from contactvisco.errors import SceneError
from contactvisco.scene import loader as scene_module


def indentation(**obstacle) -> dict:
    """A cylinder 0 <= r <= 1 indented along the axis by a sphere (raw scene)."""
    sphere = {"shape": "sphere", "centre": [0.0, 1.5], "radius": 0.5,
              "displacement": [0.0, "-0.01 * t"]}
    return {"name": "axi", "geometry": {"lower": [0.0, 0.0], "upper": [1.0, 1.0],
                                        "cells": [4, 4]},
            "material": {"model": "axisymmetric", "E": 1.0, "nu": 0.3},
            "dirichlet": [{"boundary": "bottom", "components": "all"}],
            "contact": {"boundary": "top", "g": 0.0, "mu": 0.0},
            "obstacle": {**sphere, **obstacle}, "time": {"T": 1.0, "steps": 1},
            "output": {"probes": []}}


def test_a_sphere_on_the_axis_is_accepted():
    assert scene_module.resolve(indentation())["material"]["model"] == "axisymmetric"


@pytest.mark.parametrize("change, key, words", [
    ({"centre": [0.2, 1.5]}, "obstacle.centre", "centred on the axis"),
    ({"displacement": [0.01, "-0.01 * t"]}, "obstacle.displacement", "along the axis only"),
    ({"displacement": None, "force_components": [0], "force": ["0.1 * t"]},
     "obstacle.force_components", "along the axis only"),
    ({"shape": "cylinder"}, "obstacle.shape", "no axisymmetric version"),
])
def test_obstacle_keys_without_axisymmetric_meaning_are_refused(change, key, words):
    with pytest.raises(SceneError, match=words) as caught:
        scene_module.resolve(indentation(**change))
    assert caught.value.key == key


CONE = {"shape": "cone", "point": [0.0, 1.0], "angle": 70.3, "centre": None, "radius": None}


@pytest.mark.parametrize("change, key, words", [
    ({**CONE, "point": [0.2, 1.0]}, "obstacle.point", "tip lies on the axis"),
    ({**CONE, "angle": 90}, "obstacle.angle", r"in \(0, 90\)"),
    ({**CONE, "angle": None}, "obstacle.angle", "needs obstacle.angle"),
    ({"shape": "punch", "point": [0.0, 1.0], "centre": None, "radius": None},
     "obstacle.radius", "needs obstacle.radius"),
    ({"angle": 30.0}, "obstacle.angle", "with obstacle.shape = 'cone'"),
])
def test_indenter_keys_are_checked(change, key, words):
    with pytest.raises(SceneError, match=words) as caught:
        scene_module.resolve(indentation(**change))
    assert caught.value.key == key


def test_indenters_need_a_2d_mesh():
    raw = indentation(shape="punch", point=[0.0, 0.0, 1.0], centre=None, radius=0.2,
                      displacement=None)
    raw["material"]["model"] = "3d"
    raw["geometry"] = {"lower": [0.0, 0.0, 0.0], "upper": [1.0, 1.0, 1.0], "cells": [2, 2, 2]}
    with pytest.raises(SceneError, match="needs a 2D mesh") as caught:
        scene_module.resolve(raw)
    assert caught.value.key == "obstacle.shape"


def test_two_bodies_are_refused():
    raw = indentation(shape="body", boundary="left", centre=None, radius=None,
                      displacement=None)
    with pytest.raises(SceneError, match="two deformable bodies in axisymmetry") as caught:
        scene_module.resolve(raw)
    assert caught.value.key == "obstacle.shape"


def test_a_rotated_mesh_is_refused():
    raw = indentation()
    raw["geometry"]["rotation"] = 10.0
    with pytest.raises(SceneError, match="r >= 0") as caught:
        scene_module.resolve(raw)
    assert caught.value.key == "geometry.rotation"
