"""Benchmark: GAMG settings for the iterative solver where PETSc has no hypre (run by hand).

Runs the paper scene (first steps, no output files) with MUMPS and with GMRES + GAMG under
several option sets, each configuration in its own process, and records per configuration the
Newton iterations per step, the Krylov iterations per Newton iteration (mean/max), the contact
status counts of the last step (to compare with MUMPS's), s/Newton and the block size of the
condensed matrix (GAMG's near-nullspace needs block size d). Wall times are per Newton
iteration of the steps after t_0; the CPU time of the whole run per Newton iteration is also
kept, as it depends less on other jobs on a shared machine. Writes
benchmarks/results/<out>.{json,md}.

    python benchmarks/performance/gamg.py --sizes 64 128 256 \
        --variants direct default current sor ...
    python benchmarks/performance/gamg.py --one sor 128     # one configuration, in this process
    python benchmarks/performance/gamg.py --scene block3d --sizes 0.04 0.025 \
        --variants direct current

--scene block3d runs the 3D block instead; its sizes are gmsh mesh sizes h (box3d).
"""
import argparse
import json
import pathlib
import subprocess
import sys
import time

from contactvisco.solver.newton import GAMG_OPTIONS

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1]))  # benchmarks/: common.py
from common import write_results  # noqa: E402

#: The GAMG options the variants change: the former solver.GAMG_OPTIONS (threshold 0.01, the
#: interpolation reused, PETSc's default).
BASE = {key: value for key, value in GAMG_OPTIONS.items()
        if key != "pc_gamg_reuse_interpolation"}
BASE["pc_gamg_threshold"] = 0.01

#: Option sets tried: changes to BASE (None removes a key). "direct" is MUMPS; "current" is
#: solver.GAMG_OPTIONS as it is now.
VARIANTS = {
    "direct": None,
    "current": {},
    "default": {},
    "thr0": {"pc_gamg_threshold": 0.0},
    "thr0.02": {"pc_gamg_threshold": 0.02},
    "thr0.05": {"pc_gamg_threshold": 0.05},
    "thr-1": {"pc_gamg_threshold": -1.0},
    "agg0": {"pc_gamg_aggressive_coarsening": 0},
    "nsm0": {"pc_gamg_agg_nsmooths": 0},
    "cheb3": {"mg_levels_ksp_max_it": 3},
    "cheb4": {"mg_levels_ksp_max_it": 4},
    "esteig": {"mg_levels_esteig_ksp_max_it": 20},
    "sor": {"mg_levels_pc_type": "sor"},
    "sor_rich": {"mg_levels_ksp_type": "richardson", "mg_levels_pc_type": "sor"},
    "sor3": {"mg_levels_pc_type": "sor", "mg_levels_ksp_max_it": 3},
    "sor_agg0": {"mg_levels_pc_type": "sor", "pc_gamg_aggressive_coarsening": 0},
    "sor_thr0.02": {"mg_levels_pc_type": "sor", "pc_gamg_threshold": 0.02},
    "sor_thr0.05": {"mg_levels_pc_type": "sor", "pc_gamg_threshold": 0.05},
    "thr0.02_agg0": {"pc_gamg_threshold": 0.02, "pc_gamg_aggressive_coarsening": 0},
    "thr0.02_cheb3": {"pc_gamg_threshold": 0.02, "mg_levels_ksp_max_it": 3},
    "noreuse": {"pc_gamg_reuse_interpolation": False},
    "misk": {"pc_gamg_aggressive_square_graph": False},
    "cel200": {"pc_gamg_coarse_eq_limit": 200},
}
#: The same changes on top of a prolongation rebuilt for every Jacobian.
VARIANTS.update({f"noreuse_{name}": {"pc_gamg_reuse_interpolation": False, **changes}
                 for name, changes in list(VARIANTS.items())
                 if changes and "pc_gamg_reuse_interpolation" not in changes})


def options(variant):
    from contactvisco.solver import newton as solver_module
    if variant == "current":
        return dict(solver_module.GAMG_OPTIONS)
    chosen = dict(BASE)
    for key, value in VARIANTS[variant].items():
        if value is None:
            chosen.pop(key, None)
        else:
            chosen[key] = value
    return chosen


def overrides(scene, size, steps):
    """--set overrides: paper: size cells per side; block3d: gmsh mesh size h."""
    mesh = ([f"geometry.cells=[{size}, {size}]"] if scene == "paper"
            else [f"geometry.parameters.h={size}"])
    return mesh + [f"time.T={0.1 * steps}", f"time.steps={steps}"]


def one(variant, size, steps, scene_name="paper"):
    """Run one configuration in this process and print a JSON line."""
    from contactvisco.fem import compat
    from contactvisco.scene import loader as scene_module
    from contactvisco.solver import newton as solver_module
    from contactvisco.solver.time_loop import simulate
    from mpi4py import MPI

    comm = MPI.COMM_WORLD
    direct = VARIANTS[variant] is None
    if not direct:                      # GAMG even where PETSc has hypre
        chosen = options(variant)
        solver_module.iterative_options = lambda: chosen
    block = []
    init = solver_module.CondensedSNES.__init__

    def record_block_size(self, *args, **kwargs):
        init(self, *args, **kwargs)
        block.append(self.system.J_red.getBlockSize())
    solver_module.CondensedSNES.__init__ = record_block_size
    scene = scene_module.load(scene_name, overrides(scene_name, size, steps) + [
        f"solver.linear_solver='{'direct' if direct else 'iterative'}'"])
    scene["output"]["probes"] = []
    tick, cpu = time.perf_counter(), time.process_time()
    result = simulate(scene, comm=comm, progress=False)
    run_s, cpu_s = time.perf_counter() - tick, time.process_time() - cpu
    steps_ = result.steps[1:]           # t_0 (elastic) apart, as in scaling.py
    krylov = [k for s in result.steps for k in s["krylov_iterations"]]
    wall = sum(s["wall_s"] for s in steps_)
    its = sum(s["newton_iterations"] for s in steps_)
    row = {"variant": variant, "scene": scene_name, "size": size, "ranks": comm.size,
           "unknowns_u": result.problem.count_unknowns()["u"],
           "hypre": compat.has_hypre(), "ksp_pc": result.linear_solver,
           "block_size": block[0] if block else None,
           "options": {} if direct else VARIANTS[variant],
           "newton_per_step": [s["newton_iterations"] for s in result.steps],
           "krylov_per_newton_mean": sum(krylov) / len(krylov) if krylov else 0,
           "krylov_per_newton_max": max(krylov) if krylov else 0,
           "krylov": [s["krylov_iterations"] for s in result.steps],
           "status_counts": result.steps[-1]["status_counts"],
           "s_per_newton": wall / max(1, its), "s_per_step": wall / max(1, len(steps_)),
           "run_s": run_s,
           # CPU time of the whole run (set-up and t_0 included) per Newton iteration: less
           # sensitive than wall time to other jobs on a shared machine
           "cpu_s_per_newton": cpu_s / sum(s["newton_iterations"] for s in result.steps)}
    if comm.rank == 0:
        print("ROW " + json.dumps(row), flush=True)


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--one", nargs=2, metavar=("VARIANT", "SIZE"))
    parser.add_argument("--steps", type=int, default=3)
    parser.add_argument("--scene", choices=["paper", "block3d"], default="paper")
    parser.add_argument("--sizes", type=float, nargs="+",
                        help="paper: cells per side (64 128 256); block3d: mesh size h")
    parser.add_argument("--variants", nargs="+", default=list(VARIANTS))
    parser.add_argument("--out", default="gamg_pip")
    args = parser.parse_args()
    unknown = [v for v in args.variants + ([args.one[0]] if args.one else [])
               if v not in VARIANTS]
    if unknown:
        parser.error(f"unknown variants {unknown}; known: {', '.join(VARIANTS)}")
    size_type = int if args.scene == "paper" else float
    if args.one:
        one(args.one[0], size_type(args.one[1]), args.steps, args.scene)
        return
    sizes = [size_type(s) for s in (args.sizes or [64, 128, 256])]
    from common import RESULTS
    path = RESULTS / f"{args.out}.json"
    rows = json.loads(path.read_text()) if path.exists() else []
    for variant in args.variants:
        for size in sizes:
            if any((r["variant"], r["size"]) == (variant, size) for r in rows):
                continue
            print("running", variant, size, flush=True)
            proc = subprocess.run([sys.executable, __file__, "--one", variant, str(size),
                                   "--steps", str(args.steps), "--scene", args.scene],
                                  capture_output=True, text=True)
            lines = [l for l in proc.stdout.splitlines() if l.startswith("ROW ")]
            if proc.returncode or not lines:
                print(proc.stdout[-2000:], proc.stderr[-3000:], flush=True)
                row = {"variant": variant, "size": size, "failed": proc.stderr[-500:]}
            else:
                row = json.loads(lines[0][4:])
                print(lines[0][4:], flush=True)
            rows.append(row)
            RESULTS.mkdir(exist_ok=True)
            path.write_text(json.dumps(rows, indent=1))
    write_results(args.out, rows, summary(rows) + [""] + table(rows))


def _name(variant):
    return {"direct": "MUMPS", "default": "former GAMG_OPTIONS (threshold 0.01)",
            "current": "GAMG_OPTIONS"}.get(variant) or ", ".join(
                f"{k} {v}" for k, v in VARIANTS.get(variant, {}).items())


def _size(size):
    """A size as the tables print it: cells per side (paper) or mesh size h (block3d)."""
    return f"{size}^2" if isinstance(size, int) else f"h={size}"


def summary(rows):
    """Markdown lines: one row per option set, the sizes side by side."""
    rows = [r for r in rows if "failed" not in r]
    sizes = sorted({r["size"] for r in rows})
    reference = {r["size"]: r for r in rows if r["variant"] == "direct"}
    order = ["direct", "default", "current"] + list(VARIANTS)
    lines = ["| options | Krylov per Newton, mean/max: " + " / ".join(map(_size, sizes))
             + f" | Newton per step at {_size(sizes[-1])} | contact states as MUMPS | "
             "CPU s/Newton: " + " / ".join(map(_size, sizes)) + " |",
             "|---|---|---|---|---|"]
    for variant in sorted({r["variant"] for r in rows}, key=order.index):
        by_size = {r["size"]: r for r in rows if r["variant"] == variant}
        cell = lambda f: " / ".join(f(by_size[s]) if s in by_size else "" for s in sizes)
        krylov = "-" if variant == "direct" else cell(
            lambda r: f"{r['krylov_per_newton_mean']:.1f}/{r['krylov_per_newton_max']}")
        last = by_size.get(sizes[-1])
        same = all(r["status_counts"] == reference[s]["status_counts"]
                   for s, r in by_size.items() if s in reference)
        lines.append(f"| {_name(variant)} | {krylov} | "
                     f"{' '.join(map(str, last['newton_per_step'])) if last else ''} | "
                     f"{'yes' if same else 'NO'} | "
                     f"{cell(lambda r: format(r.get('cpu_s_per_newton', float('nan')), '.3f'))} |")
    return lines


def table(rows):
    """Markdown lines: one row per option set and size."""
    reference = {r["size"]: r for r in rows if r["variant"] == "direct" and "failed" not in r}
    lines = ["| options | size | unknowns (u) | Krylov per Newton (mean/max) | Newton per step "
             "| same contact states as MUMPS | s/Newton (wall) | CPU s/Newton (whole run) |",
             "|---|---|---|---|---|---|---|---|"]
    order = ["direct", "default", "current"] + list(VARIANTS)
    for variant in sorted({r["variant"] for r in rows}, key=order.index):
        name = _name(variant)
        for r in sorted((r for r in rows if r["variant"] == variant), key=lambda r: r["size"]):
            if "failed" in r:
                lines.append(f"| {name} | {_size(r['size'])} | | failed | | | | |")
                continue
            same = (r["status_counts"] == reference[r["size"]]["status_counts"]
                    if r["size"] in reference else None)
            krylov = ("-" if variant == "direct" else
                      f"{r['krylov_per_newton_mean']:.1f}/{r['krylov_per_newton_max']}")
            cpu = r.get("cpu_s_per_newton")
            lines.append(f"| {name} | {_size(r['size'])} | {r.get('unknowns_u', '')} | "
                         f"{krylov} | "
                         f"{' '.join(map(str, r['newton_per_step']))} | "
                         f"{'-' if same is None else 'yes' if same else 'NO'} | "
                         f"{r['s_per_newton']:.3f} | {'' if cpu is None else f'{cpu:.3f}'} |")
    return lines


if __name__ == "__main__":
    main()
