"""The same scene on both routes to FEniCSx, 1 and 2 ranks: Debian's DOLFINx 0.5 (.venv, Open
MPI) and PyPI's DOLFINx 0.11 (.venv-pip, MPICH). Every run is compared with the Debian 1-rank
run: Newton iterations per step, contact-node values of every step, probes and the final
zone counts. Writes results/stacks.{md,json}; exits 1 if any run differs by more than the
tolerance (relative to each column's largest value).

    python benchmarks/accuracy/stacks.py [--scene paper] [--tolerance 1e-10]

Needs both environments (`make install` and `make STACK=pip install`). Uses only the standard
library, so any Python runs it.
"""
import argparse
import csv
import pathlib
import shutil
import subprocess
import sys
import tempfile

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1]))  # benchmarks/: common.py
from common import write_results  # noqa: E402
from helpers import ENV, ROOT, read_steps  # noqa: E402

ROUTES = {
    "debian": (ROOT / ".venv/bin/contactvisco", [shutil.which("mpirun") or "mpirun"]),
    "pip": (ROOT / ".venv-pip/bin/contactvisco", [str(ROOT / ".venv-pip/bin/mpiexec")]),
}


def run(route: str, ranks: int, scene: str, folder: pathlib.Path) -> pathlib.Path:
    program, launcher = ROUTES[route]
    out = folder / f"{route}-np{ranks}"
    command = ([*launcher, "-n", str(ranks)] if ranks > 1 else []) + [
        str(program), "run", scene, "--out", str(out), "--quiet", "--overwrite",
        "--set", "output.figures=false"]
    subprocess.run(command, check=True, env=ENV, timeout=1800)
    return out


def read(out: pathlib.Path) -> dict:
    """Newton counts, probes and final counts (steps.jsonl) and the contact rows (CSV)."""
    steps = read_steps(out)
    with open(out / "contact_nodes.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    return {"newton": [s["newton_iterations"] for s in steps],
            "probes": [[p["u"] for p in s["probes"]] for s in steps],
            "final": steps[-1]["status_counts"], "rows": rows}


def largest_difference(a: dict, b: dict) -> float:
    """The largest difference over the contact rows (per column, relative to the column's
    largest value) and the probes (relative to the largest probe value)."""
    key = lambda r: (int(r["step"]),) + tuple(round(float(r[c]), 9) for c in "xyz" if c in r)
    rows_a = sorted(a["rows"], key=key)
    rows_b = sorted(b["rows"], key=key)
    if len(rows_a) != len(rows_b):
        return float("inf")
    worst = 0.0
    numeric = [c for c in rows_a[0] if c not in ("status", "friction", "step")]
    coordinates = [c for c in numeric if c in "xyz"]
    size = max(abs(float(r[c])) for r in rows_a for c in coordinates)
    for column in numeric:
        values_a = [float(r[column]) for r in rows_a]
        values_b = [float(r[column]) for r in rows_b]
        # coordinates relative to the body's size (a coordinate 0 may come out as 1e-19)
        scale = size if column in coordinates else max(abs(v) for v in values_a)
        scale = max(scale, 1e-300)
        worst = max(worst, max(abs(x - y) for x, y in zip(values_a, values_b)) / scale)
    if any(r["status"] != s["status"] for r, s in zip(rows_a, rows_b)):
        return float("inf")
    flat_a = [c for step in a["probes"] for u in step for c in (u or [])]
    flat_b = [c for step in b["probes"] for u in step for c in (u or [])]
    if flat_a:
        scale = max(abs(v) for v in flat_a)
        worst = max(worst, max(abs(x - y) for x, y in zip(flat_a, flat_b)) / scale)
    return worst


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--scene", default="paper")
    parser.add_argument("--tolerance", type=float, default=1e-10)
    args = parser.parse_args()
    folder = pathlib.Path(tempfile.mkdtemp(prefix="contactvisco-stacks-"))
    runs = {(route, ranks): read(run(route, ranks, args.scene, folder))
            for route in ROUTES for ranks in (1, 2)}
    reference = runs[("debian", 1)]
    table, failed = [], False
    for (route, ranks), data in runs.items():
        difference = largest_difference(reference, data)
        same = data["newton"] == reference["newton"] and data["final"] == reference["final"] \
            and difference <= args.tolerance
        failed |= not same
        table.append({"route": route, "ranks": ranks, "newton": data["newton"],
                      "final": data["final"], "difference": difference, "agrees": same})
    lines = [f"Scene `{args.scene}`, every run against the Debian 1-rank run "
             f"(tolerance {args.tolerance:g}).", "",
             "| route | ranks | Newton per step | final zones | largest difference | agrees |",
             "|---|---|---|---|---|---|"]
    for row in table:
        zones = "/".join(str(v) for v in row["final"].values())
        lines.append(f"| {row['route']} | {row['ranks']} | {' '.join(map(str, row['newton']))}"
                     f" | {zones} | {row['difference']:.1e} | {'yes' if row['agrees'] else 'NO'} |")
    write_results("stacks", table, lines)
    shutil.rmtree(folder, ignore_errors=True)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
