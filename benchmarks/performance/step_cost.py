"""Benchmark: the time of a contact step in elastic solves, per scene and mesh size.

For each configuration (scene, size, linear solver) one process (or one `mpirun -n R` job)
takes the first steps of the scene with a constant step size (time.T shortened), then, in the
same process, times one linear-elastic assembly + solve on the same mesh with the direct
(MUMPS) and with the iterative solver (best of two each, scaling.elastic_floor): the fastest of
them is the unit of the step's cost. Recorded per step: wall time, Newton iterations, Krylov
iterations, preconditioner set-ups; and the converged contact values of the last step (the
multipliers and u at the contact nodes, by node coordinates) in a .npz beside the results, so
that two code versions can be compared to round-off (--compare).

    python benchmarks/performance/step_cost.py --label after [--ranks 1 2]
        [--configs paper:128:auto block3d:0.03:auto ...] [--steps 4]
    python benchmarks/performance/step_cost.py --label reference --switch KEEP=0 INEXACT=0
    python benchmarks/performance/step_cost.py --compare before after

Writes benchmarks/results/step_cost_<label>.{json,md}; contact values to
benchmarks/results/step_cost_values/<label>_<scene>_<size>_<solver>_np<R>.npz (not committed).
"""
import argparse
import ast
import json
import os
import pathlib
import subprocess
import sys
import time

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1]))  # benchmarks/: common.py
sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))      # scaling.py
from common import RESULTS, write_markdown  # noqa: E402
from helpers import mpi_env  # noqa: E402

VALUES = RESULTS / "step_cost_values"
#: The direct elastic solve is timed below these u unknowns only (3D fill-in: minutes, GB).
DIRECT_ELASTIC_LIMIT = {2: 600_000, 3: 60_000}
DEFAULT_CONFIGS = ["paper:128:auto", "paper:256:auto", "paper:512:auto",
                   "block3d:0.03:auto", "block3d:0.018:auto"]


def contact_values(problem, comm):
    """(coordinates, values) of the owned contact nodes on rank 0, sorted by coordinates:
    u and every multiplier component at each node."""
    import numpy as np
    nodes = problem.contact.nodes
    own = nodes.nodes[nodes.owned]
    V = problem.V
    d = V.dofmap.index_map_bs
    x = V.tabulate_dof_coordinates()[own]
    columns = [problem.u.x.array.reshape(-1, d)[own]]
    for f in problem.multipliers.values():
        bs = f.function_space.dofmap.index_map_bs
        columns.append(f.x.array.reshape(-1, bs)[own])
    values = np.hstack(columns)
    xs, vs = comm.gather(x, root=0), comm.gather(values, root=0)
    if comm.rank:
        return None, None
    x, values = np.vstack(xs), np.vstack(vs)
    order = np.lexsort(np.round(x, 12).T[::-1])
    return x[order], values[order]


def one(scene_name, size, solver, steps, label, switches=(), settings=()):
    import numpy as np
    from mpi4py import MPI

    from contactvisco.scene import loader as scene_module
    from contactvisco.solver.time_loop import simulate
    from scaling import elastic_floor, overrides

    import importlib
    for switch in switches:                    # e.g. KEEP=0: the reference without the rule
        name, value = switch.split("=")        # (a bare name is one of solver.linear's)
        module, _, name = name.rpartition(".")
        module = importlib.import_module(f"contactvisco.solver.{module or 'linear'}")
        current = getattr(module, name)        # a dict by literal: AUTO_DIRECT_LATER={2:0}
        if isinstance(current, dict):
            setattr(module, name, {**current, **ast.literal_eval(value)})
        elif isinstance(current, tuple):       # a tuple by literal: AFTER_LOOSE_PCS=('hypre',)
            setattr(module, name, tuple(ast.literal_eval(value)))
        else:
            setattr(module, name, type(current)(float(value)))
    from contactvisco.solver import newton
    newton_cpu = []                            # CPU seconds of every Newton solve
    solve = newton.NewtonSolver.solve

    def timed_solve(self):
        tick = time.process_time()
        try:
            return solve(self)
        finally:
            newton_cpu.append(time.process_time() - tick)
    newton.NewtonSolver.solve = timed_solve
    comm = MPI.COMM_WORLD
    scene = scene_module.load(scene_name, overrides(scene_name, size, steps)
                              + [f"solver.linear_solver='{solver}'", *settings])
    scene["output"]["probes"] = []
    cpu0 = time.process_time()
    tick = time.perf_counter()
    result = simulate(scene, comm=comm, progress=False)
    run_s = time.perf_counter() - tick
    run_cpu = time.process_time() - cpu0
    problem = result.problem
    d = problem.V.mesh.geometry.dim
    unknowns = problem.count_unknowns()["u"]
    elastic = {"iterative": elastic_floor(problem, scene, "iterative", comm)}
    if unknowns < DIRECT_ELASTIC_LIMIT[d]:
        elastic["direct"] = elastic_floor(problem, scene, "direct", comm)
    fastest = min(elastic, key=lambda k: elastic[k][0])
    unit = elastic[fastest][0]
    x, values = contact_values(problem, comm)
    if comm.rank == 0:
        VALUES.mkdir(parents=True, exist_ok=True)
        np.savez(VALUES / f"{label}_{scene_name}_{size}_{solver}_np{comm.size}.npz", x=x,
                 values=values)
    records = result.steps
    row = {"scene": scene_name, "size": size, "solver": solver, "ranks": comm.size,
           "label": label, "settings": list(settings), "switches": list(switches),
           "unknowns_u": unknowns, "ksp_pc": result.linear_solver,
           "newton": [s["newton_iterations"] for s in records],
           "krylov": [s["krylov_iterations"] for s in records],
           "setups": [s["preconditioner_setups"] for s in records],
           "step_s": [s["wall_s"] for s in records],
           "elastic_s": {k: v[0] for k, v in elastic.items()}, "elastic_fastest": fastest,
           "unit_s": unit, "run_s": run_s, "run_cpu_s": run_cpu,
           "newton_cpu_s": sum(newton_cpu),
           "load": os.getloadavg()[0]}
    if comm.rank == 0:
        print("ROW " + json.dumps(row), flush=True)


def first_loaded(row):
    """The index of the first step with Newton iterations (t_0 of block3d carries no load)."""
    return next((i for i, n in enumerate(row["newton"]) if n > 0), 0)


def ratios(row):
    """(first loaded step, mean of the later ones) in units of the fastest elastic solve."""
    k = first_loaded(row)
    later = row["step_s"][k + 1:]
    return (row["step_s"][k] / row["unit_s"],
            sum(later) / len(later) / row["unit_s"] if later else float("nan"))


def draw(rows, fig):
    """Draw a step's cost in elastic solves (left: the first loaded step open, the mean of the
    later ones filled; the dashed lines at 4 and 2) and the mean Newton iterations of the later
    steps on the fewest ranks (right), against the displacement unknowns: circles 2D, squares
    3D, colour by ranks.

    Parameters
    ----------
    rows : list of dict
        Rows of step_cost_<label>.json (failed ones are left out).
    fig : matplotlib.figure.Figure
        An empty figure to draw on (sized and laid out here).

    Returns
    -------
    matplotlib.figure.Figure
        `fig`.
    """
    import matplotlib
    from contactvisco.post.figures import PAGE, STYLE, size_constrained
    rows = [r for r in rows if "failed" not in r]
    ranks = sorted({r["ranks"] for r in rows})

    def ranks_text(n):
        return f"{n} rank{'s' if n > 1 else ''}"
    with matplotlib.rc_context(STYLE):
        size_constrained(fig, PAGE, 2.6)
        cost, newton = fig.subplots(1, 2)
        for r in rows:
            first, later = ratios(r)
            k = first_loaded(r)
            colour = f"C{ranks.index(r['ranks'])}"
            marker = "o" if r["scene"] == "paper" else "s"
            cost.semilogx(r["unknowns_u"], first, marker, color=colour, mfc="none", ms=5)
            cost.semilogx(r["unknowns_u"], later, marker, color=colour, ms=5)
            if r["ranks"] == ranks[0]:      # the Newton counts do not depend on the ranks
                later_newton = r["newton"][k + 1:]
                newton.semilogx(r["unknowns_u"], sum(later_newton) / len(later_newton), marker,
                                color=colour, ms=5)
        for goal, text in ((4, "first loaded step: 4"), (2, "later steps: 2")):
            cost.axhline(goal, color="0.5", ls="--", lw=0.7)
            cost.annotate(text, (0.02, goal), xycoords=("axes fraction", "data"), fontsize=7,
                          xytext=(0, 2), textcoords="offset points", color="0.3")
        for i, n in enumerate(ranks):
            cost.plot([], [], "o", color=f"C{i}", label=ranks_text(n))
        cost.legend(loc="lower right")
        newton.plot([], [], "o", color="0.3", mfc="none", label="2D paper scene")
        newton.plot([], [], "s", color="0.3", mfc="none", label="3D block3d")
        newton.legend(loc="center right")
        cost.set_ylim(0, None)
        newton.set_ylim(0, None)
        cost.set_xlabel("displacement unknowns")
        cost.set_ylabel("step time / elastic solve time")
        cost.set_title("open: first loaded step; filled: mean of the later steps")
        newton.set_xlabel("displacement unknowns")
        newton.set_ylabel("Newton iterations per later step (mean)")
        newton.set_title(f"on {ranks_text(ranks[0])}")
    return fig


def write_table(rows, name):
    lines = ["| scene | size | unknowns (u) | solver | ranks | Newton per step | set-ups per "
             "step | Krylov per step | s per step | elastic solve s (fastest) | first loaded "
             "step / elastic | later steps / elastic | Newton CPU s | run CPU s | load |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        if "failed" in r:
            lines.append(f"| {r['scene']} | {r['size']} | | {r['solver']} | {r['ranks']} | "
                         "failed | | | | | | | | | |")
            continue
        first, later = ratios(r)
        lines.append(
            f"| {r['scene']} | {r['size']} | {r['unknowns_u']} | {r['ksp_pc']} | {r['ranks']} "
            f"| {' '.join(map(str, r['newton']))} | {' '.join(map(str, r['setups']))} | "
            + " ".join(str(sum(k)) for k in r["krylov"])
            + f" | {' '.join(f'{s:.2f}' for s in r['step_s'])} | {r['unit_s']:.3f} "
            f"({r['elastic_fastest']}) | {first:.2f} | {later:.2f} | "
            f"{r.get('newton_cpu_s', float('nan')):.2f} | {r['run_cpu_s']:.1f} | "
            f"{r['load']:.1f} |")
    write_markdown(name, lines)


def compare(before, after):
    """Largest difference of the contact values between two labels, per configuration,
    relative to the largest value of each column."""
    import numpy as np
    for path in sorted(VALUES.glob(f"{before}_*.npz")):
        other = VALUES / path.name.replace(f"{before}_", f"{after}_", 1)
        if not other.exists():
            continue
        a, b = np.load(path), np.load(other)
        assert np.allclose(a["x"], b["x"]), path.name
        scale = np.maximum(np.abs(a["values"]).max(axis=0), 1e-300)
        diff = (np.abs(a["values"] - b["values"]) / scale).max()
        print(f"{path.name[len(before) + 1:]}: max relative difference {diff:.2e}")


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--one", nargs=3, metavar=("SCENE", "SIZE", "SOLVER"))
    parser.add_argument("--label", default="after")
    parser.add_argument("--steps", type=int, default=4)
    parser.add_argument("--ranks", type=int, nargs="+", default=[1])
    parser.add_argument("--configs", nargs="+", default=DEFAULT_CONFIGS,
                        help="scene:size:solver (paper: cells per side; another scene: "
                        "geometry.parameters.h)")
    parser.add_argument("--compare", nargs=2, metavar=("BEFORE", "AFTER"))
    parser.add_argument("--switch", nargs="*", default=[],
                        help="NAME=VALUE of contactvisco.solver.linear (KEEP=0, INEXACT=0), "
                        "or MODULE.NAME=VALUE of another contactvisco.solver module "
                        "(a dict's entries or a tuple as a literal: "
                        "newton.AUTO_DIRECT_LATER={2:0}); "
                        "recorded with each row")
    parser.add_argument("--set", nargs="*", default=[], dest="settings",
                        help="scene overrides (solver.first_iterate='coarse')")
    args = parser.parse_args()
    if args.compare:
        compare(*args.compare)
        return
    if args.one:
        scene, size, solver = args.one
        one(scene, int(size) if scene == "paper" else float(size), solver, args.steps,
            args.label, args.switch, args.settings)
        return
    from contactvisco.io import launcher
    env = mpi_env(oversubscribe=False)
    path = RESULTS / f"step_cost_{args.label}.json"
    rows = json.loads(path.read_text()) if path.exists() else []
    for config in args.configs:
        scene, size, solver = config.split(":")
        size = int(size) if scene == "paper" else float(size)
        for ranks in args.ranks:
            if any((r["scene"], r["size"], r["solver"], r["ranks"]) == (scene, size, solver,
                                                                         ranks) for r in rows):
                continue
            command = [*launcher.mpi_launcher(), "-n", str(ranks), sys.executable, __file__,
                       "--one", scene, str(size), solver, "--steps", str(args.steps),
                       "--label", args.label, "--switch", *args.switch,
                       "--set", *args.settings]
            print("running", scene, size, solver, ranks, flush=True)
            proc = subprocess.run(command, env=env, capture_output=True, text=True)
            lines = [line for line in proc.stdout.splitlines() if line.startswith("ROW ")]
            if proc.returncode or not lines:
                print(proc.stdout[-2000:], proc.stderr[-3000:], flush=True)
                rows.append({"scene": scene, "size": size, "solver": solver, "ranks": ranks,
                             "failed": proc.stderr[-500:]})
            else:
                rows.append(json.loads(lines[0][4:]))
                print(lines[0][4:], flush=True)
            RESULTS.mkdir(exist_ok=True)
            path.write_text(json.dumps(rows, indent=1))
    write_table(rows, f"step_cost_{args.label}")


if __name__ == "__main__":
    main()
