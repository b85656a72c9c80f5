"""The linear solves of the paper scene's Newton steps, solver by solver: for the direct
solvers (MUMPS with its orderings, PETSc's own LU with its orderings, SuperLU, SuperLU_dist,
UMFPACK where PETSc has them) the time per symbolic analysis, per numeric factorization and per
triangular solve (PETSc's log events MatLUFactorSym, MatLUFactorNum, MatSolve), the counts of
each (one analysis per run means PETSc kept the symbolic factorization of the unchanged
sparsity pattern), and the steps' Newton time; for the iterative solver (GMRES + BoomerAMG, or
GAMG where PETSc has no hypre) the Krylov iterations per Newton iteration and the Newton time
under a choice of BoomerAMG options.

Every configuration must give the reference's (the first configuration's) Newton iterations
and contact states, and its contact values (u_nu, p_nu, lambda_nu and the reactions at every
contact node and every step, and the final u) within --tolerance relative to the largest value.
The configurations of one size run in turn, --rounds times (the best Newton time is kept), so
that they see the same machine load; the load average is recorded before and after.

    python benchmarks/performance/linear_solvers.py [--sizes 32 64 128] [--rounds 2]
        [--part direct|iterative] [--steps N] [--tag NAME]

The table is results/linear_solvers_<part>_<stack>_np<ranks>[_<tag>].md.
"""
import argparse
import os
import pathlib
import sys
import time

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from contactvisco.scene import loader as scene_module
from contactvisco.solver.time_loop import simulate

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1]))  # benchmarks/: common.py
from common import write  # noqa: E402

#: Direct solvers: name -> (PETSc options, the external package PETSc needs or None).
DIRECT = {
    "MUMPS (default)": ({}, "mumps"),
    "MUMPS, AMD (icntl_7 0)": ({"mat_mumps_icntl_7": 0}, "mumps"),
    "MUMPS, AMF (icntl_7 2)": ({"mat_mumps_icntl_7": 2}, "mumps"),
    "MUMPS, PORD (icntl_7 4)": ({"mat_mumps_icntl_7": 4}, "mumps"),
    "MUMPS, METIS (icntl_7 5)": ({"mat_mumps_icntl_7": 5}, "mumps"),
    "MUMPS, QAMD (icntl_7 6)": ({"mat_mumps_icntl_7": 6}, "mumps"),
    "PETSc LU, nd": ({"pc_factor_mat_solver_type": "petsc",
                      "pc_factor_mat_ordering_type": "nd"}, None),
    "PETSc LU, rcm": ({"pc_factor_mat_solver_type": "petsc",
                       "pc_factor_mat_ordering_type": "rcm"}, None),
    "PETSc LU, qmd": ({"pc_factor_mat_solver_type": "petsc",
                       "pc_factor_mat_ordering_type": "qmd"}, None),
    "SuperLU": ({"pc_factor_mat_solver_type": "superlu"}, "superlu"),
    "SuperLU_dist": ({"pc_factor_mat_solver_type": "superlu_dist"}, "superlu_dist"),
    "UMFPACK": ({"pc_factor_mat_solver_type": "umfpack"}, "suitesparse"),
}

_AMG = "pc_hypre_boomeramg_"
#: BoomerAMG variants (over the defaults of contactvisco.solver.newton.ITERATIVE_OPTIONS).
ITERATIVE = {
    "BoomerAMG (default: HMIS, ext+i, theta 0.7, Chebyshev)": {},
    "hybrid symmetric Gauss-Seidel (PETSc's default smoother)": {
        _AMG + "relax_type_down": "symmetric-SOR/Jacobi",
        _AMG + "relax_type_up": "symmetric-SOR/Jacobi"},
    "hybrid Gauss-Seidel, forward down, backward up": {
        _AMG + "relax_type_down": "SOR/Jacobi", _AMG + "relax_type_up": "backward-SOR/Jacobi"},
    "l1 Gauss-Seidel, forward down, backward up": {
        _AMG + "relax_type_down": "l1-Gauss-Seidel",
        _AMG + "relax_type_up": "backward-l1-Gauss-Seidel"},
    "l1-scaled Jacobi": {_AMG + "relax_type_down": "l1scaled-Jacobi",
                         _AMG + "relax_type_up": "l1scaled-Jacobi"},
    "theta 0.5": {_AMG + "strong_threshold": 0.5},
    "theta 0.6": {_AMG + "strong_threshold": 0.6},
    "nodal coarsening 6": {_AMG + "nodal_coarsen": 6},
    "nodal coarsening 6 + vec_interp 2": {_AMG + "nodal_coarsen": 6,
                                          _AMG + "vec_interp_variant": 2},
    "nodal coarsening 4 + vec_interp 3": {_AMG + "nodal_coarsen": 4,
                                          _AMG + "vec_interp_variant": 3},
    "no aggressive level (agg_nl 0)": {_AMG + "agg_nl": 0},
}

#: Where PETSc has no hypre: GAMG's threshold.
ITERATIVE_GAMG = {
    "GAMG (default: threshold 0.02)": {},
    "GAMG threshold 0.01": {"pc_gamg_threshold": 0.01},
    "GAMG threshold 0.05": {"pc_gamg_threshold": 0.05},
}

EVENTS = ("MatLUFactorSym", "MatLUFactorNum", "MatSolve", "PCSetUp", "PCApply")


def events():
    """PETSc's log (count, seconds) of EVENTS on this rank so far."""
    out = {}
    for name in EVENTS:
        info = PETSc.Log.Event(name).getPerfInfo()
        out[name] = (info["count"], info["time"])
    return out


def values(result, comm):
    """The run's contact values at every step (every rank has the whole table) and its final
    u on this rank."""
    fields = ("u_nu", "p_nu", "lambda_nu", "reaction_nu", "reaction_tau")
    parts = [np.asarray(table[name], dtype=float) for table in result.tables
             for name in fields if name in table]
    statuses = [np.asarray(table["status"]) for table in result.tables]
    return np.concatenate(parts), statuses, result.u.x.array.copy()


def run(n, options, linear_solver, steps, comm):
    overrides = [f"geometry.cells=[{n}, {n}]", f"solver.linear_solver='{linear_solver}'"]
    if steps:
        overrides.append(f"time.steps={steps}")
        overrides.append(f"time.T={steps / 10}")
    if options:
        inner = ", ".join(f"{k}={v!r}" if isinstance(v, str) else f"{k}={v}"
                          for k, v in options.items())
        overrides.append("solver.petsc_options={" + inner.replace("'", '"') + "}")
    scene = scene_module.load("paper", overrides)
    before = events()
    tick = time.perf_counter()
    result = simulate(scene, comm=comm, progress=False, keep_tables=True)
    seconds = time.perf_counter() - tick
    after = events()
    log = {name: (after[name][0] - before[name][0], after[name][1] - before[name][1])
           for name in EVENTS}
    record = result.steps[1:]                 # the steps after t_0
    krylov = [k for s in record for k in s["krylov_iterations"]]
    return dict(run_s=seconds, newton_s=sum(s["wall_s"] for s in record),
                iterations=[s["newton_iterations"] for s in result.steps],
                setups=sum(s["preconditioner_setups"] for s in result.steps),
                krylov=krylov, log=log, linear_solver=result.linear_solver,
                values=values(result, comm))


def deviation(a, b, comm):
    """max |a - b| / max |a| over every rank: the contact values (whole tables, sorted by
    position), and the final u where both runs partitioned the mesh alike (on more than one
    rank the partition may differ between runs)."""
    worst = 0.0
    pairs = [(a[0], b[0])]
    if comm.allreduce(a[2].shape == b[2].shape, op=MPI.LAND):
        pairs.append((a[2], b[2]))
    for x, y in pairs:
        scale = comm.allreduce(float(np.max(np.abs(x), initial=0.0)), op=MPI.MAX)
        diff = comm.allreduce(float(np.max(np.abs(x - y), initial=0.0)), op=MPI.MAX)
        worst = max(worst, diff / max(scale, 1e-300))
    return worst


def available(package):
    if package is None:
        return True
    try:
        return bool(PETSc.Sys.hasExternalPackage(package))
    except Exception:           # noqa: BLE001 - older petsc4py: try the run instead
        return True


def load_average():
    try:
        return " ".join(f"{x:.2f}" for x in os.getloadavg())
    except OSError:
        return "?"


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--sizes", type=int, nargs="+", default=[32, 64, 128])
    parser.add_argument("--rounds", type=int, default=2)
    parser.add_argument("--part", choices=("direct", "iterative"), default="direct")
    parser.add_argument("--steps", type=int, default=0, help="steps after t_0 (0: the scene's)")
    parser.add_argument("--only", nargs="*", default=None, help="configuration names")
    parser.add_argument("--tolerance", type=float, default=1e-10)
    parser.add_argument("--tag", default="")
    args = parser.parse_args()
    comm = MPI.COMM_WORLD
    PETSc.Log.begin()
    stack = "pip" if PETSc.Sys.getVersion() >= (3, 20, 0) else "debian"
    has_hypre = bool(PETSc.Sys.hasExternalPackage("hypre"))
    if args.part == "direct":
        configs = {name: opts for name, (opts, package) in DIRECT.items() if available(package)}
        linear_solver = "direct"
    else:
        configs = ITERATIVE if has_hypre else ITERATIVE_GAMG
        linear_solver = "iterative"
    if args.only:
        exact = set(args.only) & set(configs)       # a whole name selects itself alone
        configs = {name: opts for name, opts in configs.items() if name in exact or any(
            word in name for word in set(args.only) - exact)}
    rows = []
    for n in args.sizes:
        load_before = load_average()
        run(n, {}, linear_solver, args.steps, comm)          # compiles the forms
        best, failed = {}, {}
        for _ in range(args.rounds):
            for name, opts in configs.items():
                if name in failed:
                    continue
                try:
                    out = run(n, opts, linear_solver, args.steps, comm)
                except Exception as err:   # noqa: BLE001 - a package PETSc lacks: noted
                    failed[name] = f"{type(err).__name__}: {str(err).splitlines()[0][:80]}"
                    continue
                if name not in best or out["newton_s"] < best[name]["newton_s"]:
                    best[name] = out
        load_after = load_average()
        reference = next(iter(best.values()))
        for name in configs:
            if name in failed:
                rows.append(dict(cells=n, ranks=comm.size, config=name, failed=failed[name]))
                continue
            out = best[name]
            dev = deviation(reference["values"], out["values"], comm)
            same_states = all(np.array_equal(a, b) for a, b in
                              zip(reference["values"][1], out["values"][1]))
            log = out["log"]

            def per(event):
                count, seconds = log[event]
                return (1e3 * seconds / count if count else float("nan")), count
            krylov = out["krylov"]
            rows.append(dict(
                cells=n, ranks=comm.size, config=name, load=f"{load_before} / {load_after}",
                linear_solver=out["linear_solver"], newton_s=out["newton_s"],
                run_s=out["run_s"], iterations=out["iterations"], setups=out["setups"],
                analysis_ms=per("MatLUFactorSym")[0], analyses=per("MatLUFactorSym")[1],
                factor_ms=per("MatLUFactorNum")[0], factors=per("MatLUFactorNum")[1],
                solve_ms=per("MatSolve")[0], solves=per("MatSolve")[1],
                pcsetup_ms=per("PCSetUp")[0], pcsetups=per("PCSetUp")[1], pcapply_ms=per("PCApply")[0],
                krylov_mean=float(np.mean(krylov)) if krylov else float("nan"),
                krylov_max=max(krylov) if krylov else 0,
                deviation=dev, same_iterations=out["iterations"] == reference["iterations"],
                same_states=same_states,
                ratio=out["newton_s"] / reference["newton_s"]))
            if comm.rank == 0:
                print(rows[-1]["config"], f"{out['newton_s']:.2f}", f"{dev:.1e}", flush=True)
    if comm.rank == 0:
        name = f"linear_solvers_{args.part}_{stack}_np{comm.size}" + (
            f"_{args.tag}" if args.tag else "")
        if args.part == "direct":
            header = ("| cells | configuration | Newton s (/ default) | analyses: count, ms each | "
                      "factorizations: count, ms each | PC set-up ms each | solves: count, ms each | "
                      "Newton iterations per step | same iterations and states | "
                      "deviation | load before / after |")
            line = _direct_line
        else:
            header = ("| cells | ranks | configuration | Newton s (/ default) | Krylov per Newton, "
                      "mean / max | PC set-up ms | PC apply ms | Newton iterations per step | "
                      "same iterations and states | deviation | load before / after |")
            line = _iterative_line
        write(name, rows, header, line)


def _direct_line(r):
    if "failed" in r:
        return f"| {r['cells']} | {r['config']} | not run: {r['failed']} |" + " |" * 8
    return (f"| {r['cells']} | {r['config']} | {r['newton_s']:.2f} ({r['ratio']:.2f}) | "
            f"{r['analyses']}, {r['analysis_ms']:.1f} | {r['factors']}, {r['factor_ms']:.1f} | "
            f"{r['pcsetup_ms']:.1f} | "
            f"{r['solves']}, {r['solve_ms']:.2f} | " + " ".join(map(str, r["iterations"]))
            + f" | {'yes' if r['same_iterations'] and r['same_states'] else 'NO'} | "
            f"{r['deviation']:.1e} | {r['load']} |")


def _iterative_line(r):
    if "failed" in r:
        return f"| {r['cells']} | {r['ranks']} | {r['config']} | not run: {r['failed']} |" + \
            " |" * 7
    return (f"| {r['cells']} | {r['ranks']} | {r['config']} | {r['newton_s']:.2f} "
            f"({r['ratio']:.2f}) | {r['krylov_mean']:.1f} / {r['krylov_max']} | "
            f"{r['pcsetup_ms']:.0f} | {r['pcapply_ms']:.2f} | "
            + " ".join(map(str, r["iterations"]))
            + f" | {'yes' if r['same_iterations'] and r['same_states'] else 'NO'} | "
            f"{r['deviation']:.1e} | {r['load']} |")


if __name__ == "__main__":
    main()
