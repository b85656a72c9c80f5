"""Stability at the extremes (run by hand: python benchmarks/robustness/extremes.py).

Each parameter is pushed to its ends on the paper scene (16 x 16, so the study stays fast) and
on a scene where part of the contact boundary separates (the paper scene pulled up at its
right half). Every case either converges, recovers by step cutting, or stops with a message.
The table goes to benchmarks/results/extremes.md (and docs/extremes.md).
"""
import json
import pathlib
import sys
import time

from mpi4py import MPI

from contactvisco.model.stability import stability_number
from contactvisco.errors import SceneError
from contactvisco.scene import loader as scene_module
from contactvisco.solver.time_loop import simulate
from contactvisco.solver.newton import NewtonFailure

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1]))  # benchmarks/: common.py
from common import write_results  # noqa: E402

# The study runs the paper's rule past its stability limit on purpose (marked in the table).
BASE = ["geometry.cells=[16, 16]", "output.probes=[[1.0, 1.0], [1.0, 0.0]]",
        "time.allow_unstable=true"]
# The paper scene with the right half of its top pulled up: 10 of 17 contact nodes separate,
# 7 stay in normal compliance.
LIFT = ["traction.0.value=[0.0, 'conditional(x[0] > 0.5, 24.0, -20.0)']"]

CASES = [
    ("compliance stiffness", "contact.stiffness", [1e-4, 1e-2, 1.0, 1e2, 1e4, 1e6, 1e8]),
    ("augmentation r", "contact.augmentation", [1e-4, 1e-2, 1.0, 1e2, 1e4, 1e6, 1e8]),
    ("alpha (paper rule, k = 0.1)", "memory.alpha", [0.0, 1.0, 1e2, 1e3, 1e4, 1e5]),
    ("alpha (trapezoid, k = 0.1)", "memory.alpha", [1e3, 1e4, 1e5]),
    ("mu", "contact.mu", [0.0, 0.01, 0.2, 0.5, 1.0, 2.0]),
    ("g", "contact.g", [1e-8, 1e-4, 1e-2, 0.05, 1.0, 1e3, "inf"]),
    ("nu (plane strain)", "material.nu", [0.0, 0.3, 0.45, 0.49, 0.499, 0.4999]),
    ("mesh cells per side", "geometry.cells", [[2, 2], [4, 4], [64, 64]]),
]
TIME = [  # (label, overrides)
    ("k = 1e-6 (T = 1e-5, 10 steps)", ["time.T=1e-5", "time.steps=10"]),
    ("k = 10, paper rule (T = 100)", ["time.T=100.0", "time.steps=10"]),
    ("k = 10, trapezoid (T = 100)", ["time.T=100.0", "time.steps=10", "time.rule='trapezoid'"]),
    ("T = 1000, 100 steps, trapezoid", ["time.T=1000.0", "time.steps=100",
                                        "time.rule='trapezoid'"]),
    ("T = 1000, 100 steps, paper rule", ["time.T=1000.0", "time.steps=100"]),
] + [(f"3D block, nu = {nu}", ["3d", nu]) for nu in (0.0, 0.3, 0.49, 0.4999)]


def run(label, overrides, comm):
    tick = time.perf_counter()
    try:
        if overrides[0] == "3d":
            scene = scene_module.load("block3d", ["geometry.parameters.h=0.25",
                                                  f"material.nu={overrides[1]}", "time.steps=3"])
        else:
            scene = scene_module.load("paper", BASE + overrides)
        b = stability_number(scene) if scene["time"]["rule"] == "paper" else 0.0
        result = simulate(scene, comm=comm, progress=False)
    except SceneError as err:
        return dict(label=label, outcome="refused", message=str(err), seconds=0.0)
    except NewtonFailure as err:
        return dict(label=label, outcome="stopped", message=str(err).split("; residual")[0],
                    seconds=time.perf_counter() - tick)
    steps = result.steps
    cuts = sum(1 for s in steps if s["cuts"])
    final = steps[-1]
    size = max((abs(v) for p in final["probes"] for v in p["u"]), default=0.0)
    return dict(label=label, outcome="recovered" if cuts else "converged", b=b, max_u=size,
                newton_max=max(s["newton_iterations"] for s in steps),
                newton_mean=sum(s["newton_iterations"] for s in steps) / len(steps),
                cut_steps=cuts, states="/".join(str(v) for v in final["status_counts"].values()),
                seconds=time.perf_counter() - tick)


def main():
    comm = MPI.COMM_WORLD
    rows = []
    for scene_label, extra in (("paper", []), ("separating", LIFT)):
        for name, key, values in CASES:
            for value in values:
                rule = ["time.rule='trapezoid'"] if "trapezoid" in name else []
                text = f"{key}={json.dumps(value) if not isinstance(value, str) else value}"
                rows.append(dict(run(f"{name}: {value}", extra + rule + [text], comm),
                                 scene=scene_label))
        for label, overrides in TIME:
            if scene_label == "separating" and "3D" in label:
                continue
            rows.append(dict(run(label, extra + overrides, comm), scene=scene_label))
    if comm.rank == 0:
        lines = ["| scene | case | outcome | Newton max/mean | cut steps | final sep/compl/bound "
                 "| max abs u at the probes | paper-rule b | message |",
                 "|---|---|---|---|---|---|---|---|---|"]
        for r in rows:
            newton = (f"{r['newton_max']}/{r['newton_mean']:.1f}" if "newton_max" in r else "")
            outcome = r["outcome"]
            if r.get("b", 0) >= 1:
                outcome += " (warned: unstable rule)"
            lines.append(f"| {r['scene']} | {r['label']} | {outcome} | {newton} | "
                         f"{r.get('cut_steps', '')} | {r.get('states', '')} | "
                         f"{r['max_u']:.3g} | {r['b']:.3g} | " if "max_u" in r else
                         f"| {r['scene']} | {r['label']} | {outcome} | | | | | | ")
            lines[-1] += f"{r.get('message', '')} |"
        write_results("extremes", rows, lines)


if __name__ == "__main__":
    main()
