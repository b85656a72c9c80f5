"""What a force-controlled obstacle that cannot be balanced says, and a rigid obstacle that
starts inside the body: each failure its own message naming the key (a force that pulls, an
obstacle driven through the body, a body held by the obstacle alone, a tangential force above
the friction limit, an obstacle out of contact, a bordered Newton system that does not
converge), with the steps before kept; on 1 and 2 ranks (the diagnosis is collective)."""
import json

import numpy as np
import pytest
from mpi4py import MPI

from contactvisco import api
from contactvisco.errors import SceneError
from contactvisco.scene import loader
from contactvisco.solver.check import INITIAL_PENETRATION
from contactvisco.solver.newton import NewtonFailure
from contactvisco.solver.time_loop import simulate

COMM = MPI.COMM_WORLD
R = 1.0


def layer(obstacle: dict, steps: int = 4, contact: dict | None = None) -> dict:
    """A layer [0, 2] x [0, 1], its top held, on an obstacle below (E = 200, nu = 0.3)."""
    return {"name": "layer", "geometry": {"type": "gmsh", "script": "rectangle",
            "parameters": {"length": 2.0, "height": 1.0, "h": 0.2, "h_bottom": 0.05}},
            "material": {"model": "plane_strain", "E": 200.0, "nu": 0.3},
            "dirichlet": [{"boundary": "top", "components": "all"}],
            "contact": contact or {"boundary": "bottom", "g": 0.0, "mu": 0.0,
                                   "augmentation": 200.0},
            "obstacle": obstacle, "time": {"T": 1.0, "steps": steps},
            "output": {"probes": [], "xdmf": False}}


def cylinder(dy: float = 0.0, **keys) -> dict:
    """A cylinder of radius 1 under the layer, touching it at (1, 0) when dy = 0."""
    return {"shape": "cylinder", "centre": [1.0, -R + dy], "radius": R, **keys}


def run(raw: dict, out):
    return simulate(loader.resolve(raw), out=out, comm=COMM, progress=False)


def records(out) -> list:
    return [json.loads(line) for line in (out / "steps.jsonl").read_text().splitlines()]


def shared(tmp_path):
    """One output folder for every rank (rank 0's temporary folder)."""
    return COMM.bcast(tmp_path if COMM.rank == 0 else None) / "out"


#: The words of each cause.
CAUSES = {"pulls": "pulls the obstacle away", "through the body": "passes through the body",
          "out of contact": "the obstacle is out of contact",
          "friction limit": "acts along the contact surface", "floats": "the body floats"}


@pytest.mark.mpi
@pytest.mark.parametrize("case, raw, words, kept", [
    ("pulls", layer(cylinder(force_components=[1], force=["-0.1 * t"])),
     ["pulls the obstacle away", "F . m = -0.025 < 0"], 1),
    ("through the body", layer(cylinder(force_components=[1], force=["400 * t"])),
     ["passes through the body", "more than the body's size 2"], 2),
    ("out of contact", layer(cylinder(-0.01, force_components=[1], force=["0.1 * t"])),
     ["the obstacle is out of contact"], 1),
    ("friction limit", layer(
        {"shape": "plane", "point": [0.0, 0.0], "normal": [0.0, 1.0],
         "force_components": [1, 0], "force": ["0.2", "0.2 * t"]},
        contact={"boundary": "bottom", "g": 0.0, "mu": 0.3, "augmentation": 200.0,
                 "friction_law": "coulomb"}),
     ["obstacle.force[1] (component 0) acts along the contact surface",
      "contact.mu = 0.3"], 2),
])
def test_force_control_failure_says_what_happened(tmp_path, case, raw, words, kept):
    """Each failure names obstacle.force, the prescribed value and time, and its own cause;
    the states before it are on disk (pulling: t = 0; through the body at t = 0.5, after the
    force 100 at t = 0.25 was carried: t = 0, 0.25; the tangential force 0.1 at t = 0.5 above
    mu P = 0.06: t = 0, 0.25)."""
    out = shared(tmp_path)
    with pytest.raises(SceneError) as err:
        run(raw, out)
    assert err.value.key == "obstacle.force"
    text = str(err.value)
    for word in words:
        assert word in text, text
    said = [cause for cause in CAUSES.values() if cause in text]
    assert said == [CAUSES[case]], text                  # its own cause, and no other
    steps = records(out)
    assert len(steps) == kept, [s["t"] for s in steps]
    if case == "through the body":
        # the force carried at t = 0.25 left the obstacle well inside the body's size
        assert 0 < steps[-1]["obstacle"]["displacement"][1] < 1.0


@pytest.mark.mpi
def test_body_held_by_the_obstacle_alone_floats():
    """The Hertz disk pressed by its top traction onto a force-controlled plane, not held
    along y: the body and the plane move together, whatever the force. Named as such, with
    the loads' resultant along y (-q R = -0.25)."""
    scene = loader.load("hertz", [
        "contact.gap=0", "obstacle.shape='plane'", "obstacle.point=[0.0, 0.0]",
        "obstacle.normal=[0.0, 1.0]", "obstacle.force_components=[1]",
        "obstacle.force=['0.25 * t']", "time.steps=2", "geometry.parameters.h_contact=0.02"])
    with pytest.raises(SceneError) as err:
        simulate(scene, comm=COMM, progress=False)
    assert err.value.key == "obstacle.force"
    assert "the body floats" in str(err.value) and "R = -0.25" in str(err.value)


def test_bordered_newton_failure_names_the_force(tmp_path):
    """A force the body carries, in one step with two Newton iterations allowed and no step
    cut: the final failure (exit 3 on the command line) names obstacle.force, the force and
    the obstacle's last equilibrium."""
    raw = layer(cylinder(force_components=[1], force=["80 * t"]), steps=1)
    raw["solver"] = {"max_cuts": 0, "petsc_options": {"snes_max_it": 2}}
    with pytest.raises(NewtonFailure) as err:
        simulate(loader.resolve(raw), comm=COMM, progress=False)
    text = str(err.value)
    assert "obstacle.force" in text and "[80.0] at t = 1" in text, text
    assert "d = [0.0, 0.0] at the last equilibrium" in text, text


@pytest.mark.mpi
@pytest.mark.parametrize("route", ["solve", "check"])
def test_obstacle_starting_deep_inside_the_body_is_refused(tmp_path, route):
    """A cylinder whose top lies 0.5 inside a layer 1 thick: refused before any step (by the
    run and by check), naming obstacle.centre, the deepest node (1, 0) and its depth 0.5, and
    the limit contact.g + 0.1 L = 0.2; nothing written."""
    raw = layer(cylinder(0.5, displacement=[0.0, "0.001 * t"]))
    out = shared(tmp_path)
    with pytest.raises(SceneError) as err:
        if route == "solve":
            run(raw, out)
        else:
            api.check(loader.resolve(raw), comm=COMM)
    text = str(err.value)
    assert err.value.key == "obstacle.centre"
    assert "the deepest by 0.5 at (1, 0)" in text, text
    assert f"more than {INITIAL_PENETRATION * 2.0:g}" in text, text
    assert not (out / "steps.jsonl").exists()


def test_shallow_interference_is_pushed_out():
    """A cylinder 0.001 inside the layer (an interference, below 0.1 L): accepted; the first
    state pushes the layer out so that the node on the axis rests on the cylinder
    (u_nu = h = -0.001 there, to round-off) with a compressive reaction."""
    raw = layer(cylinder(0.001), steps=1)
    result = simulate(loader.resolve(raw), comm=COMM, progress=False, keep_tables=True)
    table = result.tables[0]
    if len(table["x"]):
        at = np.argmin(np.abs(table["x"][:, 0] - 1.0) + np.abs(table["x"][:, 1]))
        assert abs(table["gap"][at] + 0.001) < 1e-9
        assert abs(table["u_nu"][at] - table["gap"][at]) < 1e-9
        assert table["reaction_nu"][at] > 0


def test_force_from_a_zero_force_touch():
    """A cylinder 0.001 inside the layer under F = 0.2 t: the first state (F = 0) pushes it out
    to a touch at zero force, where no node need be in contact; the next steps start pushed
    into contact and give the run that starts touching, shifted by -0.001 (the same body,
    the same forces), to 1e-9 of the depth."""
    def depths(dy):
        raw = layer(cylinder(dy, force_components=[1], force=["0.2 * t"]))
        result = simulate(loader.resolve(raw), comm=COMM, progress=False)
        return np.array([s["obstacle"]["displacement"][1] for s in result.steps])
    touching, inside = depths(0.0), depths(0.001)
    assert len(inside) == len(touching) == 5
    assert abs(inside[0] + 0.001) < 1e-12
    assert np.max(np.abs(inside - (touching - 0.001))) < 1e-9 * touching[-1]
