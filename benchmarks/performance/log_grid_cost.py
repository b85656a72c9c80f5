"""Cost per step on a logarithmic grid against a uniform one, with and without keeping the
factorization across a change of step size (contactvisco.solver.newton.enable_nearby:
FGMRES with the factors of the last factorized matrix while it converges within
NEARBY_KRYLOV iterations). Uniaxial creep of a block at 48 x 48 cells (plane strain, 4802
displacement unknowns, shear relaxing with six terms tau = 1e-2 .. 1e3 s, exponential rule,
MUMPS) under a constant pressure: 20 steps per decade from 1e-3 s to 1e4 s, and as many
uniform steps. Reports the loop's wall time per step (the sum of the records' wall_s over
the steps), the factorizations, the FGMRES iterations, and the largest difference of the
displacements from the run that factorizes every new matrix. A minute or two on one core.
Usage: .venv/bin/python benchmarks/performance/log_grid_cost.py
"""
import os
import pathlib
import sys

import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1]))  # benchmarks/
import common  # noqa: E402

from contactvisco.scene import loader  # noqa: E402
from contactvisco.solver import newton  # noqa: E402
from contactvisco.solver.time_loop import simulate  # noqa: E402

TAUS = [1e-2, 1e-1, 1.0, 10.0, 100.0, 1000.0]
CELLS = 48


def scene(grid):
    visco = {"shear": {"instantaneous": 10.0, "tau": TAUS, "fractions": [0.12] * 6},
             "bulk": {"instantaneous": 25.0}}
    return loader.resolve({
        "name": "log_grid_cost",
        "geometry": {"lower": [0.0, 0.0], "upper": [1.0, 1.0], "cells": [CELLS, CELLS]},
        "material": {"model": "plane_strain"}, "viscoelastic": visco,
        "dirichlet": [{"boundary": "bottom", "components": [1]},
                      {"boundary": "left", "components": [0]}],
        "traction": [{"boundary": "top", "value": [0.0, -0.1]}],
        "time": {"T": 1e4, "rule": "exponential", **grid},
        "solver": {"linear_solver": "direct"},
        "output": {"probes": [[1.0, 1.0], [0.5, 1.0]], "xdmf": False, "figures": False}})


def run(grid, nearby):
    newton.NEARBY = nearby
    result = simulate(scene(grid), progress=False)
    steps = result.steps[1:]
    u = np.array([[p["u"] for p in s["probes"]] for s in result.steps])
    return {"steps": len(steps), "ms_per_step": 1e3 * sum(s["wall_s"] for s in steps)
            / len(steps), "factorizations": sum(s["preconditioner_setups"] for s in steps),
            "fgmres": sum(sum(s["krylov_iterations"]) for s in steps
                          if s["preconditioner_setups"] == 0), "u": u}


def main():
    log = {"grid": "logarithmic", "first": 1e-3, "per_decade": 20}
    load = os.getloadavg()[0]
    rows = []
    reference = {}
    for repeat in range(2):
        for nearby in (False, True):
            for name, grid in (("logarithmic", log), ("uniform", None)):
                if grid is None:
                    grid = {"steps": rows[0]["steps"]} if rows else {"steps": 140}
                r = run(grid, nearby)
                key = name
                if not nearby:
                    reference[key] = r["u"]
                diff = float(np.abs(r["u"] - reference[key]).max()
                             / np.abs(reference[key]).max())
                rows.append({"grid": name, "keep factors": nearby, "repeat": repeat,
                             "steps": r["steps"], "ms_per_step": r["ms_per_step"],
                             "factorizations": r["factorizations"], "fgmres": r["fgmres"],
                             "difference": diff})
    end = os.getloadavg()[0]
    lines = [f"Load average {load:.2f} at start, {end:.2f} at end (2 cores, shared); "
             "the two repeats side by side.", "",
             "| grid | keep factors across k | repeat | steps | ms/step | factorizations | "
             "Krylov iterations of the steps without a factorization | max rel. difference of u |", "|---|---|---|---|---|---|---|---|"]
    lines += [f"| {r['grid']} | {r['keep factors']} | {r['repeat']} | {r['steps']} | "
              f"{r['ms_per_step']:.1f} | {r['factorizations']} | {r['fgmres']} | "
              f"{r['difference']:.1e} |" for r in rows]
    common.write_results("log_grid_cost", {"load": [load, end], "rows": rows}, lines)


if __name__ == "__main__":
    main()
