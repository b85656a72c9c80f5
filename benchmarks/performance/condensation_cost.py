"""Cost of one evaluation of the displacement-only Newton system (residual + Jacobian).

The paper scene on a 128 x 128 mesh is run to t = 0.2 (2 steps: bound, compliance and
sticking nodes occur); at that state one NodalCondensation.residual followed by .jacobian is
timed REPEAT times (after one warm-up evaluation) and the median and quartiles are written,
with the Newton counts per step of the shipped paper scene (32 x 32, 10 steps).

    python benchmarks/performance/condensation_cost.py [--label NAME] [--repeat N] [--cells N]
    python benchmarks/performance/condensation_cost.py --compare OTHER_CHECKOUT [--rounds R]

--compare times another checkout of the package (the folder holding its `contactvisco`)
against this one on 1 rank, in alternating fresh processes (R rounds each), so that a change in
the machine's load affects both alike; it writes results/condensation_cost_compare.md.
"""
import argparse
import json
import os
import pathlib
import statistics
import subprocess
import sys
import time

from mpi4py import MPI

from contactvisco.scene import loader as scene_module
from contactvisco.solver.time_loop import simulate

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1]))  # benchmarks/: common.py
from common import write_results  # noqa: E402
from helpers import ROOT, condensed_at  # noqa: E402


def evaluation_times(cells: int, repeat: int, comm) -> list[float]:
    scene = scene_module.load("paper", [f"geometry.cells=[{cells}, {cells}]", "time.T=0.2",
                                        "time.steps=2"])
    scene["output"]["probes"] = []
    problem = simulate(scene, comm=comm, progress=False).problem
    system, x = condensed_at(problem)
    b = x.duplicate()
    times = []
    for i in range(repeat + 1):
        comm.barrier()
        tick = time.perf_counter()
        system.residual(x, b)
        system.jacobian()
        seconds = comm.allreduce(time.perf_counter() - tick, MPI.MAX)
        if i > 0:
            times.append(seconds)
    return times


def newton_counts(comm) -> list[int]:
    scene = scene_module.load("paper")
    scene["output"]["probes"] = []
    return [s["newton_iterations"] for s in simulate(scene, comm=comm, progress=False).steps]


def measure(cells: int, repeat: int, comm) -> dict:
    times = evaluation_times(cells, repeat, comm)
    quartiles = statistics.quantiles(times, n=4)
    return {"cells": cells, "ranks": comm.size, "repeat": repeat,
            "median_s": statistics.median(times), "q1_s": quartiles[0], "q3_s": quartiles[2],
            "newton_per_step": newton_counts(comm)}


def compare(other: str, rounds: int, cells: int, repeat: int):
    """Alternating runs of `other`'s package (before) and this checkout's (after)."""
    here = str(ROOT)
    rows = {"before": [], "after": []}
    for _ in range(rounds):
        for label, path in (("before", other), ("after", here)):
            env = dict(os.environ, PYTHONPATH=path)
            proc = subprocess.run([sys.executable, __file__, "--json", "--cells", str(cells),
                                   "--repeat", str(repeat)], env=env, capture_output=True,
                                  text=True, check=True, timeout=600)
            rows[label].append(json.loads(proc.stdout.strip().splitlines()[-1]))
    lines = ["| code | medians per round (ms) | median of rounds (ms) | paper Newton counts |",
             "|---|---|---|---|"]
    for label, runs in rows.items():
        medians = [1e3 * r["median_s"] for r in runs]
        lines.append(f"| {label} | {' '.join(f'{m:.1f}' for m in medians)} | "
                     f"{statistics.median(medians):.1f} | "
                     f"{' '.join(map(str, runs[-1]['newton_per_step']))} |")
    load = os.getloadavg()
    lines.append(f"\nbefore: the package given with --compare; after: this checkout. "
                 f"{cells}^2 cells, 1 rank, {repeat} evaluations per round; load average "
                 f"after the runs {load[0]:.1f} (1 min), {load[1]:.1f} (5 min).")
    write_results("condensation_cost_compare", rows, lines)


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--label", default="condensation_cost")
    parser.add_argument("--repeat", type=int, default=20)
    parser.add_argument("--cells", type=int, default=128)
    parser.add_argument("--compare", default=None)
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    comm = MPI.COMM_WORLD
    if args.compare:
        compare(args.compare, args.rounds, args.cells, args.repeat)
        return
    row = measure(args.cells, args.repeat, comm)
    counts = row["newton_per_step"]
    if args.json:
        if comm.rank == 0:
            print(json.dumps(row))
    elif comm.rank == 0:
        write_results(args.label, [row], [
            "| cells | ranks | residual + Jacobian, median (s) | quartiles (s) | "
            "paper Newton counts |",
            "|---|---|---|---|---|",
            f"| {args.cells}^2 | {comm.size} | {row['median_s']:.4f} | "
            f"{row['q1_s']:.4f}-{row['q3_s']:.4f} | {' '.join(map(str, counts))} |"])


if __name__ == "__main__":
    main()
