"""Cost of one evaluation of the displacement-only Newton system (residual + Jacobian).

The paper scene on a 128 x 128 mesh is run to t = 0.2 (2 steps: bound, compliance and
sticking nodes occur); at that state one NodalCondensation.residual followed by .jacobian is
timed REPEAT times (after one warm-up evaluation) and the median and quartiles are written,
with the Newton counts per step of the shipped paper scene (32 x 32, 10 steps).

    python benchmarks/condensation_cost.py [--label NAME] [--repeat N] [--cells N]
"""
import argparse
import statistics
import time

from mpi4py import MPI
from petsc4py import PETSc

from common import write_results

from contactvisco import compat
from contactvisco import scene as scene_module
from contactvisco.condensed import NodalCondensation
from contactvisco.run import simulate


def evaluation_times(cells: int, repeat: int, comm) -> list[float]:
    scene = scene_module.load("paper", [f"geometry.cells=[{cells}, {cells}]", "time.T=0.2",
                                        "time.steps=2"])
    scene["output"]["probes"] = []
    problem = simulate(scene, comm=comm, progress=False).problem
    system = NodalCondensation(problem)
    x = compat.petsc_vector(problem.u).copy()
    x.ghostUpdate(addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)
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


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--label", default="condensation_cost")
    parser.add_argument("--repeat", type=int, default=20)
    parser.add_argument("--cells", type=int, default=128)
    args = parser.parse_args()
    comm = MPI.COMM_WORLD
    times = evaluation_times(args.cells, args.repeat, comm)
    counts = newton_counts(comm)
    quartiles = statistics.quantiles(times, n=4)
    row = {"cells": args.cells, "ranks": comm.size, "repeat": args.repeat,
           "median_s": statistics.median(times), "q1_s": quartiles[0], "q3_s": quartiles[2],
           "newton_per_step": counts}
    if comm.rank == 0:
        write_results(args.label, [row], [
            "| cells | ranks | residual + Jacobian, median (s) | quartiles (s) | "
            "paper Newton counts |",
            "|---|---|---|---|---|",
            f"| {args.cells}^2 | {comm.size} | {row['median_s']:.4f} | "
            f"{row['q1_s']:.4f}-{row['q3_s']:.4f} | {' '.join(map(str, counts))} |"])


if __name__ == "__main__":
    main()
