"""The adaptive time grid (time.grid = "adaptive") against fixed logarithmic grids on the
homogeneous block under a smooth ramp-and-hold strain 1 - exp(-t/0.3) over T = 1e4 s (plane
strain, shear relaxing with six terms tau = 1e-2 .. 1e3 s, the closed form of the generalized
Maxwell law: contactvisco.studies.relaxation), exponential rule: for each tolerance the
adaptive grid's steps and stress error (largest over the steps, relative to the largest
closed-form stress) and wall time, beside the logarithmic grids of first step 0.3/m and m
steps per decade; "fixed steps" is the fewest steps of that family reaching the adaptive
error (log-log interpolation between the two grids around it). About a minute on one core.
Usage: .venv/bin/python benchmarks/accuracy/adaptive_grid.py
"""
import math
import os
import pathlib
import sys
import time

import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1]))  # benchmarks/
import common  # noqa: E402

from contactvisco.model import viscoelastic as ve  # noqa: E402
from contactvisco.studies import relaxation as rl  # noqa: E402

STRAIN = [[0.01, 0.004], [0.004, -0.002]]
TAUS = [1e-2, 1e-1, 1.0, 10.0, 100.0, 1000.0]
HOLD, T = 0.3, 1e4
TOLERANCES = [1e-2, 1e-3, 1e-4, 1e-5]
PER_DECADE = [5, 10, 20, 40, 80, 160]


def run(grid):
    """(steps, error, wall seconds) of the block on the grid of [time] keys `grid`."""
    fractions = [0.12] * len(TAUS)
    visco = {"shear": {"instantaneous": 10.0, "tau": TAUS, "fractions": fractions},
             "bulk": {"instantaneous": 25.0}}
    G = ve.series(instantaneous=10.0, taus=TAUS, fractions=fractions)
    K = ve.series(instantaneous=25.0)
    raw = rl.block_scene(visco, "plane_strain", STRAIN, "smooth", T, 1, rule="exponential",
                         hold=HOLD, grid=grid)
    tick = time.perf_counter()
    t, sigma = rl.block_stress(raw)
    wall = time.perf_counter() - tick
    exact = rl.maxwell_stress("plane_strain", G, K, STRAIN, "smooth", t, hold=HOLD)
    return len(t) - 1, float(np.abs(sigma - exact).max() / np.abs(exact).max()), wall


def fewest_fixed(fixed, error):
    """The steps of the logarithmic family at `error` (log-log interpolation); None outside."""
    for (n0, e0), (n1, e1) in zip(fixed, fixed[1:]):
        if e1 <= error <= e0:
            s = math.log(error / e0) / math.log(e1 / e0)
            return math.exp(math.log(n0) + s * (math.log(n1) - math.log(n0)))
    return None


def main():
    load = os.getloadavg()[0]
    fixed_rows = []
    for m in PER_DECADE:
        steps, error, wall = run({"grid": "logarithmic", "first": HOLD / m, "per_decade": m})
        fixed_rows.append({"grid": f"logarithmic m = {m}", "steps": steps, "error": error,
                           "wall_s": wall})
    fixed = [(r["steps"], r["error"]) for r in fixed_rows]
    rows = []
    for tol in TOLERANCES:
        steps, error, wall = run({"grid": "adaptive", "first": HOLD / 20, "tolerance": tol})
        best = fewest_fixed(fixed, error)
        rows.append({"tolerance": tol, "steps": steps, "error": error, "wall_s": wall,
                     "fixed_steps": best, "ratio": best and steps / best})
    lines = [f"Load average at start: {load:.2f} (2 cores, shared).", "",
             "| tolerance | steps | error | time (s) | fixed log steps at that error | "
             "ratio |", "|---|---|---|---|---|---|"]
    for r in rows:
        best = "outside" if r["fixed_steps"] is None else f"{r['fixed_steps']:.0f}"
        ratio = "-" if r["ratio"] is None else f"{r['ratio']:.2f}"
        lines.append(f"| {r['tolerance']:.0e} | {r['steps']} | {r['error']:.2e} | "
                     f"{r['wall_s']:.2f} | {best} | {ratio} |")
    lines += ["", "| fixed grid | steps | error | time (s) |", "|---|---|---|---|"]
    lines += [f"| {r['grid']} | {r['steps']} | {r['error']:.2e} | {r['wall_s']:.2f} |"
              for r in fixed_rows]
    common.write_results("adaptive_grid", {"load": load, "adaptive": rows,
                                           "fixed": fixed_rows}, lines)


if __name__ == "__main__":
    main()
