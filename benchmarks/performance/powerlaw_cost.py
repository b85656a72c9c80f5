"""Cost per step of the power-law memory kernels: sum of exponentials against the direct sum.

The paper scene on a tiny mesh with k = 0.01 and the power kernel R = 100 (1 + t/0.1)^-0.5 or
the fractional kernel R = 100 t^-0.5 / Gamma(1/2) (trapezoid rule, memory.tolerance = 1e-6):
- memory.summation = 'soe': 10^4 steps (T = 100);
- memory.summation = 'direct' (exact kernel, O(n) per step): 2000 steps (T = 20), stopped
  there because its cost grows with n.
Per step: the wall time of the whole step (Newton included) and of the history update alone
(TimeState.record + TimeState.prepare, measured by wrapping them); the median over windows of 10
steps ending at step 10, 100, 1000, 2000 and 10^4. Memory held: the bytes of the history's
arrays (History.state()) at the end of the run, per rank.

Also, without a mesh: the number of exponentials of the fit and its measured relative error
against T/k and the tolerance (the count grows like log(T/k)).

    python benchmarks/performance/powerlaw_cost.py [--cells 8]
"""
import argparse
import json
import math
import pathlib
import statistics
import sys
import time

from mpi4py import MPI

from contactvisco.model import kernels
from contactvisco.scene import loader as scene_module
from contactvisco.solver.time_loop import simulate

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1]))  # benchmarks/: common.py
from common import HistoryClock, write_results  # noqa: E402

K = 0.01
KERNELS = {"power": ["memory.kernel='power'", "memory.alpha=100.0", "memory.tau=0.1",
                     "memory.beta=0.5"],
           "fractional": ["memory.kernel='fractional'", "memory.alpha=100.0",
                          "memory.beta=0.5"]}
RUNS = {"soe": 10000, "direct": 2000}
WINDOWS = (10, 100, 1000, 2000, 10000)


def window(values, end):
    """Median of steps end-9 .. end (values[0] is step 1)."""
    return statistics.median(values[end - 10:end]) if len(values) >= end else None


def one_run(kernel, summation, cells, clock):
    N = RUNS[summation]
    scene = scene_module.load("paper", [f"geometry.cells=[{cells}, {cells}]",
                                        "output.probes=[]", "output.figure_times=[]",
                                        "time.rule='trapezoid'", f"time.T={N * K}",
                                        f"time.steps={N}", f"memory.summation='{summation}'",
                                        "memory.tolerance=1e-6"] + KERNELS[kernel])
    clock.reset()
    tick = time.perf_counter()
    result = simulate(scene, comm=MPI.COMM_WORLD, progress=False)
    total = time.perf_counter() - tick
    steps = [s["wall_s"] for s in result.steps[1:]]
    history = clock.per_step()
    memory = result.problem.memory
    held = sum(a.nbytes for a in memory.history.state().values())
    fit = getattr(memory.history, "fit", None)
    return {"kernel": kernel, "summation": summation, "steps": N, "T": N * K, "run_s": total,
            "terms": len(fit) if fit else None, "fit_error": fit.error if fit else None,
            "history_bytes": held, "strain_bytes": memory.eps_function.x.array.nbytes,
            "step_ms": {str(w): (window(steps, w) or math.nan) * 1e3 for w in WINDOWS},
            "history_ms": {str(w): (window(history, w) or math.nan) * 1e3 for w in WINDOWS},
            "newton": sum(s["newton_iterations"] for s in result.steps[1:]),
            "final_status": result.steps[-1]["status_counts"]}


def term_counts():
    rows = []
    for beta in (0.3, 0.5, 0.8):
        for tol in (1e-4, 1e-6, 1e-8):
            counts, errors = [], []
            for decades in (2, 4, 6, 8):
                fit = kernels.soe_power(beta, 1.0, 10.0**decades, tol)
                counts.append(len(fit))
                errors.append(fit.error)
            rows.append({"beta": beta, "tol": tol, "terms": counts, "errors": errors})
    return rows


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--cells", type=int, default=8)
    args = parser.parse_args()
    comm = MPI.COMM_WORLD
    clock = HistoryClock()
    simulate(scene_module.load("paper", [f"geometry.cells=[{args.cells}, {args.cells}]",
                                         "time.steps=2"]), comm=comm, progress=False)
    rows = []
    for kernel in KERNELS:
        for summation in RUNS:
            row = one_run(kernel, summation, args.cells, clock)
            rows.append(row)
            if comm.rank == 0:
                print(json.dumps(row), flush=True)
    counts = term_counts()
    if comm.rank == 0:
        write(rows, counts, args.cells, comm.size)


def write(rows, counts, cells, ranks):
    name = f"powerlaw_cost_np{ranks}"
    head = " / ".join(f"step {w}" for w in WINDOWS)
    lines = [
        f"Paper scene, {cells} x {cells} cells, {ranks} rank(s), k = {K}, trapezoid rule, "
        "memory.tolerance = 1e-6; power: R = 100 (1 + t/0.1)^-0.5, fractional: "
        "R = 100 t^-0.5 / Gamma(1/2). The sum of exponentials (soe) runs 10^4 steps; the "
        "direct sum is stopped at 2000 steps. Times are medians over the 10 steps ending at "
        "the step named (ms); memory is the history's arrays at the end, per rank.",
        "",
        f"| kernel | summation | exponentials (fit error) | history ms per step at: {head} | "
        "memory held |",
        "|---|---|---|---|---|",
    ]
    for r in rows:
        fit = f"{r['terms']} ({r['fit_error']:.1e})" if r["terms"] else "exact kernel"
        times = " / ".join("-" if math.isnan(v) else f"{v:.3f}" for v in r["history_ms"].values())
        lines.append(f"| {r['kernel']} | {r['summation']} | {fit} | {times} | "
                     f"{r['history_bytes'] / 1e6:.2f} MB after {r['steps']} steps "
                     f"({r['history_bytes'] / r['strain_bytes']:.0f} strain arrays' worth) |")
    lines += ["", f"Whole step (Newton included), ms at: {head}. These include the solve and "
              "vary with the load of the machine (shared with other jobs while measured); the "
              "history columns above are the part the memory adds.", "",
              "| kernel | summation | ms per step | Newton iterations | run s | final "
              "sep/compl/bound |", "|---|---|---|---|---|---|"]
    for r in rows:
        times = " / ".join("-" if math.isnan(v) else f"{v:.2f}" for v in r["step_ms"].values())
        lines.append(f"| {r['kernel']} | {r['summation']} | {times} | {r['newton']} | "
                     f"{r['run_s']:.1f} | "
                     + "/".join(str(v) for v in r["final_status"].values()) + " |")
    lines += ["", "Number of exponentials (measured relative error) of u^-beta on [1, T/k], "
              "T/k = 10^2, 10^4, 10^6, 10^8:", "",
              "| beta | tolerance | terms | measured error |", "|---|---|---|---|"]
    for c in counts:
        lines.append(f"| {c['beta']} | {c['tol']:g} | {' / '.join(map(str, c['terms']))} | "
                     f"{max(c['errors']):.1e} |")
    write_results(name, {"runs": rows, "terms": counts}, lines)


if __name__ == "__main__":
    main()
