"""The side of the friction projection's derivative on a ball of radius 0
(contactvisco.model.contact_law.ZERO_BALL): "stick" (the default), "free" and "guarded" (free,
but the step is solved again with the stick side when the coupled residual finds no new
minimum in contactvisco.solver.newton.GUARD_WINDOW iterations or the free solve fails).
Newton iterations per step (both attempts counted), whether the run finished, and the
largest difference of the contact values from the stick side's run (every step).

    python benchmarks/performance/zero_ball.py [--paper 64 128 256] [--block 0.125 ...]
"""
import argparse
import pathlib
import sys

import numpy as np
from mpi4py import MPI

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1]))  # benchmarks/: common.py
from common import write_results  # noqa: E402

from contactvisco import api  # noqa: E402
from contactvisco.model import contact_law  # noqa: E402
from contactvisco.solver.newton import NewtonFailure  # noqa: E402
from contactvisco.solver.time_loop import StepFailed  # noqa: E402

KEYS = ("u_nu", "u_tau", "lambda_nu", "reaction_nu", "reaction_tau")
#: The case of tests/robustness/test_extremes.py where the free side made Newton cycle.
STIFF = ("paper", ["geometry.cells=[8, 8]", "time.steps=3", "contact.stiffness=1e8"],
         "8^2, stiffness 1e8, 3 steps")


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--paper", type=int, nargs="*", default=[64, 128, 256])
    parser.add_argument("--block", type=float, nargs="*", default=[0.125, 0.0833, 0.0625, 0.04])
    parser.add_argument("--others", nargs="*", default=["ironing", "creep", "hertz"])
    args = parser.parse_args()
    comm = MPI.COMM_WORLD
    cases = [STIFF]
    cases += [("paper", [f"geometry.cells=[{n}, {n}]"], f"{n}^2") for n in args.paper]
    cases += [("block3d", [f"geometry.parameters={{lx=1.0, ly=1.0, lz=0.5, h={h}}}"],
               f"h = {h}") for h in args.block]
    cases += [(name, [], "default") for name in args.others]
    rows = []
    for name, sets, size in cases:
        reference = None
        for tie in ("stick", "free", "guarded"):
            contact_law.ZERO_BALL = tie
            scene = api.load_scene(name, sets=["output.figures=false", *sets])
            scene["output"]["probes"] = []
            row = dict(scene=name, size=size, tie=tie)
            try:
                result = api.solve(scene, comm=comm)
                row["iterations"] = [s["newton_iterations"] for s in result.steps]
                if reference is None:
                    reference = result.contact
                else:
                    row["contact_gap"] = max(
                        float(np.max(np.abs(np.asarray(a[k]) - np.asarray(b[k])), initial=0.0))
                        for a, b in zip(reference, result.contact) for k in KEYS)
            except (NewtonFailure, StepFailed) as err:
                row["failed"] = str(err).splitlines()[0][:160]
            rows.append(row)
    contact_law.ZERO_BALL = "stick"
    load = open("/proc/loadavg").read().split()[:3]
    lines = [f"Load average at the end: {' '.join(load)}; {comm.size} rank(s). Contact gap: "
             "the largest difference of the contact values from the stick side's run.", "",
             "| scene | size | radius-0 side | Newton per step (t_0 first) | total | contact gap |",
             "|---|---|---|---|---|---|"]
    for r in rows:
        if "failed" in r:
            lines.append(f"| {r['scene']} | {r['size']} | {r['tie']} | failed: {r['failed']} "
                         "| - | - |")
            continue
        gap = f"{r['contact_gap']:.1e}" if "contact_gap" in r else "-"
        lines.append(f"| {r['scene']} | {r['size']} | {r['tie']} | {r['iterations']} | "
                     f"{sum(r['iterations'])} | {gap} |")
    if comm.rank == 0:
        write_results(f"zero_ball_np{comm.size}", rows, lines)


if __name__ == "__main__":
    main()
