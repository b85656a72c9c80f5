"""A temperature with the memory kernels of [memory] (a [viscoelastic] table holding only the
temperature and its shift function): the kernels run by a recursion of exponentials (Prony,
exponential, constant, and the power kernel as a sum of exponentials) advance it in reduced
time, and the fractional kernel with its last step integrated exactly over the reduced step;
the table kernel and the direct power and fractional sums are refused, saying why."""
import math

import numpy as np
import pytest
from mpi4py import MPI

from contactvisco.errors import SceneError
from contactvisco.model import kernels
from contactvisco.model import viscoelastic as ve
from contactvisco.model.memory import (FractionalHistory, History, ReducedFractionalHistory,
                                       ReducedTimeHistory)
from contactvisco.scene import loader
from contactvisco.scene.toml_text import scene_text
from contactvisco.studies import relaxation as rl

WLF = {"shift": "wlf", "T_ref": 50.0, "C1": 17.44, "C2": 51.6}
STRAIN = [[0.01, 0.004], [0.004, -0.002]]
POWER = {"kernel": "power", "alpha": -3.0, "beta": 0.6, "tau": 0.2, "part": "deviatoric"}
EXPONENTIAL = {"kernel": "exponential", "alpha": [-2.0, -1.0], "tau": [0.3, 2.0]}
FRACTIONAL = {"kernel": "fractional", "alpha": -3.0, "beta": 0.5, "part": "deviatoric",
              "tolerance": 1e-8}


def thermal_scene(visco, memory, T, steps, rate=1.0):
    """The homogeneous block under the ramp eps = rate t E, material in the paper's form
    (E = 30, nu = 0.3, the [memory] kernel), with the [viscoelastic] table `visco` (None:
    isothermal)."""
    raw = rl.block_scene(visco, "plane_strain", STRAIN, "ramp", T, steps, rate=rate)
    raw["material"].update(E=30.0, nu=0.3)
    raw["memory"] = dict(memory)
    if visco is None:
        del raw["viscoelastic"]
    return raw


@pytest.mark.parametrize("memory", [POWER, EXPONENTIAL, FRACTIONAL],
                         ids=["power", "exponential", "fractional"])
@pytest.mark.parametrize("theta", [53.0, 45.0])
def test_constant_temperature_is_scaled_time(memory, theta):
    """At a constant theta the ramp eps = t E over [0, 2] equals the T_ref ramp eps = a_T t E
    over [0, 2 / a_T] with the same 12 steps to round-off (the power kernel fitted over the
    reduced span 2 / a_T in both; the fractional kernel's on [k / 2^max_cuts / a_T, 2 / a_T]),
    and differs from the isothermal run."""
    a = 10 ** float(ve.log10_shift(WLF, theta))
    assert abs(math.log10(a)) > 0.9
    _, hot = rl.block_stress(thermal_scene(dict(WLF, temperature=theta), memory, 2.0, 12))
    _, ref = rl.block_stress(thermal_scene(None, memory, 2.0 / a, 12, rate=a))
    _, iso = rl.block_stress(thermal_scene(None, memory, 2.0, 12))
    assert np.abs(hot - ref).max() <= 1e-13 * np.abs(ref).max()
    assert np.abs(hot - iso).max() > 1e-2 * np.abs(iso).max()


def drive_sine(history, theta_of, T, steps):
    """The memory stress at T of the strain eps(t) = sin(t) E0 at one point, stepped through
    `history` in reduced time: H_explicit + w(dxi) eps_N per step (w the last step's implicit
    weight, none for the paper's rule); also the reduced time reached."""
    E0 = np.array([0.01, 0.004, 0.004, -0.002])
    k = T / steps
    inverse = lambda t: 10.0 ** -ve.log10_shift(WLF, np.array([theta_of(t)]))
    history.stage(inverse(0.0))
    history.commit(0.0 * E0, None)
    for n in range(1, steps + 1):
        t = n * k
        history.stage(inverse(t))
        out = history.explicit(k) + history.implicit(k).get("full", 0.0) * math.sin(t) * E0
        history.commit(math.sin(t) * E0, k)
    return out, history.reduced_time[0]


def ramp_stress(terms, theta_of, T, steps, R0):
    """drive_sine for a Prony kernel, trapezoid rule in reduced time (ReducedTimeHistory)."""
    return drive_sine(ReducedTimeHistory(History(terms, T / steps, "trapezoid", 2), 4),
                      theta_of, T, steps)


def test_power_kernel_temperature_ramp_order():
    """theta = 50 + 2 t (a_T from 1 to 0.02, xi(2) = 12.1): the power kernel's sum of
    exponentials (fitted on [0, 20]) in reduced time against the same recursion with 2560
    steps; the error falls with order 2."""
    theta_of = lambda t: 50.0 + 2.0 * t
    T = 2.0
    fit = kernels.power_soe(-3.0, 0.6, 1.0, 20.0, 1e-8)
    terms = [(w, 1.0 / s, "full") for w, s in zip(fit.weights, fit.rates)]
    ref, xi = ramp_stress(terms, theta_of, T, 2560, fit(0.0))
    assert 5.0 < xi < 20.0                       # reduced time well beyond t, inside the fit
    errors = [np.abs(ramp_stress(terms, theta_of, T, n, fit(0.0))[0] - ref).max()
              for n in (40, 80, 160)]
    orders = [math.log2(a / b) for a, b in zip(errors, errors[1:])]
    assert all(abs(p - 2.0) < 0.1 for p in orders), (errors, orders)


def fractional_ramp_stress(fit, theta_of, T, steps, rule):
    """drive_sine for the fractional kernel alpha t^-0.5 / Gamma(0.5), alpha = -3, in reduced
    time (ReducedFractionalHistory): its last step integrated exactly over dxi."""
    history = ReducedFractionalHistory(
        FractionalHistory(-3.0, 0.5, fit, rule, "full", 2, T / steps), 4)
    return drive_sine(history, theta_of, T, steps)


@pytest.mark.parametrize("rule, order", [("trapezoid", 2.0), ("paper", 1.5)])
def test_fractional_kernel_temperature_ramp_order(rule, order):
    """theta = 50 + 2 t (a_T from 1 to 0.02, xi(2) = 12.1): the fractional kernel (beta = 0.5)
    in reduced time, its last step integrated exactly over dxi per point, older steps by a sum
    of exponentials fitted on [2/2560, 20], against the same with 2560 steps. The product
    trapezoid rule converges with order 2 (the strain linear in xi over each step and
    dxi = k/2 (1/a_T(theta_n) + 1/a_T(theta_n+1)) both second order), the paper's rule (the
    last step at its left point, weight ~ dxi^(1-beta)) with order 2 - beta = 1.5."""
    theta_of = lambda t: 50.0 + 2.0 * t
    fit = kernels.fractional_soe(-3.0, 0.5, 2.0 / 2560, 20.0, 1e-10)
    ref, xi = fractional_ramp_stress(fit, theta_of, 2.0, 2560, rule)
    assert 5.0 < xi < 20.0
    errors = [np.abs(fractional_ramp_stress(fit, theta_of, 2.0, n, rule)[0] - ref).max()
              for n in (40, 80, 160)]
    orders = [math.log2(a / b) for a, b in zip(errors, errors[1:])]
    assert all(abs(p - order) < 0.25 for p in orders), (errors, orders)


@pytest.mark.parametrize("memory", [POWER, FRACTIONAL], ids=["power", "fractional"])
def test_temperature_field_with_a_fitted_kernel(memory):
    """theta = 50 + 2 t + 1.5 x[0] over two cells: the fit spans the reduced time the step
    times reach (the note says so), the points relax differently, and the hotter point lies
    closer to the relaxed stress."""
    visco = dict(WLF, temperature="50.0 + 2.0 * t + 1.5 * x[0]")
    raw = thermal_scene(visco, memory, 1.0, 10)
    raw["geometry"]["cells"] = [2, 1]
    t, sigma, points = rl.block_stress(raw, MPI.COMM_SELF, per_point=True)
    _, iso = rl.block_stress(thermal_scene(None, memory, 1.0, 10), MPI.COMM_SELF)
    last = sigma[-1, :, 0, 1]
    hot, cold = last[np.argmax(points[:, 0])], last[np.argmin(points[:, 0])]
    assert abs(hot - cold) > 1e-2 * abs(cold)
    assert hot < cold < iso[-1, 0, 1]            # R < 0: a faster clock relaxes more


@pytest.mark.mpi
@pytest.mark.skipif(MPI.COMM_WORLD.size == 1, reason="needs mpirun -n 2 or more")
@pytest.mark.parametrize("rule", ["trapezoid", "paper"])
def test_fractional_kernel_in_reduced_time_ranks_agree(rule):
    """theta = 50 + 2 t + 1.5 x[0] on a 3 x 3 block with the fractional kernel: the run
    distributed over the ranks equals the one-rank run (COMM_SELF)."""
    raw = thermal_scene(dict(WLF, temperature="50.0 + 2.0 * t + 1.5 * x[0]"), FRACTIONAL,
                        1.0, 8)
    raw["geometry"]["cells"] = [3, 3]
    raw["time"]["rule"] = rule
    _, everywhere = rl.block_stress(raw, MPI.COMM_WORLD)
    _, alone = rl.block_stress(raw, MPI.COMM_SELF)
    assert np.abs(everywhere - alone).max() <= 1e-12 * np.abs(alone).max()


@pytest.mark.parametrize("memory, words", [
    ({"kernel": "table", "times": [0.0, 1.0], "values": [-1.0, -0.5]}, "convolved in full"),
    (dict(POWER, summation="direct"), "O(n) memory per point"),
    (dict(FRACTIONAL, summation="direct"), "O(n) memory per point"),
])
def test_kernels_without_a_recursion_refused(memory, words):
    with pytest.raises(SceneError) as err:
        loader.resolve(thermal_scene(dict(WLF, temperature=53.0), memory, 1.0, 4))
    assert err.value.key == "viscoelastic.temperature" and words in str(err.value)


def test_thermal_table_needs_a_temperature_and_round_trips(tmp_path):
    """Without relaxation functions the table needs a temperature (else the message lists the
    forms); with one, the scene writes back to TOML with [material] and [memory] kept."""
    with pytest.raises(SceneError, match="none of them") as err:
        loader.resolve(thermal_scene(dict(WLF), POWER, 1.0, 4))
    assert err.value.key == "viscoelastic.shear"
    scene = loader.resolve(thermal_scene(dict(WLF, temperature=53.0), POWER, 1.0, 4))
    path = tmp_path / "again.toml"
    path.write_text(scene_text(scene))
    again = loader.load(str(path))
    assert again["memory"]["kernel"] == "power" and again["material"]["E"] == 30.0
    assert again["viscoelastic"]["temperature"] == 53.0
    from contactvisco.post.figures import relaxation_figure
    with pytest.raises(SceneError, match="relaxation functions"):
        relaxation_figure(scene)
