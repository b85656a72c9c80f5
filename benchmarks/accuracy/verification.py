"""Measured convergence orders (run by hand: python benchmarks/accuracy/verification.py).

Space: the manufactured solution (contactvisco.studies.verification.manufactured), P1 and P2 on
4..64 cells per side, L2 and H1 errors at T. Time: the uniaxial closed form, both rules and
both kernels, 10..160 steps. Contact: Hertz at a/R = 0.024 with contact mesh sizes a/5..a/40.
Writes benchmarks/results/verification.{json,md}.
"""
import math
import pathlib
import sys

from mpi4py import MPI

from contactvisco.studies.verification import hertz, manufactured, orders, uniaxial, uniaxial_exact

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1]))  # benchmarks/: common.py
from common import write_results  # noqa: E402


def main():
    out = {"space": {}, "time": {}, "hertz": []}
    lines = ["## Space (manufactured solution, T = 1, trapezoid rule, 4 steps)", "",
             "| degree | cells | L2 error | L2 order | H1 error | H1 order |",
             "|---|---|---|---|---|---|"]
    for degree in (1, 2):
        rows = [manufactured(n, degree) for n in (4, 8, 16, 32, 64)]
        h = [r["h"] for r in rows]
        o2 = [math.nan] + orders([r["L2"] for r in rows], h)
        o1 = [math.nan] + orders([r["H1"] for r in rows], h)
        out["space"][degree] = rows
        lines += [f"| P{degree} | {r['cells']} | {r['L2']:.3e} | {a:.2f} | {r['H1']:.3e} | "
                  f"{b:.2f} |" for r, a, b in zip(rows, o2, o1)]
    lines += ["", "## Time (uniaxial closed form, error of u at T = 1)", "",
              "| kernel | rule | steps | error | order |", "|---|---|---|---|---|"]
    for kernel in ("constant", "exponential"):
        for rule in ("paper", "trapezoid"):
            steps = [10, 20, 40, 80, 160]
            errors = [abs(uniaxial(kernel, rule, 1.0, n)[-1] - uniaxial_exact(kernel, 1.0))
                      for n in steps]
            o = [math.nan] + orders(errors, [1 / n for n in steps])
            out["time"][f"{kernel}-{rule}"] = errors
            lines += [f"| {kernel} | {rule} | {n} | {e:.3e} | {x:.2f} |"
                      for n, e, x in zip(steps, errors, o)]
    lines += ["", "## Hertz (a/R = 0.024; half-width from the last contact element's midpoint)",
              "", "| a/h | unknowns | a error | p0 error | s |", "|---|---|---|---|---|"]
    a = math.sqrt(4 * 2 * 0.05 / (math.pi * 200 / 0.91))
    for f in (5, 10, 20, 40):
        r = hertz([f"geometry.parameters.h_contact={a / f}", f"geometry.parameters.refine={2 * a}",
                   "traction.0.value=[0.0, -0.05]"])
        out["hertz"].append(dict(r, a_over_h=f))
        lines.append(f"| {f} | {r['unknowns']} | {r['a_error']:.2e} | {r['p0_error']:.2e} | "
                     f"{r['wall_s']:.2f} |")
    if MPI.COMM_WORLD.rank == 0:
        write_results("verification", out, lines, default=float)


if __name__ == "__main__":
    main()
