"""Where the wall time of `contactvisco run paper` goes, the whole process included: the
interpreter's start, the imports and the scene, the set-up (mesh, forms with a warm JIT
cache, SNES, output files), the steps (and, inside them, the per-step output: step records,
XDMF fields, snapshots, checkpoints), closing the run, the figures (matplotlib's import and
the drawing) and the process's exit (PETSc and MPI finalize).

Each run is a child process (`python startup.py --child OUT ...`) that runs the command line's
`main` with timers wrapped around a few functions of the package (installed by an import hook
as their modules load, so nothing is imported earlier than the command line imports it); the
parent measures the process from its start to its end. One warm-up run fills the JIT cache,
the file cache and the bytecode cache, then the median of `--repeat` runs (3) per
configuration: the default figures, `output.figures=false`, and the default figures with no
bytecode cache (every module compiled from source at every start, as under
PYTHONDONTWRITEBYTECODE=1). The bytecode cache is kept under the benchmark's temporary folder
(PYTHONPYCACHEPREFIX), so that nothing is written beside the sources. One more run under
`python -X importtime` gives the import time by top-level package. The machine's load
(`uptime`) is recorded before and after, and the CPU time of each process (user + sys, and
that of the figures): on a shared machine the wall time grows with the load, the CPU time
much less, so it is the one to compare between two measurements under different loads.

    python benchmarks/performance/startup.py [--repeat 3] [--name startup_debian]
                                             [--set KEY=VALUE ...]

Writes benchmarks/results/<name>.json and <name>.md (name: startup_<route>, the route from
the DOLFINx version: debian for 0.5, pip otherwise).
"""
import argparse
import json
import pathlib
import resource
import statistics
import subprocess
import sys
import tempfile
import time

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1]))  # benchmarks/: common.py
from common import write_results  # noqa: E402
from helpers import ENV  # noqa: E402

#: (module, attribute path, name of the timer): wrapped as the module is loaded.
TIMED = [
    ("contactvisco.solver.time_loop", "simulate", "simulate"),
    ("contactvisco.solver.time_loop", "Run.loop", "loop"),
    ("contactvisco.solver.time_loop", "FieldWriter.__call__", "records_and_fields"),
    ("contactvisco.solver.time_loop", "Snapshots.__call__", "snapshots"),
    ("contactvisco.io.checkpoint", "save", "checkpoints"),
    ("contactvisco.api", "_draw_figures", "figures"),
    ("contactvisco.post.figures", "draw_all", "figure_drawing"),
]
#: The phases of the table, in the order they happen.
PHASES = ["start", "imports_scene", "setup", "stepping", "close", "figure_import",
          "figure_drawing", "exit"]


# --- the child: one run of the command line with timers -------------------------------------


def child(out, extra):
    """Run `contactvisco run paper --out OUT *extra` in this process; write the timers as
    JSON to OUT.times.json (times from time.monotonic, a clock every process shares)."""
    import importlib.abc
    import importlib.util
    begun = time.monotonic()
    spans = {}                                    # name -> [[enter, leave], ...]

    def timed(function, name):
        def wrapper(*args, **kwargs):
            span = [time.monotonic(), None, time.process_time(), None]
            spans.setdefault(name, []).append(span)
            try:
                return function(*args, **kwargs)
            finally:
                span[1], span[3] = time.monotonic(), time.process_time()
        return wrapper

    def wrap(module):
        for module_name, path, name in TIMED:
            if module.__name__ != module_name:
                continue
            owner, *inner = path.split(".")
            if inner:
                cls = getattr(module, owner)
                setattr(cls, inner[0], timed(getattr(cls, inner[0]), name))
            else:
                setattr(module, owner, timed(getattr(module, owner), name))

    class Loader(importlib.abc.Loader):
        def __init__(self, loader):
            self.loader = loader

        def create_module(self, spec):
            return self.loader.create_module(spec)

        def exec_module(self, module):
            self.loader.exec_module(module)
            wrap(module)

    class Finder(importlib.abc.MetaPathFinder):
        names = {module for module, _, _ in TIMED}

        def find_spec(self, fullname, path, target=None):
            if fullname not in self.names:
                return None
            sys.meta_path.remove(self)
            try:
                spec = importlib.util.find_spec(fullname)
            finally:
                sys.meta_path.insert(0, self)
            spec.loader = Loader(spec.loader)
            return spec

    sys.meta_path.insert(0, Finder())
    from contactvisco.cli import main
    sys.argv = ["contactvisco", "run", "paper", "--out", out, *extra]
    code = main()                              # as the console script calls it
    ended = time.monotonic()
    pathlib.Path(out + ".times.json").write_text(json.dumps(
        {"begun": begun, "ended": ended, "code": code, "spans": spans}))
    return code


# --- the parent -------------------------------------------------------------------------------


def load_average() -> str:
    return subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()


def environment(folder: pathlib.Path, bytecode: bool = True) -> dict:
    """The children's environment: with `bytecode`, Python's compiled modules are written to
    and read from folder/pycache (a warm start, as after an installation that compiled
    them); without, every module is compiled from its source at every start."""
    env = dict(ENV)
    if bytecode:
        env.pop("PYTHONDONTWRITEBYTECODE", None)
        env["PYTHONPYCACHEPREFIX"] = str(folder / "pycache")
    else:
        env["PYTHONDONTWRITEBYTECODE"] = "1"
        env.pop("PYTHONPYCACHEPREFIX", None)
    return env


def one_run(folder: pathlib.Path, extra, bytecode: bool = True) -> dict:
    """One child run into a new folder under `folder`: its phases in seconds."""
    out = str(folder / f"run{len(list(folder.glob('run*')))}")
    used = resource.getrusage(resource.RUSAGE_CHILDREN)
    started = time.monotonic()
    done = subprocess.run([sys.executable, __file__, "--child", out, *extra],
                          env=environment(folder, bytecode), capture_output=True, text=True)
    finished = time.monotonic()
    now = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (now.ru_utime - used.ru_utime) + (now.ru_stime - used.ru_stime)
    if done.returncode != 0:
        raise RuntimeError(f"the run failed ({done.returncode}):\n{done.stderr[-3000:]}")
    times = json.loads(pathlib.Path(out + ".times.json").read_text())
    spans = times["spans"]
    summary = json.loads((pathlib.Path(out) / "summary.json").read_text())

    def total(name, cpu=False):
        return sum(span[3] - span[2] if cpu else span[1] - span[0]
                   for span in spans.get(name, []))
    (sim_in, sim_out, _, _), = spans["simulate"]
    (loop_in, loop_out, _, _), = spans["loop"]
    figures = spans.get("figures", [[sim_out, sim_out]])[0]
    drawing = total("figure_drawing")
    row = {"total": finished - started,
           "start": times["begun"] - started,
           "imports_scene": sim_in - times["begun"],
           "setup": loop_in - sim_in,
           "stepping": loop_out - loop_in,
           "close": sim_out - loop_out,
           "figure_import": (figures[1] - figures[0]) - drawing,
           "figure_drawing": drawing,
           "exit": finished - times["ended"],
           "step_output": total("records_and_fields") + total("snapshots")
           + total("checkpoints"),
           "checkpoints": total("checkpoints"),
           "setup_s_reported": summary["final"]["setup_s"],
           "cpu": cpu, "figures_cpu": total("figures", cpu=True)}
    row["unaccounted"] = row["total"] - sum(row[p] for p in PHASES)
    return row


def import_split(folder: pathlib.Path, extra) -> dict:
    """Self time of every module imported by one run, summed by top-level package (python -X
    importtime): {package: seconds}, largest first."""
    out = str(folder / "imports")
    done = subprocess.run([sys.executable, "-X", "importtime", __file__, "--child", out,
                           *extra], env=environment(folder), capture_output=True, text=True)
    by_package = {}
    for line in done.stderr.splitlines():
        if not line.startswith("import time:") or "self [us]" in line:
            continue
        _, self_us, _, name = (part.strip() for part in line.replace(":", "|", 1).split("|"))
        package = name.split(".")[0]
        by_package[package] = by_package.get(package, 0.0) + int(self_us) * 1e-6
    return dict(sorted(by_package.items(), key=lambda item: -item[1]))


def route() -> str:
    """debian (DOLFINx 0.5) or pip, asked of a child process: this one starts no MPI (a
    process with MPI started may not start MPI children)."""
    version = subprocess.run([sys.executable, "-c", "import contactvisco, dolfinx; "
                              "print(dolfinx.__version__)"], env=ENV, capture_output=True,
                             text=True, check=True).stdout.strip()
    return "debian" if version.startswith("0.5") else "pip"


def main():
    if sys.argv[1:2] == ["--child"]:           # the rest goes to the command line as it is
        sys.exit(child(sys.argv[2], sys.argv[3:]))
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--name", default=None)
    parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                        help="scene overrides for every configuration")
    args = parser.parse_args()
    stack = route()
    name = args.name or f"startup_{stack}"
    extra = [item for pair in args.set for item in ("--set", pair)]
    configurations = {"default figures": (extra, True),
                      "output.figures=false": (extra + ["--set", "output.figures=false"],
                                               True),
                      "default figures, no bytecode cache": (extra, False)}
    rows = []
    load_before = load_average()
    with tempfile.TemporaryDirectory() as tmp:
        folder = pathlib.Path(tmp)
        one_run(folder, extra)                # warm JIT, file and bytecode caches
        for label, (options, bytecode) in configurations.items():
            runs = [one_run(folder, options, bytecode) for _ in range(args.repeat)]
            median = {key: statistics.median(r[key] for r in runs) for key in runs[0]}
            rows.append({"configuration": label, "median": median,
                         "totals": [r["total"] for r in runs]})
        imports = import_split(folder, extra)
    load_after = load_average()
    interpreter = []
    for _ in range(args.repeat):
        tick = time.monotonic()
        subprocess.run([sys.executable, "-c", "pass"], env=ENV)
        interpreter.append(time.monotonic() - tick)
    lines = [f"`contactvisco run paper` {' '.join(extra)} on the {stack} route "
             f"(Python {sys.version.split()[0]}), median of {args.repeat} runs after a "
             "warm-up (JIT, file and bytecode caches warm unless said), seconds of wall time",
             "",
             f"load before: `{load_before}`", "", f"load after: `{load_after}`", "",
             "| phase | " + " | ".join(r["configuration"] for r in rows) + " |",
             "|---|" + "---|" * len(rows)]
    labels = {"start": "interpreter start", "imports_scene": "imports, command line, scene",
              "setup": "set-up (mesh, forms, SNES, files)", "stepping": "steps",
              "step_output": "  of which per-step output", "checkpoints":
              "  of which checkpoints", "close": "closing the run",
              "figure_import": "figures: import", "figure_drawing": "figures: drawing",
              "exit": "exit (finalize)", "unaccounted": "unaccounted", "total": "**total**",
              "cpu": "CPU time of the process (user + sys)",
              "figures_cpu": "  of which figures (import and drawing)"}
    for key, text in labels.items():
        lines.append(f"| {text} | " + " | ".join(f"{r['median'][key]:.3f}" for r in rows)
                     + " |")
    lines += ["", f"`python -c pass`: {statistics.median(interpreter):.3f} s", "",
              "Import self time by top-level package (one run under -X importtime, default "
              "figures; the import hook adds a little):", "",
              "| package | s |", "|---|---|"]
    lines += [f"| {package} | {seconds:.3f} |" for package, seconds in imports.items()
              if seconds >= 0.01]
    lines.append(f"| all | {sum(imports.values()):.3f} |")
    write_results(name, {"rows": rows, "imports": imports, "load_before": load_before,
                         "load_after": load_after,
                         "interpreter": statistics.median(interpreter)}, lines)


if __name__ == "__main__":
    main()
