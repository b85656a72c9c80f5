"""Redraw the figures of README.md and docs/ (`make figures`), each with its signature
(docs/figures/<name>.json: texts and data, see contactvisco.post.figures.signature), which
tests/integration/test_figures.py compares with what the program draws now.

    python docs/make_figures.py [--only paper]

Runs: the paper scene as shipped (paper_*), the Hertz scene (hertz_*), the 3D block
(block3d_*); the trade-off figure is redrawn from benchmarks/results/tradeoff_paper.json
(measured by benchmarks/accuracy/tradeoff.py; wall times are not repeatable, so it is not
rerun here), the step-cost figure likewise from benchmarks/results/step_cost_five_sizes*.json
(measured by benchmarks/performance/step_cost.py); the Cattaneo-Mindlin comparison
(coulomb_*) is run as demos/coulomb.py runs it.
"""
import json
import pathlib
import shutil
import sys

import matplotlib
from mpi4py import MPI

HERE = pathlib.Path(__file__).resolve().parent
FIGURES = HERE / "figures"
BUILD = HERE.parent / "build" / "figures"
#: scene -> the figures of its run that the documents show
SHOWN = {"paper": ["contact_displacements", "contact_reactions", "deformed_mesh", "stress",
                   "probes"],
         "hertz": ["contact_reactions", "stress"],
         "block3d": ["stress", "contact_status"]}
DPI = 200
CATTANEO_H = 0.0025     # the mesh size at the contact of demos/coulomb.py (a / 22)
CATTANEO_KEYS = ("a", "c", "p0", "a_over_h", "load_ratio", "x", "q", "p", "stick")
RUNS = FIGURES / "coulomb_cattaneo_mindlin_runs.json"
#: the runs the step-cost figure draws (benchmarks/results/)
STEP_COST_RESULTS = ("step_cost_five_sizes.json", "step_cost_five_sizes_np2.json")


def run_figures(name: str) -> list[tuple[str, object]]:
    """Run a built-in scene into build/figures/<name>; its figures as (stem, Figure)."""
    from contactvisco.post import figures
    from contactvisco.scene import loader as scene_module
    from contactvisco.solver.time_loop import simulate
    scene = scene_module.load(name)
    scene["output"].update(xdmf=False, checkpoint=False)
    out = BUILD / name
    if MPI.COMM_WORLD.rank == 0 and out.exists():
        shutil.rmtree(out)
    simulate(scene, out, progress=False)
    return [(f"{name}_{stem}", fig) for stem, fig in figures.build_all(out)
            if stem in SHOWN[name]]


def tradeoff_figure():
    from contactvisco.studies import tradeoff
    from matplotlib.figure import Figure
    path = HERE.parent / "benchmarks" / "results" / "tradeoff_paper.json"
    if not path.exists():
        return []
    result = json.loads(path.read_text())
    fig = Figure()
    tradeoff.draw(result, fig)
    return [("tradeoff", fig)]


def step_cost_figure():
    """A step's cost in elastic solves at the five sizes of step_cost.py's default run, on 1
    and 2 ranks, drawn by that benchmark's draw() from its results."""
    import importlib.util
    from matplotlib.figure import Figure
    path = HERE.parent / "benchmarks" / "performance" / "step_cost.py"
    spec = importlib.util.spec_from_file_location("step_cost", path)
    step_cost = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(step_cost)
    rows = [row for name in STEP_COST_RESULTS
            for row in json.loads((HERE.parent / "benchmarks" / "results" / name).read_text())]
    return [("step_cost", step_cost.draw(rows, Figure()))]


def cattaneo_figure():
    """The Cattaneo-Mindlin comparison of demos/coulomb.py (nu = 0.49 and 0.3, a/h = 22), drawn
    by contactvisco.post.figures.cattaneo_mindlin_figure as the demo draws it. The node values
    it plots are kept in docs/figures/coulomb_cattaneo_mindlin_runs.json, from which
    tests/test_figures.py redraws it (gmsh meshes the half disk differently from one version
    to the next, so a rerun is not compared)."""
    from contactvisco.studies.coulomb import cattaneo_mindlin
    results = {nu: cattaneo_mindlin(CATTANEO_H, nu=nu) for nu in (0.49, 0.3)}
    if MPI.COMM_WORLD.rank != 0:
        return []
    kept = {str(nu): {key: (r[key].tolist() if hasattr(r[key], "tolist") else r[key])
                      for key in CATTANEO_KEYS} for nu, r in results.items()}
    RUNS.write_text(json.dumps(kept, indent=0) + "\n")
    return [("coulomb_cattaneo_mindlin", cattaneo_from_runs(RUNS))]


def cattaneo_from_runs(path):
    """The Cattaneo-Mindlin figure from the kept node values."""
    import numpy as np
    from contactvisco.post.figures import cattaneo_mindlin_figure
    from contactvisco.studies.coulomb import cattaneo_traction
    kept = json.loads(pathlib.Path(path).read_text())
    results = {float(nu): {key: np.asarray(value) if isinstance(value, list) else value
                           for key, value in r.items()} for nu, r in kept.items()}
    return cattaneo_mindlin_figure(results, cattaneo_traction)


def save(items):
    from contactvisco.post.figures import STYLE, signature
    with matplotlib.rc_context(STYLE):
        for stem, fig in items:
            fig.savefig(FIGURES / f"{stem}.png", dpi=DPI)
            (FIGURES / f"{stem}.json").write_text(json.dumps(signature(fig), indent=0) + "\n")
            print(FIGURES / f"{stem}.png")


def main():
    only = sys.argv[sys.argv.index("--only") + 1:] if "--only" in sys.argv else None
    FIGURES.mkdir(exist_ok=True)
    for name in SHOWN:
        if only is None or name in only:
            items = run_figures(name)
            if MPI.COMM_WORLD.rank == 0:
                save(items)
    if MPI.COMM_WORLD.rank == 0 and (only is None or "tradeoff" in only):
        save(tradeoff_figure())
    if MPI.COMM_WORLD.rank == 0 and (only is None or "step_cost" in only):
        save(step_cost_figure())
    if only is None or "coulomb" in only:
        items = cattaneo_figure()
        if MPI.COMM_WORLD.rank == 0:
            save(items)


if __name__ == "__main__":
    main()
