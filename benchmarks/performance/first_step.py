"""Newton iterations per step of the paper scene and block3d at three sizes each, and, for the
first loaded step (the paper scene's t_0, block3d's t_1: its t_0 is unloaded), the contact
state of every Newton iterate: how many contact nodes have 0, 1, 2, ... active conditions (the
nullity of their multiplier block D_i in the condensed system: 0 compliance or slip, 1 at the
bound or sticking in 2D, 2 sticking in 3D). It shows where the first step's iterations go:
changes of contact state, or the convergence of a state that no longer changes.

Each case runs with both sides of the friction ball's derivative at z = 0 on a ball of radius 0
(contactvisco.model.contact_law.ZERO_BALL): "stick" (the earlier choice) and "free" (the
default).

    python benchmarks/performance/first_step.py [--paper 64 128 256] [--block 0.125 0.0833 0.0625]
"""
import argparse
import pathlib
import sys

import numpy as np
from mpi4py import MPI

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1]))  # benchmarks/: common.py
from common import first_loaded_step, write_results  # noqa: E402

from contactvisco.model import contact_law  # noqa: E402


def run(name, sets, comm):
    """(step records, the first loaded step's [(|F|, nullity counts)] per iterate)."""
    def counts(snes):
        parts = snes.system.parts         # None while a residual's blocks are deferred
        nullity = np.bincount(parts["nullity"] if parts is not None else [], minlength=4)
        return comm.allreduce(nullity, op=MPI.SUM).tolist()
    return first_loaded_step(name, sets, comm, counts)

def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--paper", type=int, nargs="+", default=[64, 128, 256])
    parser.add_argument("--block", type=float, nargs="+", default=[0.125, 0.0833, 0.0625])
    args = parser.parse_args()
    comm = MPI.COMM_WORLD
    cases = [("paper", [f"geometry.cells=[{n}, {n}]"], f"{n}^2") for n in args.paper]
    cases += [("block3d", [f"geometry.parameters={{lx=1.0, ly=1.0, lz=0.5, h={h}}}"],
               f"h = {h}") for h in args.block]
    rows = []
    for name, sets, size in cases:
        for tie in ("stick", "free"):
            contact_law.ZERO_BALL = tie
            result, history, step = run(name, sets, comm)
            rows.append(dict(scene=name, size=size, tie=tie,
                             unknowns=result.problem.count_unknowns()["u"],
                             solver=result.linear_solver,
                             iterations=[s["newton_iterations"] for s in result.steps],
                             first_loaded_step=step, history=history,
                             contact=result.contact))
        stick, free = rows[-2], rows[-1]
        gap = max(float(np.max(np.abs(np.asarray(a[k]) - np.asarray(b[k])), initial=0.0))
                  for a, b in zip(stick.pop("contact"), free.pop("contact"))
                  for k in ("u_nu", "u_tau", "lambda_nu", "reaction_nu", "reaction_tau"))
        free["contact_gap"] = stick["contact_gap"] = gap
    load = open("/proc/loadavg").read().split()[:3]
    lines = [f"Load average at the end: {' '.join(load)}; {comm.size} rank(s). Contact gap: "
             "the largest difference of the contact values between the two ties, every step.",
             "", "| scene | size | u unknowns | linear solver | radius-0 tie | Newton iterations "
             "per step (t_0 first) | contact gap | first loaded step: per iterate |F| and nodes "
             "with 0/1/2/3 active conditions |", "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        states = "; ".join(f"{f:.1e} {c[:3] if r['scene'] == 'paper' else c}"
                           for f, c in r["history"])
        lines.append(f"| {r['scene']} | {r['size']} | {r['unknowns']} | {r['solver']} | "
                     f"{r['tie']} | {r['iterations']} | {r['contact_gap']:.1e} | "
                     f"step {r['first_loaded_step']}: {states} |")
    if comm.rank == 0:
        write_results(f"first_step_np{comm.size}", rows, lines)


if __name__ == "__main__":
    main()
