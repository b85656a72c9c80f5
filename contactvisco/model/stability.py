"""Stability of the paper's time rule, eq (19), on its scalar analogue (NOTES: b = k R(0) / 2mu).

The paper's rule puts the weight 3k/2 on u_{n-1}; its scalar analogue
u_{n+1} = (1 - 3b/2) u_n + b/2 u_{n-1} has a root of modulus > 1 once b > 1.
"""
from __future__ import annotations

import math

from contactvisco.model.memory_kernel import memory_R0


def amplifies(b: float, steps: int) -> bool:
    """Whether the paper's rule amplifies errors: its scalar analogue (see stability_number) is
    u_1 = (1 - b) u_0 (one forward Euler step), then u_{n+1} = (1 - 3b/2) u_n + b/2 u_{n-1}
    with a root of modulus > 1 once b > 1. A single step amplifies only from b = 2 on."""
    return b >= 1.0 and (steps >= 2 or b >= 2.0)


def steps_for_stability(steps: int, b: float) -> str:
    return f"{math.ceil(steps * b)}" if b < 1e15 else "(far more steps)"


def stability_number(scene: dict) -> float:
    """b = k |R(0)| / (2 mu): the paper's rule is stable for b < 1 (NOTES: the scalar analogue
    u_{n+1} = (1 - 3b/2) u_n + b/2 u_{n-1}); 2 mu = E / (1 + nu) is the deviatoric modulus."""
    R0 = sum(abs(a) for a in memory_R0(scene).values())
    if R0 == 0.0:
        return 0.0
    k = scene["time"]["T"] / scene["time"]["steps"]
    mat = scene["material"]
    return k * R0 * (1.0 + mat["nu"]) / mat["E"]
