"""Creep indentation of a block on the compliant foundation with the material as relaxation
moduli ([viscoelastic], the shear terms from a CSV file): the same run as the material entered
in the paper's form, and at a raised temperature the T_ref run on the time scale a_T."""

import numpy as np
import pytest
from mpi4py import MPI

from contactvisco.model import viscoelastic as ve
from contactvisco.scene import loader
from contactvisco.scene.toml_text import document_text
from contactvisco.solver.time_loop import simulate
from helpers import run_stopped_after_checkpoint

WLF = {"shift": "wlf", "T_ref": 50.0, "C1": 17.44, "C2": 51.6}


def raw_scene(material: dict, T: float = 4.0, steps: int = 8, rule: str = "trapezoid") -> dict:
    return {"name": "prony_block",
            "geometry": {"lower": [0.0, 0.0], "upper": [2.0, 1.0], "cells": [12, 6]},
            "material": {"model": "plane_strain", **material.pop("material", {})},
            **material,
            "dirichlet": [{"boundary": "left", "components": [0]}],
            "traction": [{"boundary": "top", "value": [0.0, "-2.0 * x[0]"]}],
            "contact": {"boundary": "bottom", "stiffness": 100.0, "g": 0.03},
            "time": {"T": T, "steps": steps, "rule": rule},
            "output": {"probes": [[2.0, 1.0], [1.0, 0.0]]}}


def prony_scene(tmp_path, T=4.0, steps=8, rule="trapezoid", comm=MPI.COMM_SELF, **extra):
    """The block's scene file and its CSV written in tmp_path (by comm's first rank only: a
    folder shared by the ranks must not be rewritten while another rank reads it) and
    loaded."""
    raw = raw_scene({"viscoelastic": {
        "shear": {"instantaneous": 30.0, "file": "shear.csv", "values": "fractions"},
        "bulk": {"long_term": 50.0, "tau": [1.0], "moduli": [15.0]}, **WLF, **extra}}, T, steps,
        rule)
    path = tmp_path / "block.toml"
    if comm.rank == 0:
        (tmp_path / "shear.csv").write_text("tau (s),g_i\n0.5,0.3\n3.0,0.25\n")
        path.write_text(document_text(raw))
    comm.barrier()
    return loader.load(str(path))


def run(scene, comm=MPI.COMM_WORLD):
    result = simulate(scene, comm=comm, progress=False, keep_tables=True)
    probes = np.array([[probe["u"] for probe in record["probes"]] for record in result.steps])
    u_nu = np.array([table["u_nu"] for table in result.tables])
    status = np.array([table["status"] for table in result.tables])
    newton = [record["newton_iterations"] for record in result.steps]
    return probes, u_nu, status, newton, result.steps


def test_equals_the_paper_form(tmp_path):
    """The converted scene and the same material entered by hand as E, nu and memory.terms:
    the same Newton iterations, contact states and displacements to round-off."""
    scene = prony_scene(tmp_path)
    G0, K0 = 30.0, 65.0
    terms = []
    for g, tau in ((0.3, 0.5), (0.25, 3.0)):
        terms += [{"alpha": -2 * g * G0 / tau, "tau": tau, "part": "deviatoric"},
                  {"alpha": -2 / 3 * g * G0 / tau, "tau": tau, "part": "volumetric"}]
    terms.append({"alpha": -2 * 15.0 / 1.0, "tau": 1.0, "part": "volumetric"})
    paper = loader.resolve(raw_scene({
        "material": {"E": 9 * K0 * G0 / (3 * K0 + G0),
                     "nu": (3 * K0 - 2 * G0) / (2 * (3 * K0 + G0))},
        "memory": {"kernel": "prony", "terms": terms}}))
    converted, by_hand = run(scene), run(paper)
    assert converted[3] == by_hand[3]
    assert np.array_equal(converted[2], by_hand[2])
    scale = np.abs(by_hand[0]).max()
    assert np.abs(converted[0] - by_hand[0]).max() <= 1e-11 * scale
    assert np.abs(converted[1] - by_hand[1]).max() <= 1e-11 * scale
    assert (by_hand[0][-1, 0, 1] < 1.2 * by_hand[0][0, 0, 1]      # it creeps
            and set(np.unique(by_hand[2][-1])) >= {1, 2})           # compliance and bound


def test_raised_temperature_sinks_on_the_shifted_time_scale(tmp_path):
    """At theta = 53 (a_T = 0.110) the block sinks over [0, T] as it does at T_ref over
    [0, T / a_T] with the same 16 steps (constant loads), to round-off; faster than at
    T_ref."""
    hot = run(prony_scene(tmp_path, steps=16, temperature=53.0))
    a = 10 ** float(ve.log10_shift(WLF, 53.0))
    slow = run(prony_scene(tmp_path, T=4.0 / a, steps=16))
    iso = run(prony_scene(tmp_path, steps=16))
    scale = np.abs(slow[0]).max()
    assert hot[3] == slow[3] and np.array_equal(hot[2], slow[2])
    assert np.abs(hot[0] - slow[0]).max() <= 1e-10 * scale
    assert hot[0][-1, 0, 1] < iso[0][-1, 0, 1] - 1e-2 * scale        # sinks faster
    records = hot[4]
    assert records[-1]["temperature"] == pytest.approx([53.0, 53.0])
    assert records[-1]["reduced_time"] == pytest.approx([4.0 / a] * 2, rel=1e-12)


@pytest.mark.mpi
def test_ranks_agree(tmp_path):
    """A temperature varying in x and t: the run over the ranks equals the run on one rank
    (16 steps: k / a_T stays below the trapezoid rule's limit, so that no step is cut; where
    and whether Newton cuts a hard step depends on round-off, and so on the rank count)."""
    scene = prony_scene(tmp_path, steps=16, temperature="50.0 + 0.5 * t + 0.5 * x[0]")
    everywhere, alone = run(scene), run(scene, MPI.COMM_SELF)
    assert everywhere[3] == alone[3] and np.array_equal(everywhere[2], alone[2])
    assert np.abs(everywhere[0] - alone[0]).max() <= 1e-10 * np.abs(alone[0]).max()



@pytest.mark.mpi
@pytest.mark.parametrize("rule", ["trapezoid", "exponential", "fractional"])
def test_restart_continues_in_reduced_time(tmp_path_factory, monkeypatch, rule):
    """A run with a temperature field stopped after its checkpoint of step 3 and restarted
    reaches the uninterrupted run's answer and reduced time: the checkpoint holds 1/a_T and xi
    at each point besides the Prony sums (trapezoid and exponential rules), or besides the
    sums of the fractional kernel's exponentials (its [memory] in reduced time, trapezoid
    rule)."""
    comm = MPI.COMM_WORLD
    folders = [comm.bcast(str(tmp_path_factory.mktemp(name)) if comm.rank == 0 else None)
               for name in ("csv", "whole", "stopped")]
    import pathlib
    temperature = "50.0 + 0.5 * t + 0.5 * x[0]"
    if rule == "fractional":
        scene = loader.resolve(raw_scene({
            "material": {"E": 75.0, "nu": 0.25},
            "memory": {"kernel": "fractional", "alpha": -20.0, "beta": 0.5,
                       "part": "deviatoric"},
            "viscoelastic": dict(WLF, temperature=temperature)}, steps=16))
    else:
        scene = prony_scene(pathlib.Path(folders[0]), steps=16, rule=rule, comm=comm,
                            temperature=temperature)
    whole = simulate(scene, out=folders[1], comm=comm, progress=False, keep_tables=True)
    run_stopped_after_checkpoint(monkeypatch, 4, lambda: simulate(
        scene, out=folders[2], comm=comm, progress=False))
    restarted = simulate(scene, out=folders[2], comm=comm, progress=False, keep_tables=True,
                         restart=True)
    assert [s["t"] for s in restarted.steps] == [s["t"] for s in whole.steps][4:], \
        ([s["t"] for s in restarted.steps], [s["t"] for s in whole.steps])
    a, b = whole.tables[-1], restarted.tables[-1]
    assert np.max(np.abs(a["u_nu"] - b["u_nu"])) <= 1e-12 * np.max(np.abs(a["u_nu"]))
    assert restarted.steps[-1]["reduced_time"] == pytest.approx(
        whole.steps[-1]["reduced_time"], rel=1e-13)
    assert whole.steps[-1]["reduced_time"][1] > 1.5 * whole.steps[-1]["reduced_time"][0] > 0
