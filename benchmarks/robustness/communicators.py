"""Builds (and optionally solves) one small problem again and again in one process and counts
how many times it goes before MPI runs out of communicators (MPICH gives a process 2048).
Each problem holds a few communicators (its mesh's and index maps'); once it is collected they
must be freed, so the count should reach the limit asked for.

    python benchmarks/robustness/communicators.py [problem|solve] [N]
    mpiexec -n 2 python benchmarks/robustness/communicators.py solve 1200
"""
import gc
import sys

from mpi4py import MPI

from contactvisco.scene import loader as scene_module
from contactvisco.solver import newton as solver_module
from contactvisco.fem.geometry import build as build_geometry
from contactvisco.fem.problem import build


def small() -> dict:
    """A 2 x 2 elastic square under traction, held on the left."""
    return scene_module.resolve({
        "name": "small", "geometry": {"cells": [2, 2]}, "material": {"E": 1.0, "nu": 0.3},
        "dirichlet": [{"boundary": "left", "components": "all"}],
        "traction": [{"boundary": "right", "value": [0.1, -0.1]}],
        "time": {"T": 1.0, "steps": 1}, "output": {"figures": False}})


def main(what: str = "problem", runs: int = 1200):
    comm = MPI.COMM_WORLD
    scene = small()
    for i in range(runs):
        problem = build(scene, build_geometry(scene, comm))
        if what == "solve":
            newton = solver_module.create(problem, comm)
            newton.solve()
            newton.destroy()
        del problem
        gc.collect()
        if comm.rank == 0 and (i + 1) % 10 == 0:
            print(f"{what}: {i + 1} builds", flush=True)
    if comm.rank == 0:
        print(f"{what}: all {runs} builds done", flush=True)


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "problem",
         int(sys.argv[2]) if len(sys.argv) > 2 else 1200)
