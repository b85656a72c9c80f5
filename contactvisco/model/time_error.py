"""The local time error of the memory terms on a step, and the next step of an adaptive grid.

The exponential rule integrates each term alpha_i exp(-(t - s)/tau_i) of a Prony kernel
exactly against the strain taken linear over the step (contactvisco.model.memory.History), so
its error on the step [t_n, t_n + k] is that of the linear interpolation, eps(s) - eps_lin(s)
= -(s - t_n)(t_n + k - s)/2 eps'' + O(k^3), weighted by the kernel:

    e_{n+1} = sum_i alpha_i c_i(k) P_i eps'',
    c_i(k) = int_0^k exp(-s/tau_i) s (k - s)/2 ds = tau_i^3/2 (x - 2 + (x + 2) e^(-x)),
    x = k/tau_i,

that is k^3/12 for k << tau_i and tau_i^2 k/2 for k >> tau_i (a term that has relaxed within
the step weighs little). eps'' is the second divided difference of the last three strains,

    eps'' = 2 ((eps_{n+1} - eps_n)/k_{n+1} - (eps_n - eps_{n-1})/k_n) / (k_n + k_{n+1}).

The estimate is relative: max |e_{n+1}| over the points and components, over the largest
stress the memory can hold from the newest strain, sum_i |alpha_i| min(tau_i, t_{n+1})
max |eps_{n+1}|. The next step is the controller of an order-3 local error (Hairer, Norsett,
Wanner, Solving ODEs I, section II.4): k_{n+2} = k_{n+1} min(GROW, max(SHRINK,
SAFETY (tol/e)^(1/3))), the factor rounded down to a power of 2^(1/8), so that an estimate
changed by round-off (another number of ranks, a restart) chooses the same step.
"""
from __future__ import annotations

import math

import numpy as np

#: The largest ratio of two consecutive steps the controller takes.
GROW = 2.0
#: The smallest ratio of two consecutive steps the controller takes.
SHRINK = 0.25
#: The safety factor on the step the tolerance allows.
SAFETY = 0.9
#: The ratios of consecutive steps are powers of 2^(1/LEVELS).
LEVELS = 8


def curvature_weight(k: float, tau: float) -> float:
    """c(k) = int_0^k exp(-s/tau) s (k - s)/2 ds (module description); k^3/12 for tau = inf.

    Parameters
    ----------
    k : float
        The step, > 0.
    tau : float
        The relaxation time, > 0 or inf.

    Returns
    -------
    float
        tau^3/2 (x - 2 + (x + 2) e^(-x)), x = k/tau, by its series below x = 0.01 (where the
        closed form cancels).
    """
    if not np.isfinite(tau):
        return k ** 3 / 12.0
    x = k / tau
    if x < 1e-2:
        # x^3/6 - x^4/12 + x^5/40 - x^6/180: the terms of (x + 2) e^-x that cancel removed
        value = x ** 3 / 6.0 - x ** 4 / 12.0 + x ** 5 / 40.0 - x ** 6 / 180.0
    else:
        value = x - 2.0 + (x + 2.0) * np.exp(-x)
    return 0.5 * tau ** 3 * float(value)


def second_difference(e0: np.ndarray, e1: np.ndarray, e2: np.ndarray, k1: float,
                      k2: float) -> np.ndarray:
    """eps'' from three strains at t_{n-1}, t_n = t_{n-1} + k1, t_{n+1} = t_n + k2.

    Parameters
    ----------
    e0, e1, e2 : numpy.ndarray
        The strains (the same shape).
    k1, k2 : float
        The two steps, > 0.

    Returns
    -------
    numpy.ndarray
        2 ((e2 - e1)/k2 - (e1 - e0)/k1) / (k1 + k2), exact for a quadratic in time.
    """
    return 2.0 * ((e2 - e1) / k2 - (e1 - e0) / k1) / (k1 + k2)


def next_step(k: float, error: float | None, tolerance: float, least: float,
              largest: float) -> float:
    """The step after one of size k whose relative error estimate is `error`.

    Parameters
    ----------
    k : float
        The step just taken.
    error : float or None
        Its estimate (None: none yet, the step is kept).
    tolerance : float
        time.tolerance.
    least, largest : float
        time.min_step, time.max_step.

    Returns
    -------
    float
        k f, f = min(GROW, max(SHRINK, SAFETY (tolerance/error)^(1/3))) rounded down to a
        power of 2^(1/LEVELS), within [least, largest].
    """
    if error is None:
        factor = 1.0
    elif error <= 0.0:
        factor = GROW
    else:
        factor = min(GROW, max(SHRINK, SAFETY * (tolerance / error) ** (1.0 / 3.0)))
        # a power of 2^(1/LEVELS), rounded down: estimates that differ by round-off (another
        # rank count, a restart's first Newton iterate) choose the same step
        factor = 2.0 ** (math.floor(LEVELS * math.log2(factor) + 1e-6) / LEVELS)
    return min(largest, max(least, k * factor))
