"""Cost of the per-step output, and the whole run against the number of steps.

1. Per step, on the paper scene's 16 x 16 mesh (u P1 and sigma DG0 tensor), 200 steps:
   - "one open file": one DOLFINx XDMFFile kept open for the run (the earlier layout; its
     HDF5 file is unreadable after a kill -9);
   - "file per step": solution/step-n.xdmf/.h5 written and closed, mesh included, and the
     step appended to solution.xdmf (what contactvisco.io.output.Writer does);
   - the step record appended to steps.jsonl with flush, and with flush + fsync.
2. End to end: `contactvisco run paper --set geometry.cells=[16, 16]` with default outputs
   at N = 2000 and N = 4000 steps (same T): wall time of the command and the ratio
   (target: 4000 steps at most 2.2 times 2000 steps).

    python benchmarks/performance/output_cost.py [--skip-runs]            (1 rank)
    mpirun -n 2 python benchmarks/performance/output_cost.py --skip-runs
                                                  (the per-step part on 2 ranks)
"""
import argparse
import json
import os
import pathlib
import shutil
import sys
import tempfile
import time

from mpi4py import MPI

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1]))  # benchmarks/: common.py
from common import write_results  # noqa: E402
from helpers import run_cli  # noqa: E402


STEPS = 200
RUNS = (2000, 4000)


def per_step(comm, folder: pathlib.Path) -> dict:
    from dolfinx import fem, io

    from contactvisco.fem import geometry as geometry_module
    from contactvisco.io import output
    from contactvisco.scene import loader as scene_module
    from contactvisco.fem.problem import build
    scene = scene_module.load("paper", ["geometry.cells=[16, 16]"])
    problem = build(scene, geometry_module.build(scene, comm))
    sigma = fem.Function(problem.tensor_space, name="sigma")
    sigma.interpolate(problem.sigma_expression)
    fields = [problem.u, sigma]
    out = {}

    comm.barrier()
    tick = time.perf_counter()
    with io.XDMFFile(comm, str(folder / "open.xdmf"), "w") as f:
        f.write_mesh(problem.geometry.mesh)
        for n in range(STEPS):
            for field in fields:
                f.write_function(field, float(n))
    comm.barrier()
    out["one open file"] = (time.perf_counter() - tick) / STEPS

    writer = output.Writer(folder / "run", problem, comm)
    record = {"step": 0, "t": 0.0, "status_counts": {}, "probes": []}
    comm.barrier()
    tick = time.perf_counter()
    for n in range(STEPS):
        writer.step(dict(record, step=n, t=float(n)), None, fields)
    comm.barrier()
    out["file per step (+ index, records)"] = (time.perf_counter() - tick) / STEPS
    writer.close()

    if comm.rank == 0:
        line = json.dumps({"step": 1, "t": 0.5, "residual_history": [1.0] * 5,
                           "status_counts": {"separated": 3, "compliance": 4, "bound": 5}})
        for label, sync in (("record, flush", False), ("record, flush + fsync", True)):
            with open(folder / f"records-{sync}.jsonl", "a") as f:
                tick = time.perf_counter()
                for _ in range(STEPS * 5):
                    f.write(line + "\n")
                    f.flush()
                    if sync:
                        os.fsync(f.fileno())
                out[label] = (time.perf_counter() - tick) / (STEPS * 5)
    return out


def end_to_end(steps: int, folder: pathlib.Path) -> dict:
    out = folder / f"run{steps}"
    tick = time.perf_counter()
    proc = run_cli("run", "paper", "--set", "geometry.cells=[16, 16]", "--set",
                   f"time.steps={steps}", "--quiet", "--out", out, timeout=None)
    wall = time.perf_counter() - tick
    if proc.returncode != 0:
        raise RuntimeError(proc.stderr)
    size = sum(p.stat().st_size for p in out.rglob("*") if p.is_file())
    return {"steps": steps, "wall_s": wall, "bytes": size}


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--skip-runs", action="store_true")
    args = parser.parse_args()
    comm = MPI.COMM_WORLD
    folder = pathlib.Path(tempfile.mkdtemp(prefix="cv-output-cost-") if comm.rank == 0
                          else "")
    folder = pathlib.Path(comm.bcast(str(folder)))
    result = {"ranks": comm.size, "per_step_s": per_step(comm, folder)}
    if comm.rank == 0 and not args.skip_runs and comm.size == 1:
        result["runs"] = [end_to_end(n, folder) for n in RUNS]
        result["ratio_4000_2000"] = result["runs"][1]["wall_s"] / result["runs"][0]["wall_s"]
    if comm.rank != 0:
        return
    shutil.rmtree(folder, ignore_errors=True)
    name = f"output_cost_np{comm.size}"
    lines = [f"# Output cost ({comm.size} rank(s))", "", "| per step | ms |", "|---|---|"]
    lines += [f"| {k} | {v * 1e3:.3f} |" for k, v in result["per_step_s"].items()]
    if "runs" in result:
        lines += ["", "| steps | wall s | output bytes |", "|---|---|---|"]
        lines += [f"| {r['steps']} | {r['wall_s']:.1f} | {r['bytes']} |" for r in result["runs"]]
        lines += ["", f"ratio 4000/2000: {result['ratio_4000_2000']:.2f} (target <= 2.2)"]
    write_results(name, result, lines)


if __name__ == "__main__":
    main()
