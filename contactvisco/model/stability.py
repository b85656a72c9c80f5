"""Stability of the paper's time rule, eq (19), on its scalar analogue (NOTES: b = k R(0) / 2mu).

The paper's rule puts the weight 3k/2 on u_{n-1}; its scalar analogue
u_{n+1} = (1 - 3b/2) u_n + b/2 u_{n-1} has a root of modulus > 1 once b > 1.

On a variable grid, with b_n = k_n R(0) / 2mu per step, subtracting consecutive steps of
m u_n + alpha (trapezoid on [t_0, t_{n-1}] + k_n u_{n-1}) = f gives

    u_{n+1} = (1 - b_n/2 - b_{n+1}) u_n + b_n/2 u_{n-1},

whose characteristic polynomial (coefficients frozen at step n) has the root -1 exactly when
(b_n + b_{n+1})/2 = 1: the rule is stable step by step while the mean of two consecutive
numbers stays below 1 (b < 1 for uniform steps), and its first step (forward Euler,
u_1 = (1 - b_1) u_0) while b_1 < 2.
"""
from __future__ import annotations

import math

import numpy as np

from contactvisco.model import time_grid
from contactvisco.model.memory_kernel import memory_power, memory_R0


def amplifies(b: float, steps: int) -> bool:
    """Whether the paper's rule amplifies errors: its scalar analogue (see stability_number) is
    u_1 = (1 - b) u_0 (one forward Euler step), then u_{n+1} = (1 - 3b/2) u_n + b/2 u_{n-1}
    with a root of modulus > 1 once b > 1. A single step amplifies only from b = 2 on."""
    return b >= 1.0 and (steps >= 2 or b >= 2.0)


def steps_for_stability(steps: int, b: float) -> str:
    return f"{math.ceil(steps * b)}" if b < 1e15 else "(far more steps)"


def stability_number(scene: dict) -> float:
    """b = k |R(0)| / (2 mu): the paper's rule is stable for b < 1 (NOTES: the scalar analogue
    u_{n+1} = (1 - 3b/2) u_n + b/2 u_{n-1}); 2 mu = E / (1 + nu) is the deviatoric modulus.
    On a variable grid, the largest mean (b_n + b_{n+1})/2 of two consecutive steps
    (:func:`grid_number`). With [[body]] tables, the largest b of the bodies (worst_body).

    Parameters
    ----------
    scene : dict
        The scene: time.T, time.steps, [material] and [memory], or its [[body]] tables.

    Returns
    -------
    float
        b = k sum_parts |R_part(0)| (1 + nu) / E, the largest over the bodies; 0 without
        memory.
    """
    return worst_body(scene)[0]


def step_numbers(scene: dict) -> np.ndarray:
    """b_n = k_n |R(0)| (1 + nu) / E for each step k_n of the grid (one material and memory:
    the scene's [material] and [memory]); for the fractional kernel R(0) is the mean
    (1/k_n) int_0^{k_n} R of each step (memory_R0).

    Parameters
    ----------
    scene : dict
        The scene: its [time] grid, [material] and [memory].

    Returns
    -------
    numpy.ndarray
        b_1 .. b_N (zeros without memory).
    """
    k = time_grid.steps(scene["time"])
    power = memory_power(scene)
    if power is not None and power["kernel"] == "fractional":
        R0 = abs(float(power["alpha"])) * k ** -power["beta"] / math.gamma(2.0 - power["beta"])
    else:
        R0 = sum(abs(a) for a in memory_R0(scene).values())
    mat = scene["material"]
    return k * R0 * (1.0 + mat["nu"]) / mat["E"]


def grid_number(numbers: np.ndarray) -> float:
    """The number that bounds the paper's rule on a grid of step numbers b_n: the largest
    mean (b_n + b_{n+1})/2 of two consecutive steps (the frozen-coefficient root -1 of the
    module description), b_1 alone for a single step; b for uniform steps.

    Parameters
    ----------
    numbers : numpy.ndarray
        b_1 .. b_N.

    Returns
    -------
    float
        The bound's number (stable below 1; a single step below 2, see :func:`amplifies`).
    """
    if len(numbers) == 1:
        return float(numbers[0])
    return float(np.max(0.5 * (numbers[:-1] + numbers[1:])))


def _own_number(scene: dict) -> float:
    """b of one material and memory (the scene's [material] and [memory])."""
    if not memory_R0(scene):
        return 0.0
    return grid_number(step_numbers(scene))


def worst_body(scene: dict) -> tuple[float, str | None]:
    """The body whose memory bounds the paper's step: every cell lies in one [[body]] with
    its own A (E, nu) and kernel R, so the rule is stable when each body's
    b_j = k |R_j(0)| (1 + nu_j) / E_j < 1.

    Parameters
    ----------
    scene : dict
        The scene; its ``body`` list (each with a full [material] and [memory]) or none.

    Returns
    -------
    tuple of (float, str or None)
        max_j b_j and the name of that body (the first of equal ones); (b, None) for a scene
        without [[body]] tables (its own [material] and [memory]).
    """
    bodies = scene.get("body") or []
    if not bodies:
        return _own_number(scene), None
    numbers = [(_own_number({**scene, "material": body["material"],
                             "memory": body["memory"]}), body["name"]) for body in bodies]
    return max(numbers, key=lambda item: item[0])
