"""Cost of a run against the number of time steps: the paper scene on a coarse mesh, same final
time T, with N = 100 and N = 1000 steps, for the constant and exponential kernels (the history
of eq (19) kept by the recursion of contactvisco/memory.py, O(1) work per step) and, for
contrast, a table kernel (eq (19) summed directly, O(n) work at step n).

Per run: the wall time of the time loop (steps 1..N, the elastic solve at t_0 left out), the
Newton iterations, and the time spent in the history update (TimeState.record: eps of
the converged u into the history; TimeState.prepare: the history stress H of the next step),
measured per step by wrapping those two methods.

With O(1) history work the loop time grows like N (ratio 1000/100 near 10) and the history
time per step is the same at step 10 and at step 1000. With the direct sum the history time
at step n grows like n, and its total like N^2 (ratio near 100).

    python benchmarks/performance/time_linearity.py [--cells 16] [--repeat 2]
"""
import argparse
import math
import pathlib
import statistics
import sys
import time

from mpi4py import MPI

from contactvisco.scene import loader as scene_module
from contactvisco.solver.time_loop import simulate

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1]))  # benchmarks/: common.py
from common import HistoryClock, write_results  # noqa: E402

STEPS = (100, 1000)
ALPHA, TAU = 100.0, 0.2
# The exponential kernel r(t) = ALPHA exp(-t/TAU) sampled on [0, T]: the table kernel solves
# nearly the same problem, only its history is summed directly.
TABLE_TIMES = [round(0.025 * i, 6) for i in range(41)]
TABLE_VALUES = [round(ALPHA * math.exp(-t / TAU), 9) for t in TABLE_TIMES]
KERNELS = {
    "constant": ("R = 100 I (the paper's)", ["memory.kernel='constant'", f"memory.alpha={ALPHA}"]),
    "exponential": (f"R = 100 exp(-t/{TAU}) I",
                    ["memory.kernel='exponential'", f"memory.alpha=[{ALPHA}]",
                     f"memory.tau=[{TAU}]"]),
    "table": (f"the same exponential as a table of {len(TABLE_TIMES)} points",
              ["memory.kernel='table'", f"memory.times={TABLE_TIMES}",
               f"memory.values={TABLE_VALUES}"]),
}


def one_run(scene, clock):
    clock.reset()
    tick = time.perf_counter()
    result = simulate(scene, out=None, comm=MPI.COMM_WORLD, progress=False)
    total = time.perf_counter() - tick
    N = scene["time"]["steps"]
    steps = result.steps[1:]
    history = clock.per_step(N)
    tenth = max(1, N // 10)
    return {"run_s": total,
            "loop_s": sum(s["wall_s"] for s in steps),
            "newton": sum(s["newton_iterations"] for s in steps),
            "history_s": sum(history),
            "history_first_tenth_s": statistics.median(history[:tenth]),
            "history_last_tenth_s": statistics.median(history[-tenth:]),
            "history_by_tenth_s": [statistics.mean(history[i * tenth:(i + 1) * tenth])
                                   for i in range(N // tenth)],
            "final_status": result.steps[-1]["status_counts"]}


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--cells", type=int, default=16)
    parser.add_argument("--repeat", type=int, default=2, help="best of this many runs")
    args = parser.parse_args()
    comm = MPI.COMM_WORLD
    clock = HistoryClock()
    base = [f"geometry.cells=[{args.cells}, {args.cells}]", "output.probes=[]",
            "output.figure_times=[]"]
    # Compile the forms and load the solver libraries before anything is timed.
    simulate(scene_module.load("paper", base + ["time.steps=2"]), comm=comm, progress=False)

    rows = []
    for kernel, (description, overrides) in KERNELS.items():
        runs = {}
        for N in STEPS:
            scene = scene_module.load("paper", base + overrides + [f"time.steps={N}"])
            best = min((one_run(scene, clock) for _ in range(args.repeat)),
                       key=lambda r: r["loop_s"])
            best["s_per_step"] = best["loop_s"] / N
            best["history_s_per_step"] = best["history_s"] / N
            runs[N] = best
            if comm.rank == 0:
                print(f"{kernel:12s} N = {N:5d}: loop {best['loop_s']:.3f} s, history "
                      f"{best['history_s']:.3f} s, Newton {best['newton']}", flush=True)
        small, large = runs[STEPS[0]], runs[STEPS[1]]
        rows.append({
            "kernel": kernel, "description": description, "cells": args.cells,
            "T": scene["time"]["T"], "steps": list(STEPS), "ranks": comm.size,
            "runs": {str(N): r for N, r in runs.items()},
            "loop_ratio": large["loop_s"] / small["loop_s"],
            "newton_ratio": large["newton"] / small["newton"],
            "history_ratio": large["history_s"] / small["history_s"],
            "history_last_over_first": (large["history_last_tenth_s"]
                                        / large["history_first_tenth_s"]),
        })
    if comm.rank == 0:
        write(rows, args.cells, comm.size)


def write(rows, cells, ranks):
    name = "time_linearity"
    n0, n1 = STEPS
    ms = 1e3
    lines = [
        f"Paper scene, {cells} x {cells} cells, T = 1, N = {n0} and {n1} steps, paper's rule, "
        f"{ranks} rank(s), no output files. Loop: steps 1..N (the elastic solve at t_0 left "
        "out). History: TimeState.record + TimeState.prepare. Times are the best of the repeats.",
        "",
        "Machine-independent ratios (O(1) history work per step: loop and history near "
        f"{n1 // n0}, last/first near 1; O(n): history near {(n1 // n0) ** 2}, last/first "
        "growing with N):",
        "",
        f"| kernel | loop time {n1}/{n0} | Newton its {n1}/{n0} | history time {n1}/{n0} | "
        f"history per step, last/first tenth of N = {n1} |",
        "|---|---|---|---|---|",
    ]
    lines += [f"| {r['kernel']} | {r['loop_ratio']:.2f} | {r['newton_ratio']:.2f} | "
              f"{r['history_ratio']:.2f} | {r['history_last_over_first']:.2f} |" for r in rows]
    lines += [
        "",
        "Raw times:",
        "",
        "| kernel | N | Newton its | loop s | ms/step | history s | history ms/step | "
        "history ms/step, median of first / last tenth | final sep/compl/bound |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        for N in STEPS:
            x = r["runs"][str(N)]
            lines.append(
                f"| {r['kernel']} | {N} | {x['newton']} | {x['loop_s']:.3f} | "
                f"{x['s_per_step'] * ms:.3f} | {x['history_s']:.4f} | "
                f"{x['history_s_per_step'] * ms:.4f} | "
                f"{x['history_first_tenth_s'] * ms:.4f} / {x['history_last_tenth_s'] * ms:.4f} | "
                + "/".join(str(v) for v in x["final_status"].values()) + " |")
    lines += ["", "Kernels: " + "; ".join(f"{r['kernel']}: {r['description']}" for r in rows)
              + "."]
    write_results(name, rows, lines)


if __name__ == "__main__":
    main()
