"""The condensed Newton system's line search (solver.line_search) on nonlinear bulk laws: Newton
iterations per step and step cuts of the paper scene with the saturating strain energy

    W = K/2 tr(eps)^2 + 2 mu c^2 (sqrt(1 + |dev eps|^2 / c^2) - 1),   c = 0.15,

(K = lambda* + mu = 71.43 and mu = 38.46, the paper's in-plane moduli) and with the Hencky
law (material.law = "hencky", its defaults), each without the line search ("none"), with the
monotone Armijo rule (memory 1) and with the default non-monotone one; and the same for the
linear law of the paper and Hertz scenes, where "auto" keeps the full step. The contact values
of each run at every step are compared with those of the coupled system with PETSc's
backtracking line search (snes_linesearch_type bt) on the same time grid, where that grid was
kept (no cut).

    python benchmarks/performance/line_search.py [--sizes 32 64]
"""
import argparse
import pathlib
import sys
import time

import numpy as np
from mpi4py import MPI

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1]))  # benchmarks/: common.py
from common import write_results  # noqa: E402

from contactvisco import api  # noqa: E402
from contactvisco.solver import newton  # noqa: E402
from contactvisco.solver.newton import NewtonFailure  # noqa: E402

SATURATING = ("0.5 * (lmbda + mu_lame) * tr_eps**2 "
              "+ 2 * mu_lame * 0.15**2 * (sqrt(1 + dev_eps2 / 0.15**2) - 1)")
LAWS = {"saturating": ["material.law='energy'", f"material.energy='{SATURATING}'"],
        "hencky": ["material.law='hencky'"], "linear": []}
KEYS = ("u_nu", "u_tau", "lambda_nu", "reaction_nu", "reaction_tau")


def run(name, sets, comm):
    """(result, CPU seconds); result None where a step failed even when cut."""
    scene = api.load_scene(name, sets=["output.figures=false", *sets])
    tick = time.process_time()
    try:
        result = api.solve(scene, comm=comm)
    except NewtonFailure:
        result = None
    return result, time.process_time() - tick


def contact_gap(a, b):
    """The largest difference of the contact values of two runs over all steps (inf where
    their time grids differ)."""
    if a is None or b is None or [s["t"] for s in a.steps] != [s["t"] for s in b.steps]:
        return float("inf")
    gap = 0.0
    for ta, tb in zip(a.contact, b.contact):
        for key in KEYS:
            if ta.get(key) is not None:
                gap = max(gap, float(np.max(np.abs(np.asarray(ta[key]) - np.asarray(tb[key])),
                                            initial=0.0)))
    return gap


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--sizes", type=int, nargs="+", default=[32, 64])
    args = parser.parse_args()
    comm = MPI.COMM_WORLD
    cases = [("paper", law, n) for n in args.sizes for law in LAWS] + [("hertz", "linear", 0)]
    variants = [("none", 1), ("nonmonotone", 1), ("nonmonotone", newton.LINE_SEARCH_MEMORY)]
    memory = newton.LINE_SEARCH_MEMORY
    rows = []
    for scene, law, n in cases:
        sets = LAWS[law] + ([f"geometry.cells=[{n}, {n}]"] if n else [])
        reference, _ = run(scene, sets + ["solver.linear_system='coupled'",
                                          "solver.petsc_options={snes_linesearch_type='bt'}"],
                           comm)
        for choice, m in variants:
            newton.LINE_SEARCH_MEMORY = m
            result, cpu = run(scene, sets + [f"solver.line_search='{choice}'"], comm)
            newton.LINE_SEARCH_MEMORY = memory
            iterations = [s["newton_iterations"] for s in result.steps] if result else []
            rows.append(dict(
                scene=scene, law=law, cells=n, line_search=choice,
                memory=m if choice != "none" else None, iterations=iterations,
                total=sum(iterations), steps=len(iterations) - 1,
                cuts=sum(1 for s in result.steps if s["cuts"]) if result else None,
                coupled_bt=([s["newton_iterations"] for s in reference.steps] if reference
                            else "failed"),
                final_residual=result.steps[-1]["residual"] if result else float("nan"),
                contact_gap=contact_gap(result, reference), cpu_s=cpu))
    load = open("/proc/loadavg").read().split()[:3] if pathlib.Path("/proc/loadavg").exists() \
        else ["?"] * 3
    lines = [f"Load average before writing: {' '.join(load)}; {comm.size} rank(s).", "",
             "| scene | law | cells | line search | M | Newton iterations per step | total "
             "| steps | cut steps | coupled + bt | final |F| | contact gap to coupled | CPU s |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(
            f"| {r['scene']} | {r['law']} | {r['cells'] or 'scene'} | {r['line_search']} | "
            f"{r['memory'] or '-'} | {r['iterations'] or 'failed'} | {r['total']} | {r['steps']} | "
            f"{r['cuts']} | {r['coupled_bt']} | {r['final_residual']:.1e} | "
            f"{r['contact_gap']:.1e} | {r['cpu_s']:.1f} |")
    if comm.rank == 0:
        write_results(f"line_search_np{comm.size}", rows, lines)


if __name__ == "__main__":
    main()
