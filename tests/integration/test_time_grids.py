"""The time rules on variable grids (time.grid), verified on the homogeneous block against the
generalized Maxwell law in closed form (contactvisco.studies.relaxation: space is exact, so
the error is the time rule's alone), and runs on a logarithmic grid: restarted in its middle,
and on 1 and 2 ranks.

Measured (plane strain, shear relaxing with six terms tau = 1e-2 .. 1e3 s, 12 % each):
exponential rule, smooth ramp-and-hold 1 - exp(-t/0.3) over T = 1e4 s on a logarithmic grid
with first step 0.3/m and m steps per decade, relative stress errors 3.3e-4, 1.0e-4, 2.9e-5,
7.8e-6 at m = 10, 20, 40, 80 (orders 1.74, 1.77, 1.91). Trapezoid and paper rules need steps
below the shortest relaxation time (the trapezoid rule's stiffness A + k/2 R(0), its weight
k/2 on the newest strain): tau = 10 .. 1e3 s over T = 100 s, 1 - exp(-t/3), m = 20 .. 160:
trapezoid 4.8e-3 .. 7.8e-5 (orders 1.95, 1.99, 2.00), paper 1.5e-2 .. 4.5e-4 (orders 1.49,
1.73, 1.86: with the strain prescribed, the left point on the last sub-interval costs
k_n^2/2 R(0) eps' once, not accumulated).
"""
import math

import numpy as np
import pytest
from mpi4py import MPI

from contactvisco.api import read_results
from contactvisco.errors import SceneError
from contactvisco.model import time_grid
from contactvisco.model import viscoelastic as ve
from contactvisco.scene import loader
from contactvisco.solver.time_loop import simulate
from contactvisco.studies import relaxation as rl
from helpers import run_stopped_after_checkpoint

STRAIN = [[0.01, 0.004], [0.004, -0.002]]
WIDE = [1e-2, 1e-1, 1.0, 10.0, 100.0, 1000.0]       # relaxation times over five decades
SLOW = [10.0, 100.0, 1000.0]


def _material(taus):
    fractions = [0.12] * len(taus)
    visco = {"shear": {"instantaneous": 10.0, "tau": taus, "fractions": fractions},
             "bulk": {"instantaneous": 25.0}}
    return visco, ve.series(instantaneous=10.0, taus=taus, fractions=fractions), \
        ve.series(instantaneous=25.0)


def block_error(taus, T, m, rule, history="smooth", hold=0.3, grid=None):
    """The block's largest stress error relative to the largest closed-form stress, on the
    logarithmic grid of first step hold/m and m steps per decade (or `grid`); and the grid."""
    visco, G, K = _material(taus)
    grid = grid or {"grid": "logarithmic", "first": hold / m, "per_decade": m}
    raw = rl.block_scene(visco, "plane_strain", STRAIN, history, T, 1, rule=rule, hold=hold,
                         grid=grid)
    t, sigma = rl.block_stress(raw)
    exact = rl.maxwell_stress("plane_strain", G, K, STRAIN, history, t, hold=hold)
    if grid.get("grid") != "adaptive":              # an adaptive grid is known as it goes
        assert t.tolist() == time_grid.times(loader.resolve(raw)["time"]).tolist()
    return float(np.abs(sigma - exact).max() / np.abs(exact).max()), t


def orders(errors):
    return [math.log2(a / b) for a, b in zip(errors, errors[1:])]


def test_exponential_rule_on_a_logarithmic_grid_over_six_decades():
    """tau = 1e-2 .. 1e3 over T = 1e4: the error falls at second order as the steps per decade
    double (the strain's linear interpolation), and 20 steps per decade (99 steps) keep the
    stress within 1e-3."""
    errors = [block_error(WIDE, 1e4, m, "exponential")[0] for m in (10, 20, 40, 80)]
    found = orders(errors)
    assert all(1.6 < p < 2.2 for p in found) and found[-1] > 1.85, (errors, found)
    assert errors[1] <= 1e-3


def test_exponential_rule_is_exact_for_a_ramp_and_hold_whose_kink_is_a_step_time():
    """The strain min(t, 0.1) on a piecewise grid (a uniform ramp, then a logarithmic hold):
    piecewise linear in time with its kink a step time, so the exponential rule is exact per
    step for any k, here steps up to 5e4 times the shortest relaxation time and more."""
    for m in (4, 32):
        grid = {"grid": "piecewise",
                "segments": [{"end": 0.1, "steps": m},
                             {"end": 1e4, "grid": "logarithmic", "first": 0.1 / m,
                              "per_decade": m}]}
        error, t = block_error(WIDE, 1e4, m, "exponential", "hold", 0.1, grid)
        assert error < 1e-10 and 0.1 in t.tolist()
        assert np.diff(t).max() > 5e4 * WIDE[0]


@pytest.mark.parametrize("rule", ["trapezoid", "paper"])
def test_trapezoid_and_paper_rules_on_a_logarithmic_grid(rule):
    """tau = 10 .. 1e3 over T = 100 (steps below the shortest relaxation time at the finer
    grids): the trapezoid rule converges at order 2, the paper's rule towards 2 from below
    with larger errors (module description)."""
    errors = [block_error(SLOW, 100.0, m, rule, hold=3.0)[0] for m in (20, 40, 80, 160)]
    found = orders(errors)
    if rule == "trapezoid":
        assert all(abs(p - 2.0) < 0.1 for p in found[1:]), (errors, found)
    else:
        assert found == sorted(found) and found[-1] > 1.7, (errors, found)
        trapezoid = block_error(SLOW, 100.0, 160, "trapezoid", hold=3.0)[0]
        assert errors[-1] > 3 * trapezoid


def uniaxial_creep(time: dict):
    """A square in plane stress (E(t) with six terms tau = 1e-2 .. 1e3 s, 14 % each, nu = 0.3
    constant) held by rollers on its left and bottom and pulled by a unit traction on its
    right from t = 0: the stress is uniaxial, so u_x at (1, 1) is the strain J(t), the creep
    compliance of E(t). (times, u_x, J(times))."""
    taus = WIDE
    fractions = [0.14] * len(taus)
    scene = loader.resolve({
        "name": "uniaxial_creep",
        "geometry": {"lower": [0.0, 0.0], "upper": [1.0, 1.0], "cells": [1, 1]},
        "material": {"model": "plane_stress"},
        "viscoelastic": {"young": {"instantaneous": 100.0, "tau": taus,
                                   "fractions": fractions}, "nu": 0.3},
        "dirichlet": [{"boundary": "left", "components": [0], "value": [0.0]},
                      {"boundary": "bottom", "components": [1], "value": [0.0]}],
        "traction": [{"boundary": "right", "value": [1.0, 0.0]}],
        "time": {"T": 1e4, "rule": "exponential", **time},
        "output": {"probes": [[1.0, 1.0]], "xdmf": False, "figures": False}})
    result = simulate(scene, progress=False)
    t = np.array([record["t"] for record in result.steps])
    strain = np.array([record["probes"][0]["u"][0] for record in result.steps])
    young = ve.series(instantaneous=100.0, taus=taus, fractions=fractions)
    return t, strain, rl.prony_compliance(young, t)


def test_creep_over_seven_decades_on_a_logarithmic_grid():
    """Creep under a held load (the strain solved, not prescribed): against J(t), the error
    falls at nearly second order as the steps per decade double (measured 1.34e-3, 4.08e-4,
    1.19e-4 at m = 10, 20, 40), within 1e-3 at 20 per decade (128 steps); 1000 uniform steps
    are 10 times worse (1.2e-2: k = 10 s does not resolve the early creep)."""
    errors = []
    for m in (10, 20, 40):
        t, strain, exact = uniaxial_creep({"grid": "logarithmic", "first": 1e-2 / m,
                                           "per_decade": m})
        errors.append(np.abs(strain - exact).max() / np.abs(exact).max())
    found = orders(errors)
    assert all(p > 1.6 for p in found) and errors[1] <= 1e-3, (errors, found)
    assert exact[-1] > 5 * exact[0]                 # it crept
    t, strain, exact = uniaxial_creep({"steps": 1000})
    assert np.abs(strain - exact).max() / np.abs(exact).max() > 10 * errors[1]


def creep_scene(per_decade=4, time=None):
    """A block on the compliant foundation creeping under a constant load (shear relaxing
    over five decades), exponential rule on a logarithmic grid from 1e-3 s to 1e4 s (or the
    grid of the [time] keys `time`)."""
    visco, _, _ = _material(WIDE)
    return loader.resolve({
        "name": "log_creep",
        "geometry": {"lower": [0.0, 0.0], "upper": [2.0, 1.0], "cells": [8, 4]},
        "material": {"model": "plane_strain"}, "viscoelastic": visco,
        "dirichlet": [{"boundary": "left", "components": [0]}],
        "traction": [{"boundary": "top", "value": [0.0, "-0.5 * x[0]"]}],
        "contact": {"boundary": "bottom", "stiffness": 100.0, "g": 0.03},
        "time": {"T": 1e4, "rule": "exponential", **(time or {
            "grid": "logarithmic", "first": 1e-3, "per_decade": per_decade})},
        "output": {"probes": [[2.0, 1.0], [1.0, 0.0]], "xdmf": False, "figures": False}})


def _probes(result):
    return np.array([[probe["u"] for probe in record["probes"]] for record in result.steps])


def whole_and_restarted(tmp_path_factory, monkeypatch, scene, count):
    """The uninterrupted run of `scene`, the run stopped after its checkpoint of `count`
    accepted states and restarted, and their two output folders."""
    comm = MPI.COMM_WORLD
    folders = [comm.bcast(str(tmp_path_factory.mktemp(name)) if comm.rank == 0 else None)
               for name in ("whole", "stopped")]
    whole = simulate(scene, out=folders[0], comm=comm, progress=False)
    run_stopped_after_checkpoint(monkeypatch, count, lambda: simulate(
        scene, out=folders[1], comm=comm, progress=False))
    restarted = simulate(scene, out=folders[1], comm=comm, progress=False, restart=True)
    return whole, restarted, folders


def test_restart_in_the_middle_of_a_logarithmic_grid_continues_it(tmp_path_factory,
                                                                  monkeypatch):
    """A run stopped after its checkpoint of step 12 (of 28) and restarted steps on the same
    grid and reaches the uninterrupted run's displacements; the body creeps meanwhile. The
    records of both give each step's size k."""
    comm = MPI.COMM_WORLD
    scene = creep_scene()
    whole, restarted, folders = whole_and_restarted(tmp_path_factory, monkeypatch, scene, 13)
    grid = time_grid.times(scene["time"]).tolist()
    assert [s["t"] for s in whole.steps] == grid
    assert [s["t"] for s in restarted.steps] == grid[13:]
    # each record's k is its step of the grid, t_n - t_{n-1}, in the result and in steps.jsonl
    k = [None] + [b - a for a, b in zip(grid, grid[1:])]
    assert [s["k"] for s in whole.steps] == k
    if comm.rank == 0:
        written = read_results(folders[1])["steps"]
        assert [s["k"] for s in written] == k
        assert [s["k"] for s in restarted.steps] == k[13:]
    a, b = _probes(whole), _probes(restarted)
    assert np.abs(a[13:] - b).max() <= 1e-12 * np.abs(a).max()
    assert abs(a[-1, 0, 1]) > 1.5 * abs(a[1, 0, 1]) > 0          # it crept


@pytest.mark.mpi
def test_ranks_agree_on_a_logarithmic_grid():
    """The run over the ranks steps on the grid of the run on one rank and gives its
    displacements."""
    scene = creep_scene()
    everywhere = simulate(scene, comm=MPI.COMM_WORLD, progress=False)
    alone = simulate(scene, comm=MPI.COMM_SELF, progress=False)
    assert [s["t"] for s in everywhere.steps] == [s["t"] for s in alone.steps]
    a, b = _probes(everywhere), _probes(alone)
    assert np.abs(a - b).max() <= 1e-10 * np.abs(b).max()


def test_restart_refuses_a_time_file_whose_times_changed(tmp_path_factory, monkeypatch):
    """The grid of time.times_file is the file's: a restart continues on it, and after the
    file changed (it would step on another grid) it is refused naming the file's times."""
    comm = MPI.COMM_WORLD
    folder = comm.bcast(str(tmp_path_factory.mktemp("times")) if comm.rank == 0 else None)
    import pathlib
    folder = pathlib.Path(folder)
    scene_file, times_file = folder / "creep.toml", folder / "samples.csv"
    if comm.rank == 0:
        times_file.write_text("t,depth\n" + "".join(f"{float(t)!r},0\n"
                                                    for t in np.geomspace(1e-3, 1e4, 12)))
        scene_file.write_text(
            'name = "file_grid"\n[geometry]\ncells = [2, 2]\n[material]\nmodel = '
            '"plane_strain"\n[memory]\nkernel = "exponential"\nalpha = -20.0\ntau = 10.0\n'
            '[[dirichlet]]\nboundary = "left"\n[[traction]]\nboundary = "right"\nvalue = '
            '[0.5, 0.0]\n[time]\nT = 1e4\nrule = "exponential"\ngrid = "times"\n'
            'times_file = "samples.csv"\n[output]\nxdmf = false\nfigures = false\n')
    comm.barrier()
    out = folder / "out"
    run_stopped_after_checkpoint(monkeypatch, 5, lambda: simulate(
        loader.load(str(scene_file)), out=out, comm=comm, progress=False))
    same = simulate(loader.load(str(scene_file)), out=out, comm=comm, progress=False,
                    restart=True)                  # the same file: it continues
    assert len(same.steps) == 8 and same.steps[-1]["t"] == 1e4
    comm.barrier()
    if comm.rank == 0:
        times_file.write_text("t\n" + "".join(f"{float(t)!r}\n"
                                             for t in np.geomspace(2e-3, 1e4, 12)))
    comm.barrier()
    with pytest.raises(SceneError, match=r"time.times_file \(its times\)"):
        simulate(loader.load(str(scene_file)), out=out, comm=comm, progress=False,
                 restart=True)


@pytest.mark.parametrize("rule", ["exponential", "trapezoid"])
def test_a_constant_temperature_is_the_reference_run_on_the_scaled_grid(rule):
    """Time-temperature superposition on a logarithmic grid: at theta != T_ref each step is
    the reduced step k_n / a_T, so the block's stresses are those of the T_ref run on the
    grid scaled by 1/a_T (first step and T divided by a_T, the same growth), step by step."""
    visco, _, _ = _material(SLOW)
    wlf = {"shift": "wlf", "T_ref": 50.0, "C1": 17.44, "C2": 51.6}
    theta = 53.0
    a_T = 10.0 ** float(ve.log10_shift(wlf, theta))
    assert a_T < 0.2                                      # about ten times faster
    runs = []
    for temperature, scale in ((theta, 1.0), (None, 1.0 / a_T)):
        grid = {"grid": "logarithmic", "first": 0.01 * scale, "growth": 1.1}
        material = dict(visco, **wlf, **({"temperature": temperature} if temperature else {}))
        raw = rl.block_scene(material, "plane_strain", STRAIN, "smooth", 50.0 * scale, 1,
                             rule=rule, hold=3.0 * scale, grid=grid)
        runs.append(rl.block_stress(raw))
    (t, sigma), (t_ref, sigma_ref) = runs
    assert len(t) == len(t_ref) and np.allclose(t / a_T, t_ref, rtol=1e-12)
    assert np.abs(sigma - sigma_ref).max() <= 1e-10 * np.abs(sigma_ref).max()


def test_fractional_kernel_regains_second_order_on_a_logarithmic_grid():
    """Uniaxial creep with the fractional kernel (beta = 0.5) against the Mittag-Leffler
    closed form at T = 1: the creep behaves like t^(1 - beta) at 0, which limits uniform grids
    to order 1.5 (tests/unit/test_power_memory.py); a logarithmic grid from 1e-3/m resolves
    that start, and the trapezoid rule's product integration converges at order 2 in the
    steps per decade (measured 1.95 and 1.96 from m = 10 to 40); the paper's rule stays at
    1.5 (its left point on the last step)."""
    from contactvisco.studies.verification import uniaxial, uniaxial_exact
    exact = uniaxial_exact("fractional", 1.0)
    found = {}
    for rule in ("trapezoid", "paper"):
        errors = [abs(uniaxial("fractional", rule, 1.0, 1, memory={"tolerance": 1e-10},
                               comm=MPI.COMM_SELF,
                               time={"grid": "logarithmic", "first": 1e-3 / m,
                                     "per_decade": m})[-1] - exact) / abs(exact)
                  for m in (10, 20, 40)]
        found[rule] = orders(errors)
    assert all(p > 1.85 for p in found["trapezoid"]), found
    assert all(abs(p - 1.5) < 0.1 for p in found["paper"]), found
