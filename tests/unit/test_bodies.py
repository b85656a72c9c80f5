"""Several bodies in one mesh ([[body]] tables), each with its own A and memory kernel."""
import math

import numpy as np
import pytest
from mpi4py import MPI

from contactvisco.errors import SceneError
from contactvisco.fem import geometry as geometry_module
from contactvisco.fem.problem import build
from contactvisco.scene import loader
from contactvisco.solver.newton import create

PRESSURE = 0.3
HALF = 0.5                    # each layer's height


def bilayer(lower: dict, upper: dict, T=1.0, steps=1, **extra) -> dict:
    """A unit square of two layers glued at y = 1/2 (one conforming mesh), plane stress with
    nu = 0: under a uniform pressure on its top, held at its bottom (y) and left side (x),
    each layer is in uniaxial stress sigma_yy = -PRESSURE."""
    raw = {
        "name": "bilayer",
        "geometry": {"type": "box", "lower": [0.0, 0.0], "upper": [1.0, 1.0],
                     "cells": [3, 6]},
        "material": {"model": "plane_stress", "E": 1.0, "nu": 0.0},
        "dirichlet": [{"boundary": "bottom", "components": [1]},
                      {"boundary": "left", "components": [0]}],
        "traction": [{"boundary": "top", "value": [0.0, -PRESSURE]}],
        "body": [{"name": "lower", "cells": "0.5 - x[1]", **lower},
                 {"name": "upper", "cells": "x[1] - 0.5", **upper}],
        "time": {"T": T, "steps": steps, "rule": "trapezoid"},
        "output": {"probes": []},
    }
    raw.update(extra)
    return raw


def layer_strains(raw):
    """Per step: the strain eps_yy of the lower and of the upper layer, from u_y at y = 1/2
    and y = 1 (every node of a level must agree), and the times."""
    scene = loader.resolve(raw)
    comm = MPI.COMM_WORLD
    problem = build(scene, geometry_module.build(scene, comm))
    snes = create(problem, comm)
    x = problem.V.tabulate_dof_coordinates()
    T, N = scene["time"]["T"], scene["time"]["steps"]
    times, out = [], []
    for n in range(N + 1):
        problem.time.stage(n * T / N)
        snes.solve()
        problem.time.commit()
        uy = problem.u.x.array.reshape(-1, 2)[:, 1]
        levels = []
        for y in (HALF, 1.0):
            mine = uy[np.abs(x[:, 1] - y) < 1e-12]
            low = comm.allreduce(float(mine.min()) if mine.size else math.inf, MPI.MIN)
            high = comm.allreduce(float(mine.max()) if mine.size else -math.inf, MPI.MAX)
            assert high - low <= 1e-12 * max(abs(low), 1.0)
            levels.append(low)
        times.append(n * T / N)
        out.append((levels[0] / HALF, (levels[1] - levels[0]) / HALF))
    return np.array(times), np.array(out)


def test_bilayer_series_springs():
    """Two layers of E = 2 and 7 in series: eps_yy = -p / E_b in each, so the top moves by
    -p (h / E_1 + h / E_2)."""
    _, strains = layer_strains(bilayer({"material": {"E": 2.0}}, {"material": {"E": 7.0}}))
    assert strains[-1] == pytest.approx([-PRESSURE / 2.0, -PRESSURE / 7.0], rel=1e-10)


def creep(E, alpha, tau, t):
    """The strain of sigma = E eps + int_0^t alpha exp(-(t - s)/tau) eps(s) ds under a
    constant stress -p from t = 0 (Laplace transform): with a = 1/tau + alpha/E,
    eps = -p/E (1/(a tau) + (1 - 1/(a tau)) exp(-a t))."""
    a = 1.0 / tau + alpha / E
    return -PRESSURE / E * (1.0 / (a * tau) + (1.0 - 1.0 / (a * tau)) * np.exp(-a * t))


def test_two_kernels_creep_each_its_own_way():
    """Two layers with different exponential kernels under a constant pressure: each creeps
    with its own closed form (the trapezoid rule's error, O(k^2), is the only one)."""
    bodies = ((2.0, -0.6, 1.0), (5.0, -8.0, 0.25))
    tables = [{"material": {"E": E}, "memory": {"kernel": "exponential", "alpha": [alpha],
                                                 "tau": [tau]}} for E, alpha, tau in bodies]
    errors = []
    for steps in (20, 40):
        times, strains = layer_strains(bilayer(*tables, T=2.0, steps=steps))
        exact = np.array([creep(E, a, tau, times) for E, a, tau in bodies]).T
        errors.append(np.max(np.abs(strains - exact), axis=0)
                      / np.max(np.abs(exact), axis=0))
    # each layer has crept: its final strain is far from its elastic one
    for b, (E, alpha, tau) in enumerate(bodies):
        assert abs(exact[-1, b]) > 1.2 * PRESSURE / E
    print("relative errors (20, 40 steps):", errors)
    assert np.all(errors[-1] < 5e-3)
    assert np.all(errors[-1] < errors[0] / 3.0)          # second order: ratio about 4


@pytest.mark.parametrize("change, key", [
    (lambda raw: raw["body"][0].update(cells="nowhere + 1"), "body[0].cells"),
    (lambda raw: raw["body"][0].update(cells="0.25 - x[1]"), "body"),
    (lambda raw: raw["body"][0].update(cells="0.75 - x[1]"), "body"),
    (lambda raw: raw["body"][0].update(cells="-1"), "body[0].cells"),
])
def test_cells_refused(change, key):
    """A body whose cells name nothing, cells in no body or in two: a SceneError naming the
    key."""
    raw = bilayer({}, {})
    change(raw)
    scene = loader.resolve(raw)
    with pytest.raises(SceneError) as err:
        build(scene, geometry_module.build(scene, MPI.COMM_WORLD))
    assert err.value.key == key


@pytest.mark.parametrize("change, key", [
    (lambda raw: raw["body"][1].update(name="lower"), "body[1].name"),
    (lambda raw: raw["body"][0].update(material={"E": 1.0, "stiffnes": 2.0}),
     "body[0].material"),
    (lambda raw: raw["body"][0].update(material={"E": -1.0}), "body[0].material.E"),
    (lambda raw: raw["body"][0].update(material={"model": "3d"}), "body[0].material"),
    (lambda raw: raw["body"][0].update(material={"law": "hencky"}), "body[0].material"),
    (lambda raw: raw["body"][0].update(memory={"kernel": "exponential", "alpha": [1.0],
                                               "tau": [-1.0]}), "body[0].memory.tau"),
    (lambda raw: raw["body"][0].pop("cells"), "body[0].cells"),
    (lambda raw: raw.update(contact={"boundary": "bottom", "stiffness": 1.0},
                            obstacle={"shape": "body", "boundary": "bottom"}),
     "obstacle.boundary"),
    (lambda raw: raw.update(contact={"boundary": "bottom", "stiffness": 1.0},
                            obstacle={"shape": "body"}), "obstacle.boundary"),
    (lambda raw: raw.update(contact={"boundary": "bottom", "stiffness": 1.0,
                                     "pairing": "closest"}), "contact.pairing"),
    (lambda raw: raw.update(contact={"boundary": "bottom", "stiffness": 1.0,
                                     "search_distance": -1.0}), "contact.search_distance"),
])
def test_keys_refused(change, key):
    """[[body]], obstacle.shape = "body" and the pairing keys are checked on loading, the
    error naming the key."""
    raw = bilayer({}, {})
    change(raw)
    with pytest.raises(SceneError) as err:
        loader.resolve(raw)
    assert err.value.key == key


def test_no_body_is_one_body():
    """Without [[body]] the scene has an empty list of bodies and the material of [material]
    acts everywhere."""
    raw = bilayer({}, {})
    raw.pop("body")
    raw["material"]["E"] = 4.0
    _, strains = layer_strains(raw)
    assert loader.resolve(raw)["body"] == []
    assert strains[-1] == pytest.approx([-PRESSURE / 4.0] * 2, rel=1e-10)


def test_paper_rule_stability_takes_the_worst_body():
    """The paper's rule is stable while b = k |R(0)| (1 + nu) / E < 1 in every body: the
    scene's own [memory] is none (b = 0 there), the upper body's kernel gives
    b = k 1.5 / 1, the lower body's b = k 0.5 / 0.5 = k; at k = 1 (4 steps of T = 4) the
    upper body's b = 1.5 refuses the scene naming time.steps, the rule and that body; at
    k = 0.5 it is accepted with b = 0.75, and check() reports it with the body's name (and,
    for the trapezoid rule, the least stiff body's step stiffness)."""
    from contactvisco.model.stability import stability_number
    from contactvisco.solver.check import check
    upper = {"memory": {"kernel": "exponential", "alpha": [-1.5], "tau": [1.0]}}
    lower = {"material": {"E": 0.5}, "memory": {"kernel": "exponential", "alpha": [-0.5],
                                                 "tau": [2.0]}}
    raw = bilayer(lower, upper, T=4.0, steps=4)
    raw["time"]["rule"] = "paper"
    with pytest.raises(SceneError) as err:
        loader.resolve(raw)
    assert err.value.key == "time.steps"
    assert "time.rule = 'paper'" in str(err.value) and "body 'upper'" in str(err.value)
    assert "= 1.5 >= 1" in str(err.value)
    raw["time"]["steps"] = 8
    scene = loader.resolve(raw)
    assert stability_number(scene) == pytest.approx(0.75, rel=1e-14)
    report = check(scene, comm=MPI.COMM_WORLD)
    assert report["stability_number"] == pytest.approx(0.75, rel=1e-14)
    assert report["stability_body"] == "upper" and not report["unstable"]
    # The trapezoid rule: the step's stiffness 2 mu + k/2 R(0) of the least stiff body, the
    # lower one (0.5 - 0.25 * 0.5; the upper one has 1 - 0.25 * 1.5).
    raw["time"]["rule"] = "trapezoid"
    report = check(loader.resolve(raw), comm=MPI.COMM_WORLD)
    least, elastic = report["implicit_stiffness"]["deviatoric"]
    assert (least, elastic) == pytest.approx((0.375, 0.5), rel=1e-12)
    raw["time"]["rule"] = "paper"
    raw["body"][0]["memory"] = {"kernel": "exponential", "alpha": [-4.0], "tau": [1.0]}
    with pytest.raises(SceneError, match="body 'lower'.* = 4 >= 1"):   # 0.5 * 4 / 0.5
        loader.resolve(raw)
