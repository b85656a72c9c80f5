"""The adaptive grid's pieces (contactvisco.model.time_error, time.grid = "adaptive"): the
weight of the strain's curvature against quadrature, the estimate of the memory's local error
against the exponential rule's actual error on one step, the step controller's limits, and
the scene's refusals."""
import math

import numpy as np
import pytest
from scipy import integrate

from contactvisco.errors import SceneError
from contactvisco.model import time_error, time_grid
from contactvisco.model.memory import History
from contactvisco.scene import loader

ADAPTIVE = {"T": 100.0, "grid": "adaptive", "first": 0.01, "tolerance": 1e-3,
            "rule": "exponential"}


@pytest.mark.parametrize("k, tau", [(1e-4, 1.0), (0.005, 1.0), (0.3, 1.0), (20.0, 1.0),
                                    (2.0, math.inf)])
def test_curvature_weight_is_the_kernel_weighted_interpolation_error(k, tau):
    """c(k) = int_0^k exp(-s/tau) s (k - s)/2 ds, by its series and its closed form."""
    quad, _ = integrate.quad(lambda s: math.exp(-s / tau) * s * (k - s) / 2, 0.0, k,
                             epsabs=0.0, epsrel=1e-13)
    assert time_error.curvature_weight(k, tau) == pytest.approx(quad, rel=1e-9)


def test_estimate_is_the_exponential_rules_error_for_a_quadratic_strain():
    """For eps(t) = t^2 the exponential rule's error on a step (the history integral of the
    strain's linear interpolant minus the exact one) is what History estimates, to the
    order of the next term."""
    tau, a, k = 0.7, 2.0, 0.05
    history = History([(a, tau, "full")], rule="exponential", d=1)
    history.keep_previous = True
    times = [0.0, 0.04, 0.09, 0.09 + k]
    for i, t in enumerate(times):
        history.commit(np.array([t * t]), None if i == 0 else t - times[i - 1])
    t0, t1 = times[-2], times[-1]
    exact, _ = integrate.quad(lambda s: a * math.exp(-(t1 - s) / tau) * s * s, t0, t1,
                              epsrel=1e-13)
    linear, _ = integrate.quad(lambda s: a * math.exp(-(t1 - s) / tau) * (
        t0 * t0 + (s - t0) * (t0 + t1)), t0, t1, epsrel=1e-13)
    estimate, strain = history.local_error
    assert estimate == pytest.approx(abs(linear - exact), rel=1e-9)
    assert strain == t1 * t1
    assert history.state()["prev_full"][0] == times[-2] ** 2   # eps_{n-1}: checkpointed


def test_next_step_grows_and_shrinks_within_its_limits():
    """k' = k min(2, max(1/4, 0.9 (tol/e)^(1/3))) rounded down to a power of 2^(1/8), then
    within [min_step, max_step]."""
    assert time_error.next_step(1.0, 1e-3 / 8, 1e-3, 0.1, 10.0) == 2.0 ** (6 / 8)   # 1.8
    assert time_error.next_step(1.0, 1e-3 / 8 * (1 + 1e-9), 1e-3, 0.1, 10.0) == \
        time_error.next_step(1.0, 1e-3 / 8 * (1 - 1e-9), 1e-3, 0.1, 10.0)
    assert time_error.next_step(1.0, 0.0, 1e-3, 0.1, 10.0) == 2.0
    assert time_error.next_step(1.0, 1.0, 1e-3, 0.1, 10.0) == 0.25
    assert time_error.next_step(1.0, 1.0, 1e-3, 0.5, 10.0) == 0.5
    assert time_error.next_step(8.0, 0.0, 1e-3, 0.1, 10.0) == 10.0
    assert time_error.next_step(1.0, None, 1e-3, 0.1, 10.0) == 1.0


def test_adaptive_grid_states_its_landing_times_and_bounds():
    """Known in advance: 0, the landing times, T; the bounds of its steps for every check."""
    time = dict(ADAPTIVE, landing_times=[0.1, 200.0, 5.0], max_step=10.0)
    assert time_grid.times(time).tolist() == [0.0, 0.1, 5.0, 100.0]
    assert time_grid.steps(time).tolist() == [1e-4, 10.0]
    assert time_grid.summary(time) == (3, 1e-4, 10.0)


@pytest.mark.parametrize("time, key, words", [
    ({"tolerance": None}, "tolerance", "needs time.tolerance"),
    ({"rule": "trapezoid"}, "rule", "exponential"),
    ({"min_step": 0.1}, "max_step", "min_step 0.1 <= first 0.01"),
    ({"tolerance": 2.0}, "tolerance", "(0, 1)"),
    ({"growth": 1.5}, "growth", "belongs to"),
])
def test_bad_adaptive_grids_are_refused_naming_the_key(time, key, words):
    raw = {"name": "a", "memory": {"kernel": "exponential", "alpha": -1.0, "tau": 1.0},
           "time": {k: v for k, v in dict(ADAPTIVE, **time).items() if v is not None}}
    with pytest.raises(SceneError) as err:
        loader.resolve(raw)
    assert err.value.key == f"time.{key}"
    assert words in str(err.value)
