"""A hostile round on what a scene prescribes (run by hand:
python benchmarks/robustness/trust_round.py).

Each case is a scene a hostile but fair user could write: surface obstacles, prescribed laws
in x and t, friction coefficients, temperatures of a WLF shift, keys that only some scenes use,
repeated list entries, huge numbers, force control that cannot be balanced, obstacles that
start inside the body, whole tables given by --set. It is loaded and run through the Python interface (a small
mesh, a few steps, its output folder in a fresh working folder) and classed against what it
should give: refused naming a key, or run. The outcome classes are

- ``refused``: a SceneError naming the expected key (as it should);
- ``ran``: solved, every step written (as it should);
- ``silent wrong answer``: solved although the input means nothing or is wrong;
- ``internal error``: any other exception;
- ``refused documented input``: a SceneError for input the docs allow;
- ``wrong key``: refused, but naming another key;
- ``misleading message``: the right key, but not the words of the case's cause (force
  control's failures share their key, obstacle.force, and differ by cause);

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
from contactvisco.solver.newton import NewtonFailure  # noqa: E402
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


def layer(obstacle: dict, steps: int = 4, mu: float = 0.0, law: str = "compliance") -> dict:
    """A layer [0, 2] x [0, 1], its top held, on a rigid obstacle below (E = 200)."""
    return {"name": "layer", "geometry": {"type": "gmsh", "script": "rectangle",
            "parameters": {"length": 2.0, "height": 1.0, "h": 0.2, "h_bottom": 0.05}},
            "material": {"model": "plane_strain", "E": 200.0, "nu": 0.3},
            "dirichlet": [{"boundary": "top", "components": "all"}],
            "contact": {"boundary": "bottom", "g": 0.0, "mu": mu, "augmentation": 200.0,
                        "friction_law": law},
            "obstacle": obstacle, "time": {"T": 1.0, "steps": steps},
            "output": {"probes": [], "xdmf": False}}


def cylinder(dy: float = 0.0, **keys) -> dict:
    """A cylinder of radius 1 under the layer, touching it at (1, 0) when dy = 0."""
    return {"shape": "cylinder", "centre": [1.0, -1.0 + dy], "radius": 1.0, **keys}


def plane(y: float = 0.0, **keys) -> dict:
    return {"shape": "plane", "point": [0.0, y], "normal": [0.0, 1.0], **keys}


#: The words of each force-control failure (the key alone does not tell them apart).
PULLS, THROUGH, OUT = "pulls the obstacle away", "passes through the body", "out of contact"
FRICTION, FLOATS, NEWTON = "acts along the contact surface", "the body floats", "bordered"


def force_cases() -> list:
    """Force control that cannot be balanced, each failure with its words; force control
    that can; obstacles that start inside the body; whole tables given by --set."""
    out = []
    for text, words in [("-0.1 * t", PULLS), ("-1e-3 * t", PULLS), ("-10 * t", PULLS),
                        ("400 * t", THROUGH), ("2e3 * t", THROUGH), ("1e5 * t", THROUGH)]:
        out.append(("force", f"cylinder force {text}",
                    layer(cylinder(force_components=[1], force=[text])), [],
                    f"obstacle.force|{words}"))
    out.append(("force", "plane force -0.1 * t", layer(plane(force_components=[1],
                                                             force=["-0.1 * t"])), [],
                f"obstacle.force|{PULLS}"))
    for dy in (-0.01, -0.1):
        out.append(("force", f"cylinder {-dy} below the layer, force 0.1 * t",
                    layer(cylinder(dy, force_components=[1], force=["0.1 * t"])), [],
                    f"obstacle.force|{OUT}"))
    out.append(("force", "plane 0.05 below the layer, force 0.1 * t",
                layer(plane(-0.05, force_components=[1], force=["0.1 * t"])), [],
                f"obstacle.force|{OUT}"))
    for q, mu in (("0.2 * t", 0.3), ("1.0 * t", 0.1)):
        out.append(("force", f"plane P = 0.2, Q = {q}, mu = {mu}",
                    layer(plane(force_components=[1, 0], force=["0.2", q]), mu=mu,
                          law="coulomb"), [], f"obstacle.force|{FRICTION}"))
    hertz = ["contact.gap=0", "obstacle.shape='plane'", "obstacle.point=[0.0, 0.0]",
             "obstacle.normal=[0.0, 1.0]", "obstacle.force_components=[1]", "time.steps=2",
             "geometry.parameters.h_contact=0.02"]
    for text in ("0.25 * t", "0.25", "0.5"):
        out.append(("force", f"hertz disk held by a plane alone, force {text}", "hertz",
                    hertz + [f"obstacle.force=['{text}']"], f"obstacle.force|{FLOATS}"))
    newton = layer(cylinder(force_components=[1], force=["80 * t"]), steps=1)
    newton["solver"] = {"max_cuts": 0, "petsc_options": {"snes_max_it": 2}}
    out.append(("force", "force 80 in one step, 2 Newton iterations, no cut", newton, [],
                f"obstacle.force|{NEWTON}"))
    for label, raw in [
            ("cylinder force 0.2 * t", layer(cylinder(force_components=[1], force=["0.2 * t"]))),
            ("cylinder force 8 * t", layer(cylinder(force_components=[1], force=["8 * t"]))),
            ("cylinder 0.001 inside, force 0.2 * t",
             layer(cylinder(0.001, force_components=[1], force=["0.2 * t"]))),
            ("plane P = 0.2, Q = 0.03 * t, mu = 0.3",
             layer(plane(force_components=[1, 0], force=["0.2", "0.03 * t"]), mu=0.3,
                   law="coulomb"))]:
        out.append(("force", label, raw, [], None))
    # obstacles that start inside the body (L = 2 for the layer, 1 for the disk)
    for label, raw, key in [
            ("cylinder 0.5 inside, moved", layer(cylinder(0.5, displacement=[0.0, "1e-3 * t"])),
             "obstacle.centre"),
            ("cylinder 0.85 inside, force", layer(cylinder(0.85, force_components=[1],
                                                           force=["0.1 * t"])),
             "obstacle.centre"),
            ("plane 0.3 inside", layer(plane(0.3, displacement=[0.0, "1e-3 * t"])),
             "obstacle.point"),
            ("surface 0.5 inside", layer({"shape": "surface", "distance": "x[1] - 0.5",
                                          "displacement": [0.0, "1e-3 * t"]}),
             "obstacle.distance")]:
        out.append(("penetration", label, raw, [], key))
    out.append(("penetration", "hertz plane 0.3 above the disk's bottom", "hertz",
                ["contact.gap=0", "obstacle.shape='plane'", "obstacle.point=[0.0, 0.3]",
                 "obstacle.normal=[0.0, 1.0]", "geometry.parameters.h_contact=0.02"],
                "obstacle.point"))
    for label, raw in [
            ("cylinder 0.001 inside", layer(cylinder(0.001), steps=1)),
            ("cylinder 0.15 inside", layer(cylinder(0.15), steps=1)),
            ("plane 0.04 inside a layer g = 0.05",
             {**layer(plane(0.04), steps=1),
              "contact": {"boundary": "bottom", "g": 0.05, "stiffness": 100.0, "mu": 0.0}})]:
        out.append(("penetration", label, raw, [], None))
    # whole tables by --set, checked as the file's
    for text, expected in [
            ("viscoelastic.shear={instantaneous=30.0, tau=[1.0], fractions=[0.3]}", None),
            ("viscoelastic.bulk={long_term=40.0}", None),
            ("viscoelastic={shear={instantaneous=30.0, tau=[2.0], moduli=[5.0]}}", None),
            ("contact={stiffness=200.0, g=0.02}", None),
            ("time={T=2.0, steps=4}", None),
            ("geometry={lower=[0.0, 0.0], upper=[2.0, 1.0], cells=[6, 2]}", None),
            ("viscoelastic.shear={instantaneous=30.0, tau=[1.0], modli=[10.0]}",
             "viscoelastic.shear"),
            ("viscoelastic.shear={instantaneous=-30.0}", "viscoelastic.shear"),
            ("contact={law='signorini'}", "contact.law"),
            ("time={T=-1.0}", "time.T")]:
        out.append(("whole table", f"--set {text}", wlf("50 + 2 * t"), [text], expected))
    return out


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
    return out + force_cases()


def run_case(family, label, scene, sets, expected) -> dict:
    """One case in a fresh working folder: its class, the key named, the time."""
    work = pathlib.Path(tempfile.mkdtemp(prefix="cv-trust-"))
    before = os.getcwd()
    os.chdir(work)
    start = time.perf_counter()
    key, message = None, ""
    expected, _, words = (expected or "").partition("|")
    expected = expected or None
    try:
        resolved = (loader.load(scene, sets) if isinstance(scene, str)
                    else loader.resolve(scene, sets))
        simulate(resolved, out=work / "out", comm=MPI.COMM_SELF, progress=False)
        outcome = "ran" if expected is None else "silent wrong answer"
    except (SceneError, NewtonFailure) as err:
        # a NewtonFailure (exit 3) counts as refused when it names the expected key
        key = getattr(err, "key", None) or (expected if expected and expected in str(err)
                                            else None)
        message = str(err).splitlines()[0][:160]
        if expected is None:
            outcome = ("refused documented input" if isinstance(err, SceneError)
                       else "internal error")
        elif not (key or "").startswith(expected):
            outcome = "wrong key"
        else:
            outcome = "refused" if words in str(err) else "misleading message"
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
