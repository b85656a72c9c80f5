"""`contactvisco tradeoff` on every built-in scene and on a user's scene file
(benchmarks/scenes/strip_punch.toml), each recommendation checked against a reference finer
than its ladder (one mesh level above the top, twice the largest step count):

    python benchmarks/accuracy/tradeoff.py [scene ...]

Writes results/tradeoff_<scene>.json (the ladder, the recommendation, the check) and the table
results/tradeoff_scenes.md. Targets and budgets per scene below: the ladder is the command's
default (4 mesh levels from 1/4 of the scene's mesh, N/2, N, 2N steps, P2 where it converges)
with fewer levels where a level costs minutes on two cores.
"""
import json
import pathlib
import sys
import time

from mpi4py import MPI

from contactvisco.studies import tradeoff

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1]))  # benchmarks/: common.py
from common import RESULTS, SCENES, write_markdown  # noqa: E402

COMM = MPI.COMM_WORLD
USER = str(SCENES / "strip_punch.toml")
#: scene: (target, measure, levels, coarsest, budget s, --set lines)
CASES = {
    "paper": (0.05, "contact_pressure", 4, 0.25, 60, []),
    "hertz": (0.05, "contact_pressure", 3, 0.5, 60, []),
    "ironing": (0.05, "contact_displacement", 3, 0.25, 60, []),
    "creep": (0.02, "probe", 3, 0.25, 90, []),
    "block3d": (0.15, "contact_pressure", 3, 0.25, 90, []),
    "strip_punch": (0.03, "contact_pressure", 4, 0.25, 60, []),
}


def measure(name):
    target, measure_name, levels, coarsest, budget, sets = CASES[name]
    source = USER if name == "strip_punch" else name
    tick = time.perf_counter()
    say = print if COMM.rank == 0 else (lambda *a: None)
    result = tradeoff.tradeoff(source, target, sets, measure=measure_name, levels=levels,
                               coarsest=coarsest, budget=budget, say=say)
    reference = tradeoff.finer_reference(source, sets, levels, coarsest)
    if result["recommended"] is not None:
        check = tradeoff.verify(source, sets, result["recommended"]["set"], measure_name,
                                reference)
        result["check"] = dict(check, reference_set=reference,
                               within_target=check["error"] <= target)
    result["benchmark_s"] = time.perf_counter() - tick
    if COMM.rank == 0:
        RESULTS.mkdir(exist_ok=True)
        (RESULTS / f"tradeoff_{name}.json").write_text(json.dumps(result, indent=1))
        tradeoff.figure(result, RESULTS / f"tradeoff_{name}.png", dpi=150)
        say("\n".join(tradeoff.summary_lines(result)))
        if "check" in result:
            say(f"check: error {result['check']['error']:.3g} against "
                f"{' '.join(reference)} ({result['check']['reference_wall_s']:.1f} s)")
    return result


def table():
    lines = ["| scene | measure | target | runs | budget stop | recommended | estimated | "
             "measured vs finer reference | within | wall s | reference |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    for name in CASES:
        path = RESULTS / f"tradeoff_{name}.json"
        if not path.exists():
            continue
        r = json.loads(path.read_text())
        rec, check = r["recommended"], r.get("check")
        if rec is None:
            lines.append(f"| {name} | {r['measure']} | {r['target']:g} | {len(r['ladder'])} | "
                         f"{'yes' if r['stopped'] else 'no'} | none: {r['not_reached']} "
                         "| | | | | |")
            continue
        settings = " ".join(s for s in rec["set"] if not s.startswith("discretization.cont"))
        lines.append(
            f"| {name} | {r['measure']} | {r['target']:g} | {len(r['ladder'])} | "
            f"{'yes' if r['stopped'] else 'no'} | `{settings}` | "
            f"{rec['estimated_error']:.3g} | {check['error']:.3g} | "
            f"{'yes' if check['within_target'] else 'NO'} | {rec['wall_s']:.2f} | "
            f"`{' '.join(s for s in check['reference_set'] if 'quadrature' not in s)}` |")
    write_markdown("tradeoff_scenes", lines)


if __name__ == "__main__":
    for scene in sys.argv[1:] or list(CASES):
        measure(scene)
    if COMM.rank == 0:
        table()
