"""Benchmark: the paper scene at 32, 64 and 128 cells per side (run by hand: make benchmark).

For each mesh: Newton iterations per step, wall time per step and per Newton iteration, and
the cost of one linear-elastic assembly + MUMPS solve on the same mesh (the floor a Newton
iteration cannot go below). Writes benchmarks/results/paper_scaling.{json,md}.

    python benchmarks/performance/paper_scaling.py [--sizes 32 64 128] [--repeat 3]
"""
import argparse
import json
import pathlib
import statistics
import sys
import time

import numpy as np
import ufl
from dolfinx import fem
from mpi4py import MPI
from petsc4py import PETSc

from contactvisco.fem import compat, geometry
from contactvisco.scene import loader as scene_module
from contactvisco.model.material import elasticity, lame_constants, strain

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1]))  # benchmarks/: common.py
from common import assemble_linear, timed_run, write_results  # noqa: E402
from helpers import mumps_lu  # noqa: E402

def linear_elastic_solve(scene, repeat):
    """Seconds for one assembly (matrix + vector) and one MUMPS factorization + solve of the
    memoryless, contactless elasticity problem on the scene's mesh (best of `repeat`)."""
    geo = geometry.build(scene, MPI.COMM_WORLD)
    mesh = geo.mesh
    V = compat.vector_space(mesh, "CG", 1)
    u, v = ufl.TrialFunction(V), ufl.TestFunction(V)
    lmbda, mu = lame_constants(scene["material"]["model"], scene["material"]["E"],
                               scene["material"]["nu"])
    a = fem.form(ufl.inner(elasticity(strain(u), lmbda, mu), strain(v)) * ufl.dx)
    f = fem.Constant(mesh, PETSc.ScalarType((0.0, -10.0)))
    L = fem.form(ufl.dot(f, v) * ufl.dx)
    dofs = fem.locate_dofs_topological(V, 1, geo.facets("left"))
    bcs = [fem.dirichletbc(np.zeros(2, dtype=PETSc.ScalarType), dofs, V)]
    times = []
    for _ in range(repeat):
        tick = time.perf_counter()
        A, b = assemble_linear(a, L, bcs)
        ksp = mumps_lu(A, mesh.comm)
        x = b.duplicate()
        ksp.solve(b, x)
        times.append(time.perf_counter() - tick)
        ksp.destroy()
        A.destroy()
    return min(times)


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--sizes", type=int, nargs="+", default=[32, 64, 128])
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    comm = MPI.COMM_WORLD
    rows = []
    for n in args.sizes:
        row = measure(n, args.repeat, comm)
        rows.append(row)
        if comm.rank == 0:
            print(json.dumps(row), flush=True)
    if comm.rank == 0:
        write(rows, comm.size)


def measure(n, repeat, comm):
    """The row of n x n cells: the fastest of `repeat` runs of the paper scene (MUMPS), its
    Newton iterations and times, and the linear-elastic floor on the same mesh."""
    # MUMPS throughout: the same linear solver as the elastic reference (and as before).
    scene = scene_module.load("paper", [f"geometry.cells=[{n}, {n}]",
                                        "solver.linear_solver='direct'"])
    scene["output"]["probes"] = []
    total, result = timed_run(scene, comm, repeat)
    steps = result.steps
    iterations = [s["newton_iterations"] for s in steps]
    step_time = [s["wall_s"] for s in steps]
    per_iteration = sum(step_time) / sum(iterations)
    linear = linear_elastic_solve(scene, repeat)
    return {"cells_per_side": n, "ranks": comm.size,
            # unknowns of the Newton linear system (u alone when condensed)
            "unknowns": (result.problem.count_unknowns()["u"]
                         if result.linear_system != "coupled"
                         else sum(result.problem.count_unknowns().values())),
            "linear_system": result.linear_system, "linear_solver": result.linear_solver,
            "newton_per_step": iterations,
            "mean_newton": statistics.mean(iterations),
            "wall_per_step_s": statistics.mean(step_time),
            "wall_per_newton_s": per_iteration,
            "linear_elastic_solve_s": linear,
            "newton_over_linear": per_iteration / linear,
            "run_s": total,
            "final_status": steps[-1]["status_counts"]}


def write(rows, ranks):
    """results/paper_scaling_np<ranks>.json and .md (rank 0)."""
    name = f"paper_scaling_np{ranks}"
    lines = ["| cells/side | system, solver | unknowns | Newton per step (t_0..t_10) | s/step | "
             "s/Newton it. | s/linear solve (MUMPS) | ratio | run s | final status "
             "(sep/compl/bound) |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        st = r["final_status"]
        lines.append(f"| {r['cells_per_side']} | {r['linear_system']}, {r['linear_solver']} | "
                     f"{r['unknowns']} | "
                     f"{' '.join(map(str, r['newton_per_step']))} | "
                     f"{r['wall_per_step_s']:.3f} | {r['wall_per_newton_s']:.4f} | "
                     f"{r['linear_elastic_solve_s']:.4f} | {r['newton_over_linear']:.2f} | "
                     f"{r['run_s']:.2f} | {st['separated']}/{st['compliance']}/{st['bound']} |")
    write_results(name, rows, lines)


if __name__ == "__main__":
    main()
