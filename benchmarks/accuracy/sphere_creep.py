"""The sphere_creep scene under refinement, and the cost of the same accuracy in 3D (run by
hand: .venv/bin/python benchmarks/accuracy/sphere_creep.py).

1. sphere_creep (a/R = 0.1, a rigid sphere under a force held from t = 0, 12 steps of the
   exponential rule to T = 3 tau) with h = a/n at the contact, n = 4, 6 (the scene's) and 12,
   the sizes growing at 0.42/n of the distance: unknowns (u and the multipliers), Newton
   iterations per step, wall time of the run, and the errors of delta(t) against Lee and
   Radok's closed form (studies.indentation.SphereLeeRadok: delta = a^2/R, a^3 = 3 R P C(t)/4)
   over the steps, of the depth itself (which keeps the exact sphere's departure from Hertz's
   paraboloid, about 0.18 a/R, and the block's finite size) and of the creep ratio
   delta(t)/delta(0).
2. The cost ratio of axisymmetry to 3D at the same accuracy (studies.revolution: the elastic
   sphere on a cylinder in both models, errors of the total force against the axisymmetric
   run at a/32): unknowns and wall time of each run.

Writes benchmarks/results/sphere_creep.{json,md}.
"""
import pathlib
import sys
import time

import numpy as np
from mpi4py import MPI

from contactvisco.scene import loader
from contactvisco.solver.time_loop import simulate
from contactvisco.studies.indentation import SphereLeeRadok
from contactvisco.studies.revolution import sphere_on_cylinder

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1]))  # benchmarks/: common.py
from common import write_results  # noqa: E402

COMM = MPI.COMM_WORLD
A = 0.1


def creep(n: int) -> dict:
    """sphere_creep at h = a/n: its size, cost and errors (module description)."""
    scene = loader.load("sphere_creep", [f"geometry.parameters.h_contact={A / n!r}",
                                         f"geometry.parameters.growth={0.42 / n!r}",
                                         "output.xdmf=false", "output.figures=false"])
    start = time.perf_counter()
    result = simulate(scene, comm=COMM, progress=False)
    wall = COMM.allreduce(time.perf_counter() - start, op=MPI.MAX)
    t = np.array([step["t"] for step in result.steps])
    depth = -np.array([step["obstacle"]["displacement"][1] for step in result.steps])
    shear = scene["viscoelastic"]["shear"]
    R = scene["obstacle"]["radius"]
    closed = SphereLeeRadok(scene["material"]["E"], scene["material"]["nu"],
                            -2.0 * shear["fractions"][0] * shear["instantaneous"],
                            shear["tau"][0], R)
    exact = closed.radius(-scene["obstacle"]["force"][0], t) ** 2 / R
    return {"n": n, "unknowns": sum(result.problem.count_unknowns().values()),
            "newton_per_step": float(np.mean([s["newton_iterations"]
                                              for s in result.steps[1:]])),
            "wall_s": wall, "depth_error": float(np.max(np.abs(depth / exact - 1.0))),
            "ratio_error": float(np.max(np.abs((depth / depth[0]) / (exact / exact[0]) - 1.0)))}


def main():
    out = {"creep": [creep(n) for n in (4, 6, 12)]}
    lines = ["## sphere_creep under refinement (a/R = 0.1, 12 steps to T = 3 tau)", "",
             "| a/h | unknowns | Newton per step | wall s | max depth error | "
             "max creep ratio error |", "|---|---|---|---|---|---|"]
    lines += [f"| {r['n']} | {r['unknowns']} | {r['newton_per_step']:.2f} | "
              f"{r['wall_s']:.2f} | {r['depth_error']:.2%} | {r['ratio_error']:.3%} |"
              for r in out["creep"]]
    reference = sphere_on_cylinder("axisymmetric", 32, comm=COMM)
    runs = [dict(sphere_on_cylinder(model, n, comm=COMM), model=model, n=n)
            for model, sizes in (("axisymmetric", (4, 8, 16)), ("3d", (2, 4, 8, 16)))
            for n in sizes]
    for run in runs:
        run["error"] = abs(run["P"] / reference["P"] - 1.0)
    out["revolution"] = {"reference": reference, "runs": runs}
    lines += ["", "## The same accuracy in axisymmetry and in 3D (elastic sphere on a "
              "cylinder, studies.revolution)", "",
              f"Reference: the axisymmetric run at a/32, P = {reference['P']:.6e} "
              f"({reference['unknowns']} unknowns).", "",
              "| model | a/h | unknowns | wall s | P error |", "|---|---|---|---|---|"]
    lines += [f"| {r['model']} | {r['n']} | {r['unknowns']} | {r['wall_s']:.2f} | "
              f"{r['error']:.2%} |" for r in runs]
    if COMM.rank == 0:
        write_results("sphere_creep", out, lines, default=float)


if __name__ == "__main__":
    main()
