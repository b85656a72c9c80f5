"""Cost per step of a 20-term Prony material ([viscoelastic], shear relaxation with 20 terms,
plane strain: 40 memory terms, deviatoric and volumetric) with and without a temperature field
varying in x and t (time-temperature superposition, WLF): the reduced-time recursion takes a
decay per point instead of one per term, and the temperature is interpolated at every step.

A box of cells x cells under a traction, no contact (one Newton iteration per step, so the
history is the largest share of a step: the least favourable case for the ratio); N = 50 and
200 steps over the same T. Per run: the loop's wall time per step (steps 1..N) and the time of
the history update per step (TimeState.prepare + record, plus the temperature's interpolation
in TimeState.move_to for the thermal run). The ratio thermal / isothermal should stay below
1.3 and the cost per step should not grow with N.

    python benchmarks/performance/prony_temperature_cost.py [--cells 64] [--repeat 2]
"""
import argparse
import pathlib
import statistics
import sys
import time

import numpy as np
from mpi4py import MPI

from contactvisco.scene import loader
from contactvisco.solver.time_loop import simulate

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1]))  # benchmarks/: common.py
from common import HistoryClock, write_results  # noqa: E402

TAUS = np.geomspace(0.05, 500.0, 20).tolist()
FRACTIONS = [0.045] * 20                       # sum 0.9
WLF = {"shift": "wlf", "T_ref": 50.0, "C1": 17.44, "C2": 51.6}
TEMPERATURE = "48.0 - 2.0 * x[0] + sin(t)"     # cooler than T_ref: reduced steps < k


def scene(cells: int, steps: int, thermal: bool) -> dict:
    visco = {"shear": {"instantaneous": 10.0, "tau": TAUS, "fractions": FRACTIONS},
             "bulk": {"instantaneous": 25.0}, **WLF}
    if thermal:
        visco["temperature"] = TEMPERATURE
    return loader.resolve({
        "name": "prony_cost", "material": {"model": "plane_strain"}, "viscoelastic": visco,
        "geometry": {"lower": [0.0, 0.0], "upper": [1.0, 1.0], "cells": [cells, cells]},
        "dirichlet": [{"boundary": "bottom"}],
        "traction": [{"boundary": "top", "value": [0.1, "-0.5 * (1 + t)"]}],
        "time": {"T": 10.0, "steps": steps, "rule": "trapezoid"},
        "output": {"xdmf": False, "figures": False, "checkpoint": False}})


def move_clock():
    """Wall time of every TimeState.move_to (the temperature's interpolation and a_T)."""
    from contactvisco.fem.problem import TimeState
    calls = []
    original = TimeState.move_to

    def timed(state, t):
        tick = time.perf_counter()
        original(state, t)
        calls.append(time.perf_counter() - tick)
    TimeState.move_to = timed
    return calls


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--cells", type=int, default=64)
    parser.add_argument("--repeat", type=int, default=2)
    args = parser.parse_args()
    clock, moves = HistoryClock(), move_clock()
    rows = []
    for steps in (50, 200):
        for thermal in (False, True):
            best = None
            for _ in range(args.repeat):
                clock.reset()
                moves.clear()
                result = simulate(scene(args.cells, steps, thermal), comm=MPI.COMM_WORLD,
                                  progress=False)
                loop = sum(s["wall_s"] for s in result.steps[1:]) / steps
                history = (sum(clock.per_step(steps)) + sum(moves[1:])) / steps
                if best is None or loop < best["loop_s_per_step"]:
                    best = {"steps": steps, "thermal": thermal, "loop_s_per_step": loop,
                            "history_s_per_step": history,
                            "newton": statistics.mean(s["newton_iterations"]
                                                      for s in result.steps[1:])}
            rows.append(best)
    lines = [f"Prony material with 20 shear terms (40 memory terms), {args.cells} x "
             f"{args.cells} box, plane strain, {MPI.COMM_WORLD.size} rank(s); best of "
             f"{args.repeat}", "",
             "| steps | temperature | loop s/step | history s/step | thermal / isothermal |",
             "|---|---|---|---|---|"]
    for row in rows:
        iso = next(r for r in rows if r["steps"] == row["steps"] and not r["thermal"])
        ratio = row["loop_s_per_step"] / iso["loop_s_per_step"]
        lines.append(f"| {row['steps']} | {TEMPERATURE if row['thermal'] else 'none'} | "
                     f"{row['loop_s_per_step']:.4f} | {row['history_s_per_step']:.4f} | "
                     f"{ratio:.2f} |")
    if MPI.COMM_WORLD.rank == 0:
        write_results("prony_temperature_cost", rows, lines)


if __name__ == "__main__":
    main()
