"""The speed-accuracy grid behind the presets (run by hand:
python benchmarks/accuracy/tradeoff_grid.py; writes results/tradeoff.json, .md, .png). The
per-scene ladder is benchmarks/accuracy/tradeoff.py.

1. Paper scene under refinement in space: 16..128 cells per side at k = 0.1, both time rules,
   against the 128 run of the same rule.
2. Paper scene under refinement in time: 10..1000 steps on 32 x 32, both rules, against the
   1000-step trapezoid run.
3. A grid of (mesh, degree, rule, steps) on the paper scene against the finest P1 run
   (128 x 128, trapezoid, 40 steps), and of (contact mesh, degree) on the Hertz scene against
   the closed form; error against wall time, with the Pareto front marked.
4. The presets (fast, balanced, accurate) on both scenes (--presets-only: just these).

Error on the paper scene: the largest difference of (u_nu, u_tau) at the contact nodes at T,
the reference taken at the same positions (linear along the boundary), relative to the largest
|u| there. Transition: the first node at the bound (x_B). Wall time: the time steps (no JIT,
no set-up).
"""
import json
import math
import pathlib
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from mpi4py import MPI  # noqa: E402

from contactvisco.scene import loader as scene_module  # noqa: E402
from contactvisco.solver.time_loop import simulate  # noqa: E402
from contactvisco.solver.newton import NewtonFailure  # noqa: E402
from contactvisco.studies.verification import hertz  # noqa: E402

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1]))  # benchmarks/: common.py
from common import RESULTS, write_markdown  # noqa: E402

COMM = MPI.COMM_WORLD


def paper(cells, degree=1, rule="paper", steps=10, preset=None):
    overrides = [f"geometry.cells=[{cells}, {cells}]", f"discretization.degree={degree}",
                 f"time.rule='{rule}'", f"time.steps={steps}", "output.probes=[]"]
    if degree > 1:
        overrides.append("discretization.contact_quadrature='gauss'")
    if preset:
        overrides = [f"preset='{preset}'", "output.probes=[]"]
    scene = scene_module.load("paper", overrides)
    result = simulate(scene, comm=COMM, progress=False, keep_tables=True)
    table = result.tables[-1]
    bound = table["x"][table["status"] == 2, 0]
    return {"cells": scene["geometry"]["cells"][0], "degree": scene["discretization"]["degree"],
            "rule": scene["time"]["rule"], "steps": scene["time"]["steps"],
            "unknowns": sum(result.problem.count_unknowns().values()),
            "newton_mean": float(np.mean([s["newton_iterations"] for s in result.steps])),
            "wall_s": sum(s["wall_s"] for s in result.steps),
            "x": table["x"][:, 0], "u_nu": table["u_nu"], "u_tau": table["u_tau"],
            "x_B": float(bound.min()) if bound.size else math.nan}


def compare(run, ref):
    scale = max(np.max(np.abs(ref["u_nu"])), np.max(np.abs(ref["u_tau"])))
    diff = max(np.max(np.abs(run["u_nu"] - np.interp(run["x"], ref["x"], ref["u_nu"]))),
               np.max(np.abs(run["u_tau"] - np.interp(run["x"], ref["x"], ref["u_tau"]))))
    return {"error": diff / scale, "x_B_error": abs(run["x_B"] - ref["x_B"])}


def strip(run):
    return {k: v for k, v in run.items() if k not in ("x", "u_nu", "u_tau")}


def pareto(rows, key="error"):
    """Rows not beaten in both error and wall time by another row."""
    return [r for r in rows if not any(o is not r and o[key] <= r[key] and
                                       o["wall_s"] <= r["wall_s"] and
                                       (o[key] < r[key] or o["wall_s"] < r["wall_s"])
                                       for o in rows)]


def main():
    if "--presets-only" in sys.argv:     # remeasure the presets, keep the rest
        out = json.loads((RESULTS / "tradeoff.json").read_text())
        finest = paper(128, rule="trapezoid", steps=40)
        out["presets"] = measure_presets(finest)
        save(out)
        report(out)
        return
    out = {}
    out["space"] = space_refinement()
    save(out)
    out["time"] = time_refinement()
    save(out)
    finest = paper(128, rule="trapezoid", steps=40)
    out["paper_grid"] = paper_grid(finest)
    save(out)
    hertz_rows, failures = hertz_grid()
    out["failures"], out["hertz_grid"] = failures, hertz_rows
    out["presets"] = measure_presets(finest)
    save(out)
    if COMM.rank == 0:
        report(out)


def space_refinement():
    """Part 1: 16..128 cells per side, both rules, each against the 128 run of its rule."""
    space = {}
    for rule in ("paper", "trapezoid"):
        runs = [paper(n, rule=rule) for n in (16, 32, 64, 128)]
        space[rule] = [dict(strip(r), **compare(r, runs[-1])) for r in runs]
    return space


def time_refinement():
    """Part 2: 10..1000 steps on 32 x 32, both rules, against 1000 trapezoid steps."""
    reference = paper(32, rule="trapezoid", steps=1000)
    time_rows = {}
    for rule in ("paper", "trapezoid"):
        runs = [paper(32, rule=rule, steps=n) for n in (10, 20, 40, 100, 1000)]
        time_rows[rule] = [dict(strip(r), **compare(r, reference)) for r in runs]
    return time_rows


def paper_grid(finest):
    """Part 3, paper scene: (mesh, degree, rule, steps) against `finest`, Pareto marked."""
    grid = []
    for cells in (16, 32, 64):
        for rule in ("paper", "trapezoid"):
            for steps in (10, 40):
                grid.append(dict(strip(r := paper(cells, 1, rule, steps)), **compare(r, finest)))
    for cells in (16, 32):
        for steps in (10, 40):
            grid.append(dict(strip(r := paper(cells, 2, "trapezoid", steps)),
                             **compare(r, finest)))
    front = pareto(grid)
    for r in grid:
        r["pareto"] = r in front
    return grid


def hertz_grid():
    """Part 3, Hertz scene: (contact mesh a/h, degree) against the closed form, Pareto
    marked; returns the rows and the runs whose Newton solve failed (with residuals)."""
    a = math.sqrt(4 * 2 * 0.25 / (math.pi * 200 / 0.91))
    hertz_rows, failures = [], []
    for degree in (1, 2):
        for f in (5, 10, 20, 40):
            overrides = [f"geometry.parameters.h_contact={a / f}",
                         f"discretization.degree={degree}"]
            if degree == 2:
                overrides.append("discretization.contact_quadrature='gauss'")
            try:
                r = hertz(overrides)
            except NewtonFailure as err:       # a measured result too: recorded, not hidden
                failures.append({"scene": "hertz", "degree": degree, "a_over_h": f,
                                 "residuals": err.residuals[:3] + err.residuals[-2:]})
                continue
            r.update(degree=degree, a_over_h=f, error=max(r["a_error"], r["p0_error"]))
            hertz_rows.append(r)
    front = pareto(hertz_rows)
    for r in hertz_rows:
        r["pareto"] = r in front
    return hertz_rows, failures


def measure_presets(finest):
    presets = []
    for name in ("fast", "balanced", "accurate"):
        r = paper(0, preset=name)
        row = dict(strip(r), **compare(r, finest), preset=name, scene="paper")
        h = hertz([f"preset='{name}'"])
        presets.append(row)
        presets.append(dict(preset=name, scene="hertz", wall_s=h["wall_s"],
                            error=max(h["a_error"], h["p0_error"]), a_error=h["a_error"],
                            p0_error=h["p0_error"], unknowns=h["unknowns"]))
    return presets


def save(out):
    """Written after each part, so a failure later loses nothing measured."""
    if COMM.rank == 0:
        RESULTS.mkdir(exist_ok=True)
        (RESULTS / "tradeoff.json").write_text(json.dumps(out, indent=1, default=float))


def report(out):
    """results/tradeoff.md (printed too) and results/tradeoff.png."""
    lines = report_lines(out)
    write_markdown("tradeoff", lines)
    report_figure(out)


def report_lines(out):
    """The markdown tables of every part."""
    lines = ["## Paper scene under refinement in space (k = 0.1; reference: 128 x 128, same rule)",
             "", "| rule | cells | unknowns | error | x_B | x_B error | Newton mean | s |",
             "|---|---|---|---|---|---|---|---|"]
    for rule, rows in out["space"].items():
        lines += [f"| {rule} | {r['cells']} | {r['unknowns']} | {r['error']:.2e} | "
                  f"{r['x_B']:.4f} | {r['x_B_error']:.4f} | {r['newton_mean']:.2f} | "
                  f"{r['wall_s']:.2f} |" for r in rows]
    lines += ["", "## Paper scene under refinement in time (32 x 32; reference: 1000 steps, "
              "trapezoid)", "", "| rule | steps | error | x_B error | Newton mean | s |",
              "|---|---|---|---|---|---|"]
    for rule, rows in out["time"].items():
        lines += [f"| {rule} | {r['steps']} | {r['error']:.2e} | {r['x_B_error']:.4f} | "
                  f"{r['newton_mean']:.2f} | {r['wall_s']:.2f} |" for r in rows]
    lines += ["", "## Speed-accuracy grid, paper scene (reference: P1 128 x 128, trapezoid, "
              "40 steps); * = Pareto front", "",
              "| cells | degree | rule | steps | unknowns | error | s | front |",
              "|---|---|---|---|---|---|---|---|"]
    lines += [f"| {r['cells']} | {r['degree']} | {r['rule']} | {r['steps']} | {r['unknowns']} | "
              f"{r['error']:.2e} | {r['wall_s']:.2f} | {'*' if r['pareto'] else ''} |"
              for r in sorted(out["paper_grid"], key=lambda r: r["wall_s"])]
    lines += ["", "## Speed-accuracy grid, Hertz scene (closed form); * = Pareto front", "",
              "| degree | a/h | unknowns | a error | p0 error | s | front |",
              "|---|---|---|---|---|---|---|"]
    lines += [f"| {r['degree']} | {r['a_over_h']} | {r['unknowns']} | {r['a_error']:.2e} | "
              f"{r['p0_error']:.2e} | {r['wall_s']:.2f} | {'*' if r['pareto'] else ''} |"
              for r in sorted(out["hertz_grid"], key=lambda r: r["wall_s"])]
    for f in out.get("failures", []):
        lines.append(f"| {f['degree']} | {f['a_over_h']} | Newton diverged: residuals "
                     f"{', '.join('%.2e' % r for r in f['residuals'])} | | | | |")
    lines += ["", "## Presets", "", "| preset | scene | unknowns | error | s |",
              "|---|---|---|---|---|"]
    lines += [f"| {r['preset']} | {r['scene']} | {r['unknowns']} | {r['error']:.2e} | "
              f"{r['wall_s']:.2f} |" for r in out["presets"]]
    return lines


def report_figure(out):
    """Error against wall time of both grids, Pareto fronts and presets marked."""
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2))
    for ax, rows, title in ((axes[0], out["paper_grid"], "paper scene (vs P1 128, 40 steps)"),
                            (axes[1], out["hertz_grid"], "Hertz (vs closed form)")):
        for r in rows:
            marker = "o" if r.get("degree", 1) == 1 else "s"
            colour = "C1" if r.get("rule") == "paper" else "C0"
            ax.loglog(r["wall_s"], r["error"], marker, color=colour,
                      mfc=colour if r["pareto"] else "none", ms=6)
        front = sorted((r for r in rows if r["pareto"]), key=lambda r: r["wall_s"])
        ax.loglog([r["wall_s"] for r in front], [r["error"] for r in front], "k--", lw=0.8,
                  label="Pareto front")
        for r in out["presets"]:
            if r["scene"] == ("paper" if rows is out["paper_grid"] else "hertz"):
                ax.loglog(r["wall_s"], r["error"], "*", color="C3", ms=12)
                ax.annotate(r["preset"], (r["wall_s"], r["error"]), fontsize=8,
                            xytext=(4, 4), textcoords="offset points")
        ax.set_xlabel("wall time of the time steps [s]")
        ax.set_ylabel("relative error")
        ax.set_title(title + "\no P1, s P2; orange paper rule, blue trapezoid; filled = front",
                     fontsize=9)
        ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(RESULTS / "tradeoff.png", dpi=120)


if __name__ == "__main__":
    main()
