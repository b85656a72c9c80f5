"""Newton iterations and preconditioner set-ups (LU factorizations) of the paper scene per
mesh size, with each step started from the last accepted state (solver.predictor = "none") and
from the extrapolation of the last two (the default), and the Newton wall time of each.
Without the operator reuse of contactvisco.solver.newton every Newton iteration factorized:
the "before" column is the iteration count of predictor = "none".

With --tie bound, Newton's derivative at the bound s = g is taken on the bound side (slope 0,
contactvisco.model.contact_law.BOUND_TIE = "bound", UFL's min_value) in place of the compliance
side, the default; the table is then results/newton_work_bound_np<ranks>.md.

    python benchmarks/performance/newton_work.py [--sizes 16 32 64 128] [--tie bound]
"""
import argparse
import pathlib
import sys

from mpi4py import MPI

from contactvisco.model import contact_law
from contactvisco.scene import loader as scene_module

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1]))  # benchmarks/: common.py
from common import timed_run, write  # noqa: E402


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--sizes", type=int, nargs="+", default=[16, 32, 64, 128])
    parser.add_argument("--tie", choices=contact_law.BOUND_TIES, default=contact_law.BOUND_TIE)
    args = parser.parse_args()
    contact_law.BOUND_TIE = args.tie
    comm = MPI.COMM_WORLD
    rows = []
    for n in args.sizes:
        for predictor in ("none", "extrapolate"):
            scene = scene_module.load("paper", [f"geometry.cells=[{n}, {n}]",
                                                f"solver.predictor='{predictor}'"])
            seconds, result = timed_run(scene, comm)
            steps = result.steps
            rows.append(dict(
                cells=n, ranks=comm.size, predictor=predictor, run_s=seconds,
                iterations=[s["newton_iterations"] for s in steps],
                setups=[s["preconditioner_setups"] for s in steps],
                newton_s=sum(s["wall_s"] for s in steps)))
    if comm.rank == 0:
        name = "newton_work" + ("" if args.tie == "compliance" else f"_{args.tie}")
        write(f"{name}_np{comm.size}", rows,
              "| cells | ranks | predictor | Newton iterations per step | total | "
              "factorizations (before: one per iteration) | steps' wall s | run s |",
              lambda r: f"| {r['cells']} | {r['ranks']} | {r['predictor']} | "
                        + " ".join(map(str, r["iterations"])) + f" | {sum(r['iterations'])} | "
                        f"{sum(r['setups'])} | {r['newton_s']:.2f} | {r['run_s']:.2f} |")


if __name__ == "__main__":
    main()
