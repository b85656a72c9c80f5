"""Figures of a finished run, drawn from its output folder alone (`contactvisco plot DIR`
redraws them): the paper's Figures 2-4, the stress on the deformed body, probe histories.

Reads summary.json (step records in it, or in steps.jsonl beside it: see step_records),
contact_nodes.csv and snapshots.npz. Every figure is a matplotlib Figure without pyplot (no
global backend switch, so notebooks keep theirs), sized for a journal column (8.5 cm wide, or
17.8 cm for side-by-side panels) with 7-8 pt text; axes carry the scene's [units]
("(model units)" when it gives none). Stress maps colour by the 1st-99th percentile of the
von Mises stress (the clipping is said on the colour bar): a corner singularity would
otherwise set the range. 2D maps are drawn by matplotlib (vector output stays vector); 3D
bodies are rendered by pyvista (contactvisco.post.render) and framed here.
"""
from __future__ import annotations

import contextlib
import csv
import io
import math
import pathlib

import matplotlib
import numpy as np
from matplotlib.figure import Figure
from matplotlib.collections import LineCollection
from matplotlib.patches import Rectangle

from contactvisco.fem.contact_state import STATUSES
from contactvisco.io import files
from contactvisco.io.output import DamagedFile, load_npz, read_json, read_summary

ZONE_COLOURS = {"separated": "#dddddd", "compliance": "#9ecae1", "bound": "#fdae6b"}
COLUMN = 3.35        # inches: one journal column (8.5 cm)
PAGE = 7.0           # inches: two columns (17.8 cm)
STYLE = {"font.size": 8, "axes.titlesize": 8, "axes.labelsize": 8, "xtick.labelsize": 7,
         "ytick.labelsize": 7, "legend.fontsize": 7, "legend.title_fontsize": 7,
         "lines.linewidth": 1.0, "lines.markersize": 3, "savefig.bbox": "tight",
         "savefig.pad_inches": 0.03, "svg.fonttype": "none", "pdf.fonttype": 42}
# (SVG text stays text and PDF fonts TrueType: labels remain editable and searchable)
PERCENTILES = (1.0, 99.0)   # the colour range of stress maps
SLENDER = 0.45       # height/width under which a 2D body's panels are stacked, page-wide
PANEL_MIN = 1.3      # inches: the least height of a stacked panel (its y label fits beside)
#: Raster resolution of a run's figures: 7-8 pt text and 0.3 pt mesh lines stay legible at
#: 150 dots per inch, and a PNG costs a quarter of the pixels (and of their encoding) of 300
#: dpi; `contactvisco plot DIR --dpi 300` redraws them for print.
DPI = 150


# --- reading a run ------------------------------------------------------------------------


def step_records(folder) -> list[dict]:
    """The step records of a run (steps.jsonl, or the "steps" of an earlier layout's
    summary.json): output.read_summary."""
    return read_summary(folder)["steps"]


def units_of(scene: dict) -> dict:
    """The scene's unit labels (None where not given)."""
    given = scene.get("units") or {}
    if not isinstance(given, dict):
        given = {}
    return {key: given.get(key) for key in ("length", "force", "time")}


def unit(kind: str, units: dict) -> str | None:
    """The unit of a length, force, time or stress (force per length squared)."""
    if kind == "stress":
        if units["force"] and units["length"]:
            return f"{units['force']}/{units['length']}²"
        return None
    return units[kind]


def label(name: str, kind: str, units: dict) -> str:
    """An axis label with its unit: 'u_x [mm]', or 'u_x (model units)'."""
    text = unit(kind, units)
    return f"{name} [{text}]" if text else f"{name} (model units)"


def final_contact_table(path: pathlib.Path, t=None):
    """One step of contact_nodes.csv as arrays (the last, or the one nearest time t), and its
    time."""
    tables = contact_tables(path)
    if not tables:
        return None, None
    times = np.array(sorted(tables))
    chosen = times[-1] if t is None else times[np.argmin(np.abs(times - t))]
    return tables[chosen], float(chosen)


def contact_tables(path: pathlib.Path, steps: int | None = None) -> dict:
    """Every step of contact_nodes.csv: {t: table}. A last row cut by a stop is dropped, and
    with `steps` (the number of step records) the rows of later steps, which a stop may have
    left incomplete; any other damage is a DamagedFile naming the file and line."""
    if files.what(path) is None:
        return {}
    text = files.read_bytes(path).decode(errors="replace")
    lines = text.split("\n")
    reader = csv.reader(io.StringIO(text))
    try:
        header = next(reader)
    except StopIteration:
        return {}
    by_step = {}
    for number, row in enumerate(reader, 2):
        if len(row) != len(header):
            if number >= len(lines) - 1 and not text.endswith("\n"):
                break                    # the last row, cut by a stop
            raise DamagedFile(path, f"line {number} has {len(row)} fields, the header "
                              f"{len(header)}")
        row = dict(zip(header, row))
        with _reading(path, f"line {number}"):
            step = int(row["step"])
        if steps is None or step < steps:
            by_step.setdefault(step, []).append((number, row))
    out = {}
    for group in by_step.values():
        first = group[0][1]
        with _reading(path, f"line {group[0][0]}"):
            coords = [c for c in "xyz" if c in first]
            table = {"x": np.array([[float(row[c]) for c in coords] for _, row in group])}
            for key in ("u_nu", "gap", "u_tau", "reaction_nu", "reaction_tau",
                        "friction_bound"):
                table[key] = np.array([float(row[key]) for _, row in group])
            table["status"] = np.array([STATUSES.index(row["status"]) for _, row in group])
            out[float(first["t"])] = table
    return out


@contextlib.contextmanager
def _reading(path, where: str = ""):
    """Any failure to use what was read from `path` is a DamagedFile naming it."""
    try:
        yield
    except (KeyError, IndexError, TypeError, ValueError, AttributeError) as err:
        raise DamagedFile(path, (f"{where}: " if where else "") + "does not hold what a run "
                          f"writes ({type(err).__name__}: {err})") from None


# --- all figures ----------------------------------------------------------------------------


def draw_all(folder, fmt: str = "png", dpi: int = DPI, times=None,
             edges: bool = False, notes: list | None = None) -> list[pathlib.Path]:
    """Every figure the files in `folder` allow, saved as `fmt`; returns the paths written.
    times: see build_all (figures at requested times carry the time in their file name, so
    they never replace the figures at T); notes: a list that receives the lines saying where
    a figure is drawn at another time than the one requested."""
    folder = pathlib.Path(folder)
    written = []
    with matplotlib.rc_context(STYLE):
        figures = build_all(folder, times, edges, notes)
        paths = [folder / f"{name}.{fmt}" for name, _ in figures]
        for path in paths:              # nothing is written if one of them may not be
            kind = files.what(path)
            if kind:
                raise files.refusal(path, kind, "a figure (a regular file)")
        for path, (_, fig) in zip(paths, figures):
            # Not synced to the disk (durable=False): the rename still leaves the old or the
            # new figure after a stop, and a figure lost to a power cut is redrawn from the
            # synced run files (`contactvisco plot DIR`); a sync costs milliseconds a file.
            files.replace_with(path, lambda f: _save(fig, f, fmt, dpi), durable=False)
            written.append(path)
    return written


def _save(fig: Figure, f, fmt: str, dpi: float) -> None:
    """fig saved as `fmt` into the open file f, cropped to what it draws plus
    savefig.pad_inches (savefig.bbox "tight" of STYLE).

    A PNG is drawn once and cropped to its ink: savefig's tight box draws the figure three
    times (once to lay it out, once to measure the box, once into the cropped canvas), and
    most of a run's figure time went there. The picture is the same (the same layout, drawn
    at the same dpi); the crop follows the drawn pixels instead of the artists' boxes, so it
    may differ from savefig's by the few pixels of empty space a text box holds. Vector
    formats, and rc settings the crop does not know (a transparent or other coloured saved
    background), go through savefig."""
    rc = matplotlib.rcParams
    if fmt != "png" or rc["savefig.transparent"] or rc["savefig.facecolor"] != "auto" or \
            rc["savefig.edgecolor"] != "auto" or rc["savefig.bbox"] != "tight":
        fig.savefig(f, format=fmt, dpi=dpi)
        return
    from matplotlib import image
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    fig.dpi = dpi
    canvas = FigureCanvasAgg(fig)
    canvas.draw()
    pixels = np.asarray(canvas.buffer_rgba())
    image.imsave(f, ink_crop(pixels, round(rc["savefig.pad_inches"] * dpi)), format="png",
                 origin="upper", dpi=dpi)


def ink_crop(pixels: np.ndarray, pad: int) -> np.ndarray:
    """The smallest box of an image that holds every pixel unlike its top left corner (the
    figure's background), widened by `pad` pixels of that background on every side.

    Parameters
    ----------
    pixels : numpy.ndarray
        An image (rows, columns, channels), its first row at the top.
    pad : int
        The margin kept around the drawn pixels, in pixels.

    Returns
    -------
    numpy.ndarray
        out[pad + i, pad + j] = pixels[r0 + i, c0 + j] for r0 <= r0 + i <= r1 and
        c0 <= c0 + j <= c1, where [r0, r1] x [c0, c1] bounds the pixels p with
        p != pixels[0, 0]; the background pixels[0, 0] elsewhere. An image of background
        only is returned whole.
    """
    background = pixels[0, 0]
    if pixels.dtype == np.uint8 and pixels.shape[2:] == (4,) and pixels.flags.c_contiguous:
        words = pixels.view(np.uint32)[..., 0]         # a pixel as one word: 4x fewer tests
        ink = words != words[0, 0]
    else:
        ink = np.any(pixels != background, axis=-1)
    rows, columns = np.flatnonzero(ink.any(axis=1)), np.flatnonzero(ink.any(axis=0))
    if not rows.size:
        return pixels.copy()
    drawn = pixels[rows[0]:rows[-1] + 1, columns[0]:columns[-1] + 1]
    out = np.empty((drawn.shape[0] + 2 * pad, drawn.shape[1] + 2 * pad) + pixels.shape[2:],
                   dtype=pixels.dtype)
    out[...] = background
    out[pad:pad + drawn.shape[0], pad:pad + drawn.shape[1]] = drawn
    return out


def build_all(folder, times=None, edges: bool = False,
              notes: list | None = None) -> list[tuple[str, Figure]]:
    """(file stem, Figure) of every figure of a run folder (not saved).

    times None: the figures at T (stress, contact profiles or map) under their plain names,
    the deformed mesh at every snapshot, the probe histories. times given: the stress maps,
    contact figures and deformed mesh at those times, named with the time drawn
    (stress_t0.5, contact_reactions_t0.5, deformed_mesh_t0.1_1); where the files hold no
    state at a requested time (snapshots are taken at output.figure_times and T only) the
    nearest one is drawn, its title says so and a line is appended to `notes`. The probe
    histories span all times and are drawn only without `times`."""
    folder = pathlib.Path(folder)
    summary = read_json(folder / "summary.json")
    with _reading(folder / "summary.json"):
        scene = summary["scene"]
        units = units_of(scene)
        g = float((scene.get("contact") or {}).get("g") or 0.0)
    steps = step_records(folder)
    notes = [] if notes is None else notes
    requested = None if not times else sorted({float(t) for t in times})
    out = []
    with matplotlib.rc_context(STYLE):
        tables = contact_tables(folder / "contact_nodes.csv", len(steps))
        snapshots = folder / "snapshots.npz"
        if files.what(snapshots) is not None:
            with _reading(snapshots):
                out += _snapshot_figures(load_npz(snapshots), requested, tables, units,
                                         edges, notes, obstacle_at(scene, steps))
        with _reading(folder / "contact_nodes.csv"):
            out += _contact_figures(tables, requested, g, units, notes)
        if requested is None and any(step.get("probes") for step in steps):
            with _reading(folder / "steps.jsonl"):
                out.append(("probes", probe_histories(steps, units)))
        if requested is None and steps and "obstacle" in steps[0]:
            with _reading(folder / "steps.jsonl"):
                out.append(("obstacle", obstacle_history(steps, units)))
        if requested is None and steps and "contact_radius" in steps[0]:
            with _reading(folder / "steps.jsonl"):
                out.append(("contact_radius", contact_radius_history(steps, units)))
        for _, fig in out:
            fit_labels(fig)
    return out


def size_constrained(fig: Figure, width: float, height: float) -> None:
    """Size `fig` to width x height inches and lay it out with matplotlib's constrained
    layout (set_layout_engine from matplotlib 3.6 on, set_constrained_layout before it)."""
    fig.set_size_inches(width, height)
    if hasattr(fig, "set_layout_engine"):
        fig.set_layout_engine("constrained")
    else:
        fig.set_constrained_layout(True)


def fit_labels(fig: Figure, passes: int = 3) -> None:
    """Break every axis label (colour bars' included) longer than its axes onto one more
    line, at the space nearest the middle of its longest line (never inside $...$), until it
    fits: constrained layout and savefig's tight box count an axis label by its middle only,
    so the ends of a longer one would be cut from the saved file."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    for _ in range(passes):
        renderer = FigureCanvasAgg(fig).get_renderer()
        fig.draw(renderer)
        changed = False
        for ax in fig.axes:
            for label, room, along in ((ax.xaxis.label, ax.bbox.width, "width"),
                                       (ax.yaxis.label, ax.bbox.height, "height")):
                text = label.get_text()
                if not text or not label.get_visible():
                    continue
                if getattr(label.get_window_extent(renderer), along) <= room:
                    continue
                broken = _break_longest_line(text)
                if broken != text:
                    label.set_text(broken)
                    changed = True
        if not changed:
            return


def _break_longest_line(text: str) -> str:
    """`text` with its longest line broken at the space nearest that line's middle outside
    $...$ (unchanged when there is none)."""
    lines = text.split("\n")
    i = max(range(len(lines)), key=lambda k: len(lines[k]))
    line, spaces, inside = lines[i], [], False
    for k, char in enumerate(line):
        if char == "$":
            inside = not inside
        elif char == " " and not inside:
            spaces.append(k)
    if not spaces:
        return text
    k = min(spaces, key=lambda k: abs(k - len(line) / 2))
    lines[i] = line[:k] + "\n" + line[k + 1:]
    return "\n".join(lines)


def obstacle_at(scene: dict, steps: list):
    """A function of (t, lower, upper) giving the segments (m, 2, 2) of the scene's rigid
    obstacle (2D: a plane's line, a cylinder's or an axisymmetric sphere's circle) moved
    by its displacement at the step record nearest t, drawn to cover the box [lower,
    upper] (contactvisco.io.obstacle_file.surface); None for a scene without a drawn
    obstacle or without obstacle records."""
    from contactvisco.io.obstacle_file import DRAWN, surface
    obstacle = scene.get("obstacle") or {}
    moves = [(float(s["t"]), s["obstacle"].get("displacement")) for s in steps
             if isinstance(s.get("obstacle"), dict)]
    if obstacle.get("shape") not in DRAWN or not moves:
        return None

    def segments(t, lower, upper):
        drawing = surface(obstacle, np.asarray(lower, float), np.asarray(upper, float))
        if drawing is None or drawing[2] != "Polyline":
            return None
        points, cells, _ = drawing
        shift = min(moves, key=lambda move: abs(move[0] - t))[1]
        xy = points[:, :2] + (np.asarray(shift, float)[:2] if shift is not None else 0.0)
        return xy[np.asarray(cells)]
    return segments


def _snapshot_figures(data, requested, tables, units, edges, notes, obstacle=None) -> list:
    """The deformed mesh and stress figures of the snapshots `data` (build_all)."""
    out = []
    available = np.asarray(data["times"], dtype=float)
    if requested is None:
        chosen = list(range(len(available)))
        asked = {}
    else:
        drawn = "stress map" + (" and deformed mesh" if data["points"].shape[1] == 2
                                else "")
        asked = _matches(available, requested, "snapshot", drawn, notes)
        chosen = sorted(asked)
    if data["points"].shape[1] == 2:
        stem = "deformed_mesh" if requested is None else \
            "deformed_mesh_t" + "_".join(f"{available[i]:g}" for i in chosen)
        out.append((stem, deformed_meshes(data, chosen, units, asked=asked,
                                          obstacle=obstacle)))
    for i in (chosen if requested else chosen[-1:]):
        t = float(available[i])
        stem = "stress" if requested is None else f"stress_t{t:g}"
        table = tables[min(tables, key=lambda time: abs(time - t))] if tables else None
        fig = stress_map(data, i, units, table, edges, asked=asked.get(i))
        if fig is not None:
            out.append((stem, fig))
    return out


def _contact_figures(tables, requested, g, units, notes) -> list:
    """The contact profiles (2D) or status map (3D) of the contact tables (build_all)."""
    out = []
    if tables:
        keys = np.array(sorted(tables))
        if requested is None:
            picks = {len(keys) - 1: None}
        else:
            picks = _matches(keys, requested, "contact table", "contact figures", notes)
        for k in sorted(picks):
            t = float(keys[k])
            suffix = "" if requested is None else f"_t{t:g}"
            if tables[t]["x"].shape[1] == 2:
                for name, fig in contact_profiles(tables[t], t, g, units, picks[k]):
                    out.append((name + suffix, fig))
            else:
                out.append(("contact_status" + suffix,
                            contact_map(tables[t], t, units, picks[k])))
    return out


def obstacle_history(steps: list, units: dict) -> Figure:
    """The obstacle's displacement d and the contact force it exerts on the body against
    time, one line per component (the step records' ``obstacle`` entries).

    Parameters
    ----------
    steps : list of dict
        The step records of steps.jsonl, each with ``obstacle`` = {``displacement``,
        ``force``}.
    units : dict
        The scene's [units] labels.

    Returns
    -------
    matplotlib.figure.Figure
        Two panels: d_j(t) and F_j(t).
    """
    times = [record["t"] for record in steps]
    if "displacement" not in steps[0]["obstacle"]:
        return interface_forces(steps, units)
    d = np.array([record["obstacle"]["displacement"] for record in steps], dtype=float)
    force = np.array([record["obstacle"]["force"] for record in steps], dtype=float)
    fig = Figure(figsize=(PAGE * 0.75, 2.4), layout="constrained")
    axes = fig.subplots(1, 2)
    for j in range(d.shape[1]):
        style = dict(marker="os^"[j], ls=("-", "--", ":")[j], ms=2.5, lw=0.9, color=f"C{j}",
                     label=f"${'xyz'[j]}$")
        axes[0].plot(times, d[:, j], **style)
        axes[1].plot(times, force[:, j], **style)
    axes[0].set_ylabel(label("obstacle displacement $d$", "length", units))
    axes[1].set_ylabel(label("contact force on the body", "force", units))
    for ax in axes:
        ax.set_xlabel(label("t", "time", units))
        ax.axhline(0.0, color="k", lw=0.5)
    axes[1].legend(frameon=False)
    return fig


def interface_forces(steps: list, units: dict) -> Figure:
    """Two bodies in contact: the resultant contact force on the slave and on the master
    body against time, one line per component (the step records' ``obstacle`` entries
    ``slave_force`` and ``master_force``, equal and opposite).

    Parameters
    ----------
    steps : list of dict
        The step records of steps.jsonl.
    units : dict
        The scene's [units] labels.

    Returns
    -------
    matplotlib.figure.Figure
        Two panels: F_s,j(t) and F_m,j(t).
    """
    times = [record["t"] for record in steps]
    fig = Figure(figsize=(PAGE * 0.75, 2.4), layout="constrained")
    axes = fig.subplots(1, 2, sharey=True)
    for ax, key, name in zip(axes, ("slave_force", "master_force"), ("slave", "master")):
        force = np.array([record["obstacle"][key] for record in steps], dtype=float)
        for j in range(force.shape[1]):
            ax.plot(times, force[:, j], marker="os^"[j], ls=("-", "--", ":")[j], ms=2.5,
                    lw=0.9, color=f"C{j}", label=f"${'xyz'[j]}$")
        ax.set_xlabel(label("t", "time", units))
        ax.set_ylabel(label(f"contact force on the {name}", "force", units))
        ax.axhline(0.0, color="k", lw=0.5)
    axes[1].legend(frameon=False)
    return fig


def _matches(available, requested, what: str, drawn: str, notes: list) -> dict:
    """{index of the available time nearest each requested time: the requested times it
    stands for that it is not equal to (None when it is exactly one of them)}; a note for
    every requested time drawn at another."""
    available = np.asarray(available, dtype=float)
    tolerance = 1e-9 * max(1.0, float(np.max(np.abs(available))))
    out = {}
    for t in requested:
        i = int(np.argmin(np.abs(available - t)))
        out.setdefault(i, [])
        if abs(available[i] - t) > tolerance:
            out[i].append(t)
            notes.append(f"no {what} at t = {t:g}: {drawn} drawn at the nearest, "
                         f"t = {available[i]:g} (available: "
                         + ", ".join(f"{a:g}" for a in available[:12])
                         + (", ..." if len(available) > 12 else "") + ")")
    return {i: (ts or None) for i, ts in out.items()}


def _time_text(t: float, units: dict) -> str:
    return f"t = {t:g}" + (f" {units['time']}" if units["time"] else "")


def _asked(asked) -> str:
    """The title line of a figure drawn at another time than the requested ones."""
    if not asked:
        return ""
    return "\n(nearest state kept to the t = " + ", ".join(f"{a:g}" for a in asked) + \
        " asked)"


# --- 2D meshes and stress -------------------------------------------------------------------


def _aspect(points: np.ndarray, *moved: np.ndarray) -> float:
    """Height over width of the box around a 2D body and its deformed shapes."""
    span = np.ptp(np.vstack([points[:, :2], *(m[:, :2] for m in moved)]), axis=0)
    return float(span[1] / span[0]) if span[0] > 0 else 1.0


def _strip_panels(rows: int, aspect: float, below: float):
    """Figure size and panel height for `rows` page-wide panels of a slender body stacked one
    above the other, with `below` inches under them (colour bar, legend). A panel is at least
    PANEL_MIN tall (the body then sits in a wider y-range: adjustable="datalim"), so that an
    axis label fits beside it."""
    panel = max((PAGE - 0.6) * aspect * 1.08, PANEL_MIN)
    return (PAGE, rows * (panel + 0.45) + below), panel


def _under(ax, fig, inches: float):
    """A transform for placing a legend `inches` below the bottom of `ax` (under its tick
    labels and x label), whatever the axes' height."""
    from matplotlib.transforms import offset_copy
    return offset_copy(ax.transAxes, fig=fig, y=-inches, units="inches")


def deformed_meshes(data, indices, units, scale: float = 1.0, asked=None, obstacle=None):
    """Figure 2: the deformed mesh at the chosen snapshots over the undeformed mesh (2D), the
    panels side by side, or stacked for a slender body (height < SLENDER x width); with
    `obstacle` (obstacle_at), the rigid obstacle where it is at each snapshot, in red, the
    view kept on the body."""
    from matplotlib.lines import Line2D
    points, cells = data["points"], data["cells"]
    n = len(indices)
    moved = {i: points + scale * data["displacements"][i] for i in indices}
    aspect = _aspect(points, *moved.values())
    slender = aspect < SLENDER
    if slender:
        size, _ = _strip_panels(n, aspect, 0.55)
    else:
        width = COLUMN if n == 1 else PAGE
        size = (width, width / n * 1.05 + 0.55)
    fig = Figure(figsize=size, layout="constrained")
    axes = fig.subplots(n, 1, squeeze=False)[:, 0] if slender else \
        fig.subplots(1, n, squeeze=False)[0]
    for k, (ax, i) in enumerate(zip(axes, indices)):
        ax.triplot(points[:, 0], points[:, 1], cells, color="0.75", lw=0.3)
        ax.triplot(moved[i][:, 0], moved[i][:, 1], cells, color="C0", lw=0.35)
        drawn_obstacle = obstacle and obstacle(float(data["times"][i]), points.min(axis=0),
                                               points.max(axis=0))
        if drawn_obstacle is not None:
            ax.autoscale_view()
            ax.autoscale(False)            # the view stays on the body: a plane is long
            ax.add_collection(LineCollection(drawn_obstacle, colors="C3", linewidths=1.0))
        ax.set_aspect("equal", adjustable="datalim" if slender else "box")
        ax.set_title(_time_text(float(data["times"][i]), units)
                     + ("" if scale == 1 else f" (displacement x{scale:g})")
                     + _asked((asked or {}).get(i)))
        if not slender or k == n - 1:
            ax.set_xlabel(label("x", "length", units))
        ax.set_ylabel(label("y", "length", units))
    key = axes[-1] if slender else axes[0]
    handles = [Line2D([], [], color="0.75", lw=1.0), Line2D([], [], color="C0", lw=1.0)]
    names = ["undeformed", "deformed" + ("" if scale == 1 else f" (x{scale:g})")]
    if drawn_obstacle is not None:
        handles.append(Line2D([], [], color="C3", lw=1.0))
        names.append("obstacle")
    key.legend(handles, names,
               loc="upper center" if slender else "upper left",
               bbox_to_anchor=(0.5 if slender else 0.0, 0.0),
               bbox_transform=_under(key, fig, 0.36),
               # three entries in one row are wider than one column's figure
               ncol=len(handles) if size[0] > COLUMN or len(handles) < 3 else 2,
               frameon=False)
    return fig


def robust_range(values: np.ndarray) -> tuple[float, float, str]:
    """The 1st-99th percentile of `values` and the colour-bar note that says so (with the
    full range) when it clips."""
    lo, hi = (float(v) for v in np.percentile(values, PERCENTILES))
    vmin, vmax = float(np.min(values)), float(np.max(values))
    if hi <= lo:
        return vmin, vmax, ""
    clipped = lo > vmin or hi < vmax
    note = (f"colours: {PERCENTILES[0]:g}-{PERCENTILES[1]:g}th percentile "
            f"(all: {vmin:.3g} to {vmax:.3g})") if clipped else ""
    return lo, hi, note


def boundary_edges(cells: np.ndarray) -> np.ndarray:
    """Edges (2D: of triangles) that belong to one cell only: the outline."""
    edges = np.sort(np.concatenate([cells[:, [0, 1]], cells[:, [1, 2]], cells[:, [2, 0]]]),
                    axis=1)
    unique, counts = np.unique(edges, axis=0, return_counts=True)
    return unique[counts == 1]


def contact_zone(table) -> np.ndarray | None:
    """Coordinates of the contact nodes that carry a force (not separated)."""
    if table is None:
        return None
    active = table["status"] > 0
    return table["x"][active] if active.any() else None


def zoom_box(points: np.ndarray, zone: np.ndarray | None, fraction: float = 0.15):
    """A square window around the contact zone, when the zone is smaller than `fraction` of
    the body; None otherwise."""
    if zone is None:
        return None
    size = float(np.max(np.ptp(points, axis=0)))
    extent = float(np.max(np.ptp(zone, axis=0)))
    if extent >= fraction * size:
        return None
    half = max(1.5 * extent, 0.02 * size)
    centre = 0.5 * (zone.min(axis=0) + zone.max(axis=0))
    # Shifted into the body's bounding box: the window shows the body, not the space beside.
    lo = np.maximum(centre - half, points.min(axis=0) - 0.05 * half)
    lo = np.minimum(lo, points.max(axis=0) + 0.05 * half - 2 * half)
    return lo, lo + 2 * half


def stress_map(data, index: int, units: dict, table=None, edges: bool = False, asked=None):
    """The deformed body coloured by the von Mises stress (2D: matplotlib, with a zoomed
    second panel on a small contact zone; 3D: pyvista views of the body and of the contact
    face)."""
    values = data["von_mises"][index]
    lo, hi, note = robust_range(values)
    bar_label = label("von Mises stress" + (", in-plane" if data["points"].shape[1] == 2
                                            else ""), "stress", units)
    if note:
        bar_label += "\n" + note
    t_text = _time_text(float(data["times"][index]), units)
    if data["points"].shape[1] == 3:
        return _stress_3d(data, index, (lo, hi), bar_label, t_text, table, edges,
                          _asked(asked))
    points, cells = data["points"], data["cells"]
    moved = points + data["displacements"][index]
    box = zoom_box(points, contact_zone(table))
    panels = 2 if box is not None else 1
    aspect = _aspect(points, moved)
    slender = aspect < SLENDER           # a strip: panels stacked, colour bar underneath
    if slender:
        size, _ = _strip_panels(panels, aspect, 0.85 if note else 0.7)
    else:
        size = (COLUMN if panels == 1 else PAGE, COLUMN * 0.95 if panels == 1 else 3.2)
    fig = Figure(figsize=size, layout="constrained")
    axes = fig.subplots(panels, 1, squeeze=False)[:, 0] if slender else \
        fig.subplots(1, panels, squeeze=False)[0]
    outline = boundary_edges(cells)
    for panel, ax in enumerate(axes):
        mesh = ax.tripcolor(moved[:, 0], moved[:, 1], cells, facecolors=values, cmap="viridis",
                            vmin=lo, vmax=hi, edgecolors="0.25" if edges else "face",
                            linewidth=0.1 if edges else 0.0, antialiased=edges,
                            rasterized=len(cells) > 20000)
        ax.add_collection(LineCollection(points[outline], colors="k", linewidths=0.6))
        ax.set_aspect("equal", adjustable="datalim" if slender else "box")
        ax.set_xlabel(label("x", "length", units))
        ax.set_ylabel(label("y", "length", units))
        if panel == 1:
            ax.set_xlim(box[0][0], box[1][0])
            ax.set_ylim(box[0][1], box[1][1])
            ax.set_title("contact zone (red box)")
            axes[0].add_patch(Rectangle(box[0], *(box[1] - box[0]), fill=False,
                                        edgecolor="C3", lw=0.9))
        else:
            ax.set_title(f"{t_text}; black: undeformed outline{_asked(asked)}")
    if slender:
        bar = fig.colorbar(mesh, ax=list(axes), location="bottom", shrink=0.7, aspect=40,
                           extend=_extend(values, lo, hi))
    else:
        bar = fig.colorbar(mesh, ax=list(axes), shrink=0.9, extend=_extend(values, lo, hi))
    bar.set_label(bar_label)
    return fig


def _extend(values, lo, hi) -> str:
    below, above = np.min(values) < lo, np.max(values) > hi
    return {(False, False): "neither", (True, False): "min", (False, True): "max",
            (True, True): "both"}[(bool(below), bool(above))]


def contact_face_view(points: np.ndarray, table) -> np.ndarray:
    """The direction from which the contact face is seen from outside the body (3D): along
    the axis the contact nodes span least, towards the side they lie on."""
    if table is None:
        return np.array([0.0, 0.0, -1.0])
    x = table["x"]
    axis = int(np.argmin(np.ptp(x, axis=0)))
    side = np.sign(np.mean(x[:, axis]) - np.mean(points[:, axis])) or -1.0
    view = np.zeros(3)
    view[axis] = side
    return view


def _stress_3d(data, index, clim, bar_label, t_text, table, edges, asked_line=""):
    """Two pyvista views (isometric, and the contact face from outside) in one figure with a
    matplotlib colour bar and titles (no text inside the rendering to clip)."""
    from matplotlib import cm, colors

    from contactvisco.post import render
    view = contact_face_view(data["points"], table)
    images = render.images(data["points"], data["cells"], data["displacements"][index],
                           data["von_mises"][index], clim,
                           [("iso", None), ("face", view.tolist())], edges)
    if images is None:
        return None
    fig = Figure(figsize=(PAGE, 3.0), layout="constrained")
    axes = fig.subplots(1, 2)
    face = "xyz"[int(np.argmax(np.abs(view)))]
    titles = (f"{t_text}; black: undeformed edges{asked_line}",
              f"contact face, seen from {'+' if view.max() > 0 else '-'}{face}")
    for ax, image, title in zip(axes, images, titles):
        ax.imshow(image)
        ax.set_axis_off()
        ax.set_title(title)
    mappable = cm.ScalarMappable(colors.Normalize(*clim), "viridis")
    bar = fig.colorbar(mappable, ax=list(axes), shrink=0.85,
                       extend=_extend(data["von_mises"][index], *clim))
    bar.set_label(bar_label)
    return fig


# --- contact boundary -----------------------------------------------------------------------


def _shade_zones(ax, s, status):
    """Shade runs of equal status along the boundary coordinate s: node i owns the interval
    between the midpoints to its neighbours, and a run of nodes of one status is one span
    (one patch per run, not per node: a figure to draw and to lay out stays small)."""
    if len(s) < 2:
        return
    mids = np.concatenate([[s[0]], 0.5 * (s[1:] + s[:-1]), [s[-1]]])
    status = np.asarray(status)
    starts = np.flatnonzero(np.concatenate([[True], status[1:] != status[:-1]]))
    ends = np.append(starts[1:], len(status))
    done = set()
    for first, stop in zip(starts, ends):
        name = STATUSES[status[first]]
        ax.axvspan(mids[first], mids[stop], color=ZONE_COLOURS[name], alpha=0.5, lw=0,
                   label=None if name in done else name)
        done.add(name)


def contact_profiles(table, t: float, g: float, units: dict, asked=None):
    """Figures 3 and 4: reactions and displacements of the contact nodes at time t (2D); the
    axis is cut to the contact zone where that is small (Hertz)."""
    order = np.argsort(table["x"][:, 0])
    s = table["x"][order, 0]
    status = table["status"][order]
    active = s[status > 0]
    window = None
    if active.size and np.ptp(active) < 0.25 * np.ptp(s):
        reach = max(np.ptp(active), np.ptp(s) * 0.01)
        window = (max(s[0], active.min() - 0.5 * reach), min(s[-1], active.max() + 1.0 * reach))
    out = []
    for name, keys, ylabel in (
            ("contact_reactions", (("reaction_nu", "normal $-\\sigma_\\nu$"),
                                   ("reaction_tau", "tangential $\\sigma_\\tau$"),
                                   ("friction_bound", "friction bound $\\mu p_\\nu$")),
             label("traction", "stress", units)),
            ("contact_displacements", (("u_nu", "$u_\\nu$"), ("u_tau", "$u_\\tau$")),
             label("displacement", "length", units))):
        fig = Figure(figsize=(COLUMN, 2.6), layout="constrained")
        ax = fig.subplots()
        _shade_zones(ax, s, status)
        for i, (key, text) in enumerate(keys):
            if key == "friction_bound" and not np.any(table[key]):
                continue                              # no friction: no bound to draw
            style = dict(ls="--", color="k", lw=0.8) if key == "friction_bound" else dict(
                marker="o", ms=2, lw=0.9, color=f"C{i}")
            ax.plot(s, table[key][order], label=text, **style)
        if name == "contact_displacements" and np.isfinite(g):
            ax.plot(s, table["gap"][order] + g, color="k", ls="--", lw=0.8,
                    label="bound $g$ (+ gap)")
        ax.axhline(0.0, color="k", lw=0.5)
        if window is not None:
            ax.set_xlim(*window)
            visible = (s >= window[0]) & (s <= window[1])
            keys_drawn = [key for key, _ in keys if np.any(table[key])]
            if keys_drawn:
                y = np.concatenate([table[key][order][visible] for key in keys_drawn] + [[0.0]])
                pad = 0.08 * (np.ptp(y) or 1.0)
                ax.set_ylim(y.min() - pad, y.max() + pad)
        counts = {st: int(np.sum(table["status"] == i)) for i, st in enumerate(STATUSES)}
        ax.set_title(f"{_time_text(t, units)}: "
                     + ", ".join(f"{count} {st}" for st, count in counts.items())
                     + ("\n(axis cut to the contact zone)" if window is not None else "")
                     + _asked(asked))
        ax.set_xlabel(label("x along the contact boundary", "length", units))
        ax.set_ylabel(ylabel)
        ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.3), ncol=3, frameon=False,
                  handlelength=1.5, columnspacing=1.0)
        out.append((name, fig))
    return out


def contact_map(table, t: float, units: dict, asked=None):
    """The contact nodes of a 3D run in the plane of the contact face, coloured by status,
    with the normal reaction as marker size."""
    fig = Figure(figsize=(COLUMN, 3.3), layout="constrained")
    ax = fig.subplots()
    x = table["x"]
    span = np.ptp(x, axis=0)
    a, b = sorted(np.argsort(span, kind="stable")[-2:])   # the two directions the face spans
    size = 4 + 30 * table["reaction_nu"] / max(table["reaction_nu"].max(), 1e-300)
    for i, name in enumerate(STATUSES):
        mask = table["status"] == i
        ax.scatter(x[mask, a], x[mask, b], s=size[mask], color=ZONE_COLOURS[name],
                   edgecolors="0.3", linewidths=0.3, label=f"{name} ({int(mask.sum())})")
    ax.set_aspect("equal")
    ax.set_xlabel(label("xyz"[a], "length", units))
    ax.set_ylabel(label("xyz"[b], "length", units))
    ax.set_title(f"contact nodes at {_time_text(t, units)}\n(marker area: normal reaction)"
                 + _asked(asked))
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.18), ncol=3, frameon=False)
    return fig


def contact_radius_history(steps: list, units: dict) -> Figure:
    """An axisymmetric body's contact radius against time: the outermost node in contact and
    the edge interpolated between it and the first open node (the step records'
    ``contact_radius``, fem.contact_state.contact_radius).

    Parameters
    ----------
    steps : list of dict
        The step records of steps.jsonl, each with ``contact_radius`` = {``node``,
        ``interpolated``}.
    units : dict
        The scene's [units] labels.

    Returns
    -------
    matplotlib.figure.Figure
        One panel: a(t), both estimates.
    """
    times = [record["t"] for record in steps]
    fig = Figure(figsize=(PAGE * 0.5, 2.4), layout="constrained")
    ax = fig.subplots()
    for j, (key, name) in enumerate((("node", "outermost node in contact"),
                                     ("interpolated", "interpolated edge"))):
        ax.plot(times, [record["contact_radius"][key] for record in steps],
                marker="os"[j], ls=("-", "--")[j], ms=2.5, lw=0.9, color=f"C{j}",
                drawstyle="steps-post" if key == "node" else "default", label=name)
    ax.set_xlabel(label("t", "time", units))
    ax.set_ylabel(label("contact radius $a$", "length", units))
    ax.legend(frameon=False)
    return fig


def probe_histories(steps: list, units: dict):
    """Displacement components at each probe against time."""
    times = [record["t"] for record in steps]
    probes = steps[0]["probes"]
    d = len(probes[0]["x"])
    fig = Figure(figsize=(PAGE if d == 3 else PAGE * 0.75, 2.4), layout="constrained")
    axes = fig.subplots(1, d, squeeze=False)[0]
    for j, probe in enumerate(probes):
        series = np.array([[math.nan] * d if record["probes"][j]["u"] is None
                            else record["probes"][j]["u"] for record in steps], dtype=float)
        text = "(" + ", ".join(f"{c:g}" for c in probe["x"]) + ")"
        # Each probe its own marker and line style (open markers after the first): series
        # that coincide over a time span stay visible one over the other.
        # (markers grow with j, so an earlier one shows inside a later open one)
        style = dict(marker="os^Dv<>"[j % 7], ls=("-", "--", ":", "-.")[j % 4],
                     ms=2.2 + 0.9 * (j % 4), lw=0.9, color=f"C{j % 10}", mfc=None if j == 0 else "none", mew=0.7,
                     zorder=3 + j)
        for i in range(d):
            axes[i].plot(times, series[:, i], label=text, **style)
    for i, ax in enumerate(axes):
        ax.set_xlabel(label("t", "time", units))
        ax.set_ylabel(label(f"$u_{'xyz'[i]}$", "length", units))
        ax.axhline(0.0, color="k", lw=0.5)
    axes[-1].legend(loc="center left", bbox_to_anchor=(1.02, 0.5), title="probe at",
                    frameon=False)
    return fig


def cattaneo_mindlin_figure(results: dict, traction) -> Figure:
    """The tangential traction of a cylinder pressed and then pulled on a plane, against
    Cattaneo (1938) and Mindlin (1949), one panel per Poisson ratio. Nodes that stick:
    filled; that slip: open; separated: grey; dashed: the slip limit mu p of Hertz's pressure;
    dotted: the closed-form stick zone.

    Parameters
    ----------
    results : dict
        {nu: the dict that contactvisco.cattaneo_mindlin returns}.
    traction : callable
        The closed form q(x, a, c, p0, mu) (contactvisco.cattaneo_traction; passed in, since
        post stands below studies).

    Returns
    -------
    matplotlib.figure.Figure
        The figure, one journal page wide.
    """
    with matplotlib.rc_context(STYLE):
        return _cattaneo_mindlin(results, traction)


def _cattaneo_mindlin(results, traction):
    fig = Figure(figsize=(PAGE, 2.7), layout="constrained")
    axes = fig.subplots(1, len(results), squeeze=False, sharey=True)[0]
    for ax, (nu, r) in zip(axes, results.items()):
        a, c, p0, mu = r["a"], r["c"], r["p0"], r.get("mu", 0.3)
        xs = np.linspace(-1.2 * a, 1.2 * a, 241)
        ax.plot(xs / a, traction(xs, a, c, p0, mu) / (mu * p0), "k-", lw=0.9,
                label="Cattaneo-Mindlin")
        ax.plot(xs / a, np.sqrt(np.maximum(0.0, 1 - (xs / a) ** 2)), "k--", lw=0.7,
                label="$\\mu p$ (Hertz)")
        stick, touching = np.asarray(r["stick"]), np.asarray(r["p"]) > 0
        slip = touching & ~stick
        x, q = np.asarray(r["x"]) / a, np.asarray(r["q"]) / (mu * p0)
        ax.plot(x[stick], q[stick], "o", color="C0", ms=2.5, label="stick")
        ax.plot(x[slip], q[slip], "o", mfc="none", color="C1", ms=2.5, mew=0.7, label="slip")
        ax.plot(x[~touching], q[~touching], ".", color="0.6", ms=2.5, label="separated")
        for sign in (-1, 1):
            ax.axvline(sign * c / a, color="k", ls=":", lw=0.7)
        ax.set_title(f"$\\nu$ = {nu:g}\n(a/h = {r['a_over_h']:.0f}, "
                     f"Q/($\\mu$P) = {r['load_ratio']:.2f})")
        ax.set_xlabel("x / a [-]")
    axes[0].set_ylabel("$q / (\\mu p_0)$ [-]")
    axes[-1].legend(loc="center left", bbox_to_anchor=(1.02, 0.5), frameon=False)
    return fig


def relaxation_figure(scene: dict, temperatures=(), times=None, omegas=None) -> Figure:
    """The relaxation moduli of a scene's [viscoelastic] material as entered (shear and bulk,
    or Young's), their storage and loss moduli, and the master curves shifted to other
    temperatures (contactvisco.model.viscoelastic).

    Parameters
    ----------
    scene : dict
        A resolved scene with a [viscoelastic] table.
    temperatures : sequence of float, optional
        Temperatures at which to draw the shifted curves besides T_ref (they need
        viscoelastic.shift): phi(t / a_T), E'(a_T w), E''(a_T w).
    times, omegas : array_like, optional
        The times and angular frequencies; by default four decades beyond the relaxation
        times at every temperature drawn.

    Returns
    -------
    matplotlib.figure.Figure
        Three panels: phi(t) = phi_inf + sum_i phi_i exp(-t/tau_i);
        E'(w) = phi_inf + sum_i phi_i w^2 tau_i^2 / (1 + w^2 tau_i^2);
        E''(w) = sum_i phi_i w tau_i / (1 + w^2 tau_i^2).
    """
    from contactvisco.errors import SceneError
    from contactvisco.model import viscoelastic as ve
    table = scene.get("viscoelastic")
    if table is None or not getattr(table, "functions", None):
        raise SceneError("the relaxation figure needs a scene with [viscoelastic] and its "
                         "relaxation functions (shear and bulk, or young)", key="viscoelastic")
    temperatures = [float(x) for x in temperatures]
    if temperatures and table["shift"] == "none":
        raise SceneError("temperatures other than T_ref need viscoelastic.shift",
                         key="viscoelastic.shift")
    for theta in temperatures:
        error = ve.shift_error(table, theta)
        if error:
            raise SceneError(error, key="viscoelastic.temperature")
    shifts = [(None, 1.0)] + [(x, 10.0 ** float(ve.log10_shift(table, x)))
                              for x in temperatures]
    taus = [tau * a for phi in table.functions.values() for tau in phi.taus
            for _, a in shifts] or [1.0]
    times = np.geomspace(min(taus) / 1e2, max(taus) * 1e2, 300) if times is None else times
    omegas = (np.geomspace(1e-2 / max(taus), 1e2 / min(taus), 300) if omegas is None
              else omegas)
    with matplotlib.rc_context(STYLE):
        fig = Figure(figsize=(PAGE, 2.6), layout="constrained")
        axes = fig.subplots(1, 3)
        units = units_of(scene)
        modulus_unit = unit("stress", units)
        suffix = f" [{modulus_unit}]" if modulus_unit else ""
        T_ref = table["T_ref"]
        for j, (name, phi) in enumerate(table.functions.items()):
            for i, (theta, a) in enumerate(shifts):
                shifted = ve.shifted(phi, math.log10(a))
                at = (f"T_ref = {T_ref:g}" if theta is None and T_ref is not None else
                      "T_ref" if theta is None else f"T = {theta:g}")
                style = dict(color=f"C{j}", ls=("-", "--", ":", "-.")[i % 4], lw=0.9)
                storage, loss = ve.storage_loss(shifted, omegas)
                axes[0].plot(times, ve.relaxation(shifted, times), label=f"{name}, {at}",
                             **style)
                axes[1].plot(omegas, storage, **style)
                axes[2].plot(omegas, loss, **style)
        for ax, title in zip(axes, ("relaxation modulus", "storage modulus",
                                    "loss modulus")):
            ax.set_xscale("log")
            ax.set_title(title)
        axes[1].set_yscale("log")
        if np.any([np.any(line.get_ydata() > 0) for line in axes[2].lines]):
            axes[2].set_yscale("log")
        time_unit = unit("time", units)
        axes[0].set_xlabel("t" + (f" [{time_unit}]" if time_unit else ""))
        axes[0].set_ylabel("$\\phi(t)$" + suffix)
        for ax, name in ((axes[1], "$E\'(\\omega)$"), (axes[2], "$E\'\'(\\omega)$")):
            ax.set_xlabel("$\\omega$" + (f" [1/{time_unit}]" if time_unit else ""))
            ax.set_ylabel(name + suffix)
        # At early times every curve is at phi(0): the lower left corner is free.
        axes[0].legend(frameon=False, fontsize="small", loc="lower left")
    return fig


# --- what a figure shows, for checking committed figures ------------------------------------


def signature(fig: Figure) -> dict:
    """The texts and data of a figure, independent of the matplotlib version's rendering:
    per axes the title, axis labels, limits, legend entries, line data and the colour
    arrays (as summary statistics: their order depends on the mesh numbering)."""
    out = []
    for ax in fig.axes:
        entry = {"title": ax.get_title(), "xlabel": ax.get_xlabel(),
                 "ylabel": ax.get_ylabel(), "lines": [], "arrays": []}
        legend = ax.get_legend()
        if legend is not None:
            entry["legend"] = [t.get_text() for t in legend.get_texts()]
        for line in ax.get_lines():
            xy = np.asarray(line.get_xydata(), dtype=float)
            xy = xy[np.isfinite(xy).all(axis=1)]
            if len(xy) > 200:    # a mesh drawn as lines: its order follows the numbering
                xy = np.percentile(xy, (0, 1, 25, 50, 75, 99, 100), axis=0)
            entry["lines"].append(xy.round(10).tolist())
        for artist in ax.collections:
            values = artist.get_array()
            if values is not None and np.size(values):
                values = np.asarray(values, dtype=float).ravel()
                entry["arrays"].append({"n": int(values.size),
                                        "stats": [float(v) for v in np.percentile(
                                            values, (0, 1, 50, 99, 100))] + [
                                            float(values.mean())],
                                        "clim": [float(c) for c in artist.get_clim()]})
        out.append(entry)
    for legend in fig.legends:
        out.append({"legend": [t.get_text() for t in legend.get_texts()]})
    return {"axes": out}


def compare_signatures(new: dict, old: dict, rtol: float = 1e-4, path: str = "") -> list[str]:
    """Differences between two signatures: texts exactly, numbers to rtol of the largest
    magnitude in the same list."""
    problems = []
    if isinstance(old, dict):
        if not isinstance(new, dict) or set(new) != set(old):
            return [f"{path}: keys {sorted(new) if isinstance(new, dict) else new} != "
                    f"{sorted(old)}"]
        for key in old:
            problems += compare_signatures(new[key], old[key], rtol, f"{path}.{key}")
        return problems
    if isinstance(old, list):
        if not isinstance(new, list) or len(new) != len(old):
            return [f"{path}: length {len(new) if isinstance(new, list) else new} != "
                    f"{len(old)}"]
        b = _numeric(old)
        if b is not None:
            a = _numeric(new)
            scale = max(float(np.max(np.abs(b))) if b.size else 0.0, 1e-12)
            if a is None or a.shape != b.shape or \
                    np.max(np.abs(a - b), initial=0.0) > rtol * scale:
                return [f"{path}: numbers differ by more than {rtol:g} of {scale:.3g}"]
            return []
        for i, (a, b) in enumerate(zip(new, old)):
            problems += compare_signatures(a, b, rtol, f"{path}[{i}]")
        return problems
    if new != old:
        return [f"{path}: {new!r} != {old!r}"]
    return []


def _numeric(value) -> np.ndarray | None:
    """value as a float array if it is a (nested, rectangular) list of numbers."""
    def numbers_only(v):
        return all(numbers_only(x) for x in v) if isinstance(v, list) else \
            isinstance(v, (int, float)) and not isinstance(v, bool)
    if not value or not numbers_only(value):
        return None
    try:
        return np.asarray(value, dtype=float)
    except ValueError:            # ragged
        return None
