"""Shared by the benchmarks (performance/, accuracy/, robustness/): timing a scene, its step
statistics, and writing result tables to benchmarks/results/. Importing it also puts tests/
on sys.path, so that a benchmark takes the harness it shares with the tests (the command line
in a child process, the MPI launcher and environment, steps.jsonl, the fault cases) from
tests/helpers.py. A script in a group folder finds this module with

    sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1]))  # benchmarks/

Only the standard library is imported when it loads (contactvisco inside the functions), so
accuracy/stacks.py, which needs no FEniCSx, runs under any Python."""
import json
import pathlib
import statistics
import sys
import time

BENCHMARKS = pathlib.Path(__file__).resolve().parent
RESULTS = BENCHMARKS / "results"
#: Scene files of the benchmarks (a user's scene for `contactvisco tradeoff`).
SCENES = BENCHMARKS / "scenes"
if str(BENCHMARKS.parent / "tests") not in sys.path:
    sys.path.insert(0, str(BENCHMARKS.parent / "tests"))     # tests/helpers.py


def timed_run(scene, comm, repeat=2):
    """Best of `repeat` runs (the first also compiles the forms): (seconds, result)."""
    from contactvisco.solver.time_loop import simulate
    best = None
    for _ in range(repeat):
        tick = time.perf_counter()
        result = simulate(scene, comm=comm, progress=False)
        seconds = time.perf_counter() - tick
        if best is None or seconds < best[0]:
            best = (seconds, result)
    return best


class HistoryClock:
    """Wall time of every TimeState.record and TimeState.prepare call (the history update of
    eq (19)), in call order, from its creation on: it wraps both methods of
    contactvisco.fem.problem.TimeState for the rest of the process."""

    def __init__(self):
        from contactvisco.fem.problem import TimeState
        self.calls = {"record": [], "prepare": []}
        for name, record in self.calls.items():
            original = getattr(TimeState, name)

            def timed(state, k, original=original, record=record):
                tick = time.perf_counter()
                original(state, k)
                record.append(time.perf_counter() - tick)
            setattr(TimeState, name, timed)

    def reset(self):
        for record in self.calls.values():
            record.clear()

    def per_step(self, N=None):
        """History seconds of steps 1..N: prepare(k) before the solve, record(k) after it.
        Step 0 records eps_0 only and is left out, like its solve. With N, no step may have
        been cut."""
        record, prepare = self.calls["record"], self.calls["prepare"]
        if N is not None:
            assert len(record) == N + 1 and len(prepare) == N, "a step was cut"
        return [p + c for p, c in zip(prepare, record[1:])]


def step_statistics(result):
    steps = result.steps
    iterations = [s["newton_iterations"] for s in steps]
    return {"unknowns": sum(result.problem.count_unknowns().values()),
            "unknowns_by_field": result.problem.count_unknowns(),
            "steps": len(steps) - 1,
            "mean_newton": statistics.mean(iterations), "max_newton": max(iterations),
            "s_per_step": statistics.mean(s["wall_s"] for s in steps),
            "s_per_newton": sum(s["wall_s"] for s in steps) / max(1, sum(iterations)),
            "final_status": steps[-1]["status_counts"]}


def write(name, rows, header, line):
    """results/<name>.json and results/<name>.md (a table: header, then line(row) per row)."""
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / f"{name}.json").write_text(json.dumps(rows, indent=1))
    lines = [header, "|" + "|".join("---" for _ in header.strip("|").split("|")) + "|"]
    lines += [line(r) for r in rows]
    (RESULTS / f"{name}.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


def write_results(name, rows, lines, default=None):
    """results/<name>.json (the rows; `default` as in json.dumps, for values JSON has no type
    for) and results/<name>.md (table lines); also printed."""
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / f"{name}.json").write_text(json.dumps(rows, indent=1, default=default))
    write_markdown(name, lines)


def write_markdown(name, lines):
    """results/<name>.md from table lines; also printed."""
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / f"{name}.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


def assemble_linear(a, L, bcs):
    """Matrix and right-hand side of a linear problem with Dirichlet conditions (lifted)."""
    from dolfinx.fem.petsc import apply_lifting, assemble_matrix, assemble_vector, set_bc
    from petsc4py import PETSc
    A = assemble_matrix(a, bcs=bcs)
    A.assemble()
    b = assemble_vector(L)
    apply_lifting(b, [a], [bcs])
    b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
    set_bc(b, bcs)
    return A, b


def first_loaded_step(name, sets, comm, record):
    """Run a built-in scene (`sets` as --set texts, no figures, no probes) and keep, for every
    Newton iterate of every step, record(snes) (snes: the CondensedSNES at that iterate).

    Returns (the run's result, the records of the first loaded step: the first step whose
    first |F| is above 0, and that step's index)."""
    from contactvisco import api
    from contactvisco.solver import newton
    steps = []
    original = newton.CondensedSNES._monitor

    def monitor(self, snes, it, norm):
        original(self, snes, it, norm)
        if it == 0:
            steps.append([])
        steps[-1].append((float(self.system.full_norm), record(self)))

    newton.CondensedSNES._monitor = monitor
    try:
        scene = api.load_scene(name, sets=["output.figures=false", *sets])
        scene["output"]["probes"] = []
        result = api.solve(scene, comm=comm)
    finally:
        newton.CondensedSNES._monitor = original
    loaded = next(i for i, s in enumerate(steps) if s[0][0] > 0)
    return result, steps[loaded], loaded
