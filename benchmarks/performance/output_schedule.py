"""Wall time per step against the output schedule ([output] field_every, checkpoint_every).

The paper scene at 16 x 16 and 64 x 64, 200 steps, 1 rank, in one process (a warm-up run
first: the forms are compiled once): (field_every, checkpoint_every) = (1, 1) (the default),
(10, 10), (100, 100); the fields and the checkpoint off (output.xdmf = false,
output.checkpoint = false: the step records and contact rows are still written); and no
output folder at all. Per step: the wall time from the record of step 0 to that of step 200,
divided by 200 (set-up and the final summary left out; every field file and checkpoint of the
steps between included), and the solving part (the records' wall_s: the Newton solve and the
history update). The load of the machine (`uptime`) is written before and after.

    python benchmarks/performance/output_schedule.py          (about 1.5 minutes)
    python benchmarks/performance/output_schedule.py --table  (the .md from the .json)
"""
import json
import pathlib
import shutil
import subprocess
import sys
import tempfile
import time

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1]))  # benchmarks/: common.py
from common import write_results  # noqa: E402

STEPS = 200
MESHES = (16, 64)
#: (label, [output] overrides, whether an output folder is given)
CASES = (
    ("(1, 1) default", ["output.field_every=1", "output.checkpoint_every=1"], True),
    ("(10, 10)", ["output.field_every=10", "output.checkpoint_every=10"], True),
    ("(100, 100)", ["output.field_every=100", "output.checkpoint_every=100"], True),
    ("fields and checkpoint off", ["output.xdmf=false", "output.checkpoint=false"], True),
    ("no output folder", [], False),
)


def load():
    return subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()


def one_run(cells: int, overrides: list, folder) -> dict:
    from mpi4py import MPI

    from contactvisco.scene import loader as scene_module
    from contactvisco.solver.time_loop import simulate
    scene = scene_module.load("paper", [f"geometry.cells=[{cells}, {cells}]",
                                        f"time.steps={STEPS}", "output.figures=false",
                                        *overrides])
    stamps = []
    if folder is not None:
        shutil.rmtree(folder, ignore_errors=True)
    result = simulate(scene, out=folder, comm=MPI.COMM_SELF, progress=False,
                      on_step=lambda record: stamps.append(time.perf_counter()))
    solve = sum(r["wall_s"] for r in result.steps[1:])
    size = (sum(p.stat().st_size for p in folder.rglob("*") if p.is_file())
            if folder is not None else 0)
    return {"cells": cells, "per_step_ms": (stamps[-1] - stamps[0]) / STEPS * 1e3,
            "solve_ms": solve / STEPS * 1e3, "bytes": size}


def main():
    if "--table" in sys.argv:
        from common import RESULTS, write_markdown
        write_markdown("output_schedule", table(json.loads(
            (RESULTS / "output_schedule.json").read_text())))
        return
    tmp = pathlib.Path(tempfile.mkdtemp(prefix="cv-output-schedule-"))
    before = load()
    one_run(8, ["time.steps=2"], tmp / "warm-up")          # compile the forms once
    rows = []
    for cells in MESHES:
        for label, overrides, with_folder in CASES:
            row = one_run(cells, overrides, tmp / "run" if with_folder else None)
            row["case"] = label
            rows.append(row)
            print(row, flush=True)
    after = load()
    shutil.rmtree(tmp, ignore_errors=True)
    result = {"steps": STEPS, "load_before": before, "load_after": after, "rows": rows}
    write_results("output_schedule", result, table(result))


def table(result: dict) -> list[str]:
    """The results file's lines. "Besides solving" is the run's wall time per step minus its
    own solving time: the output, the contact table and the records, free of the variation
    of the solving time between runs (other jobs on the machine)."""
    rows = result["rows"]
    lines = ["# Wall time per step against the output schedule", "",
             f"Paper scene, {result['steps']} steps, 1 rank "
             "(`benchmarks/performance/output_schedule.py`).", "",
             f"Load before: `{result['load_before']}`  ",
             f"Load after: `{result['load_after']}`", "",
             "| mesh | (field_every, checkpoint_every) | wall ms / step | solving ms / step | "
             "besides solving ms / step | folder MB |", "|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['cells']} x {r['cells']} | {r['case']} | {r['per_step_ms']:.2f} | "
                     f"{r['solve_ms']:.2f} | {r['per_step_ms'] - r['solve_ms']:.2f} | "
                     f"{r['bytes'] / 1e6:.1f} |")
    lines += ["", "Solving is the records' `wall_s` (Newton with its assembly, the contact "
              "terms and the history update of eq 19), not the linear solve alone. The same "
              "problem took different solving times from run to run:"]
    for cells in sorted({r["cells"] for r in rows}):
        solve = [r["solve_ms"] for r in rows if r["cells"] == cells]
        rest = {r["case"]: r["per_step_ms"] - r["solve_ms"] for r in rows if r["cells"] == cells}
        lines.append(f"- {cells} x {cells}: solving {min(solve):.1f} to {max(solve):.1f} ms per "
                     "step (the machine's 2 cores are shared with other jobs); compare the "
                     "column besides solving: the default schedule costs "
                     f"{rest['(1, 1) default']:.1f} ms per step, (10, 10) "
                     f"{rest['(10, 10)']:.1f}, (100, 100) {rest['(100, 100)']:.1f}, against "
                     f"{rest['fields and checkpoint off']:.1f} for the records and contact rows "
                     f"alone and {rest['no output folder']:.1f} without a folder (the contact "
                     "table and the step record are made either way).")
    return lines

if __name__ == "__main__":
    main()
