"""Two deformable bodies in contact (obstacle.shape = "body"): the patch test of two blocks
with non-matching interface nodes (meshes/two_blocks.py: 13 slave against 10 master segments).

The upper (slave) block is pressed by a uniform pressure p on its top onto the lower (master)
block, held at its bottom (y), both blocks' sides held in x, frictionless normal compliance at
the interface: the exact solution has u_x = 0, uniform stresses sigma_yy = -p,
sigma_xx = -p nu / (1 - nu), sigma_xy = 0 in both blocks, and a uniform interface pressure p
(the compliance's uniform penetration p / c_nu). The mortar pairing reproduces it to round-off;
node to segment does not (its error is measured, not bounded).
"""
import math

import numpy as np
import pytest
from dolfinx import fem
from mpi4py import MPI

from contactvisco.errors import SceneError
from contactvisco.fem import geometry as geometry_module
from contactvisco.fem.problem import build
from contactvisco.scene import loader
from contactvisco.solver.newton import NewtonFailure, create

PRESSURE, NU = 0.01, 0.3


def patch_scene(pairing="mortar", **contact) -> dict:
    return {
        "name": "patch",
        "geometry": {"type": "gmsh", "script": "two_blocks",
                     "parameters": {"h_slave": 0.077, "h_master": 0.1}},
        "material": {"model": "plane_strain", "E": 1.0, "nu": NU},
        "dirichlet": [{"boundary": "bottom", "components": [1]},
                      {"boundary": "master_sides", "components": [0]},
                      {"boundary": "slave_sides", "components": [0]}],
        "traction": [{"boundary": "top", "value": [0.0, -PRESSURE]}],
        "contact": {"boundary": "slave", "stiffness": 100.0, "pairing": pairing, **contact},
        "obstacle": {"shape": "body", "boundary": "master"},
        "time": {"T": 1.0, "steps": 1},
        "solver": {"petsc_options": {"snes_rtol": 1e-14, "snes_atol": 1e-15}},
        "output": {"probes": []},
    }


def solve_one_step(raw: dict, comm):
    """The scene's problem and Newton solver after one step to t = 1 from rest, with the
    Newton iteration count."""
    scene = loader.resolve(raw)
    problem = build(scene, geometry_module.build(scene, comm))
    snes = create(problem, comm)
    problem.time.stage(1.0)
    return problem, snes, snes.solve()


def solve_patch(raw):
    """The converged patch: per block (slave, master) the largest deviation of the stress
    from the exact one over p, the interface pressure's deviation over p, and the resultants
    of the slave's contact forces and of what the master receives."""
    comm = MPI.COMM_WORLD
    problem, snes, iterations = solve_one_step(raw, comm)
    sigma = fem.Function(problem.tensor_space)
    sigma.interpolate(problem.sigma_expression)
    owned = problem.tensor_space.dofmap.index_map.size_local
    values = sigma.x.array.reshape(-1, 2, 2)[:owned]
    y = problem.tensor_space.tabulate_dof_coordinates()[:owned, 1]
    exact = np.array([[-PRESSURE * NU / (1 - NU), 0.0], [0.0, -PRESSURE]])
    deviation = np.abs(values - exact).max(axis=(1, 2)) / PRESSURE
    blocks = [comm.allreduce(float(deviation[side].max(initial=0.0)), MPI.MAX)
              for side in (y > 0, y < 0)]
    system = getattr(snes, "system", snes)        # the condensed system, with multipliers
    c = system.contact_forces().array.reshape(-1, 2).copy()
    share = system.master_share().array.reshape(-1, 2)
    nodes = problem.contact.nodes
    own = nodes.nodes[nodes.owned]
    pressure = -c[own, 1] / nodes.weights[nodes.owned]
    spread = comm.allreduce(float(np.abs(pressure / PRESSURE - 1).max(initial=0.0)), MPI.MAX)
    slave = comm.allreduce(c.sum(axis=0), MPI.SUM)
    master = comm.allreduce(-share.sum(axis=0), MPI.SUM)
    return dict(blocks=blocks, pressure=spread, slave=slave, master=master,
                iterations=iterations)


#: The interface laws: a normal compliance (no multiplier: fem.body_contact's own Newton
#: system), the unilateral bound g = 0 (Signorini) and a compliance whose bound is reached
#: (the condensed system with the multiplier lambda_nu), Signorini with Coulomb friction.
LAWS = {
    "compliance": {},
    "signorini": {"stiffness": 0.0, "g": 0.0},
    "bound reached": {"g": 5e-5},                # the compliance alone would give 1e-4
    "coulomb": {"stiffness": 0.0, "g": 0.0, "mu": 0.3, "friction_law": "coulomb"},
}


@pytest.mark.mpi
@pytest.mark.parametrize("law", LAWS)
def test_mortar_patch_test_is_passed(law):
    """Mortar: uniform stresses in both blocks and a uniform interface pressure to 1e-10 of p;
    the master receives the opposite of the slave's resultant (to 1e-12 of p times the
    interface's length), which equals the load."""
    out = solve_patch(patch_scene("mortar", **LAWS[law]))
    print(f"mortar, {law}: stress deviation (slave, master) / p:", out["blocks"],
          "pressure:", out["pressure"], "iterations:", out["iterations"])
    assert max(out["blocks"]) < 1e-10
    assert out["pressure"] < 1e-10
    assert np.allclose(out["slave"] + out["master"], 0.0, atol=1e-12 * PRESSURE)
    assert out["slave"] == pytest.approx([0.0, -PRESSURE], abs=1e-12 * PRESSURE)


@pytest.mark.mpi
@pytest.mark.parametrize("law", ["compliance", "signorini"])
def test_node_to_segment_balances_forces(law):
    """Node to segment: the resultants balance to round-off (every row of Pi sums to 1); its
    stresses are not uniform (the error is measured and reported, far above mortar's)."""
    out = solve_patch(patch_scene("node_to_segment", **LAWS[law]))
    print(f"node to segment, {law}: stress deviation (slave, master) / p:", out["blocks"],
          "pressure:", out["pressure"], "iterations:", out["iterations"])
    assert np.allclose(out["slave"] + out["master"], 0.0, atol=1e-12 * PRESSURE)
    assert out["slave"] == pytest.approx([0.0, -PRESSURE], abs=1e-12 * PRESSURE)
    assert max(out["blocks"]) > 1e-6


@pytest.mark.parametrize("change, key", [
    (dict(obstacle={"shape": "body", "boundary": "nowhere"}), "obstacle.boundary"),
    (dict(obstacle={"shape": "body", "boundary": "bottom"},
          contact={"boundary": "slave", "stiffness": 100.0, "search_distance": 0.4}),
     "contact.search_distance"),
    (dict(contact={"boundary": "slave", "stiffness": 100.0, "g": 0.1, "mu": 0.2,
                   "slip": "increment"}), "contact.slip"),
])
def test_interface_refused(change, key):
    """An unknown master boundary, a slave node with no master within the search distance,
    friction on the slip of a step: a SceneError naming the key."""
    raw = dict(patch_scene(), **change)
    scene = loader.resolve(raw)
    with pytest.raises(SceneError) as err:
        build(scene, geometry_module.build(scene, MPI.COMM_WORLD))
    assert err.value.key == key


def hertz_scene(pairing="mortar", h=0.01, R=1.0, a=0.1, materials=((1.0, 0.3), (2.0, 0.25))):
    """A cylinder (radius R, [[body]] "cylinder") pressed onto a block ("block") of another
    material (meshes/cylinder_on_block.py), Signorini contact between them, the load per unit
    length P chosen for the Hertz half-width a: a^2 = 4 P R / (pi E*),
    1/E* = sum_b (1 - nu_b^2) / E_b. Returns the raw scene and P."""
    E_star = 1.0 / sum((1.0 - nu ** 2) / E for E, nu in materials)
    P = a ** 2 * np.pi * E_star / (4.0 * R)
    (E1, nu1), (E2, nu2) = materials
    raw = {
        "name": "cylinder_on_block",
        "geometry": {"type": "gmsh", "script": "cylinder_on_block",
                     "parameters": {"radius": R, "h_contact": h, "h_far": 0.2,
                                    "refine": 0.15}},
        "material": {"model": "plane_strain"},
        "body": [{"name": "cylinder", "cells": "cylinder", "material": {"E": E1, "nu": nu1}},
                 {"name": "block", "cells": "block", "material": {"E": E2, "nu": nu2}}],
        "dirichlet": [{"boundary": "bottom", "components": "all"},
                      {"boundary": "top", "components": [0]}],
        "traction": [{"boundary": "top", "value": [0.0, -P / (2.0 * R)]}],
        "contact": {"boundary": "contact", "stiffness": 0.0, "g": 0.0, "pairing": pairing,
                    "augmentation": 1.0},
        "obstacle": {"shape": "body", "boundary": "block_top"},
        "time": {"T": 1.0, "steps": 1},
        "solver": {"predictor": "none"},
        "output": {"probes": []},
    }
    return raw, P


@pytest.mark.parametrize("pairing", ["mortar", "node_to_segment"])
def test_hertz_cylinder_on_block(pairing):
    """Two elastic bodies of different materials: the contact half-width is Hertz's within one
    node spacing h (the first slave node past the edge carries no pressure), the peak
    pressure 2 P / (pi a) within 1 %, and the slave's resultant the load."""
    h, a = 0.01, 0.1
    raw, P = hertz_scene(pairing, h=h, a=a)
    comm = MPI.COMM_WORLD
    problem, snes, iterations = solve_one_step(raw, comm)
    c = snes.system.contact_forces().array.reshape(-1, 2)
    nodes = problem.contact.nodes
    own = nodes.nodes[nodes.owned]
    x = problem.V.tabulate_dof_coordinates()[own, 0]
    pressure = -c[own, 1] / nodes.weights[nodes.owned]
    touching = np.abs(x[pressure > 1e-10 * P])
    half_width = comm.allreduce(float(touching.max(initial=0.0)), MPI.MAX)
    peak = comm.allreduce(float(pressure.max(initial=0.0)), MPI.MAX)
    resultant = comm.allreduce(c[own].sum(axis=0), MPI.SUM)
    print(f"Hertz, {pairing}: half-width {half_width:.5f} (a = {a}), peak pressure "
          f"{peak:.5g} (Hertz {2 * P / (np.pi * a):.5g}), Newton iterations {iterations}")
    assert abs(half_width - a) < h
    assert peak == pytest.approx(2.0 * P / (np.pi * a), rel=1e-2)
    assert resultant == pytest.approx([0.0, -P], abs=1e-10 * P)


@pytest.mark.mpi
def test_creeping_cylinder_restarts_exactly(tmp_path_factory, monkeypatch):
    """A creeping cylinder (its own exponential kernel, [[body]]) on an elastic block: a run
    stopped after its checkpoint of step 3 and restarted reaches the uninterrupted run's
    contact state (the checkpoint holds each body's history), and the cylinder has crept (its
    contact zone grows under the constant load)."""
    from helpers import run_stopped_after_checkpoint
    from contactvisco.solver.time_loop import simulate
    comm = MPI.COMM_WORLD
    folders = [comm.bcast(str(tmp_path_factory.mktemp(name)) if comm.rank == 0 else None)
               for name in ("whole", "stopped")]
    raw, P = hertz_scene(h=0.02)
    raw["body"][0]["memory"] = {"kernel": "exponential", "alpha": [-0.6], "tau": [1.0]}
    raw["traction"][0]["value"][1] = f"-{P / 2.0} * min(2 * t, 1)"
    raw["time"] = {"T": 3.0, "steps": 6, "rule": "trapezoid"}
    scene = loader.resolve(raw)
    whole = simulate(scene, out=folders[0], comm=comm, progress=False, keep_tables=True)
    run_stopped_after_checkpoint(monkeypatch, 3, lambda: simulate(
        scene, out=folders[1], comm=comm, progress=False))
    restarted = simulate(scene, out=folders[1], comm=comm, progress=False, keep_tables=True,
                         restart=True)
    a, b = whole.tables[-1], restarted.tables[-1]
    assert np.max(np.abs(a["u_nu"] - b["u_nu"])) <= 1e-12 * np.max(np.abs(a["u_nu"]))
    touching = [s["status_counts"] for s in whole.steps]
    print("status counts per step:", touching)
    assert touching[-1]["bound"] > touching[2]["bound"]      # the load is constant from t = 0.5


@pytest.mark.parametrize("pairing", ["mortar", "node_to_segment"])
def test_block_slides_on_block(pairing):
    """Coulomb friction on the tangential part of u_rel: the upper block, pressed by p and
    dragged by its top (u_x = 0.2 t) over the lower one (clamped at its bottom), slides: every
    pressed slave node carries |c_tau| = mu |c_nu| (to 1e-10), the slave's resultant is
    (mu p, -p) per unit length, the friction opposing the motion, and the master receives
    the opposite."""
    mu = 0.3
    raw = patch_scene(pairing, stiffness=0.0, g=0.0, mu=mu, friction_law="coulomb")
    raw["dirichlet"] = [{"boundary": "bottom", "components": "all"},
                        {"boundary": "top", "components": [0], "value": "0.2 * t"}]
    comm = MPI.COMM_WORLD
    scene = loader.resolve(raw)
    problem = build(scene, geometry_module.build(scene, comm))
    snes = create(problem, comm)
    for t in (0.0, 0.5, 1.0):
        problem.time.stage(t)
        snes.solve()
        problem.time.commit()
    c = snes.system.contact_forces().array.reshape(-1, 2).copy()
    share = snes.system.master_share().array.reshape(-1, 2)
    nodes = problem.contact.nodes
    own = nodes.nodes[nodes.owned]
    pressed = np.abs(c[own, 1]) > 1e-12 * PRESSURE
    ratio = np.abs(c[own, 0][pressed]) / np.abs(c[own, 1][pressed])
    worst = comm.allreduce(float(np.abs(ratio - mu).max(initial=0.0)), MPI.MAX)
    count = comm.allreduce(int(pressed.sum()), MPI.SUM)
    slave = comm.allreduce(c.sum(axis=0), MPI.SUM)
    master = comm.allreduce(-share.sum(axis=0), MPI.SUM)
    print(f"sliding, {pairing}: {count} pressed slave nodes, largest ||c_tau|/|c_nu| - mu| "
          f"{worst:.2e}, slave resultant {slave}")
    assert count >= 10 and worst < 1e-10
    assert slave == pytest.approx([mu * PRESSURE, -PRESSURE], abs=1e-10 * PRESSURE)
    assert np.allclose(slave + master, 0.0, atol=1e-12 * PRESSURE)


def rigid_limit_scene(E_layer=None) -> dict:
    """The paper's body (unit square, plane stress, E = 100, nu = 0.3, clamped on the left,
    u_x = 0 on the right, f0 = (0, -10), fN = (0, -20) on its top; normal compliance 100 with
    the bound g = 0.05, friction mu = 0.2; no memory) on the layer (0, 1) x (-0.5, 0), clamped
    at its bottom, of modulus E_layer (meshes/two_blocks.py: non-matching interface nodes,
    16 against 12 segments); E_layer None: the rigid plane y = 0 instead, the layer clamped
    all round and out of the contact."""
    raw = {
        "name": "rigid_limit",
        "geometry": {"type": "gmsh", "script": "two_blocks",
                     "parameters": {"height": 1.0, "depth": 0.5, "h_slave": 1 / 16,
                                    "h_master": 1 / 12, "split_sides": 1}},
        "material": {"model": "plane_stress", "E": 100.0, "nu": 0.3},
        "dirichlet": [{"boundary": "slave_left", "components": "all"},
                      {"boundary": "slave_right", "components": [0]},
                      {"boundary": "bottom", "components": "all"}],
        "body_force": {"value": [0.0, "conditional(x[1] > 0, -10.0, 0.0)"]},
        "traction": [{"boundary": "top", "value": [0.0, -20.0]}],
        "body": [{"name": "square", "cells": "slave_body"},
                 {"name": "layer", "cells": "master_body",
                  "material": {"E": E_layer or 100.0}}],
        "contact": {"boundary": "slave", "stiffness": 100.0, "g": 0.05, "mu": 0.2},
        "obstacle": {"shape": "body", "boundary": "master"},
        "time": {"T": 1.0, "steps": 1},
        "output": {"probes": []},
    }
    if E_layer is None:
        raw["obstacle"] = {"shape": "plane", "point": [0.0, 0.0], "normal": [0.0, 1.0]}
        raw["dirichlet"] += [{"boundary": side, "components": "all"}
                             for side in ("master_left", "master_right")]
    return raw


def test_stiff_layer_tends_to_the_rigid_plane():
    """The rigid limit: the layer's displacement at the interface is of order E1/E2 of the
    body's, so the contact state on a layer of modulus E2 differs from the one on the rigid
    plane by O(E1/E2). Measured (relative to the rigid answer's largest value) at E2 = 1e4,
    1e6, 1e8: u_nu 1.7e-3, 1.7e-5, 1.7e-7; u_tau 1.7e-2, 1.8e-4, 1.8e-6; the normal and
    tangential reactions 4e-3 and 1e-3 falling alike, the zones (separated 1, compliance 4,
    bound 12) the same: each difference falls by 100 (to 5 %) per two decades of E2.

    The slave's interface corners are held in x (the body's sides): on the rigid plane, held
    too, their friction goes to the support alone; on the layer, whose surface is free, the
    layer receives it (a held slave node keeps its coupling). The tangential reaction of
    those two nodes is therefore left out of the comparison."""
    from contactvisco.solver.time_loop import simulate
    comm = MPI.COMM_WORLD
    KEYS = ("u_nu", "u_tau", "reaction_nu", "reaction_tau")

    def final(raw):
        result = simulate(loader.resolve(raw), comm=comm, progress=False, keep_tables=True)
        table = result.tables[-1]
        order = np.lexsort((table["x"][:, 1], table["x"][:, 0]))
        values = {key: np.asarray(table[key])[order] for key in KEYS}
        x = np.asarray(table["x"])[order, 0]
        inner = (x > 1e-12) & (x < 1.0 - 1e-12)
        values["reaction_tau"] = values["reaction_tau"][inner]
        return values, result.steps[-1]["status_counts"]

    rigid, zones = final(rigid_limit_scene())
    errors = []
    for E2 in (1e4, 1e6, 1e8):
        table, counts = final(rigid_limit_scene(E2))
        assert counts == zones
        errors.append([np.abs(table[k] - rigid[k]).max() / np.abs(rigid[k]).max()
                       for k in KEYS])
    errors = np.array(errors)
    print("relative differences (rows E2 = 1e4, 1e6, 1e8; columns", KEYS, "):\n", errors)
    assert zones["bound"] > 0 and zones["compliance"] > 0
    assert np.all(errors[0] < 0.05)
    ratios = errors[:-1] / errors[1:]
    assert np.all((ratios > 95.0) & (ratios < 105.0)), ratios


@pytest.mark.parametrize("pairing", ["mortar", "node_to_segment"])
@pytest.mark.parametrize("pull", [0.002, 0.004])
def test_cattaneo_mindlin_between_identical_materials(pairing, pull):
    """Cattaneo-Mindlin between two bodies of one material (Dundurs' beta = 0: pressing
    makes no tangential traction, so the rigid-plane solution holds with
    1/E* = 2 (1 - nu^2) / E): the cylinder on the block (E = 1, nu = 0.3), Coulomb friction
    mu = 0.3, its top clamped and moved down by 0.017 (t = 1/2, the normal force P), then
    sideways by `pull` (t = 1, the tangential force Q < mu P). The contact half-width is
    Hertz's a = sqrt(4 P R / (pi E*)) and the stick zone's c = a sqrt(1 - Q/(mu P))
    (studies.coulomb) within one node spacing h = 0.01, at Q/(mu P) = 0.24 and 0.48
    (measured: |c_h - c| = 0.03 h and 0.06 h mortar, 0.03 h and 0.41 h node to segment),
    the stick zone centred to a node spacing (each of its ends is placed to h/2)."""
    from contactvisco.studies.coulomb import _zone_half_width
    from contactvisco.solver.time_loop import simulate
    h, mu, nu, w = 0.01, 0.3, 0.3, 0.017
    raw, _ = hertz_scene(pairing, h=h, a=0.1, materials=((1.0, nu), (1.0, nu)))
    raw["traction"] = []
    raw["dirichlet"][1] = {"boundary": "top", "components": "all",
                           "value": [f"{pull} * max(2 * t - 1, 0)", f"{-w} * min(2 * t, 1)"]}
    raw["contact"].update(mu=mu, friction_law="coulomb")
    raw["time"] = {"T": 1.0, "steps": 2}
    result = simulate(loader.resolve(raw), comm=MPI.COMM_WORLD, progress=False,
                      keep_tables=True)
    table = result.tables[-1]
    order = np.argsort(table["x"][:, 0])
    x, weight = table["x"][order, 0], table["weight"][order]
    P = float(np.sum(weight * table["reaction_nu"][order]))
    Q = abs(float(np.sum(weight * table["reaction_tau"][order])))
    E_star = 1.0 / (2.0 * (1.0 - nu ** 2))
    a = np.sqrt(4.0 * P / (np.pi * E_star))
    c = a * np.sqrt(1.0 - Q / (mu * P))
    touching = table["status"][order] == 2
    a_h, _ = _zone_half_width(x, touching)
    c_h, centre = _zone_half_width(x, touching & (table["friction"][order] == 1))
    print(f"{pairing}, pull {pull}: Q/(mu P) = {Q / (mu * P):.3f}, a = {a:.4f} (computed "
          f"{a_h:.4f}), c = {c:.4f} (computed {c_h:.4f}, centre {centre:.4f})")
    assert 0.2 < Q / (mu * P) < 0.6
    assert abs(a_h - a) < h and abs(c_h - c) < h and abs(centre) < 1.5 * h


@pytest.mark.parametrize("pairing", ["mortar", "node_to_segment"])
def test_prescribed_master_displacement_moves_the_master_under_the_slave(pairing):
    """The two blocks, the master held at its bottom and sides (all components) at a given
    displacement (0, -a), the slave's sides held in x, a pressure on its top: translating the
    master rigidly by a moves the slave with it and leaves the contact state as it was, with
    the normal compliance alone (Newton on u, D = P u) and with a bound that is never reached
    (the condensed system with its multipliers, D = P u with u = g on prescribed components). Before the condensed system
    carried the prescribed master displacements to the slave nodes, its corners saw a master
    that had not moved (pressures 0.037 against 0.025)."""
    from contactvisco.solver.time_loop import simulate
    comm = MPI.COMM_WORLD

    def contact(shift, **law):
        raw = patch_scene(pairing, **law)
        raw["dirichlet"] = [{"boundary": "bottom", "components": "all",
                             "value": [0.0, -shift]},
                            {"boundary": "master_sides", "components": "all",
                             "value": [0.0, -shift]},
                            {"boundary": "slave_sides", "components": [0]}]
        table = simulate(loader.resolve(raw), comm=comm, progress=False,
                         keep_tables=True).tables[-1]
        order = np.argsort(table["x"][:, 0])
        return table["u_nu"][order], table["reaction_nu"][order]

    reference = contact(0.0)
    scale = [np.abs(v).max() for v in reference]
    for shift, law in ((0.002, {}), (0.0, {"g": 10.0}), (0.002, {"g": 10.0})):
        moved = contact(shift, **law)
        worst = [np.abs(m - r).max() / s for m, r, s in zip(moved, reference, scale)]
        print(f"{pairing}, shift {shift}, law {law}: u_nu, reaction_nu differ by {worst}")
        assert max(worst) < 1e-8
    assert reference[1].max() > 2 * reference[1].min() > 0     # not the uniform patch state


def held_patch_scene(pairing="mortar", E_master=1.0, **contact) -> dict:
    """The patch test with both components of the slave block's sides held at the exact
    solution's values (the interface corners of the slave are then held slave nodes), the
    master of modulus E_master: plane strain with u_x = 0 gives eps_yy = -p k / E,
    k = (1 + nu)(1 - 2 nu)/(1 - nu), so u_y = eps_m (y + 1/2) in the master and
    u_y = eps_m / 2 - s + eps_s y in the slave, s = p / c_nu the compliance's penetration."""
    raw = patch_scene(pairing, **contact)
    k = (1 + NU) * (1 - 2 * NU) / (1 - NU)
    slave, master = -PRESSURE * k, -PRESSURE * k / E_master
    stiffness = raw["contact"]["stiffness"]
    bound = raw["contact"].get("g")
    s = PRESSURE / stiffness if stiffness else 0.0
    s = min(s, bound) if bound is not None else s
    raw["dirichlet"][2] = {"boundary": "slave_sides", "components": "all",
                           "value": [0.0, f"{master * 0.5 - s!r} + {slave!r} * x[1]"]}
    if E_master != 1.0:
        raw["body"] = [{"name": "upper", "cells": "slave_body"},
                       {"name": "lower", "cells": "master_body",
                        "material": {"E": E_master}}]
    return raw


#: The laws of the patch test with held slave nodes: those of LAWS and a compliance whose
#: bound is not reached (linear, but solved with the multiplier lambda_nu: the condensed
#: system; the held corners start 4e-3 inside the master, within the bound); the linear
#: ones must converge in one Newton iteration.
HELD_LAWS = dict(LAWS, **{"bound not reached": {"g": 1e-2}})
LINEAR = ("compliance", "bound not reached")


@pytest.mark.parametrize("E_master", [1.0, 10.0])
@pytest.mark.parametrize("law", HELD_LAWS)
def test_held_slave_nodes_keep_their_coupling(law, E_master):
    """Slave nodes held by a support (both components of the slave's sides, its interface
    corners among them, held at their exact values) still act on u_rel = u_i - (Pi u)_i: the
    master receives -Pi^T c of every slave node, the held components' share of c going to
    the support (where the corner's condition is active, the held corner pins the master
    there). Mortar passes the patch test to 1e-12 of p, for a master of the slave's modulus
    and one 10 times stiffer, and Newton's first step is exact for the linear laws (1
    iteration from u = 0, off the held values), with the displacement-only system
    (compliance) and the condensed one (bound not reached). Measured: at most 3e-14; with
    the multipliers of held slave components left out, 61 % in the master."""
    out = solve_patch(held_patch_scene("mortar", E_master, **HELD_LAWS[law]))
    print(f"held slave sides, mortar, {law}, E2 = {E_master}: stress deviation (slave, "
          "master) / p:", out["blocks"], "pressure:", out["pressure"], "iterations:",
          out["iterations"])
    assert max(out["blocks"]) < 1e-12
    assert out["pressure"] < 1e-12
    if law in LINEAR:
        assert out["iterations"] == 1
    assert np.allclose(out["slave"] + out["master"], 0.0, atol=1e-12 * PRESSURE)


@pytest.mark.parametrize("E_master", [1.0, 10.0])
@pytest.mark.parametrize("law", LINEAR)
def test_held_slave_nodes_node_to_segment(law, E_master):
    """Node to segment with held slave sides: the resultants balance (every row of Pi sums to
    1), Newton's first step is exact (1 iteration); the stresses miss the uniform ones by
    several per cent (measured and reported)."""
    out = solve_patch(held_patch_scene("node_to_segment", E_master, **HELD_LAWS[law]))
    print(f"held slave sides, node to segment, {law}, E2 = {E_master}: stress deviation "
          "(slave, master) / p:", out["blocks"], "pressure:", out["pressure"])
    assert out["iterations"] == 1
    assert np.allclose(out["slave"] + out["master"], 0.0, atol=1e-12 * PRESSURE)
    assert max(out["blocks"]) > 1e-6


def dragged_scene() -> dict:
    """The block dragged on the block (test_block_slides_on_block) far: its top moved by
    0.04 per unit time over 4 steps, Signorini with Coulomb friction (mu = 0.3), so that the
    slave nodes slide past half a master segment (h_master = 0.1: the limit 0.05)."""
    raw = patch_scene("mortar", stiffness=0.0, g=0.0, mu=0.3, friction_law="coulomb")
    raw["dirichlet"] = [{"boundary": "bottom", "components": "all"},
                        {"boundary": "top", "components": [0], "value": "0.04 * t"}]
    raw["time"] = {"T": 4.0, "steps": 4}
    raw["solver"] = {"predictor": "none"}
    return raw


def test_sliding_past_the_pairing_stops_the_run(tmp_path_factory):
    """A slave node that slides past half its master facet stops the run with SlidingLimit
    (a NewtonFailure: exit 3), naming its position, its slip and the limit; the steps before
    are kept (steps.jsonl, and the checkpoint of the last of them). The command line ends
    with exit 3 and the same words."""
    from helpers import read_steps, run_cli
    from contactvisco import SlidingLimit, solve
    from contactvisco.api import scene_toml
    comm = MPI.COMM_WORLD
    out = comm.bcast(str(tmp_path_factory.mktemp("dragged")) if comm.rank == 0 else None)
    scene = loader.resolve(dragged_scene())
    with pytest.raises(SlidingLimit) as caught:
        solve(scene, out, comm=comm, progress=False)
    err = caught.value
    print("stopped:", err)
    assert err.slip > err.limit == pytest.approx(0.05, rel=1e-9)
    assert err.position[1] == pytest.approx(0.0, abs=1e-12)
    assert f"{err.limit:.4g}" in str(err) and f"{err.slip:.4g}" in str(err)
    steps = read_steps(out)
    assert 1 <= len(steps) and steps[-1]["t"] < err.t
    import json
    import pathlib
    meta = json.loads((pathlib.Path(out) / "checkpoint" / "meta.json").read_text())
    assert meta["t"] == steps[-1]["t"] and meta["count"] == len(steps)
    if comm.size > 1:
        return
    path = tmp_path_factory.mktemp("cli") / "dragged.toml"
    path.write_text(scene_toml(scene))
    done = run_cli("run", path, "--out", path.parent / "out", "--quiet")
    print(done.stderr)
    assert done.returncode == 3
    assert "small-sliding limit" in done.stderr and f"{err.slip:.4g}" in done.stderr
    assert len(read_steps(path.parent / "out")) == len(steps)


@pytest.mark.parametrize("fraction", [0.25, math.inf])
def test_sliding_limit_is_a_fraction_of_the_facet(fraction):
    """contact.sliding_limit scales the limit (a quarter of h_master = 0.1: 0.025 against
    the half's 0.05); inf turns the check off, and the dragged block then takes all its
    steps on the reference pairing."""
    from contactvisco import SlidingLimit
    from contactvisco.solver.time_loop import simulate
    raw = dragged_scene()
    raw["contact"]["sliding_limit"] = fraction
    scene = loader.resolve(raw)
    if fraction == math.inf:
        result = simulate(scene, comm=MPI.COMM_WORLD, progress=False)
        assert len(result.steps) == raw["time"]["steps"] + 1
        return
    with pytest.raises(SlidingLimit) as caught:
        simulate(scene, comm=MPI.COMM_WORLD, progress=False)
    assert caught.value.limit == pytest.approx(0.1 * fraction, rel=1e-9)
    assert caught.value.slip > caught.value.limit
    assert "contact.sliding_limit = 0.25" in str(caught.value)


@pytest.mark.parametrize("value", [0, -0.5, "half", True])
def test_sliding_limit_values_refused(value):
    raw = patch_scene()
    raw["contact"]["sliding_limit"] = value
    with pytest.raises(SceneError, match="contact.sliding_limit"):
        loader.resolve(raw)


def test_facet_sizes():
    """The small-sliding limit of a facet: half a segment's length, half a triangle's
    smallest height (2 A over its longest edge): 1.5 for a segment of length 3; for the
    triangle (0, 0, 0), (2, 0, 0), (0, 1, 0) of area 1 and longest edge sqrt(5), 1/sqrt(5)."""
    from contactvisco.fem.body_contact import facet_sizes
    segment = np.array([[[1.0, 1.0], [1.0, 4.0]]])
    triangle = np.array([[[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [0.0, 1.0, 0.0]]])
    assert facet_sizes(segment) == pytest.approx([1.5], rel=1e-15)
    assert facet_sizes(triangle) == pytest.approx([1.0 / np.sqrt(5.0)], rel=1e-15)


def two_cylinders_scene(pairing="mortar", h=0.01, radii=(1.0, 2.0), a=0.1,
                        materials=((1.0, 0.3), (3.0, 0.2))):
    """Two half cylinders of radii R1 (upper, [[body]] "upper", slave) and R2 (lower,
    "lower", master) of two materials touching at the origin (meshes/two_cylinders.py),
    Signorini contact, the load per unit length P on the upper one's diameter chosen for the
    Hertz half-width a (plane strain): a^2 = 4 P R / (pi E*), 1/R = 1/R1 + 1/R2,
    1/E* = sum_b (1 - nu_b^2) / E_b. Returns the raw scene and P."""
    R1, R2 = radii
    R = 1.0 / (1.0 / R1 + 1.0 / R2)
    E_star = 1.0 / sum((1.0 - nu ** 2) / E for E, nu in materials)
    P = a ** 2 * np.pi * E_star / (4.0 * R)
    raw, _ = hertz_scene(pairing, h=h, a=a, materials=materials)
    raw["name"] = "two_cylinders"
    raw["geometry"]["script"] = "two_cylinders"
    raw["geometry"]["parameters"] = {"r_upper": R1, "r_lower": R2, "h_contact": h,
                                     "h_far": 0.2, "refine": 0.15}
    raw["body"][0]["name"] = raw["body"][0]["cells"] = "upper"
    raw["body"][1]["name"] = raw["body"][1]["cells"] = "lower"
    raw["traction"][0]["value"][1] = -P / (2.0 * R1)
    raw["obstacle"]["boundary"] = "lower_contact"
    return raw, P


def hertz_errors(raw, P, a):
    """Solve a Hertz scene (one load step) and compare the slave's nodal pressures
    p_i = -c_i,y / D_i with Hertz's p(x) = p0 sqrt(1 - x^2 / a^2), p0 = 2 P / (pi a): the
    half-width (the farthest slave node that carries pressure), the peak's relative error
    max p_i / p0 - 1, the relative L2 error sqrt(sum_i D_i (p_i - p(x_i))^2 /
    sum_i D_i p(x_i)^2) (D_i the slave vertex weights), the slave's resultant and Newton's
    iterations."""
    comm = MPI.COMM_WORLD
    problem, snes, iterations = solve_one_step(raw, comm)
    c = snes.system.contact_forces().array.reshape(-1, 2)
    nodes = problem.contact.nodes
    own = nodes.nodes[nodes.owned]
    weight = nodes.weights[nodes.owned]
    x = problem.V.tabulate_dof_coordinates()[own, 0]
    pressure = -c[own, 1] / weight
    p0 = 2.0 * P / (np.pi * a)
    hertz = p0 * np.sqrt(np.maximum(0.0, 1.0 - (x / a) ** 2))
    sums = comm.allreduce(np.array([np.sum(weight * (pressure - hertz) ** 2),
                                    np.sum(weight * hertz ** 2)]), MPI.SUM)
    touching = np.abs(x[pressure > 1e-10 * P])
    return dict(half_width=comm.allreduce(float(touching.max(initial=0.0)), MPI.MAX),
                peak=comm.allreduce(float(pressure.max(initial=0.0)), MPI.MAX) / p0 - 1.0,
                l2=float(np.sqrt(sums[0] / sums[1])),
                resultant=comm.allreduce(c[own].sum(axis=0), MPI.SUM),
                iterations=iterations)


@pytest.mark.parametrize("pairing", ["mortar", "node_to_segment"])
def test_hertz_two_cylinders(pairing):
    """Two cylinders of radii 1 and 2 and of two materials (E = 1, nu = 0.3 on E = 3,
    nu = 0.2), frictionless: Hertz with the relative radius 1/R = 1/R1 + 1/R2 and the
    contact modulus 1/E* = sum (1 - nu^2)/E. The half-width a = 0.1 within one node spacing
    h = a/10, the peak pressure within 0.5 %, the L2 error of the pressure within 5 %, the
    slave's vertical resultant the load (its horizontal part is not zero: the master's
    normals turn along the arc)."""
    h, a = 0.01, 0.1
    raw, P = two_cylinders_scene(pairing, h=h, a=a)
    out = hertz_errors(raw, P, a)
    print(f"two cylinders, {pairing}: half-width {out['half_width']:.5f} (a = {a}), peak "
          f"error {out['peak']:+.2e}, L2 error {out['l2']:.2e}, Newton iterations "
          f"{out['iterations']}")
    assert abs(out["half_width"] - a) < h
    assert abs(out["peak"]) < 5e-3
    assert out["l2"] < 5e-2
    assert out["resultant"][1] == pytest.approx(-P, rel=1e-10)


@pytest.mark.mpi
@pytest.mark.parametrize("pairing", ["mortar", "node_to_segment"])
def test_the_first_step_takes_a_free_body_into_the_contact(pairing):
    """The two cylinders at h = 0.01 from rest: no slave node is active at the first
    iterate, and the load pushes the upper cylinder down freely (a null motion of the Newton
    matrix with the residual along it). The direct solver's first step moves it down, by a
    length the load fixes (solver.floating's stabilization), the same on every rank count
    and run: over a pivot of round-off size it took |F| to between 7e10 and 2e11 from run to
    run on 2 ranks, and in 4 of 20 runs Newton then drifted without converging."""
    raw, _ = two_cylinders_scene(pairing, h=0.01, a=0.1)
    raw["solver"] = {**raw["solver"], "petsc_options": {"snes_max_it": 1}}
    moves = []
    for comm in (MPI.COMM_WORLD, MPI.COMM_SELF):
        scene = loader.resolve(raw)
        problem = build(scene, geometry_module.build(scene, comm))
        snes = create(problem, comm)
        problem.time.stage(1.0)
        with pytest.raises(NewtonFailure):            # stopped after its first step
            snes.solve()
        assert snes.floating.found[0] >= 1
        owned = problem.V.dofmap.index_map.size_local
        y = problem.V.tabulate_dof_coordinates()[:owned, 1]
        u_y = problem.u.x.array.reshape(-1, 2)[:owned, 1]
        upper = y > 1e-9
        moves.append(comm.allreduce(float(u_y[upper].sum()), MPI.SUM)
                     / comm.allreduce(int(upper.sum()), MPI.SUM))
        snes.destroy()
    assert moves[0] < 0.0
    assert moves[0] == pytest.approx(moves[1], rel=1e-6)


def _hertz_orders(pairings, ratios):
    """hertz_errors of the cylinder on the block (E2 = 2 E1, a = 0.1) for each pairing at
    h = a / r, r in ratios."""
    a = 0.1
    out = {}
    for pairing in pairings:
        for r in ratios:
            raw, P = hertz_scene(pairing, h=a / r, a=a)
            out[pairing, r] = hertz_errors(raw, P, a)
            print(f"cylinder on block, {pairing}, a/h = {r}: peak error "
                  f"{out[pairing, r]['peak']:+.2e}, L2 error {out[pairing, r]['l2']:.2e}, "
                  f"half-width {out[pairing, r]['half_width']:.5f}, Newton iterations "
                  f"{out[pairing, r]['iterations']}")
    return out


def test_hertz_pressure_error_falls_with_the_mesh():
    """The cylinder on the block at a/h = 8 and 16: mortar's L2 pressure error falls by a
    factor between 1.25 and 2 when h halves (measured 2.0 % to 1.4 %, a factor 1.45: the
    pressure's square-root edge limits the order), and it is below node to segment's at both
    sizes (measured 2.3 % and 1.9 %); both peaks within 0.5 % of Hertz (measured 0.1 %: the
    finite bodies' own deviation from the half-planes, which no mesh removes)."""
    out = _hertz_orders(("mortar", "node_to_segment"), (8, 16))
    ratio = out["mortar", 8]["l2"] / out["mortar", 16]["l2"]
    assert 1.25 < ratio < 2.0, ratio
    for r in (8, 16):
        assert out["mortar", r]["l2"] < out["node_to_segment", r]["l2"]
        assert abs(out["mortar", r]["peak"]) < 5e-3
        assert abs(out["node_to_segment", r]["peak"]) < 5e-3


@pytest.mark.slow
def test_hertz_pressure_error_keeps_falling():
    """Mortar on the cylinder on the block at a/h = 8, 16, 32, 64: the L2 pressure error
    falls by more than 1.25 at every halving of h (measured 1.45, 1.53, ...), the peak stays
    within 0.5 % of Hertz."""
    ratios = (8, 16, 32, 64)
    out = _hertz_orders(("mortar",), ratios)
    errors = np.array([out["mortar", r]["l2"] for r in ratios])
    print("L2 errors", errors, "ratios", errors[:-1] / errors[1:])
    assert np.all(errors[:-1] / errors[1:] > 1.25)
    assert all(abs(out["mortar", r]["peak"]) < 5e-3 for r in ratios)
