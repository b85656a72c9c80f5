"""A hostile round on what a scene prescribes (run by hand:
python benchmarks/robustness/trust_round.py).

Each case is a scene a hostile but fair user could write: surface obstacles, prescribed laws
in x and t, friction coefficients, temperatures of a WLF shift, keys that only some scenes use,
repeated list entries, huge numbers. It is loaded and run through the Python interface (a small
mesh, a few steps, its output folder in a fresh working folder) and classed against what it
should give: refused naming a key, or run. The outcome classes are

- ``refused``: a SceneError naming the expected key (as it should);
- ``ran``: solved, every step written (as it should);
- ``silent wrong answer``: solved although the input means nothing or is wrong;
- ``internal error``: any other exception;
- ``refused documented input``: a SceneError for input the docs allow;
- ``wrong key``: refused, but naming another key;

and a case that writes anything outside its output folder is counted apart. The table goes to
benchmarks/results/trust_round.md (its counts in docs/reliability.md).
"""
import os
import pathlib
import sys
import tempfile
import time

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1]))  # benchmarks/: common.py
from common import write_results  # noqa: E402
from helpers import layer_on_surface  # noqa: E402

from mpi4py import MPI  # noqa: E402

from contactvisco.errors import SceneError  # noqa: E402
from contactvisco.scene import loader  # noqa: E402
from contactvisco.solver.time_loop import simulate  # noqa: E402

SMALL = ["geometry.cells=[6, 3]", "time.steps=3"]


def surface(distance: str) -> dict:
    """A layer [0, 2] x [0, 1] (its top held) on a surface obstacle that rises by 1e-3."""
    return layer_on_surface(distance, h=0.5, h_bottom=0.25, steps=2)


def wlf(temperature: str) -> dict:
    """A Prony block on a compliant foundation at a WLF temperature."""
    return {"name": "wlf",
            "geometry": {"lower": [0.0, 0.0], "upper": [2.0, 1.0], "cells": [4, 2]},
            "material": {"model": "plane_strain"},
            "viscoelastic": {"shear": {"instantaneous": 30.0, "tau": [1.0], "moduli": [10.0]},
                             "bulk": {"long_term": 50.0}, "shift": "wlf", "T_ref": 50.0,
                             "C1": 17.44, "C2": 51.6, "temperature": temperature},
            "dirichlet": [{"boundary": "left", "components": [0]}],
            "traction": [{"boundary": "top", "value": [0.0, -1.0]}],
            "contact": {"boundary": "bottom", "stiffness": 100.0, "g": 0.03},
            "time": {"T": 4.0, "steps": 8}, "output": {"probes": []}}


def cases() -> list:
    """(family, label, scene (name or raw dict), overrides, expected key or None: runs)."""
    out = []
    # 1. surface distances: a direction at every contact node, or refused
    refused = ["abs(x[1])", "abs(x[1]) + 0", "x[1]**2", "x[1]**4", "2.5", "-1.0", "0 * x[0]",
               "sqrt(x[1] - 0.2)", "ln(x[1] - 1)", "1e-5 * x[1]", "1e-4 * (x[1] + x[0])",
               "x[1] * abs(x[1])", "max(x[1], 0)**2", "sqrt(x[1]**2)", "abs(x[1] - 0)",
               "5e3 * x[1]", "x[1]**3"]
    ran = ["x[1]", "0.5 * x[1]", "2 * x[1]", "x[1] + 0.01 * (x[0] - 1)**2",
           "sqrt((x[0] - 1)**2 + (x[1] + 10)**2) - 10", "x[1] - 0.001 * sin(x[0])",
           "x[1] + 1e-3", "0.9 * x[1] + 0.1 * x[1]"]
    out += [("surface", f"distance {d!r}", surface(d), [], "obstacle.distance")
            for d in refused]
    out += [("surface", f"distance {d!r}", surface(d), [], None) for d in ran]
    # 2. prescribed normal laws in x and t (g = 0.01): negative somewhere refuses
    law = ["contact.stiffness=0", "contact.g=0.01"]
    for k in (0.5, 0.9, 2.0, 4.0, 8.0):
        expect = "contact.p_nu" if k * 1.0 * 1.0 > 1.0 else None     # x[0] <= 1, t <= 1
        out.append(("p_nu", f"2e3 s (1 - {k} x t)", "paper",
                    SMALL + law + [f"contact.p_nu='2e3 * s * (1 - {k} * x[0] * t)'"], expect))
    for text, expect in [("2e3 * s * (1 + x[0])", None), ("2e3 * s * (1 + t)", None),
                         ("2e3 * s * (x[0] - 0.5)", "contact.p_nu"),
                         ("2e3 * s * (0.5 - t)", "contact.p_nu"),
                         ("2e3 * s**1.5 * (1 + sin(10 * x[0]))", None),
                         ("2e3 * s * (1 + 2 * sin(10 * x[0]))", "contact.p_nu"),
                         ("conditional(x[0] > 0.7, 2e3 * s * (1.2 - 100 * s), 2e3 * s)",
                          "contact.p_nu"),
                         ("conditional(t > 0.5, 1e3 * s, 2e3 * s)", None),
                         ("2e3 * s + 1e-3 * x[0]", "contact.p_nu"),
                         ("1/(x[0] - 0.5) * s", "contact.p_nu")]:
        out.append(("p_nu", text, "paper", SMALL + law + [f"contact.p_nu='{text}'"], expect))
    for text, expect in [("0.3 * p_nu", None), ("0.3 * p_nu * (1 - 2 * x[0])", "contact.p_tau"),
                         ("0.3 * p_nu * (1 - 2 * t)", "contact.p_tau"),
                         ("0.3 * min(p_nu, 10 * x[0])", None),
                         ("0.3 * p_nu + 0.01 * x[0]", "contact.p_tau")]:
        out.append(("p_tau", text, "paper", SMALL + law + [
            "contact.p_nu='2e3 * s'", "contact.mu=0", f"contact.p_tau='{text}'"], expect))
    # 3. friction coefficients in x and t
    for text, expect in [("0.2 * x[0]", None), ("0.2 * (1 - x[0])", None),
                         ("0.2 / (t - 1/3)", "contact.mu"), ("0.2 / (x[0] - 0.5)", "contact.mu"),
                         ("0.2 * (x[0] - 0.5)", None), ("conditional(t > 0.5, 0.3, 0.0)", None),
                         ("0.2 / (x[0] - 1/3)", "contact.mu"), ("exp(x[0]) / 10", None)]:
        out.append(("mu", text, "paper", SMALL + [f"contact.mu='{text}'"], expect))
    # 4. WLF temperatures: a dip through the pole between step times (0.5 apart)
    for centre, width, depth, expect in [
            (0.75, 0.05, 60, "viscoelastic.temperature"), (1.25, 0.05, 60,
                                                           "viscoelastic.temperature"),
            (0.75, 0.05, 40, None), (2.3, 0.08, 70, "viscoelastic.temperature"),
            (3.6, 0.05, 55, "viscoelastic.temperature"), (0.75, 0.05, 5, None)]:
        text = f"50 - {depth} * exp(-((t - {centre}) / {width})**2)"
        out.append(("WLF", text, wlf(text), [], expect))
    out.append(("WLF", "50 + 2 * t", wlf("50 + 2 * t"), [], None))
    out.append(("WLF", "50 - 20 * t", wlf("50 - 20 * t"), [], "viscoelastic.temperature"))
    # 5. keys without a meaning in their scene
    meaningless = [("material.hencky_exponent=0.5", "material.hencky_exponent"),
                   ("material.hencky_exponent=-0.2", "material.hencky_exponent"),
                   ("material.hencky_strain=0.05", "material.hencky_strain"),
                   ("material.hencky_strain=1.0", "material.hencky_strain"),
                   ("contact.pairing='node_to_segment'", "contact.pairing"),
                   ("contact.search_distance=0.2", "contact.search_distance"),
                   ("contact.search_distance=1e-3", "contact.search_distance"),
                   ("contact.sliding_limit=0.1", "contact.sliding_limit"),
                   ("contact.sliding_limit=inf", "contact.sliding_limit")]
    for text, key in meaningless:
        out.append(("meaning", text, "paper", ["geometry.cells=[4, 2]", text], key))
    for text in ("material.hencky_exponent=1.0", "material.hencky_strain=0.01",
                 "contact.pairing='mortar'", "contact.sliding_limit=0.5"):
        out.append(("meaning", f"{text} (the default)", "paper",
                    ["geometry.cells=[4, 2]", "time.steps=1", text], None))
    out.append(("meaning", "hencky_exponent with law = hencky", "paper",
                ["geometry.cells=[4, 2]", "time.steps=1", "material.law='hencky'",
                 "material.hencky_exponent=0.5"], None))
    plane = ["contact.gap=0", "obstacle.shape='plane'", "obstacle.point=[0.0, 0.0]",
             "obstacle.normal=[0.0, 1.0]"]
    for extra, key in [("obstacle.centre=[0.0, 0.0]", "obstacle.centre"),
                       ("obstacle.radius=1.0", "obstacle.radius"),
                       ("obstacle.axis=[0.0, 1.0]", "obstacle.axis"),
                       ("obstacle.distance='x[1]'", "obstacle.distance"),
                       ("obstacle.boundary='top'", "obstacle.boundary")]:
        out.append(("meaning", f"plane with {extra}", "hertz", plane + [extra], key))
    cylinder = ["contact.gap=0", "obstacle.shape='cylinder'", "obstacle.centre=[0.0, -1.0]",
                "obstacle.radius=1.0"]
    for extra, key in [("obstacle.axis=[0.0, 0.0]", "obstacle.axis"),
                       ("obstacle.axis=[1.0, 0.0]", "obstacle.axis"),
                       ("obstacle.normal=[0.0, 1.0]", "obstacle.normal"),
                       ("obstacle.point=[0.0, 0.0]", "obstacle.point")]:
        out.append(("meaning", f"2D cylinder with {extra}", "hertz", cylinder + [extra], key))
    # 6. repeated and contradictory list entries
    for comps, values, key in [("[0, 0]", "[0.0, 1.0]", "dirichlet[0].components"),
                               ("[1, 1]", "[0.0, 0.0]", "dirichlet[0].components"),
                               ("[0, 1, 0]", "[0.0, 0.0, 0.0]", "dirichlet[0].components"),
                               ("[1, 0]", "[0.0, 0.0]", None)]:
        out.append(("repeats", f"components {comps}", "paper",
                    ["geometry.cells=[4, 2]", "time.steps=1", f"dirichlet.0.components={comps}",
                     f"dirichlet.0.value={values}"], key))
    out.append(("repeats", "contact boundary twice", "paper",
                ["contact.boundary=['bottom', 'bottom']"], "contact.boundary"))
    out.append(("repeats", "force components [1, 1]", "hertz",
                plane + ["obstacle.force_components=[1, 1]", "obstacle.force=[-0.1, -0.1]"],
                "obstacle.force_components"))
    # 7. numbers too large for the compiled forms
    for text, key in [("1e200 * x[1]", "obstacle.distance"), ("x[1] + 1e150", "obstacle.distance"),
                      ("1e99 * x[1] / 1e99", None)]:
        out.append(("numbers", text, surface(text), [], key))
    for text, expect in [("1e101 * t", "body_force.value"), ("1e100 * 0 + 1", None)]:
        out.append(("numbers", f"body force {text}", "paper",
                    SMALL + [f"body_force.value=[0.0, '{text}']"], expect))
    hencky = ["geometry.cells=[4, 2]", "time.steps=1", "material.law='hencky'"]
    out += [("numbers", "hencky_strain 1e-300 with law = hencky", "paper",
             hencky + ["material.hencky_strain=1e-300"], "material.hencky_strain"),
            ("numbers", "hencky_strain 1e101 with law = hencky", "paper",
             hencky + ["material.hencky_strain=1e101"], "material.hencky_strain"),
            ("numbers", "p_nu 1e150 * s", "paper", SMALL + law + ["contact.p_nu='1e150 * s'"],
             "contact.p_nu"),
            ("numbers", "mu 1e200 * x[0]", "paper", SMALL + ["contact.mu='1e200 * x[0]'"],
             "contact.mu")]
    for energy in ("57.69 / 2 * tr_eps**2 + 38.46 * dev_eps2",
                   "lmbda / 2 * tr_eps**2 + mu_lame * dev_eps2"):
        out.append(("energy", energy, "paper",
                    SMALL + ["material.law='energy'", f"material.energy='{energy}'",
                             "time.rule='trapezoid'"], None))
    return out


def run_case(family, label, scene, sets, expected) -> dict:
    """One case in a fresh working folder: its class, the key named, the time."""
    work = pathlib.Path(tempfile.mkdtemp(prefix="cv-trust-"))
    before = os.getcwd()
    os.chdir(work)
    start = time.perf_counter()
    key, message = None, ""
    try:
        resolved = (loader.load(scene, sets) if isinstance(scene, str)
                    else loader.resolve(scene, sets))
        simulate(resolved, out=work / "out", comm=MPI.COMM_SELF, progress=False)
        outcome = "ran" if expected is None else "silent wrong answer"
    except SceneError as err:
        key, message = err.key, str(err).splitlines()[0][:160]
        if expected is None:
            outcome = "refused documented input"
        else:
            outcome = "refused" if (key or "").startswith(expected) else "wrong key"
    except Exception as err:             # noqa: BLE001 - the class being counted
        outcome, message = "internal error", f"{type(err).__name__}: {err}"[:160]
    finally:
        os.chdir(before)
    outside = sorted(str(p.relative_to(work)) for p in work.rglob("*")
                     if p != work / "out" and work / "out" not in p.parents)
    return {"family": family, "case": label, "expected": expected or "runs", "outcome": outcome,
            "key": key, "message": message, "outside": outside,
            "seconds": round(time.perf_counter() - start, 2)}


def main():
    rows = [run_case(*case) for case in cases()]
    counts = {}
    for row in rows:
        counts[row["outcome"]] = counts.get(row["outcome"], 0) + 1
    outside = sum(1 for row in rows if row["outside"])
    lines = [f"# Trust round: {len(rows)} cases", "",
             "| outcome | cases |", "|---|---|"]
    lines += [f"| {name} | {count} |" for name, count in sorted(counts.items())]
    lines += [f"| wrote outside its output folder | {outside} |", "",
              "| family | case | expected | outcome | key | seconds |", "|---|---|---|---|---|---|"]
    lines += [f"| {r['family']} | `{r['case']}` | {r['expected']} | {r['outcome']} | "
              f"{r['key'] or ''} | {r['seconds']} |" for r in rows]
    bad = [r for r in rows if r["outcome"] not in ("refused", "ran")]
    if bad:
        lines += ["", "Cases that fall short:", ""]
        lines += [f"- {r['family']} `{r['case']}`: {r['outcome']}: {r['message']}" for r in bad]
    write_results("trust_round", rows, lines)


if __name__ == "__main__":
    main()
