"""Figures of a finished run, drawn from its output folder alone (`contactvisco plot DIR`
redraws them): the paper's Figures 2-4, the stress on the deformed body, probe histories.

Reads summary.json and steps.jsonl, contact_nodes.csv and snapshots.npz. Line plots use matplotlib without
pyplot (no global backend switch, so notebooks keep theirs); the stress rendering uses pyvista
off screen, in a child process (contactvisco.render).
"""
from __future__ import annotations

import csv
import json
import pathlib

import numpy as np
from matplotlib.figure import Figure

from .output import STATUSES, read_summary

ZONE_COLOURS = {"separated": "#dddddd", "compliance": "#9ecae1", "bound": "#fdae6b"}


def draw_all(folder) -> list[pathlib.Path]:
    """Every figure the files in `folder` allow; returns the paths written."""
    folder = pathlib.Path(folder)
    summary = read_summary(folder)
    written = []
    snapshots = folder / "snapshots.npz"
    if snapshots.exists():
        data = np.load(snapshots)
        if data["points"].shape[1] == 2:
            written.append(deformed_meshes(data, folder / "deformed_mesh.png"))
        written.append(stress_rendering(snapshots, folder / "stress.png"))
    table, t = final_contact_table(folder / "contact_nodes.csv")
    if table is not None:
        g = float(summary["scene"]["contact"]["g"])
        if table["x"].shape[1] == 2:
            written += contact_profiles(table, t, g, folder)
        else:
            written.append(contact_map(table, t, folder / "contact_status.png"))
    if any(step["probes"] for step in summary["steps"]):
        written.append(probe_histories(summary, folder / "probes.png"))
    return [p for p in written if p is not None]


def final_contact_table(path: pathlib.Path):
    """The last step of contact_nodes.csv as arrays, and its time."""
    if not path.exists():
        return None, None
    with open(path) as f:
        rows = list(csv.DictReader(f))
    if not rows:
        return None, None
    last = rows[-1]["step"]
    rows = [r for r in rows if r["step"] == last]
    coords = [c for c in "xyz" if c in rows[0]]
    table = {"x": np.array([[float(r[c]) for c in coords] for r in rows])}
    for key in ("u_nu", "gap", "u_tau", "reaction_nu", "reaction_tau", "friction_bound"):
        table[key] = np.array([float(r[key]) for r in rows])
    table["status"] = np.array([STATUSES.index(r["status"]) for r in rows])
    return table, float(rows[0]["t"])


def deformed_meshes(data, path: pathlib.Path, scale: float = 1.0):
    """Figure 2: the deformed mesh at each snapshot, over the undeformed mesh (2D)."""
    times, points, cells = data["times"], data["points"], data["cells"]
    fig = Figure(figsize=(4.2 * len(times), 4.2))
    axes = fig.subplots(1, len(times), squeeze=False)
    for ax, t, disp in zip(axes[0], times, data["displacements"]):
        ax.triplot(points[:, 0], points[:, 1], cells, color="0.85", lw=0.4)
        moved = points + scale * disp
        ax.triplot(moved[:, 0], moved[:, 1], cells, color="C0", lw=0.5)
        ax.set_aspect("equal")
        ax.set_title(f"t = {t:g}" + ("" if scale == 1 else f" (displacement x{scale:g})"))
        ax.set_xlabel("x")
        ax.set_ylabel("y")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    return path


def stress_rendering(snapshots: pathlib.Path, path: pathlib.Path):
    """The deformed body coloured by the von Mises stress (contactvisco.render), drawn in a
    child process: VTK's wheel aborts (std::regex, bad_alloc) when drawn in a process that has
    loaded DOLFINx and PETSc, and an abort would take the run with it. Returns the path, or
    None (with a warning) if pyvista is missing or the drawing failed."""
    import subprocess
    import sys
    try:
        proc = subprocess.run([sys.executable, "-m", "contactvisco.render", str(snapshots),
                               str(path)], capture_output=True, text=True, timeout=300)
    except subprocess.TimeoutExpired:
        proc = None
    if proc is not None and proc.returncode == 0 and path.exists():
        return path
    reason = "timed out" if proc is None else (proc.stderr.strip().splitlines() or ["?"])[-1]
    print(f"contactvisco: warning: no {path.name}: {reason}", file=sys.stderr)
    return None


def _shade_zones(ax, s, status):
    """Shade runs of equal status along the boundary coordinate s."""
    if len(s) < 2:
        return
    mids = np.concatenate([[s[0]], 0.5 * (s[1:] + s[:-1]), [s[-1]]])
    done = set()
    for i, st in enumerate(status):
        name = STATUSES[st]
        ax.axvspan(mids[i], mids[i + 1], color=ZONE_COLOURS[name], alpha=0.5, lw=0,
                   label=None if name in done else name)
        done.add(name)


def contact_profiles(table, t: float, g: float, folder: pathlib.Path):
    """Figures 3 and 4: reactions and displacements of the contact nodes at time t (2D)."""
    order = np.argsort(table["x"][:, 0])
    s = table["x"][order, 0]
    written = []
    for name, keys, ylabel in (
            ("reactions", (("reaction_nu", "normal reaction $-\\sigma_\\nu$"),
                           ("reaction_tau", "tangential reaction $\\sigma_\\tau$"),
                           ("friction_bound", "friction bound $\\mu p_\\nu$")), "traction"),
            ("displacements", (("u_nu", "$u_\\nu$"), ("u_tau", "$u_\\tau$")), "displacement")):
        fig = Figure(figsize=(6.4, 3.8))
        ax = fig.subplots()
        _shade_zones(ax, s, table["status"][order])
        for i, (key, label) in enumerate(keys):
            style = dict(ls="--", color="k", lw=0.9) if key == "friction_bound" else dict(
                marker="o", ms=3, lw=1, color=f"C{i}")
            ax.plot(s, table[key][order], label=label, **style)
        if name == "displacements" and np.isfinite(g):
            ax.plot(s, table["gap"][order] + g, color="k", ls="--", lw=0.8,
                    label="bound g (+ gap)")
        ax.axhline(0.0, color="k", lw=0.5)
        counts = {st: int(np.sum(table["status"] == i)) for i, st in enumerate(STATUSES)}
        ax.set_title(f"contact boundary at t = {t:g}: "
                     + ", ".join(f"{v} {k}" for k, v in counts.items()), fontsize=10)
        ax.set_xlabel("x along the contact boundary")
        ax.set_ylabel(ylabel)
        ax.legend(fontsize=8, loc="best")
        fig.tight_layout()
        path = folder / f"contact_{name}.png"
        fig.savefig(path, dpi=130)
        written.append(path)
    return written


def contact_map(table, t: float, path: pathlib.Path):
    """The contact nodes of a 3D run in the plane of the contact face, coloured by status,
    with the normal reaction as marker size."""
    fig = Figure(figsize=(5.6, 4.8))
    ax = fig.subplots()
    x = table["x"]
    span = np.ptp(x, axis=0)
    a, b = sorted(np.argsort(span, kind="stable")[-2:])   # the two directions the face spans
    size = 10 + 60 * table["reaction_nu"] / max(table["reaction_nu"].max(), 1e-300)
    for i, name in enumerate(STATUSES):
        mask = table["status"] == i
        ax.scatter(x[mask, a], x[mask, b], s=size[mask], color=ZONE_COLOURS[name],
                   edgecolors="0.3", linewidths=0.4, label=f"{name} ({int(mask.sum())})")
    ax.set_aspect("equal")
    ax.set_xlabel("xyz"[a])
    ax.set_ylabel("xyz"[b])
    ax.set_title(f"contact nodes at t = {t:g} (size: normal reaction)", fontsize=10)
    ax.legend(fontsize=8, loc="upper center", bbox_to_anchor=(0.5, -0.12), ncol=3)
    fig.tight_layout()
    fig.savefig(path, dpi=130)
    return path


def probe_histories(summary: dict, path: pathlib.Path):
    """Displacement components at each probe against time."""
    steps = summary["steps"]
    t = [s["t"] for s in steps]
    probes = steps[0]["probes"]
    d = len(probes[0]["x"])
    fig = Figure(figsize=(4.0 * d, 3.6))
    axes = fig.subplots(1, d, squeeze=False)[0]
    for j, probe in enumerate(probes):
        series = np.array([s["probes"][j]["u"] for s in steps], dtype=float)
        label = "(" + ", ".join(f"{c:g}" for c in probe["x"]) + ")"
        for i in range(d):
            axes[i].plot(t, series[:, i], "o-", ms=3, lw=1, label=label)
    for i, ax in enumerate(axes):
        ax.set_xlabel("t")
        ax.set_ylabel(f"$u_{'xyz'[i]}$")
        ax.axhline(0.0, color="k", lw=0.5)
    axes[-1].legend(fontsize=8, title="probe", title_fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    return path
