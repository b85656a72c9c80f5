"""The memory kernel R of a scene, as the history integral needs it: Prony terms, a table, or
a power law, and R(0), the instantaneous stiffness that the memory adds."""
from __future__ import annotations

import math


def as_list(x) -> list:
    """A scalar or a list as a list (the kernel's alpha and tau take either)."""
    return list(x) if isinstance(x, (list, tuple)) else [x]


def memory_terms(scene: dict) -> list[tuple[float, float, str]]:
    """A Prony kernel as terms [(alpha_i, tau_i, part_i)], tau = inf for the constant kernel;
    empty without memory and for a table kernel (see :func:`memory_table`)."""
    mem = scene["memory"]
    if mem["kernel"] == "constant":
        alpha = float(mem["alpha"])
        return [(alpha, math.inf, "full")] if alpha != 0.0 else []
    if mem["kernel"] == "exponential":
        return [(float(a), float(t), "full")
                for a, t in zip(as_list(mem["alpha"]), as_list(mem["tau"])) if a != 0]
    if mem["kernel"] == "prony":
        return [(float(t["alpha"]), float(t.get("tau", math.inf)), t.get("part", "full"))
                for t in mem["terms"] if t["alpha"] != 0]
    return []


def memory_table(scene: dict):
    """(times, values) of a table kernel, else None."""
    mem = scene["memory"]
    if mem["kernel"] == "table" and any(v != 0 for v in mem["values"]):
        return list(map(float, mem["times"])), list(map(float, mem["values"]))
    return None


def memory_power(scene: dict) -> dict | None:
    """The memory table of a power or fractional kernel with alpha != 0, else None."""
    mem = scene["memory"]
    if mem["kernel"] in ("power", "fractional") and mem["alpha"] != 0:
        return mem
    return None


def memory_R0(scene: dict) -> dict[str, float]:
    """R(0) per part: the instantaneous stiffness the memory adds (for the fractional kernel,
    infinite, the mean (1/k) int_0^k R of the grid's largest step k instead)."""
    power = memory_power(scene)
    if power is not None:
        alpha = float(power["alpha"])
        if power["kernel"] == "fractional":
            from contactvisco.model import time_grid
            k = float(time_grid.steps(scene["time"]).max())
            alpha *= k ** -power["beta"] / math.gamma(2.0 - power["beta"])
        return {power["part"]: alpha}
    table = memory_table(scene)
    if table is not None:
        return {"full": table[1][0]}
    out: dict[str, float] = {}
    for a, _, part in memory_terms(scene):
        out[part] = out.get(part, 0.0) + a
    return out
