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
    u_{n+1} = (1 - 3b/2) u_n + b/2 u_{n-1}); 2 mu = E / (1 + nu) is the deviatoric modulus.
    With [[body]] tables, the largest b of the bodies (worst_body).

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


def _own_number(scene: dict) -> float:
    """b of one material and memory (the scene's [material] and [memory])."""
    R0 = sum(abs(a) for a in memory_R0(scene).values())
    if R0 == 0.0:
        return 0.0
    k = scene["time"]["T"] / scene["time"]["steps"]
    mat = scene["material"]
    return k * R0 * (1.0 + mat["nu"]) / mat["E"]


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
