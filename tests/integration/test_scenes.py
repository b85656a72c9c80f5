"""Built-in scenes, gmsh geometries, kernels, expressions, and building only what a scene needs."""
import math

import numpy as np
import pytest
from mpi4py import MPI

from contactvisco.errors import SceneError
from contactvisco.fem import geometry, problem as problem_module
from contactvisco.scene import loader as scene_module
from contactvisco.model.memory import DirectHistory, History, table_kernel
from contactvisco.solver.time_loop import simulate
from contactvisco.studies.verification import hertz

COMM = MPI.COMM_WORLD


@pytest.mark.mpi
@pytest.mark.parametrize("name", scene_module.builtin_names())
def test_builtin_scene_builds(name):
    """Every built-in scene resolves and builds (gmsh meshes made and named), with the unknowns
    its contact law needs."""
    scene = scene_module.load(name)
    problem = problem_module.build(scene, geometry.build(scene, COMM))
    contact = scene["contact"]
    unknowns = set(problem.count_unknowns())
    assert ("lambda_nu" in unknowns) == math.isfinite(contact["g"])
    assert ("lambda_tau" in unknowns) == (contact["mu"] > 0)
    assert problem.contact is not None
    n_contact = COMM.allreduce(int(problem.contact.nodes.owned.sum()))
    assert n_contact >= 9


def test_hertz_against_closed_form():
    """The built-in hertz scene (a/R = 0.054, contact mesh a/20): half-width (the midpoint of
    the last contact element, so up to h/2a = 2.5 % off by construction) within 3 % and peak
    pressure within 1 % of Hertz (measured 2.75 % and 0.41 %); Signorini holds node by node."""
    result = hertz()
    assert result["a_error"] < 0.03 and result["p0_error"] < 0.01, result
    scene = scene_module.load("hertz")
    table = simulate(scene, comm=COMM, progress=False, keep_tables=True).tables[-1]
    touching = table["status"] == 2
    assert np.all(table["penetration"] <= 1e-10) and np.all(table["reaction_nu"] >= -1e-10)
    assert np.max(np.abs(table["reaction_nu"][~touching])) < 1e-10


@pytest.mark.mpi
def test_ironing_nodes_go_through_every_state():
    scene = scene_module.load("ironing", ["geometry.parameters.h=0.1", "time.steps=20"])
    result = simulate(scene, comm=COMM, progress=False, keep_tables=True)
    states = np.array([t["status"] for t in result.tables])     # (steps, nodes)
    x = result.tables[0]["x"][:, 0]
    middle = np.flatnonzero(np.abs(x - 1.5) < 0.3)
    cycled = 0
    for node in middle:
        history = states[:, node]
        if history[0] != 2 and 2 in history:
            first_bound = np.argmax(history == 2)
            after = history[first_bound:]
            if 1 in history[:first_bound] and np.any(after < 2) and history[-1] != 2:
                cycled += 1
    assert cycled >= 3


def test_no_contact_is_plain_viscoelasticity():
    scene = scene_module.load("paper", ["geometry.cells=[4, 4]"])
    scene["contact"] = None
    scene["dirichlet"].append({"boundary": "bottom", "components": "all"})
    problem = problem_module.build(scene, geometry.build(scene, COMM))
    assert set(problem.count_unknowns()) == {"u"} and problem.contact is None
    assert problem.memory is not None


def test_signorini_builds_no_compliance_term():
    scene = scene_module.load("paper", ["geometry.cells=[4, 4]", "contact.g=0",
                                        "contact.mu=0"])
    problem = problem_module.build(scene, geometry.build(scene, COMM))
    assert "stiffness" not in problem.constants
    assert set(problem.count_unknowns()) == {"u", "lambda_nu"}
    stiffness = scene_module.load("paper", ["geometry.cells=[4, 4]"])
    full = problem_module.build(stiffness, geometry.build(stiffness, COMM))
    assert "stiffness" in full.constants


def uniaxial(memory, rule="paper", traction="-10.0", top=None, steps=4):
    raw = {"name": "uniaxial",
           "geometry": {"lower": [0.0, 0.0], "upper": [1.0, 1.0], "cells": [2, 2]},
           "material": {"model": "plane_strain", "E": 100.0, "nu": 0.3},
           "memory": memory,
           "dirichlet": [{"boundary": "bottom", "components": [1]},
                         {"boundary": "left", "components": [0]},
                         {"boundary": "right", "components": [0]}],
           "traction": [] if top else [{"boundary": "top", "value": [0.0, traction]}],
           "time": {"T": 1.0, "steps": steps, "rule": rule},
           "output": {"probes": [[0.5, 1.0], [0.5, 0.5]]}}
    if top:
        raw["dirichlet"].append({"boundary": "top", "components": [1], "value": top})
    result = simulate(scene_module.resolve(raw), comm=COMM, progress=False)
    return np.array([[p["u"][1] for p in s["probes"]] for s in result.steps])


@pytest.mark.parametrize("rule", ["paper", "trapezoid"])
def test_kernels_that_are_the_same_give_the_same_answer(rule):
    """constant alpha == prony full == prony deviatoric + volumetric with equal alpha ==
    table with r(t) = alpha (a direct sum): the dev/vol split and the direct sum are exact."""
    constant = uniaxial({"kernel": "constant", "alpha": 60.0}, rule)
    variants = [
        {"kernel": "prony", "terms": [{"alpha": 60.0}]},
        {"kernel": "prony", "terms": [{"alpha": 60.0, "part": "deviatoric"},
                                      {"alpha": 60.0, "part": "volumetric"}]},
        {"kernel": "table", "times": [0.0, 5.0], "values": [60.0, 60.0]},
    ]
    for memory in variants:
        assert np.max(np.abs(uniaxial(memory, rule) - constant)) < 1e-13, memory
    assert abs(constant[-1, 0] - constant[0, 0]) > 1e-3     # the memory did act


def test_deviatoric_and_volumetric_parts_differ():
    dev = uniaxial({"kernel": "prony", "terms": [{"alpha": 60.0, "part": "deviatoric"}]})
    vol = uniaxial({"kernel": "prony", "terms": [{"alpha": 60.0, "part": "volumetric"}]})
    # in uniaxial strain eps = e (0,1)(0,1): dev carries e/2 on eps_yy, vol e/2 as well (2D)
    assert np.allclose(dev, vol, atol=1e-13)
    shear = uniaxial({"kernel": "prony", "terms": [{"alpha": 60.0, "part": "deviatoric"},
                                                   {"alpha": 30.0, "part": "volumetric"}]})
    assert np.max(np.abs(shear - dev)) > 1e-4


def test_direct_history_matches_recursion():
    rng = np.random.default_rng(1)
    strains = [rng.standard_normal(8) for _ in range(25)]
    k, alpha, tau = 0.1, 7.0, 0.4
    recursion = History([(alpha, tau, "full")], k)
    direct = DirectHistory(lambda t: alpha * math.exp(-t / tau), k)
    for e in strains:
        assert np.allclose(recursion.advance(e), direct.advance(e), rtol=1e-12, atol=0)
    r = table_kernel([0.0, 1.0, 2.0], [3.0, 1.0, 1.0])
    assert r(0.5) == 2.0 and r(10.0) == 1.0


def test_time_dependent_traction_and_dirichlet_expressions():
    """Memoryless uniaxial strain: u_y(top) = -q(t) / M for q(t) = 10 t; and with the top
    displacement prescribed as -0.02 t**2, the mid-height node moves by half of it."""
    M = 100.0 * 0.7 / (1.3 * 0.4)
    u = uniaxial({"kernel": "none"}, traction="-10.0 * t")
    t = np.linspace(0.0, 1.0, 5)
    assert np.allclose(u[:, 0], -10.0 * t / M, atol=1e-13)
    u = uniaxial({"kernel": "none"}, top="-0.02 * t**2")
    assert np.allclose(u[:, 0], -0.02 * t**2, atol=1e-14)
    assert np.allclose(u[:, 1], -0.01 * t**2, atol=1e-13)


def test_lame_input():
    scene = scene_module.load("paper", ["material.E=1", "material.nu=0.3",
                                        "time.rule='trapezoid'"])
    raw = {"material": {"model": "plane_strain", "lambda": 100 * 0.3 / (1.3 * 0.4),
                        "mu": 100 / 2.6}}
    scene = scene_module.resolve(raw)
    assert scene["material"]["E"] == pytest.approx(100.0)
    assert scene["material"]["nu"] == pytest.approx(0.3)
    with pytest.raises(SceneError, match="either E and nu or lambda and mu"):
        scene_module.resolve({"material": {"E": 1.0, "mu": 2.0}})


@pytest.mark.parametrize("value, words", [
    ([0.0, "-10 * s"], "the name 's' is not allowed"),
    ([0.0, "-10 *"], "not a valid expression"),
    ([0.0], "must be a list of 2 components"),
    ([0.0, "x"], "x without an index is not allowed"),
])
def test_bad_expressions_are_named(value, words):
    scene = scene_module.load("paper", ["geometry.cells=[2, 2]"])
    scene["traction"][0]["value"] = value
    with pytest.raises(SceneError) as err:
        problem_module.build(scene, geometry.build(scene, COMM))
    assert words in str(err.value) and "traction[0].value" in str(err.value)


def test_unknown_mesh_script():
    with pytest.raises(SceneError, match="built-in mesh script .* got 'nope'"):
        scene_module.load("hertz", ["geometry.script='nope'"])
    scene = scene_module.load("hertz")
    scene["geometry"]["script"] = "/tmp/nope"         # past the scene check: refused again
    with pytest.raises(SceneError, match="no mesh script '/tmp/nope'"):
        geometry.build(scene, COMM)
