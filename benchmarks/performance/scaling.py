"""Benchmark: cost against size, solver and rank count (run by hand: make benchmark-scaling).

Each configuration (scene, mesh size, linear solver, ranks) runs in its own `mpirun` process so
that the peak memory (max RSS) of every rank belongs to it alone. A run takes the first steps
of the scene with its own step size (time.T shortened), no output files, and records per step
Newton iterations, Krylov iterations per Newton iteration, wall time, and the time of one
linear-elastic assembly + solve on the same mesh with the same linear solver (the floor a
Newton iteration cannot go below). Writes benchmarks/results/scaling.{json,md}.

    python benchmarks/performance/scaling.py [--quick] [--only paper|block3d]
    python benchmarks/performance/scaling.py --one paper 128 direct   # one configuration
                                                          # (under mpirun)
"""
import argparse
import json
import pathlib
import resource
import subprocess
import sys
import time

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1]))  # benchmarks/: common.py
from common import RESULTS, assemble_linear, write_markdown  # noqa: E402
from helpers import mpi_env  # noqa: E402


PYTHON = sys.executable

#: (scene, size) -> --set overrides. paper: cells per side; another scene (block3d, ironing,
#: creep): its mesh size geometry.parameters.h. time.T = 0.1 steps (a later override of
#: time.T keeps another scene's own step size).
def overrides(scene, size, steps):
    if scene == "paper":
        return [f"geometry.cells=[{size}, {size}]", f"time.T={0.1 * steps}",
                f"time.steps={steps}"]
    return [f"geometry.parameters.h={size}", f"time.T={0.1 * steps}", f"time.steps={steps}"]


def elastic_floor(problem, scene, solver, comm):
    """(seconds, Krylov iterations) of one linear-elastic assembly + solve on the problem's
    mesh with the same linear solver: elasticity with the scene's Dirichlet conditions and
    Gamma_C clamped, the faster of two runs (the floor a Newton iteration cannot go below)."""
    import numpy as np
    import ufl
    from dolfinx import fem
    from petsc4py import PETSc

    from contactvisco.solver import newton as solver_module
    from contactvisco.model.material import elasticity, strain

    V = problem.V
    mesh = V.mesh
    d = mesh.geometry.dim
    u, v = ufl.TrialFunction(V), ufl.TestFunction(V)
    lmbda, mu = problem.constants["lame_lambda"], problem.constants["lame_mu"]
    a = fem.form(ufl.inner(elasticity(strain(u), lmbda, mu), strain(v)) * ufl.dx)
    f = fem.Constant(mesh, PETSc.ScalarType((0.0,) * (d - 1) + (-1.0,)))
    L = fem.form(ufl.dot(f, v) * ufl.dx)
    names = scene["contact"]["boundary"]
    names = [names] if isinstance(names, str) else names
    facets = np.concatenate([problem.geometry.facets(n) for n in names])
    dofs = fem.locate_dofs_topological(V, d - 1, np.unique(facets))
    bcs = [fem.dirichletbc(np.zeros(d, dtype=PETSc.ScalarType), dofs, V)] + problem.bcs_u
    options = dict(solver_module.DEFAULT_OPTIONS)
    if solver == "iterative":
        options.update(solver_module.iterative_options())
    opts = PETSc.Options()
    linear = []
    for _ in range(2):
        comm.Barrier()
        tick = time.perf_counter()
        A, b = assemble_linear(a, L, bcs)
        A.setNearNullSpace(solver_module.rigid_body_modes(V))
        ksp = PETSc.KSP().create(comm)
        ksp.setOptionsPrefix("elastic_")
        for key, value in options.items():
            if key.startswith(("ksp_", "pc_", "mg_")):
                opts[f"elastic_{key}"] = value
        ksp.setOperators(A)
        ksp.setFromOptions()
        x = b.duplicate()
        ksp.solve(b, x)
        linear.append((time.perf_counter() - tick, ksp.getIterationNumber()))
        ksp.destroy()
        A.destroy()
    return min(linear)


def one(scene_name, size, solver, steps):
    """Run one configuration in this (MPI) process and print a JSON line on rank 0."""
    from mpi4py import MPI

    from contactvisco.scene import loader as scene_module
    from contactvisco.solver.time_loop import simulate

    comm = MPI.COMM_WORLD
    scene = scene_module.load(scene_name, overrides(scene_name, size, steps)
                              + [f"solver.linear_solver='{solver}'"])
    scene["output"]["probes"] = []
    tick = time.perf_counter()
    result = simulate(scene, comm=comm, progress=False)
    run_s = time.perf_counter() - tick
    problem = result.problem
    steps_ = result.steps[1:]          # t_0 (elastic, no memory) is reported apart
    newton = [s["newton_iterations"] for s in result.steps]
    krylov = [k for s in result.steps for k in s["krylov_iterations"]]

    linear_s, linear_its = elastic_floor(problem, scene, solver, comm)
    peak = comm.gather(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0, root=0)
    wall = sum(s["wall_s"] for s in steps_)
    its = sum(s["newton_iterations"] for s in steps_)
    row = {"scene": scene_name, "size": size, "solver": solver, "ranks": comm.size,
           "unknowns_u": problem.count_unknowns()["u"],
           "contact_nodes": comm.allreduce(int(problem.contact.nodes.owned.sum())),
           "system": result.linear_system, "ksp_pc": result.linear_solver,
           "newton_per_step": newton,
           "krylov_per_newton_max": max(krylov) if krylov else 0,
           "krylov_per_newton_mean": (sum(krylov) / len(krylov)) if krylov else 0,
           "s_per_step": wall / max(1, len(steps_)),
           "s_per_newton": wall / max(1, its),
           "elastic_solve_s": linear_s, "elastic_krylov": linear_its,
           "run_s": run_s, "peak_mb_per_rank": peak}
    if comm.rank == 0:
        row["newton_over_elastic"] = row["s_per_newton"] / linear_s
        print("ROW " + json.dumps(row), flush=True)


CONFIGS = {
    # paper: cells per side; block3d: gmsh mesh size h
    "paper": [32, 64, 128, 256, 512],
    "block3d": [0.125, 0.0625, 0.04, 0.025, 0.016, 0.013],
}
#: MUMPS is not run above these sizes (3D fill-in: minutes and many GB per factorization).
DIRECT_LIMIT = {"paper": 256, "block3d": 0.04}


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--one", nargs=3, metavar=("SCENE", "SIZE", "SOLVER"))
    parser.add_argument("--steps", type=int, default=3)
    parser.add_argument("--only", choices=list(CONFIGS))
    parser.add_argument("--ranks", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--solvers", nargs="+", default=["direct", "iterative"])
    parser.add_argument("--max-unknowns", type=float, default=6e5,
                        help="skip direct solves above this many unknowns (time)")
    parser.add_argument("--quick", action="store_true", help="the two smallest sizes")
    parser.add_argument("--out", default="scaling")
    parser.add_argument("--sizes", type=float, nargs="+",
                        help="only these sizes (paper: cells per side; block3d: h)")
    args = parser.parse_args()
    if args.one:
        scene, size, solver = args.one
        one(scene, float(size) if scene == "block3d" else int(size), solver, args.steps)
        return
    from contactvisco.io import launcher
    env = mpi_env(oversubscribe=False)
    rows = []
    path = RESULTS / f"{args.out}.json"
    if path.exists():
        rows = json.loads(path.read_text())
    for scene, sizes in CONFIGS.items():
        if args.only and scene != args.only:
            continue
        if args.sizes:
            sizes = [s for s in sizes if s in args.sizes]
        for size in sizes[:2] if args.quick else sizes:
            for solver in args.solvers:
                for ranks in args.ranks:
                    done = [r for r in rows if (r["scene"], r["size"], r["solver"], r["ranks"])
                            == (scene, size, solver, ranks)]
                    too_big = size > DIRECT_LIMIT[scene] if scene == "paper" else \
                        size < DIRECT_LIMIT[scene]
                    if done or (solver == "direct" and too_big):
                        continue
                    command = [*launcher.mpi_launcher(), "-n", str(ranks), PYTHON, __file__,
                               "--one", scene, str(size), solver, "--steps", str(args.steps)]
                    print("running", scene, size, solver, ranks, flush=True)
                    proc = subprocess.run(command, env=env, capture_output=True, text=True)
                    lines = [l for l in proc.stdout.splitlines() if l.startswith("ROW ")]
                    if proc.returncode or not lines:
                        print(proc.stdout[-2000:], proc.stderr[-3000:], flush=True)
                        rows.append({"scene": scene, "size": size, "solver": solver,
                                     "ranks": ranks, "failed": proc.stderr[-500:]})
                    else:
                        rows.append(json.loads(lines[0][4:]))
                        print(lines[0][4:], flush=True)
                    RESULTS.mkdir(exist_ok=True)
                    path.write_text(json.dumps(rows, indent=1))
    write_table(rows, args.out)


def write_table(rows, name):
    lines = ["| scene | size | unknowns (u) | solver | ranks | Newton per step | Krylov per Newton "
             "(mean/max) | s/step | s/Newton | s/elastic solve | Newton/elastic | peak MB/rank | "
             "2-rank speedup |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        if "failed" in r:
            lines.append(f"| {r['scene']} | {r['size']} | | {r['solver']} | {r['ranks']} | "
                         f"failed | | | | | | | |")
            continue
        serial = [q for q in rows if "failed" not in q and q["ranks"] == 1 and
                  (q["scene"], q["size"], q["solver"]) == (r["scene"], r["size"], r["solver"])]
        speedup = (f"{serial[0]['s_per_step'] / r['s_per_step']:.2f}"
                   if r["ranks"] > 1 and serial else "")
        krylov = (f"{r['krylov_per_newton_mean']:.1f}/{r['krylov_per_newton_max']}"
                  if r["solver"] == "iterative" else "-")
        lines.append(
            f"| {r['scene']} | {r['size']} | {r['unknowns_u']} | {r['solver']} | {r['ranks']} | "
            f"{' '.join(map(str, r['newton_per_step']))} | {krylov} | {r['s_per_step']:.3f} | "
            f"{r['s_per_newton']:.4f} | {r['elastic_solve_s']:.4f} | "
            f"{r['newton_over_elastic']:.2f} | {max(r['peak_mb_per_rank']):.0f} | {speedup} |")
    write_markdown(name, lines)


if __name__ == "__main__":
    main()
