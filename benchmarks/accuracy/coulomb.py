"""Coulomb friction measured (run by hand: python benchmarks/accuracy/coulomb.py; about 3 minutes).

1. Cattaneo-Mindlin under refinement (contactvisco.studies.coulomb.cattaneo_mindlin): the cylinder
   at nu = 0.49 with contact mesh sizes a/5.6 .. a/44: errors of the stick-zone half-width c,
   of the transmitted force and of the nodal tractions, observed orders.
2. The effect of the normal-tangential coupling (Dundurs' beta = (1 - 2 nu) / (2 (1 - nu))
   against a rigid plane): the same run at nu = 0.3 .. 0.49.
3. Linear solvers on the nonsymmetric Coulomb Jacobian: MUMPS LU and GMRES + BoomerAMG on the
   condensed system (Newton and Krylov iterations, time, difference of the answers).
4. Ironing with slip = "total" and "increment" (Coulomb on the total pressure in both).

Writes benchmarks/results/coulomb.{json,md}.
"""
import math
import pathlib
import sys
import time

import numpy as np
from mpi4py import MPI

from contactvisco.scene import loader as scene_module
from contactvisco.studies.coulomb import cattaneo_mindlin, cattaneo_scene
from contactvisco.solver.time_loop import simulate
from contactvisco.studies.verification import orders

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1]))  # benchmarks/: common.py
from common import write_results  # noqa: E402

KEYS = ("h", "a", "a_over_h", "nu", "load_ratio", "c", "c_h", "c_error", "stick_centre", "q_error",
        "q_error_l2", "F_error", "p_error", "newton", "unknowns")


def _cm(h, nu):
    tick = time.perf_counter()
    r = cattaneo_mindlin(h, nu=nu)
    return dict({k: r[k] for k in KEYS}, wall_s=time.perf_counter() - tick)


def refinement():
    """Section 1: Cattaneo-Mindlin at nu = 0.49 on four contact mesh sizes, with the observed
    orders of the stick-zone and force errors. Returns (rows, table lines)."""
    lines = ["## Cattaneo-Mindlin under refinement (nu = 0.49, Q ~ 0.44 mu P)", "",
             "| a/h | u unknowns | Newton | c/a exact | c/a | c error / a | order | "
             "force error / Q | order | traction error (max, / mu p0) | "
             "traction error (L2, rel.) | pressure error (max, / p0) | stick centre / a |",
             "|" + "---|" * 13]
    sizes = [0.01, 0.005, 0.0025, 0.00125]
    rows = [_cm(h, 0.49) for h in sizes]
    order_c = [math.nan] + orders([r["c_error"] for r in rows], sizes)
    order_F = [math.nan] + orders([r["F_error"] for r in rows], sizes)
    for r, oc, oF in zip(rows, order_c, order_F):
        lines.append(f"| {r['a_over_h']:.1f} | {r['unknowns']} | {r['newton']} | "
                     f"{r['c'] / r['a']:.4f} | {r['c_h'] / r['a']:.4f} | "
                     f"{r['c_error']:.4f} | {oc:.2f} | {r['F_error']:.4f} | {oF:.2f} | "
                     f"{r['q_error']:.3f} | {r['q_error_l2']:.3f} | {r['p_error']:.3f} | "
                     f"{r['stick_centre']:.3f} |")
    return rows, lines


def coupling():
    """Section 2: the same run at a/h = 22 for nu = 0.3 .. 0.49 (Dundurs' beta).
    Returns (rows, table lines)."""
    lines = ["", "## Normal-tangential coupling (a/h = 22)", "",
             "| nu | beta | Q / (mu P) | c error / a | stick centre / a | force error / Q | "
             "traction error (L2, rel.) |", "|---|---|---|---|---|---|---|"]
    rows = [_cm(0.0025, nu) for nu in (0.3, 0.4, 0.45, 0.475, 0.49)]
    for r in rows:
        beta = (1 - 2 * r["nu"]) / (2 * (1 - r["nu"]))
        lines.append(f"| {r['nu']} | {beta:.3f} | {r['load_ratio']:.3f} | {r['c_error']:.3f} | "
                     f"{r['stick_centre']:.3f} | {r['F_error']:.3f} | {r['q_error_l2']:.3f} |")
    return rows, lines


def solvers():
    """Section 3: MUMPS LU and GMRES + BoomerAMG on the condensed Coulomb Jacobian, on two
    scenes: Newton and Krylov iterations, time, and the largest relative difference of the
    final contact tractions. Returns (rows, table lines)."""
    lines = ["", "## Linear solvers on the nonsymmetric Coulomb Jacobian (condensed system)",
             "", "| scene | u unknowns | solver | Newton per step | Krylov max | s | "
             "max difference of the contact tractions |", "|---|---|---|---|---|---|---|"]
    cases = {
        "Cattaneo-Mindlin a/h = 44": scene_module.resolve(cattaneo_scene(0.00125)),
        "paper 128^2, coulomb, increment": scene_module.load(
            "paper", ["geometry.cells=[128, 128]", "contact.friction_law='coulomb'",
                      "contact.slip='increment'"]),
    }
    rows = []
    for name, scene in cases.items():
        scene["output"]["probes"] = []
        runs = {}
        for kind in ("direct", "iterative"):
            scene["solver"]["linear_solver"] = kind
            tick = time.perf_counter()
            runs[kind] = simulate(scene, comm=MPI.COMM_WORLD, progress=False, keep_tables=True)
            runs[kind].wall = time.perf_counter() - tick
        direct, iterative = runs["direct"].tables[-1], runs["iterative"].tables[-1]
        diff = max(float(np.max(np.abs(direct[key] - iterative[key])))
                   / max(1e-300, float(np.max(np.abs(direct[key]))))
                   for key in ("reaction_nu", "reaction_tau"))
        for kind, result in runs.items():
            krylov = [count for record in result.steps for count in record["krylov_iterations"]]
            row = {"scene": name, "solver": result.linear_solver,
                   "unknowns": result.problem.count_unknowns()["u"],
                   "newton": [record["newton_iterations"] for record in result.steps],
                   "krylov_max": max(krylov) if krylov else 0, "wall_s": result.wall,
                   "difference": diff}
            rows.append(row)
            lines.append(f"| {name} | {row['unknowns']} | {row['solver']} | "
                         f"{' '.join(map(str, row['newton']))} | {row['krylov_max']} | "
                         f"{row['wall_s']:.1f} | {diff:.1e} |")
    return rows, lines


def ironing():
    """Section 4: ironing with Coulomb friction, slip measured in total and per step.
    Returns (rows, table lines)."""
    lines = ["", "## Ironing: slip measured in total and per step (Coulomb on the total "
             "pressure)", "",
             "| slip | Newton mean/max | final sep/compl/bound | nodes sliding at T | "
             "u_tau range at T | friction force at T (sum w sigma_tau) |",
             "|---|---|---|---|---|---|"]
    rows = []
    for slip in ("total", "increment"):
        scene = scene_module.load("ironing", ["contact.friction_law='coulomb'",
                                              f"contact.slip='{slip}'"])
        scene["output"]["probes"] = []
        result = simulate(scene, comm=MPI.COMM_WORLD, progress=False, keep_tables=True)
        table = result.tables[-1]
        newton = [record["newton_iterations"] for record in result.steps]
        row = {"slip": slip, "newton_mean": float(np.mean(newton)), "newton_max": max(newton),
               "status": result.steps[-1]["status_counts"],
               "sliding": int(np.sum(table["friction"] == 2)),
               "u_tau": [float(table["u_tau"].min()), float(table["u_tau"].max())],
               "force": float(np.sum(table["weight"] * table["reaction_tau"]))}
        rows.append(row)
        status = row["status"]
        lines.append(f"| {slip} | {row['newton_mean']:.1f}/{row['newton_max']} | "
                     f"{status['separated']}/{status['compliance']}/{status['bound']} | "
                     f"{row['sliding']} | {row['u_tau'][0]:.2e} .. {row['u_tau'][1]:.2e} | "
                     f"{row['force']:.4f} |")
    return rows, lines


def main():
    out, lines = {}, []
    for key, section in (("refinement", refinement), ("coupling", coupling),
                         ("solvers", solvers), ("ironing", ironing)):
        out[key], section_lines = section()
        lines += section_lines
    if MPI.COMM_WORLD.rank == 0:
        write_results("coulomb", out, lines, default=str)


if __name__ == "__main__":
    main()
