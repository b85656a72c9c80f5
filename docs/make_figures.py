"""Redraw the figures of README.md and docs/ (`make figures`), each with its signature
(docs/figures/<name>.json: texts and data, see contactvisco.post.figures.signature), which
tests/integration/test_figures.py compares with what the program draws now.

    python docs/make_figures.py [--only paper]

Runs: the paper scene as shipped (paper_*), the Hertz scene (hertz_*), the 3D block
(block3d_*); the trade-off figure is redrawn from benchmarks/results/tradeoff_paper.json
(measured by benchmarks/accuracy/tradeoff.py; wall times are not repeatable, so it is not rerun here).
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


if __name__ == "__main__":
    main()
