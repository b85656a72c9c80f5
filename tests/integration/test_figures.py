"""The figures: the committed docs figures match what the program draws now (their
signatures: texts and data), every axis carries units, no text leaves the figure, vector
output, --times, and step records read from either output layout."""
import json
import pathlib
import shutil

import numpy as np
import pytest
from matplotlib.backends.backend_agg import FigureCanvasAgg
from mpi4py import MPI

from contactvisco.post import figures
from contactvisco.scene import loader as scene_module
from contactvisco.studies import tradeoff
from contactvisco.cli import main
from contactvisco.solver.time_loop import simulate
from helpers import ROOT

COMM = MPI.COMM_WORLD
DOCS = ROOT / "docs" / "figures"


@pytest.fixture(scope="module")
def paper_folder(tmp_path_factory):
    """The paper scene as shipped (as docs/make_figures.py runs it), in a folder every rank
    names alike."""
    return _shipped_run(tmp_path_factory, "paper")


@pytest.fixture(scope="module")
def ironing_folder(tmp_path_factory):
    """The ironing scene as shipped: a strip six times longer than high."""
    return _shipped_run(tmp_path_factory, "ironing")


@pytest.fixture(scope="module")
def sphere_creep_folder(tmp_path_factory):
    """The sphere_creep scene on 4 steps: a rigid sphere under a force (obstacle.png) on an
    axisymmetric block."""
    return _shipped_run(tmp_path_factory, "sphere_creep", ["time.steps=4"])


def _shipped_run(tmp_path_factory, name, overrides=()):
    """A built-in scene as shipped, run into a folder every rank names alike (no XDMF, no
    checkpoint: the figures need neither)."""
    folder = pathlib.Path(COMM.bcast(str(tmp_path_factory.mktemp(name)), root=0))
    scene = scene_module.load(name, overrides)
    scene["output"].update(xdmf=False, checkpoint=False)
    simulate(scene, folder, progress=False)
    COMM.barrier()
    return folder


def _module(path):
    """The Python file at `path` imported as a module of its stem's name."""
    import importlib.util
    spec = importlib.util.spec_from_file_location(pathlib.Path(path).stem, path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def committed(stem):
    path = DOCS / f"{stem}.json"
    assert path.exists(), f"{path} missing: run make figures"
    return json.loads(path.read_text())


def test_docs_figures_match_the_program(paper_folder):
    if COMM.rank != 0:
        return                                        # the figures are drawn on rank 0
    drawn = dict(figures.build_all(paper_folder))
    for stem in ("contact_displacements", "contact_reactions", "deformed_mesh", "stress",
                 "probes"):
        problems = figures.compare_signatures(figures.signature(drawn[stem]),
                                              committed(f"paper_{stem}"))
        assert not problems, f"docs/figures/paper_{stem}.png is stale (make figures): " \
                             f"{problems[:3]}"
    results = ROOT / "benchmarks" / "results"
    from matplotlib.figure import Figure
    fig = tradeoff.draw(json.loads((results / "tradeoff_paper.json").read_text()), Figure())
    assert not figures.compare_signatures(figures.signature(fig), committed("tradeoff"))


def test_cattaneo_mindlin_figure_matches_the_program():
    """docs/figures/coulomb_cattaneo_mindlin.png is drawn by figures.cattaneo_mindlin_figure
    (the code demos/coulomb.py draws with) from the node values make figures kept: redrawn
    from them now, its signature is the committed one."""
    if COMM.rank != 0:
        return
    make_figures = _module(DOCS.parent / "make_figures.py")
    fig = make_figures.cattaneo_from_runs(make_figures.RUNS)
    problems = figures.compare_signatures(figures.signature(fig),
                                          committed("coulomb_cattaneo_mindlin"))
    assert not problems, f"docs/figures/coulomb_cattaneo_mindlin.png is stale: {problems[:3]}"
    titles = [ax.get_title() for ax in fig.axes]
    assert titles[0].startswith("$\\nu$ = 0.49") and titles[1].startswith("$\\nu$ = 0.3")


def test_step_cost_figure_matches_the_program():
    """docs/figures/step_cost.png is drawn by benchmarks/performance/step_cost.py's draw from
    the committed results: redrawn now, its signature is the committed one, and its open and
    filled points are the first loaded and the later steps' ratios of those results."""
    if COMM.rank != 0:
        return
    make_figures = _module(DOCS.parent / "make_figures.py")
    (stem, fig), = make_figures.step_cost_figure()
    problems = figures.compare_signatures(figures.signature(fig), committed(stem))
    assert not problems, f"docs/figures/{stem}.png is stale (make figures): {problems[:3]}"
    step_cost = _module(ROOT / "benchmarks" / "performance" / "step_cost.py")
    expected = set()
    for name in make_figures.STEP_COST_RESULTS:
        for row in json.loads((ROOT / "benchmarks" / "results" / name).read_text()):
            first, later = step_cost.ratios(row)
            expected |= {(row["unknowns_u"], round(first, 9), "open"),
                         (row["unknowns_u"], round(later, 9), "filled")}
    drawn = {(line.get_xdata()[0], round(line.get_ydata()[0], 9),
              "open" if line.get_markerfacecolor() == "none" else "filled")
             for line in fig.axes[0].get_lines()
             if len(line.get_xdata()) == 1 and line.get_linestyle() == "None"}
    assert drawn == expected


def test_signature_sees_a_changed_label(paper_folder):
    if COMM.rank != 0:
        return
    drawn = dict(figures.build_all(paper_folder))["contact_reactions"]
    before = figures.signature(drawn)
    drawn.axes[0].set_ylabel("traction")
    assert figures.compare_signatures(figures.signature(drawn), before)
    line = drawn.axes[0].get_lines()[0]
    line.set_ydata(np.asarray(line.get_ydata()) * 1.01)
    assert any("numbers" in p for p in figures.compare_signatures(
        figures.signature(drawn), before))


def _texts(fig):
    return [t for t in fig.findobj(lambda a: hasattr(a, "get_text") and
                                   hasattr(a, "get_window_extent"))
            if t.get_visible() and t.get_text().strip()]


def _drawn_texts(fig):
    """_texts without the tick labels matplotlib keeps but does not draw (outside the view)."""
    kept, made = set(), set()
    for ax in fig.axes:
        for axis in (ax.xaxis, ax.yaxis):
            for tick in axis.get_major_ticks() + axis.get_minor_ticks():
                made.update({id(tick.label1), id(tick.label2)})
            for tick in axis._update_ticks():
                kept.update({id(tick.label1), id(tick.label2)})
    return [t for t in _texts(fig) if id(t) not in made or id(t) in kept]


def _inside(box, area, slack=0.01):
    return box.x0 >= area.x0 - slack and box.y0 >= area.y0 - slack and \
        box.x1 <= area.x1 + slack and box.y1 <= area.y1 + slack


@pytest.mark.parametrize("scene", ["paper", "ironing", "sphere_creep"])
def test_units_and_nothing_clipped(scene, request):
    """Every text of every figure (tick labels, titles, axis and colour-bar labels, legends)
    lies inside the canvas and inside what savefig keeps of it (STYLE crops to the tight box
    plus pad_inches, a box in which matplotlib counts an axis label only by its middle: a
    label longer than its axes is cut there), and fits the figure."""
    folder = request.getfixturevalue(f"{scene}_folder")    # a collective run: every rank
    if COMM.rank != 0:
        return
    with figures.matplotlib.rc_context(figures.STYLE):
        pad = figures.matplotlib.rcParams["savefig.pad_inches"]
        drawn = figures.build_all(folder)
        if scene == "sphere_creep":
            assert "obstacle" in dict(drawn)
        for stem, fig in drawn:
            renderer = FigureCanvasAgg(fig).get_renderer()
            fig.draw(renderer)
            inches = fig.dpi_scale_trans.inverted()
            kept = fig.get_tightbbox(renderer).padded(pad)
            canvas = fig.bbox_inches
            for text in _drawn_texts(fig):
                e = text.get_window_extent(renderer)
                box = e.transformed(inches)
                assert _inside(box, canvas) and _inside(box, kept), \
                    f"{scene} {stem}: '{text.get_text()}' at {box} beyond the canvas " \
                    f"{canvas} or the saved box {kept}"
                assert e.width <= fig.bbox.width and e.height <= fig.bbox.height, \
                    f"{stem}: '{text.get_text()}' larger than the figure"
            for ax in fig.axes:
                for text in (ax.get_xlabel(), ax.get_ylabel()):
                    if text:
                        assert "[" in text and "]" in text or "(model units)" in text, \
                            f"{stem}: no unit in '{text}'"
            assert fig.get_size_inches()[0] <= figures.PAGE + 1e-9


@pytest.mark.skipif(COMM.size > 1, reason="the plot command on one rank of several would "
                    "initialize PETSc's options there alone, and PETSc's finalize then waits "
                    "for the other ranks; plotting has no parallel part")
@pytest.mark.slow
def test_plot_vector_output_and_times(paper_folder, tmp_path):
    folder = tmp_path / "copy"
    shutil.copytree(paper_folder, folder)
    assert main(["plot", str(folder), "--format", "svg", "--times", "0.1", "1",
                 "--dpi", "50"]) == 0
    svg = (folder / "stress_t0.1.svg").read_text()
    assert "x [m]" in svg and "N/m²" in svg and "1-99th percentile" in svg
    assert (folder / "contact_reactions_t0.1.svg").exists()
    assert (folder / "contact_reactions_t1.svg").exists()
    assert main(["plot", str(folder), "--format", "pdf"]) == 0
    assert (folder / "stress.pdf").read_bytes()[:5] == b"%PDF-"
    assert main(["plot", str(folder), "--dpi", "0"]) == 2


@pytest.mark.skipif(COMM.size > 1, reason="the plot command runs on one rank")
def test_plot_at_a_time_without_a_snapshot(paper_folder, tmp_path, capsys):
    """--times 0.5 on the paper run (snapshots at 0.1 and T = 1, contact tables at every
    step): the contact figures at 0.5, the stress map and deformed mesh at the nearest
    snapshot 0.1 with the time in their names, titles and printed lines; the figures at T
    are left as they were."""
    folder = tmp_path / "copy"
    shutil.copytree(paper_folder, folder)
    assert main(["plot", str(folder), "--dpi", "40"]) == 0
    at_T = {p.name: p.read_bytes() for p in folder.glob("*.png")}
    assert {"stress.png", "contact_reactions.png", "deformed_mesh.png"} <= set(at_T)
    capsys.readouterr()
    assert main(["plot", str(folder), "--times", "0.5", "--dpi", "40"]) == 0
    printed = capsys.readouterr().out
    assert "no snapshot at t = 0.5" in printed and "nearest, t = 0.1" in printed
    assert "no contact table" not in printed                   # 0.5 is a step
    names = {p.name for p in folder.glob("*.png")} - set(at_T)
    assert names == {"stress_t0.1.png", "deformed_mesh_t0.1.png", "contact_reactions_t0.5.png",
                     "contact_displacements_t0.5.png"}, names
    assert {p.name: p.read_bytes() for p in folder.glob("*.png") if p.name in at_T} == at_T
    drawn = dict(figures.build_all(folder, times=[0.5]))
    assert "t = 0.1 s" in drawn["stress_t0.1"].axes[0].get_title()
    assert "nearest" in drawn["stress_t0.1"].axes[0].get_title()
    assert "0.5 asked" in drawn["deformed_mesh_t0.1"].axes[0].get_title()
    title = drawn["contact_reactions_t0.5"].axes[0].get_title()
    assert title.startswith("t = 0.5 s") and "nearest" not in title
    notes = []
    drawn = dict(figures.build_all(folder, times=[0.1, 1.0], notes=notes))
    assert not notes and {"stress_t0.1", "stress_t1", "contact_reactions_t1"} <= set(drawn)
    assert all("nearest" not in ax.get_title() for fig in drawn.values() for ax in fig.axes)


def test_step_records_from_either_layout(paper_folder, tmp_path):
    """summary.json with the steps in it, or a small summary and steps.jsonl."""
    if COMM.rank != 0:
        return
    steps = figures.step_records(paper_folder)                  # from steps.jsonl
    assert [s["step"] for s in steps] == list(range(len(steps))) and len(steps) > 1
    folder = tmp_path / "summary_with_steps"                    # the earlier layout
    shutil.copytree(paper_folder, folder)
    summary = json.loads((folder / "summary.json").read_text())
    summary["steps"] = steps
    (folder / "summary.json").write_text(json.dumps(summary))
    (folder / "steps.jsonl").unlink()
    assert figures.step_records(folder) == steps
    cut = tmp_path / "cut"
    shutil.copytree(paper_folder, cut)
    with open(cut / "steps.jsonl", "a") as f:
        f.write('{"step": 99, "t"')                             # a line cut by a hard stop
    assert figures.step_records(cut) == steps
    a = dict(figures.build_all(paper_folder))["probes"]
    b = dict(figures.build_all(folder))["probes"]
    assert not figures.compare_signatures(figures.signature(b), figures.signature(a))


@pytest.mark.skipif(COMM.size > 1, reason="may start a rendering process; run on one rank")
def test_pyvista_rendering_shows_the_colour_range():
    """Two tetrahedra with values 0 and 1 on the colour range (-1, 1): the picture holds
    viridis' middle and last colours and not its first (in this process or in the child
    process, whichever render.in_process_safe() picks on this stack)."""
    pytest.importorskip("pyvista")
    from matplotlib import colormaps

    from contactvisco.post import render
    points = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 1]], float)
    cells = np.array([[0, 1, 2, 3], [1, 2, 3, 4]])
    images = render.images(points, cells, np.zeros_like(points), np.array([0.0, 1.0]),
                           (-1.0, 1.0), [("iso", None), ("face", [0.0, 0.0, -1.0])])
    assert images is not None and len(images) == 2
    rgb = np.concatenate([image[..., :3].reshape(-1, 3) for image in images]).astype(float)
    assert np.mean(np.all(rgb > 250, axis=1)) > 0.3               # a white background
    for end, present in ((0.0, False), (0.5, True), (1.0, True)):
        # lighting scales brightness: compare the colour's direction
        target = np.array(colormaps["viridis"](end)[:3]) * 255
        cosine = rgb @ target / (np.linalg.norm(rgb, axis=1) * np.linalg.norm(target) + 1e-12)
        assert (np.mean(cosine > 0.98) > 0.001) == present, f"viridis({end})"


def test_contact_radius_figure_draws_the_step_records(sphere_creep_folder):
    """An axisymmetric run draws its contact radius: the figure's two lines are the step
    records' node and interpolated radii, and under the held force the interpolated radius
    grows with the creep (a^3 proportional to the creep function, Lee-Radok) as a^2 = R delta
    of the sphere's depth delta."""
    if COMM.rank != 0:
        return
    steps = figures.step_records(sphere_creep_folder)
    drawn = dict(figures.build_all(sphere_creep_folder))
    fig = drawn["contact_radius"]
    renderer = FigureCanvasAgg(fig).get_renderer()
    fig.draw(renderer)
    for text in _drawn_texts(fig):
        assert _inside(text.get_window_extent(renderer), fig.bbox, slack=1.0), text.get_text()
    assert all("(model units)" in text for text in (fig.axes[0].get_xlabel(),
                                                   fig.axes[0].get_ylabel()))
    lines = fig.axes[0].get_lines()
    for line, key in zip(lines, ("node", "interpolated")):
        assert np.array_equal(line.get_ydata(), [s["contact_radius"][key] for s in steps])
    radius = np.array([s["contact_radius"]["interpolated"] for s in steps[1:]])
    assert np.all(np.diff(radius) >= -1e-12) and radius[-1] > radius[0]
    depth = -np.array([s["obstacle"]["displacement"][1] for s in steps[1:]])
    assert np.allclose(radius**2 / depth, 1.0, rtol=0.08)     # R = 1; measured 0.99-1.07


def test_the_obstacle_is_drawn_in_the_deformed_mesh(sphere_creep_folder):
    """sphere_creep's deformed mesh at T shows the sphere's meridian where the sphere is at
    T: every drawn point at distance R = 1 from the centre moved by the last step's
    displacement (which differs from 0: the sphere sinks), and the legend names it."""
    if COMM.rank != 0:
        return
    from matplotlib.collections import LineCollection
    fig = dict(figures.build_all(sphere_creep_folder))["deformed_mesh"]
    steps = figures.step_records(sphere_creep_folder)
    shift = np.asarray(steps[-1]["obstacle"]["displacement"], float)
    assert abs(shift[1]) > 1e-3
    ax = fig.axes[-1]
    drawn = [c for c in ax.collections if isinstance(c, LineCollection)
             and np.allclose(c.get_colors()[0][:3], figures.matplotlib.colors.to_rgb("C3"))]
    assert len(drawn) == 1
    points = np.concatenate(drawn[0].get_segments())
    centre = np.array([0.0, 1.0]) + shift
    assert np.allclose(np.linalg.norm(points - centre, axis=1), 1.0, atol=1e-9)
    assert "obstacle" in [t.get_text() for t in fig.axes[0].get_legend().get_texts()]
