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

2b. The fit of two experiments (creep under P and 2P, 13 samples each, mu_0 and the
   fraction 20 % off, sensitivities) with fit.communicators = "split" and "shared": wall time
   of the whole fit, best of 3 (on 1 rank both are the same fit; on 2 ranks "split" runs one
   experiment per rank, "shared" both on both ranks).

Wall and CPU times are the largest over the ranks, best of 3; the 1-minute load average is
written before and after each part (the machine is shared). Under Open MPI a rank waiting
in a collective spins: with OMPI_MCA_mpi_yield_when_idle=1 (written in the header when set)
it yields the core, so that its CPU time is closer to its work.

3. Coverage (`identification.py coverage`, 1 rank): mu_0 and the fraction from 13 samples
   of creep with 1 % Gaussian noise on the depth (sigma = 1e-4, noise = sigma in the fit),
   20 seeds, sensitivities: how often the truth lies in the 95 % interval
   estimate +- t_0.975(m - n) standard error (the issue's goal: at least 17 of 20).

Writes benchmarks/results/identification[_np<ranks>].{json,md} (parts 1 and 2) or
identification_coverage.{json,md} (part 3). identification_np2_spin.{json,md} is the 2-rank
output without OMPI_MCA_mpi_yield_when_idle (Open MPI's default busy waiting), renamed;
identification_np2 the one with it.
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
    return timed(run)[0]


def timed(run) -> tuple:
    """(CPU s, wall s) of run(), each the largest over the ranks."""
    COMM.Barrier()
    tick, wall = time.process_time(), time.perf_counter()
    run()
    return (COMM.allreduce(time.process_time() - tick, op=MPI.MAX),
            COMM.allreduce(time.perf_counter() - wall, op=MPI.MAX))


def load() -> float:
    return os.getloadavg()[0]


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
            before_load = load()
            for _ in range(3):
                plain.append(timed(lambda: model.run(base)))
                before = model.sensitivity.factorizations
                sens.append(timed(lambda: model.run(base, tangents)))
                factorizations = model.sensitivity.factorizations - before
            plain_cpu, sens_cpu = min(c for c, _ in plain), min(c for c, _ in sens)
            plain_wall, sens_wall = min(w for _, w in plain), min(w for _, w in sens)
            rows.append({"parameters": n, "plain_cpu_s": plain_cpu,
                         "sensitivities_cpu_s": sens_cpu, "ratio": sens_cpu / plain_cpu,
                         "plain_wall_s": plain_wall, "sensitivities_wall_s": sens_wall,
                         "wall_ratio": sens_wall / plain_wall,
                         "load": [before_load, load()],
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


def split_fits(repeats: int = 3) -> list:
    """Part 2b: the two-experiment fit, split and shared, wall time best of `repeats`."""
    names = {"viscoelastic.shear.instantaneous": ("log", [0.05, 2.0], 0.31),
             "viscoelastic.shear.fractions.0": ("linear", [0.05, 0.9], 0.4)}
    times = np.linspace(0.0, 3.0, 13)
    rows = []
    folder = pathlib.Path(tempfile.mkdtemp() if COMM.rank == 0 else "")
    folder = pathlib.Path(COMM.bcast(str(folder), root=0)) / f"rank{COMM.rank}"
    folder.mkdir(parents=True, exist_ok=True)
    text = '[fit]\ncommunicators = "MODE"\n\n'
    for k, factor in enumerate((1.0, 2.0)):
        (folder / f"data{k}.csv").write_text("t,force,depth\n" + "".join(
            f"{float(t)!r},{-0.0015 * factor!r},0\n" for t in times))
        text += (f'[[experiment]]\nscene = "sphere_creep"\ndata = "data{k}.csv"\n'
                 f"set = ['{COARSE}']\nweight = 1e10\n\n")
    for key, (scale, bounds, initial) in names.items():
        text += (f'[[parameter]]\nkey = "{key}"\ninitial = {initial!r}\n'
                 f'bounds = {bounds!r}\nscale = "{scale}"\n\n')
    for mode in ("split", "shared") if COMM.size > 1 else ("shared",):
        (folder / "fit.toml").write_text(text.replace("MODE", mode))
        spec = ident.read_fit(folder / "fit.toml")
        for e in spec["experiments"]:
            e["depth"] = ident.forward(e, spec["parameters"],
                                       [THETA[k] for k in names], MPI.COMM_SELF)
        walls, before_load = [], load()
        for _ in range(repeats):
            COMM.Barrier()
            report = ident.fit(spec, comm=COMM)
            walls.append(COMM.allreduce(report["wall_s"], op=MPI.MAX))
        error = max(abs(p["estimate"] / THETA[p["key"]] - 1) for p in report["parameters"])
        rows.append({"mode": mode, "groups": report["communicators"]["groups"],
                     "wall_s": min(walls), "walls_s": walls,
                     "evaluations": report["evaluations"], "max_relative_error": error,
                     "estimates": [p["estimate"] for p in report["parameters"]],
                     "load": [before_load, load()]})
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
    start_load = load()
    yield_idle = os.environ.get("OMPI_MCA_mpi_yield_when_idle")
    rows = {"ranks": COMM.size, "load": start_load, "yield_when_idle": yield_idle,
            "cost": cost(), "split_fits": split_fits()}
    if COMM.size == 1:
        rows["fits"] = fits()
    rows["end_load"] = load()
    if COMM.rank:
        return
    lines = [f"# Forward sensitivities: cost and fits ({COMM.size} rank(s), load average "
             f"{start_load:.1f} at the start, {rows['end_load']:.1f} at the end, on 2 cores"
             + (f"; OMPI_MCA_mpi_yield_when_idle={yield_idle}" if yield_idle else "") + ")",
             "", "One run of sphere_creep (12 steps) with the sensitivities of n parameters "
             "against one plain run of the same built problem (best of 3, the largest over "
             "the ranks; load average before and after each row):", "",
             "| n | plain run CPU s | with sensitivities CPU s | CPU ratio | plain run wall s | "
             "with sensitivities wall s | wall ratio | goal 1 + 0.3 n | factorizations for "
             "the sensitivities | load |", "|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows["cost"]:
        lines.append(f"| {r['parameters']} | {r['plain_cpu_s']:.3f} | "
                     f"{r['sensitivities_cpu_s']:.3f} | {r['ratio']:.2f} | "
                     f"{r['plain_wall_s']:.3f} | {r['sensitivities_wall_s']:.3f} | "
                     f"{r['wall_ratio']:.2f} | {r['goal']:.1f} | "
                     f"{r['factorizations']} of {r['steps'] + 1} states | "
                     f"{r['load'][0]:.1f}-{r['load'][1]:.1f} |")
    lines += ["", "Fit of mu_0 and the fraction from two creep experiments (P and 2P, 13 "
              "samples each, 20 % off, sensitivities), fit.communicators, wall s best of 3:",
              "", "| mode | groups | wall s | runs of the fit (walls) | forward runs | largest "
              "relative error | load |", "|---|---|---|---|---|---|---|"]
    for r in rows["split_fits"]:
        lines.append(f"| {r['mode']} | {r['groups']} | {r['wall_s']:.2f} | "
                     f"{', '.join(f'{w:.2f}' for w in r['walls_s'])} | {r['evaluations']} | "
                     f"{r['max_relative_error']:.1e} | {r['load'][0]:.1f}-{r['load'][1]:.1f} |")
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
