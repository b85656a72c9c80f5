"""What composes with the axisymmetric body, each checked cheaply: Coulomb friction sliding in
the meridian plane, the compliance law's total force, time-temperature superposition, and a
restart from a checkpoint of the force-controlled sphere_creep scene."""
import pathlib

import numpy as np
import pytest
from mpi4py import MPI

from contactvisco.model import viscoelastic as ve
from contactvisco.scene import loader
from contactvisco.solver.time_loop import simulate
from helpers import run_stopped_after_checkpoint

pytestmark = pytest.mark.mpi

COMM = MPI.COMM_WORLD
E, NU, Q = 50.0, 0.3, 2.0


def sliding(mu: float):
    """A free cylinder 0 <= r <= 1, 0 <= z <= 1 pressed by Q onto the compliant layer
    (stiffness 100, bound 0.05 not reached) with the friction coefficient mu: the contact
    table and the probes at (1, 0), (1, 1), (0.5, 0.5)."""
    raw = {"name": "cylinder_sliding",
           "geometry": {"lower": [0.0, 0.0], "upper": [1.0, 1.0], "cells": [6, 4]},
           "material": {"model": "axisymmetric", "E": E, "nu": NU},
           "traction": [{"boundary": "top", "value": [0.0, -Q]}],
           "contact": {"boundary": "bottom", "stiffness": 100.0, "g": 0.05, "mu": mu},
           "time": {"T": 1.0, "steps": 1},
           "output": {"probes": [[1.0, 0.0], [1.0, 1.0], [0.5, 0.5]]}}
    result = simulate(loader.resolve(raw), comm=COMM, progress=False, keep_tables=True)
    return result.tables[-1], result.steps[-1]["probes"]


def test_frictionless_cylinder_expands_freely():
    """mu = 0: the homogeneous uniaxial stress state, u_r = nu Q r / E, u_z = -Q/100 - Q z / E,
    exact in P1; no tangential reaction; the ring forces add up to Q pi."""
    table, probes = sliding(0.0)
    for probe in probes:
        r, z = probe["x"]
        assert probe["u"] == pytest.approx([NU * Q * r / E, -Q / 100 - Q * z / E], abs=1e-12)
    assert np.abs(table["reaction_tau"]).max() < 1e-12
    assert np.sum(table["weight"] * table["reaction_nu"]) == pytest.approx(np.pi * Q, rel=1e-10)


def test_cylinder_slides_outwards_against_coulomb_friction():
    """mu = 0.05: the Poisson expansion slides every contact node off the axis outwards
    (friction status slip), with the tangential reaction mu p_nu pointing inwards, against the
    slip; the axis node sticks (u_r = 0 there); friction holds the bottom's edge back
    (0 < u_r(1, 0) < nu Q / E) and the ring forces still add up to Q pi."""
    mu = 0.05
    table, probes = sliding(mu)
    r = table["x"][:, 0]
    off = r > 1e-12
    assert set(table["friction"][off]) == {2} and set(table["friction"][~off]) <= {1}
    assert np.allclose(table["reaction_tau"][off], -mu * table["reaction_nu"][off],
                       rtol=1e-8, atol=0)
    assert np.all(table["u_tau"][off] > 0)
    edge = probes[0]["u"][0]
    assert 0.5 * NU * Q / E < edge < 0.9 * NU * Q / E, edge
    assert np.sum(table["weight"] * table["reaction_nu"]) == pytest.approx(np.pi * Q, rel=1e-10)


def test_cylinder_sticks_under_large_friction():
    """mu = 5: no node slides (u_tau = 0, status stick), each tangential reaction strictly
    inside the cone |r_tau| < mu p_nu, the largest at the edge; the total force is Q pi."""
    table, _ = sliding(5.0)
    assert np.abs(table["u_tau"]).max() < 1e-12 and set(table["friction"]) == {1}
    assert np.all(np.abs(table["reaction_tau"]) < 5.0 * table["reaction_nu"])
    edge = np.argmax(table["x"][:, 0])
    assert np.argmax(np.abs(table["reaction_tau"])) == edge
    assert np.sum(table["weight"] * table["reaction_nu"]) == pytest.approx(np.pi * Q, rel=1e-10)


CREEP = ["time.steps=6", "output.xdmf=false", "output.figures=false"]


def test_a_constant_temperature_creeps_as_the_reference_run_on_the_scaled_time():
    """sphere_creep at theta = T_ref + 3 (WLF, a_T = 0.110): every step is the reduced step
    k / a_T, so the depths are those of the T_ref run over T / a_T, step by step (measured
    7e-15 relative); the sphere creeps on (the last depth 1.45 times the first)."""
    wlf = {"shift": "wlf", "T_ref": 50.0, "C1": 17.44, "C2": 51.6}
    a_T = 10.0 ** float(ve.log10_shift(wlf, 53.0))
    assert a_T < 0.2
    hot = loader.load("sphere_creep", CREEP + ['viscoelastic.shift="wlf"'] + [
        f"viscoelastic.{key}={value!r}" for key, value in wlf.items() if key != "shift"]
        + ["viscoelastic.temperature=53.0"])
    reference = loader.load("sphere_creep", CREEP + [f"time.T={3.0 / a_T!r}"])
    depths = [np.array([step["obstacle"]["displacement"][1]
                        for step in simulate(scene, comm=COMM, progress=False).steps])
              for scene in (hot, reference)]
    assert depths[1][-1] / depths[1][0] > 1.3
    assert np.abs(depths[0] - depths[1]).max() <= 1e-10 * np.abs(depths[1]).max()


def test_sphere_creep_restarts_to_the_uninterrupted_answer(tmp_path_factory, monkeypatch):
    """sphere_creep stopped right after its third checkpoint and restarted: the sphere's
    depth (force control: the obstacle's state is part of the checkpoint) and the contact
    table at the end equal the uninterrupted run's to the solver's tolerance."""
    folder = pathlib.Path(COMM.bcast(str(tmp_path_factory.mktemp("axi_restart"))
                                     if COMM.rank == 0 else None, root=0))
    whole = simulate(loader.load("sphere_creep", CREEP), out=folder / "whole", comm=COMM,
                     progress=False, keep_tables=True)
    out = folder / "stopped"
    run_stopped_after_checkpoint(monkeypatch, 3, lambda: simulate(
        loader.load("sphere_creep", CREEP), out=out, comm=COMM, progress=False))
    again = simulate(loader.load("sphere_creep", CREEP), out=out, comm=COMM, progress=False,
                     restart=True, keep_tables=True)
    assert again.steps[-1]["t"] == pytest.approx(3.0) and len(again.steps) < len(whole.steps)
    depth = whole.steps[-1]["obstacle"]["displacement"][1]
    assert again.steps[-1]["obstacle"]["displacement"][1] == pytest.approx(depth, rel=1e-9)
    assert depth / whole.steps[0]["obstacle"]["displacement"][1] > 1.3
    a, b = again.tables[-1], whole.tables[-1]
    assert np.array_equal(a["status"], b["status"])
    assert np.allclose(a["reaction_nu"], b["reaction_nu"], rtol=1e-8,
                       atol=1e-8 * np.abs(b["reaction_nu"]).max())


def prescribed(law: dict):
    """The free cylinder of sliding() on a layer whose pressure is the prescribed p_nu =
    2000 s^2 (bound 0.05 not reached), with the [contact] keys `law` added."""
    raw = {"name": "cylinder_prescribed",
           "geometry": {"lower": [0.0, 0.0], "upper": [1.0, 1.0], "cells": [6, 4]},
           "material": {"model": "axisymmetric", "E": E, "nu": NU},
           "traction": [{"boundary": "top", "value": [0.0, -Q]}],
           "contact": {"boundary": "bottom", "stiffness": 0.0, "g": 0.05,
                       "p_nu": "2000 * s**2", **law},
           "time": {"T": 1.0, "steps": 1},
           "output": {"probes": [[1.0, 0.0], [1.0, 1.0], [0.5, 0.5]]}}
    result = simulate(loader.resolve(raw), comm=COMM, progress=False, keep_tables=True)
    return result.tables[-1], result.steps[-1]["probes"]


def test_prescribed_pressure_and_friction_laws():
    """contact.p_nu = 2000 s^2 in axisymmetry: without friction the uniaxial state on a
    penetration s = sqrt(Q/2000) at every node, u_z = -s - Q z / E exact in P1, the ring
    forces adding up to Q pi; contact.p_tau = "0.05 * p_nu" (the friction bound) slides every
    node off the axis outwards with r_tau = -0.05 p_nu, friction holding the edge back."""
    s = np.sqrt(Q / 2000.0)
    table, probes = prescribed({"mu": 0.0})
    for probe in probes:
        r, z = probe["x"]
        assert probe["u"] == pytest.approx([NU * Q * r / E, -s - Q * z / E], abs=1e-10)
    assert np.allclose(table["penetration"], s, rtol=1e-9)
    assert np.sum(table["weight"] * table["reaction_nu"]) == pytest.approx(np.pi * Q, rel=1e-9)
    law, probes = prescribed({"mu": 0.0, "p_tau": "0.05 * p_nu"})
    assert np.allclose(law["radius"], 0.05 * law["reaction_nu"], rtol=1e-9)
    assert 0.5 * NU * Q / E < probes[0]["u"][0] < 0.9 * NU * Q / E     # held back at the edge
    off = law["x"][:, 0] > 1e-12
    assert np.allclose(law["reaction_tau"][off], -0.05 * law["reaction_nu"][off], rtol=1e-8)
    assert set(law["friction"][off]) == {2}
