"""Property-based tests (hypothesis, derandomized so that every run checks the same cases):
valid scenes solve with the discrete contact conditions satisfied at every step; invalid
values anywhere in a scene give a SceneError, never another exception."""
import math

import numpy as np
import pytest
from helpers import assert_contact_conditions
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from mpi4py import MPI

from contactvisco.errors import SceneError
from contactvisco.fem import geometry, problem as problem_module
from contactvisco.scene import loader as scene_module
from contactvisco.solver.time_loop import simulate

pytestmark = pytest.mark.skipif(MPI.COMM_WORLD.size > 1,
                                reason="hypothesis draws per process; run on one rank")
SETTINGS = settings(max_examples=12, deadline=None, derandomize=True, database=None,
                    suppress_health_check=list(HealthCheck))


@st.composite
def valid_scenes(draw):
    cells = draw(st.integers(2, 8))
    g = draw(st.sampled_from([0.01, 0.05, 0.3, math.inf]))
    stiffness = draw(st.sampled_from([1.0, 100.0, 1e4]))
    return [f"geometry.cells=[{cells}, {draw(st.integers(2, 8))}]",
            f"material.model='{draw(st.sampled_from(['plane_stress', 'plane_strain']))}'",
            f"material.nu={draw(st.sampled_from([0.0, 0.2, 0.3, 0.45]))}",
            f"memory.alpha={draw(st.sampled_from([0.0, 10.0, 100.0]))}",
            f"contact.stiffness={stiffness}",
            f"contact.g={'inf' if math.isinf(g) else g}",
            f"contact.mu={draw(st.sampled_from([0.0, 0.2, 0.8]))}",
            f"contact.augmentation={draw(st.sampled_from([1.0, 100.0, 1e5]))}",
            f"time.steps={draw(st.integers(1, 4))}",
            f"time.rule='{draw(st.sampled_from(['paper', 'trapezoid']))}'",
            "output.probes=[]"]


@SETTINGS
@given(valid_scenes())
def test_valid_scenes_satisfy_the_contact_conditions(overrides):
    scene = scene_module.load("paper", overrides)
    result = simulate(scene, comm=MPI.COMM_SELF, progress=False, keep_tables=True)
    scale = max(1.0, max(np.max(np.abs(t["reaction_nu"])) for t in result.tables))
    for step, table in zip(result.steps, result.tables):
        assert step["residual"] < 1e-9
        roller = table["x"][:, 0] > 1.0 - 1e-12
        assert_contact_conditions(table, scene["contact"]["g"], 1e-9 * scale, roller,
                                  direction_tol=1e-6 * scale)


KEYS = ["material.E", "material.nu", "material.model", "memory.kernel", "memory.alpha",
        "contact.g", "contact.mu", "contact.stiffness", "contact.augmentation",
        "contact.boundary", "contact.gap", "time.T", "time.steps", "time.rule",
        "geometry.cells", "geometry.lower", "geometry.diagonal", "geometry.rotation",
        "discretization.degree", "discretization.contact_quadrature", "body_force.value",
        "traction.0.value", "traction.0.boundary", "dirichlet.0.components",
        "dirichlet.0.value", "output.probes", "output.fields", "solver.max_cuts", "preset"]

toml_values = st.recursive(
    st.one_of(st.integers(-10**6, 10**6), st.sampled_from(["nan", "inf", "-inf", "-1.0", "0.0"]),
              st.booleans().map(lambda b: str(b).lower()),
              st.text("abcxyz0[] ,.", max_size=6).map(lambda s: repr(s))),
    lambda inner: st.lists(inner, max_size=3).map(lambda v: "[" + ", ".join(map(str, v)) + "]"),
    max_leaves=4)


@SETTINGS
@given(st.sampled_from(KEYS), toml_values)
def test_any_value_gives_a_scene_error_or_a_scene(key, value):
    """Arbitrary values at every key: either a scene that builds, or a SceneError; never
    another exception (a bare traceback for the user)."""
    try:
        scene = scene_module.load("paper", [f"{key}={value}", "geometry.cells=[2, 2]"]
                                  if key != "geometry.cells" else [f"{key}={value}"])
        if scene["geometry"]["cells"] and max(scene["geometry"]["cells"]) > 64:
            return                                    # valid, but too big to build here
        problem_module.build(scene, geometry.build(scene, MPI.COMM_SELF))
    except SceneError as err:
        assert str(err)
