"""Time discretization of the memory term against a closed form, and its stability (the closed
form is in contactvisco.studies.verification). Differencing eq (19) shows the paper's rule is forward
Euler for one step, then two-step Adams-Bashforth: second order and stable for
b = k R(0) / m < 1. The trapezoid rule is Crank-Nicolson: second order and stable for every k.
"""
import math

import numpy as np
import pytest

from contactvisco.model.memory import History, direct_sum, prony
from contactvisco.studies.verification import UNIAXIAL_KERNELS as KERNELS
from contactvisco.studies.verification import manufactured, uniaxial
from contactvisco.studies.verification import uniaxial_exact as exact


def top_displacement(kernel, rule, T, steps):
    return uniaxial(kernel, rule, T, steps)


@pytest.mark.convergence
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
        exact_sum = direct_sum(prony(terms, 3), k, strains[:n], rule="trapezoid")
        assert np.max(np.abs(incremental - exact_sum)) <= 1e-12 * np.max(np.abs(exact_sum))


@pytest.mark.parametrize("rule", ["paper", "trapezoid"])
def test_static_solution_is_exact_in_time(rule):
    """u(x, t) = U(x) under sigma = (A + alpha t) eps(U): both rules are exact in time for it
    semi-discretely (the t_0 step has no history, and no implicit memory term either), so the
    error hardly depends on the number of steps. It differs by O(h^p) only, because each
    step's Galerkin projection is taken with another operator A + alpha t_n. Measured:
    1e-4 (paper) and 2e-3 (trapezoid) relative; with the implicit term wrongly present at t_0
    the 1-step error was 250 times the 5-step one."""
    one = manufactured(8, 2, rule=rule, steps=1)["L2"]
    many = manufactured(8, 2, rule=rule, steps=5)["L2"]
    assert abs(one - many) < 0.01 * many
