"""What each reduction of the model saves: the paper scene (64 x 64 by default) with the terms
a simpler contact law does not need left out. Unknowns, Newton iterations and time per step.

    python benchmarks/performance/reductions.py [--cells 64]
"""
import argparse
import pathlib
import sys

from mpi4py import MPI

from contactvisco.scene import loader as scene_module

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1]))  # benchmarks/: common.py
from common import step_statistics, timed_run, write  # noqa: E402

VARIANTS = [
    ("full model (lambda_nu, lambda_tau, history)", []),
    ("no friction: mu = 0 (no lambda_tau)", ["contact.mu=0"]),
    ("no bound: g = inf (no lambda_nu)", ["contact.g=inf"]),
    ("compliance only: g = inf, mu = 0 (no multiplier)", ["contact.g=inf", "contact.mu=0"]),
    ("no memory (no history field)", ["memory.kernel='none'"]),
    ("all of the above", ["contact.g=inf", "contact.mu=0", "memory.kernel='none'"]),
]


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--cells", type=int, default=64)
    args = parser.parse_args()
    comm = MPI.COMM_WORLD
    rows = []
    for label, overrides in VARIANTS:
        scene = scene_module.load("paper", [f"geometry.cells=[{args.cells}, {args.cells}]",
                                            "output.probes=[]"] + overrides)
        seconds, result = timed_run(scene, comm)
        rows.append(dict(variant=label, run_s=seconds, **step_statistics(result)))
    full = rows[0]
    if comm.rank == 0:
        write(f"reductions_{args.cells}_np{comm.size}", rows,
              "| variant | unknowns | mean Newton | s/step | s/Newton it. | vs full (per it.) |"
              " final sep/compl/bound |",
              lambda r: f"| {r['variant']} | {r['unknowns']} | {r['mean_newton']:.2f} | "
                        f"{r['s_per_step']:.4f} | {r['s_per_newton']:.4f} | "
                        f"{r['s_per_newton'] / full['s_per_newton']:.2f} | "
                        + "/".join(str(v) for v in r["final_status"].values()) + " |")


if __name__ == "__main__":
    main()
