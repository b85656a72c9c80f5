"""The cost of forward sensitivities and of a fit with them (run by hand:
.venv/bin/python benchmarks/accuracy/identification.py, or under mpirun -n 2 for part 1).

1. One forward run of sphere_creep (its own mesh, 12 steps to T = 3 tau, force held) with
   the sensitivities of n = 1, 2 and 4 parameters (mu_0, the relaxing fraction, its tau, the
   bulk modulus) against one plain run of the same built problem (ForwardModel), CPU time of
   each measured side by side in one process, best of three after a warm-up run (which
   compiles the derivative forms); the goal is a ratio of at most 1 + 0.3 n. Also the
   factorizations of the sensitivities' own Newton matrix (one per step whose matrix changed).
2. The fit of the tests (sphere_creep on a coarse mesh, 13 samples of noise-free creep made
   by a whole run, mu_0, the fraction and tau started 30 % off) with the Jacobian of the
   sensitivities and with central differences: forward runs, the optimizer's residual and
   Jacobian evaluations, wall time and the largest relative error of the estimates
   (1 rank only).

3. Coverage (`identification.py coverage`, 1 rank): mu_0 and the fraction from 13 samples
   of creep with 1 % Gaussian noise on the depth (sigma = 1e-4, noise = sigma in the fit),
   20 seeds, sensitivities: how often the truth lies in the 95 % interval
   estimate +- t_0.975(m - n) standard error (the issue's goal: at least 17 of 20).

Writes benchmarks/results/identification[_np<ranks>].{json,md} (parts 1 and 2) or
identification_coverage.{json,md} (part 3).
"""
import os
import pathlib
import sys
import tempfile
import time

import numpy as np
from mpi4py import MPI

from contactvisco.scene import loader
from contactvisco.solver.sensitivity import ForwardModel
from contactvisco.studies import identification as ident

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1]))  # benchmarks/: common.py
from common import write_results  # noqa: E402

COMM = MPI.COMM_WORLD
THETA = {"viscoelastic.shear.instantaneous": 0.38461538461538464,
         "viscoelastic.shear.fractions.0": 0.5, "viscoelastic.shear.tau.0": 1.0,
         "viscoelastic.bulk.instantaneous": 0.8333333333333334}
COARSE = ('geometry.parameters={radius = 10.0, height = 10.0, h_contact = 0.04, h_far = 3.0, '
          'refine = 0.3, growth = 0.15}')


def scene(values, sets=()):
    return loader.load("sphere_creep", ["output.figures=false", *sets]
                       + [f"{k}={v!r}" for k, v in values.items()])


def cpu(run) -> float:
    """CPU seconds of run(), the largest over the ranks."""
    COMM.Barrier()
    tick = time.process_time()
    run()
    return COMM.allreduce(time.process_time() - tick, op=MPI.MAX)


def cost() -> list:
    model = ForwardModel(scene(THETA), COMM)
    rows = []
    try:
        base = scene(THETA)
        for n in (1, 2, 4):
            keys = list(THETA)[:n]
            tangents = []
            for key in keys:
                h = 1e-5 * THETA[key]
                tangents.append((scene({**THETA, key: THETA[key] + h}),
                                 scene({**THETA, key: THETA[key] - h}), 2 * h))
            model.run(base, tangents)                      # compiles the forms
            plain, sens = [], []
            for _ in range(3):
                plain.append(cpu(lambda: model.run(base)))
                before = model.sensitivity.factorizations
                sens.append(cpu(lambda: model.run(base, tangents)))
                factorizations = model.sensitivity.factorizations - before
            ratio = min(sens) / min(plain)
            rows.append({"parameters": n, "plain_cpu_s": min(plain),
                         "sensitivities_cpu_s": min(sens), "ratio": ratio,
                         "goal": 1 + 0.3 * n, "factorizations": factorizations,
                         "steps": len(model.run(base)["t"]) - 1,
                         "unknowns": model.problem.count_unknowns()})
    finally:
        model.destroy()
    return rows


def fits() -> list:
    rows = []
    names = {"viscoelastic.shear.instantaneous": ("log", [0.05, 2.0]),
             "viscoelastic.shear.fractions.0": ("linear", [0.05, 0.9]),
             "viscoelastic.shear.tau.0": ("log", [0.1, 10.0])}
    start = {"viscoelastic.shear.instantaneous": 0.7 * THETA["viscoelastic.shear.instantaneous"],
             "viscoelastic.shear.fractions.0": 0.35, "viscoelastic.shear.tau.0": 1.3}
    times = np.linspace(0.0, 3.0, 13)
    for jacobian in ("sensitivities", "finite-differences"):
        with tempfile.TemporaryDirectory() as folder:
            folder = pathlib.Path(folder)
            (folder / "data.csv").write_text("t,force,depth\n" + "".join(
                f"{float(t)!r},-0.0015,0\n" for t in times))
            text = (f'[fit]\njacobian = "{jacobian}"\n\n[[experiment]]\nscene = '
                    f'"sphere_creep"\ndata = "data.csv"\nset = [\'{COARSE}\']\nweight = 1e10\n\n')
            for key, (scale, bounds) in names.items():
                text += (f'[[parameter]]\nkey = "{key}"\ninitial = {start[key]!r}\n'
                         f'bounds = {bounds!r}\nscale = "{scale}"\n\n')
            (folder / "fit.toml").write_text(text)
            spec = ident.read_fit(folder / "fit.toml")
            (experiment,) = spec["experiments"]
            experiment["depth"] = ident.forward(experiment, spec["parameters"],
                                                [THETA[k] for k in names])
            report = ident.fit(spec)
        error = max(abs(p["estimate"] / THETA[p["key"]] - 1) for p in report["parameters"])
        rows.append({"jacobian": jacobian, "evaluations": report["evaluations"],
                     "residual_evaluations": report["residual_evaluations"],
                     "jacobian_evaluations": report["jacobian_evaluations"],
                     "wall_s": report["wall_s"], "max_relative_error": error,
                     "success": report["success"]})
    return rows


def coverage(seeds: int = 20) -> list:
    from scipy import stats
    sigma, times = 1e-4, np.linspace(0.0, 3.0, 13)
    names = {"viscoelastic.shear.instantaneous": ("log", [0.05, 2.0], 0.3),
             "viscoelastic.shear.fractions.0": ("linear", [0.05, 0.9], 0.4)}
    rows = []
    with tempfile.TemporaryDirectory() as folder:
        folder = pathlib.Path(folder)
        (folder / "data.csv").write_text("t,force,depth\n" + "".join(
            f"{float(t)!r},-0.0015,0\n" for t in times))
        text = (f'[[experiment]]\nscene = "sphere_creep"\ndata = "data.csv"\nset = '
                f'[\'{COARSE}\']\nnoise = {sigma!r}\n\n')
        for key, (scale, bounds, initial) in names.items():
            text += (f'[[parameter]]\nkey = "{key}"\ninitial = {initial!r}\n'
                     f'bounds = {bounds!r}\nscale = "{scale}"\n\n')
        (folder / "fit.toml").write_text(text)
        spec = ident.read_fit(folder / "fit.toml")
        (experiment,) = spec["experiments"]
        exact = ident.forward(experiment, spec["parameters"], [THETA[k] for k in names])
        quantile = stats.t.ppf(0.975, len(times) - len(names))
        for seed in range(seeds):
            experiment["depth"] = exact + sigma * np.random.default_rng(seed).standard_normal(
                exact.size)
            report = ident.fit(spec)
            row = {"seed": seed, "s2": report["s2"], "evaluations": report["evaluations"],
                   "wall_s": report["wall_s"]}
            for p in report["parameters"]:
                half = quantile * p["standard_error"]
                row[p["key"]] = {"estimate": p["estimate"], "standard_error":
                                 p["standard_error"],
                                 "inside": abs(p["estimate"] - THETA[p["key"]]) <= half}
            rows.append(row)
    return rows


def main_coverage():
    load = os.getloadavg()[0]
    rows = coverage()
    keys = [k for k in rows[0] if k.startswith("viscoelastic")]
    lines = [f"# Coverage of the 95 % intervals (20 seeds, 1 % noise; load average {load:.1f} "
             "on 2 cores)", "",
             "mu_0 and the relaxing fraction of sphere_creep (coarse mesh) from 13 samples of "
             "creep with Gaussian noise sigma = 1e-4 on the depth (1 % of it), sensitivities:",
             "", "| parameter | truth inside estimate +- t_0.975(11) s.e. | median s.e. / truth |",
             "|---|---|---|"]
    for key in keys:
        inside = sum(r[key]["inside"] for r in rows)
        median = float(np.median([r[key]["standard_error"] for r in rows])) / THETA[key]
        lines.append(f"| {key} | {inside} of {len(rows)} | {median:.2%} |")
    lines += ["", f"Forward runs per fit: {min(r['evaluations'] for r in rows)} to "
              f"{max(r['evaluations'] for r in rows)}; wall per fit "
              f"{np.mean([r['wall_s'] for r in rows]):.1f} s on average; s^2 from "
              f"{min(r['s2'] for r in rows):.2f} to {max(r['s2'] for r in rows):.2f}."]
    write_results("identification_coverage", {"load": load, "fits": rows}, lines,
                  default=bool)


def main():
    load = os.getloadavg()[0]
    rows = {"ranks": COMM.size, "load": load, "cost": cost()}
    if COMM.size == 1:
        rows["fits"] = fits()
    if COMM.rank:
        return
    lines = [f"# Forward sensitivities: cost and fits ({COMM.size} rank(s), load average "
             f"{load:.1f} on 2 cores)", "",
             "One run of sphere_creep (12 steps) with the sensitivities of n parameters "
             "against one plain run of the same built problem (CPU s, best of 3):", "",
             "| n | plain run | with sensitivities | ratio | goal 1 + 0.3 n | "
             "factorizations for the sensitivities |", "|---|---|---|---|---|---|"]
    for r in rows["cost"]:
        lines.append(f"| {r['parameters']} | {r['plain_cpu_s']:.3f} | "
                     f"{r['sensitivities_cpu_s']:.3f} | {r['ratio']:.2f} | {r['goal']:.1f} | "
                     f"{r['factorizations']} of {r['steps'] + 1} states |")
    if "fits" in rows:
        lines += ["", "Fit of mu_0, fraction, tau from 30 % off (13 noise-free samples, coarse "
                  "mesh):", "", "| Jacobian | forward runs | residual evaluations | Jacobian "
                  "evaluations | wall s | largest relative error |", "|---|---|---|---|---|---|"]
        for r in rows["fits"]:
            lines.append(f"| {r['jacobian']} | {r['evaluations']} | "
                         f"{r['residual_evaluations']} | {r['jacobian_evaluations']} | "
                         f"{r['wall_s']:.1f} | {r['max_relative_error']:.1e} |")
    suffix = "" if COMM.size == 1 else f"_np{COMM.size}"
    write_results(f"identification{suffix}", rows, lines)


if __name__ == "__main__":
    main_coverage() if sys.argv[1:] == ["coverage"] else main()
