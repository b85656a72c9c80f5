"""time.rule = "exponential": each exponential term of the kernel integrated exactly against the
strain taken linear over each step (Taylor, Pister & Goudreau 1970; Simo & Hughes 1998 ch. 10).
A single Maxwell term against its closed form (second order, exact for a piecewise-linear
strain, any step sizes), the weights over k/tau from 1e-8 to 1e8, the homogeneous block with a
published nine-term asphalt series at steps of seconds (where the trapezoid rule is refused),
the agreement with the trapezoid rule for k << tau, and reduced time."""
import math

import numpy as np
import pytest

from contactvisco.errors import SceneError
from contactvisco.model import viscoelastic as ve
from contactvisco.model.material import lame_constants
from contactvisco.model.memory import History, ReducedTimeHistory, exponential_weights
from contactvisco.scene import loader
from contactvisco.studies import relaxation as rl

ALPHA, TAU = -3.0, 0.4                  # R(t) = ALPHA exp(-t/TAU): G_1 = -ALPHA TAU = 1.2
KINK = 0.7                              # the ramp eps = t holds from t = KINK on

#: Asphalt mixture SBS-AC13 at 20 C, E(0) = 1550 MPa: "Multiple Reflective Cracks in Semirigid
#: Base Asphalt Pavement under Traffic Load Using XFEM", Advances in Civil Engineering, vol.
#: 2022, article ID 9405338 (Hindawi), Table 2 (as demos/data/sbs_ac13_prony.csv).
SBS_TAU = [1e-5, 1e-4, 1e-3, 1e-2, 1e-1, 1.0, 10.0, 100.0, 1000.0]
SBS_G = [0.31288, 0.20212, 0.21377, 0.14498, 0.06803, 0.02679, 0.01078, 0.00428, 0.00264]
SBS = {"young": {"instantaneous": 1550.0, "tau": SBS_TAU, "fractions": SBS_G}, "nu": 0.35}
STRAIN = [[0.01, 0.004], [0.004, -0.002]]


def maxwell(times, strain, rule="exponential"):
    """H(t_n), n >= 1, of one term from History: explicit part + implicit weight eps_n."""
    history = History([(ALPHA, TAU, "full")], rule=rule, d=1)
    history.commit(np.array([strain(times[0])]), None)
    out = []
    for a, b in zip(times, times[1:]):
        k = b - a
        H = history.explicit(k) + history.implicit(k).get("full", 0.0) * strain(b)
        out.append(H[0])
        history.commit(np.array([strain(b)]), k)
    return np.array(out)


def ramp_hold(t):
    return min(t, KINK)


def ramp_hold_exact(t):
    """int_0^t ALPHA exp(-(t - s)/TAU) min(s, KINK) ds."""
    ramp = lambda s: ALPHA * (TAU * s - TAU**2 * -math.expm1(-s / TAU))
    if t <= KINK:
        return ramp(t)
    return (math.exp(-(t - KINK) / TAU) * ramp(KINK)
            + ALPHA * KINK * TAU * -math.expm1(-(t - KINK) / TAU))


def test_piecewise_linear_strain_is_exact_for_any_steps():
    """Steps of random sizes with the kink among the step times: the rule integrates exactly
    what it assumes, so H equals the closed form to round-off (the trapezoid rule does not)."""
    rng = np.random.default_rng(5)
    times = np.unique(np.concatenate([[0.0, KINK, 3.0], rng.uniform(0.0, 3.0, 30)]))
    exact = np.array([ramp_hold_exact(t) for t in times[1:]])
    error = np.abs(maxwell(times, ramp_hold) - exact).max() / np.abs(exact).max()
    assert error < 1e-14, error
    trapezoid = np.abs(maxwell(times, ramp_hold, "trapezoid") - exact).max()
    assert trapezoid > 1e-4 * np.abs(exact).max()


def test_second_order_for_a_smooth_strain():
    """eps = sin(3t) on [0, 2]: the error at T falls with order 2 (measured 2.00)."""
    omega = 3.0
    # int_0^t e^{-(t-s)/TAU} sin(w s) ds, closed form
    c = 1.0 / TAU
    exact = ALPHA * ((c * math.sin(omega * 2.0) - omega * math.cos(omega * 2.0)
                      + omega * math.exp(-c * 2.0)) / (c**2 + omega**2))
    errors = [abs(maxwell(np.linspace(0.0, 2.0, n + 1), lambda t: math.sin(omega * t))[-1]
                  - exact) for n in (20, 40, 80, 160)]
    orders = [math.log2(a / b) for a, b in zip(errors, errors[1:])]
    assert all(abs(p - 2.0) < 0.05 for p in orders), (errors, orders)


def test_weights_over_k_from_1e_8_to_1e8_tau():
    """w0, w1 finite and >= 0, w1 -> k/2 (trapezoid) for k << tau and -> tau for k >> tau, the
    implicit stiffness A + alpha w1 = A - G (1 - (1 - e^-z)/z) between G_inf = A - G and A,
    and w0 + w1 = tau (1 - d) (the exact integral of a constant strain); arrays (reduced time)
    give the numbers' values."""
    z = np.logspace(-8, 8, 161)
    G, A = 5.0, 7.0
    for tau in (1e-5, 1.0, 1e3):
        k = z * tau
        d, w0, w1 = exponential_weights(k, tau)
        assert np.all(np.isfinite(w0)) and np.all(np.isfinite(w1))
        assert np.all(w0 >= 0) and np.all(w1 > 0)
        np.testing.assert_allclose(w0 + w1, -tau * np.expm1(-z), rtol=1e-14)
        np.testing.assert_allclose(w1[z < 1e-6], k[z < 1e-6] / 2, rtol=1e-6)
        np.testing.assert_allclose(w1[z > 1e6], tau, rtol=1e-6)
        stiffness = A + (-G / tau) * w1
        assert np.all(stiffness >= A - G) and np.all(stiffness <= A)
        np.testing.assert_allclose(stiffness, A - G * (1 + np.expm1(-z) / z), rtol=1e-13)
        numbers = [exponential_weights(float(x), tau) for x in k[::40]]
        np.testing.assert_allclose(np.array(numbers).T, np.array([d, w0, w1])[:, ::40],
                                   rtol=1e-15)
    assert exponential_weights(0.3, math.inf) == (1.0, 0.15, 0.15)


def test_block_step_and_ramp_are_exact():
    """The homogeneous block (plane strain, shear and bulk relaxing) under a strain step and a
    ramp: the strain is linear over every step, so the stress is the generalized Maxwell
    closed form to round-off at 7 steps."""
    shear = {"instantaneous": 10.0, "tau": [0.3, 2.0], "fractions": [0.3, 0.2]}
    bulk = {"long_term": 20.0, "tau": [0.5], "moduli": [5.0]}
    Gs = ve.series(instantaneous=10.0, taus=[0.3, 2.0], fractions=[0.3, 0.2])
    Ks = ve.series(long_term=20.0, taus=[0.5], moduli=[5.0])
    for history in ("step", "ramp"):
        t, sigma = rl.block_stress(rl.block_scene({"shear": shear, "bulk": bulk},
                                                  "plane_strain", STRAIN, history, 2.0, 7,
                                                  rule="exponential"))
        exact = rl.maxwell_stress("plane_strain", Gs, Ks, STRAIN, history, t)
        assert np.abs(sigma - exact).max() <= 1e-13 * np.abs(exact).max(), history


def sbs_stress(history, T, steps, rule="exponential", omega=0.5):
    return rl.block_stress(rl.block_scene(SBS, "plane_stress", STRAIN, history, T, steps,
                                          rule=rule, omega=omega))


def test_published_series_at_steps_of_seconds():
    """The nine-term series (tau from 1e-5 to 1e3 s): the trapezoid rule is refused at k = 1 s
    (its stiffness needs k < 6e-5 s) and points to the exponential rule, which runs. A strain
    step is exact (relaxation E(t) A0/E(0) E at every step); for eps = sin(t/2) E the error
    at k = 1 s against a run with 16x smaller steps and against the closed form stays under
    the rule's bound sum_i g_i max|eps - eps_h| <= sum_i g_i k^2 w^2/8 (relative to A0 E),
    and it falls as k^2 does (ratio of k and k/2 > 2.5; the bound's constant counts every
    term, the error mostly those with tau > k)."""
    with pytest.raises(SceneError, match="take k < 5.96.*e-05.*'exponential'") as err:
        loader.resolve(rl.block_scene(SBS, "plane_stress", STRAIN, "sine", 8.0, 8))
    assert err.value.key == "viscoelastic.young"
    young = ve.series(instantaneous=1550.0, taus=SBS_TAU, fractions=SBS_G)
    shear, bulk = ve.young_series(young, 0.35)
    lam, mu = lame_constants("plane_stress", 1550.0, 0.35)
    E = np.array(STRAIN)
    scale = np.abs(lam * np.trace(E) * np.eye(2) + 2 * mu * E).max()      # |A0 E|
    t, step = sbs_stress("step", 100.0, 10)
    exact = rl.maxwell_stress("plane_stress", shear, bulk, STRAIN, "step", t)
    assert np.abs(step - exact).max() <= 1e-12 * scale
    assert np.abs(step[-1]).max() < 0.05 * scale                  # relaxed to E(100)/E(0)
    omega, bound = 0.5, lambda k: sum(SBS_G) * k**2 * 0.25 / 8
    t, coarse = sbs_stress("sine", 8.0, 8)
    _, half = sbs_stress("sine", 8.0, 16)
    _, fine = sbs_stress("sine", 8.0, 128)
    exact = rl.maxwell_stress("plane_stress", shear, bulk, STRAIN, "sine", t, omega=omega)
    difference = np.abs(coarse - fine[::16]).max() / scale
    assert difference <= bound(1.0) + bound(1.0 / 16), difference
    assert np.abs(coarse - exact).max() / scale <= bound(1.0)
    ratio = difference / (np.abs(half - fine[::8]).max() / scale)
    assert ratio > 2.5, ratio


def test_agrees_with_the_trapezoid_rule_for_small_steps():
    """k = 0.01 and 0.005 <= tau/30 (eps = sin(3t) E, 3 relaxation times): the two rules
    differ by O(k^2) (the difference falls 4-fold with k)."""
    visco = {"shear": {"instantaneous": 10.0, "tau": [0.3, 2.0], "fractions": [0.3, 0.2]},
             "bulk": {"long_term": 20.0, "tau": [0.5], "moduli": [5.0]}}
    differences = []
    for steps in (40, 80):
        runs = [rl.block_stress(rl.block_scene(visco, "plane_strain", STRAIN, "sine", 0.4,
                                               steps, rule=rule, omega=3.0))[1]
                for rule in ("exponential", "trapezoid")]
        differences.append(np.abs(runs[0] - runs[1]).max() / np.abs(runs[1]).max())
    order = math.log2(differences[0] / differences[1])
    assert abs(order - 2.0) < 0.1, differences
    assert differences[1] < 1e-4


WLF = {"shift": "wlf", "T_ref": 50.0, "C1": 17.44, "C2": 51.6}


def thermal_block(visco, memory, T, steps, history="ramp", rate=1.0):
    """The block in the paper's form (E = 30, nu = 0.3, the [memory] kernel) with the
    exponential rule; visco None: isothermal."""
    raw = rl.block_scene(visco, "plane_strain", STRAIN, history, T, steps,
                         rule="exponential", rate=rate)
    raw["material"].update(E=30.0, nu=0.3)
    raw["memory"] = dict(memory)
    if visco is None:
        del raw["viscoelastic"]
    return raw


@pytest.mark.parametrize("memory", [
    {"kernel": "prony", "terms": [{"alpha": -2.0, "tau": 0.3, "part": "deviatoric"},
                                  {"alpha": -1.0, "tau": 2.0}, {"alpha": 0.5}]},
    {"kernel": "power", "alpha": -3.0, "beta": 0.6, "tau": 0.2, "part": "deviatoric"}],
    ids=["prony-constant", "power"])
def test_constant_temperature_is_scaled_time(memory):
    """theta = 53 (a_T = 0.11): the run with 1/a_T per point equals the T_ref run over 2/a_T
    to round-off (the weights at dxi = k/a_T per point), and differs from the isothermal run."""
    a = 10 ** float(ve.log10_shift(WLF, 53.0))
    _, hot = rl.block_stress(thermal_block(dict(WLF, temperature=53.0), memory, 2.0, 12))
    _, ref = rl.block_stress(thermal_block(None, memory, 2.0 / a, 12, rate=a))
    _, iso = rl.block_stress(thermal_block(None, memory, 2.0, 12))
    assert np.abs(hot - ref).max() <= 1e-13 * np.abs(ref).max()
    assert np.abs(hot - iso).max() > 1e-2 * np.abs(iso).max()


def test_temperature_ramp_second_order():
    """theta = 50 + 2t at one point, eps = sin(t) E0, two Prony terms with large k/tau at the
    end (dxi/tau up to 10): ReducedTimeHistory with the exponential rule converges with
    order 2 to its 2560-step run (the reduced-time increment is the trapezoid rule in t)."""
    terms = [(-40.0, 0.01, "full"), (-2.0, 0.5, "full")]
    E0 = np.array([0.01, 0.004, 0.004, -0.002])
    inverse = lambda t: 10.0 ** -ve.log10_shift(WLF, np.array([50.0 + 2.0 * t]))

    def stress(steps, T=2.0):
        k = T / steps
        history = ReducedTimeHistory(History(terms, k, "exponential", 2), 4)
        history.stage(inverse(0.0))
        history.commit(0.0 * E0, None)
        for n in range(1, steps + 1):
            history.stage(inverse(n * k))
            out = history.explicit(k) + history.implicit(k)["full"] * math.sin(n * k) * E0
            history.commit(math.sin(n * k) * E0, k)
        return out

    ref = stress(2560)
    errors = [np.abs(stress(n) - ref).max() for n in (40, 80, 160)]
    orders = [math.log2(a / b) for a, b in zip(errors, errors[1:])]
    assert all(abs(p - 2.0) < 0.15 for p in orders), (errors, orders)


def test_kernels_refused_and_fractional_accepted():
    """The table kernel and the power kernel summed directly have no exponential terms: the
    rule is refused naming time.rule; the fractional kernel's product integration is the same
    rule (its run equals the trapezoid one)."""
    for memory, words in (({"kernel": "table", "times": [0.0, 1.0], "values": [-1.0, -0.5]},
                           "no exponential terms"),
                          ({"kernel": "power", "alpha": -1.0, "beta": 0.5, "tau": 1.0,
                            "summation": "direct"}, "memory.summation = 'soe'")):
        with pytest.raises(SceneError) as err:
            loader.resolve(thermal_block(None, memory, 1.0, 4))
        assert err.value.key == "time.rule" and words in str(err.value), str(err.value)
    fractional = {"kernel": "fractional", "alpha": -1.0, "beta": 0.5}
    _, exponential = rl.block_stress(thermal_block(None, fractional, 1.0, 4, history="sine"))
    raw = thermal_block(None, fractional, 1.0, 4, history="sine")
    raw["time"]["rule"] = "trapezoid"
    _, trapezoid = rl.block_stress(raw)
    assert np.array_equal(exponential, trapezoid)
    assert np.abs(exponential[-1]).max() > 0


def test_paper_scene_constant_kernel_is_the_trapezoid_rule():
    """The paper's scene (contact, friction, R = alpha I, tau = inf): w0 = w1 = k/2, so the
    exponential rule is the trapezoid rule, to round-off, through the whole time loop."""
    from contactvisco.solver.time_loop import simulate
    runs = {}
    for rule in ("exponential", "trapezoid"):
        scene = loader.load("paper", ["geometry.cells=[8, 8]", "time.steps=5",
                                      f"time.rule='{rule}'"])
        result = simulate(scene, progress=False)
        runs[rule] = np.array([[p["u"] for p in s["probes"]] for s in result.steps])
    assert np.abs(runs["exponential"] - runs["trapezoid"]).max() \
        <= 1e-12 * np.abs(runs["trapezoid"]).max()
    assert np.abs(runs["trapezoid"][-1] - runs["trapezoid"][1]).max() > 1e-3
