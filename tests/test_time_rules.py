"""Time discretization of the memory term against a closed form, and its stability.

A block in uniaxial strain (rollers on the sides, u_y = 0 at the bottom) under a constant
pressure q has e = eps_yy(t) with M e(t) + int_0^t R(t - s) e(s) ds = -q, M = lambda + 2 mu:
    R = alpha:                  e(t) = -(q/M) exp(-alpha t / M)
    R = alpha exp(-t/tau):      e(t) = -(q/M) (1/(tau beta) + (1 - 1/(tau beta)) exp(-beta t)),
                                beta = 1/tau + alpha/M.
The space discretization is exact for this state, so the error at T is the time error.
Differencing eq (19) shows the paper's rule is forward Euler for one step, then two-step
Adams-Bashforth: second order and stable for b = k R(0) / m < 1. The trapezoid rule is
Crank-Nicolson: second order and stable for every k.
"""
import math

import numpy as np
import pytest
from mpi4py import MPI

from contactvisco import scene as scene_module
from contactvisco.material import lame_constants
from contactvisco.memory import History, direct_sum, prony
from contactvisco.run import simulate

E, NU, Q = 100.0, 0.3, 10.0
LMBDA, MU = lame_constants("plane_strain", E, NU)
M = LMBDA + 2 * MU
KERNELS = {"constant": {"kernel": "constant", "alpha": 100.0},
           "exponential": {"kernel": "exponential", "alpha": [300.0], "tau": [0.2]}}


def exact(kernel, t):
    if kernel == "constant":
        return -(Q / M) * math.exp(-100.0 * t / M)
    alpha, tau = 300.0, 0.2
    beta = 1 / tau + alpha / M
    return -(Q / M) * (1 / (tau * beta) + (1 - 1 / (tau * beta)) * math.exp(-beta * t))


def top_displacement(kernel, rule, T, steps):
    raw = {"name": "uniaxial",
           "geometry": {"lower": [0.0, 0.0], "upper": [1.0, 1.0], "cells": [1, 1]},
           "material": {"model": "plane_strain", "E": E, "nu": NU},
           "memory": KERNELS[kernel],
           "dirichlet": [{"boundary": "bottom", "components": [1]},
                         {"boundary": "left", "components": [0]},
                         {"boundary": "right", "components": [0]}],
           "traction": [{"boundary": "top", "value": [0.0, -Q]}],
           "time": {"T": T, "steps": steps, "rule": rule},
           "output": {"probes": [[0.5, 1.0]]}}
    result = simulate(scene_module.resolve(raw), comm=MPI.COMM_WORLD, progress=False)
    return np.array([s["probes"][0]["u"][1] for s in result.steps])   # u_y(top) = e(t)


@pytest.mark.parametrize("kernel", KERNELS)
@pytest.mark.parametrize("rule", ["paper", "trapezoid"])
def test_second_order_in_time(kernel, rule):
    steps = [10, 20, 40, 80]
    errors = [abs(top_displacement(kernel, rule, 1.0, n)[-1] - exact(kernel, 1.0))
              for n in steps]
    orders = [math.log2(a / b) for a, b in zip(errors, errors[1:])]
    assert abs(orders[-1] - 2.0) < 0.2, (errors, orders)
    assert errors[-1] < 1e-3 * abs(exact(kernel, 1.0))


def test_trapezoid_is_more_accurate_for_a_fast_kernel():
    """Same order, but a 4x smaller error constant for the exponential kernel (measured 3.9)."""
    paper = abs(top_displacement("exponential", "paper", 1.0, 40)[-1] - exact("exponential", 1.0))
    trap = abs(top_displacement("exponential", "trapezoid", 1.0, 40)[-1]
               - exact("exponential", 1.0))
    assert trap < paper / 3


def test_stability_limit():
    """b = k alpha / (2 mu) = 2.6: the paper's rule blows up (the scalar analysis predicts a
    root of modulus > 1 once b > 1), the trapezoid rule decays like the exact solution."""
    T, steps = 30.0, 15
    paper = top_displacement("constant", "paper", T, steps)
    trap = top_displacement("constant", "trapezoid", T, steps)
    assert abs(paper[-1]) > 100 * abs(paper[0])                       # grows
    # decays at every step (it may stall once |F| is below the absolute Newton tolerance)
    assert np.all(np.abs(trap[1:]) <= np.abs(trap[:-1]))
    assert abs(trap[-1]) < 1e-3 * abs(trap[0])
    # below the limit (b = 0.65) the paper's rule is stable and decays too
    stable = top_displacement("constant", "paper", T, 120)
    assert abs(stable[-1]) < 1e-3 * abs(stable[0])


@pytest.mark.parametrize("terms", [[(100.0, math.inf, "full")],
                                   [(30.0, 0.05, "deviatoric"), (5.0, 2.0, "full")]])
def test_trapezoid_history_equals_direct_sum(terms):
    k = 0.05
    rng = np.random.default_rng(3)
    strains = [rng.standard_normal(9) for _ in range(30)]
    history = History(terms, k, "trapezoid", d=3)
    for n in range(1, len(strains) + 1):
        incremental = history.advance(strains[n - 1])
        exact_sum = direct_sum(prony(terms, 3), k, strains[:n], "trapezoid")
        assert np.max(np.abs(incremental - exact_sum)) <= 1e-12 * np.max(np.abs(exact_sum))
