"""Figures in the manner of the paper's Figures 2-4 (matplotlib, no display needed)."""
from __future__ import annotations

import pathlib

import numpy as np
# Figures without pyplot: no global backend switch, so notebooks keep their inline backend.
from matplotlib.figure import Figure

from .output import STATUSES

ZONE_COLOURS = {"separated": "#dddddd", "compliance": "#9ecae1", "bound": "#fdae6b"}


def deformed_meshes(snapshots, path: pathlib.Path, scale: float = 1.0):
    """Figure 2: the deformed mesh at each snapshot (t, points, triangles, displacement),
    over the undeformed outline."""
    fig = Figure(figsize=(4.2 * len(snapshots), 4.2))
    axes = fig.subplots(1, len(snapshots), squeeze=False)
    for ax, (t, points, triangles, disp) in zip(axes[0], snapshots):
        ax.triplot(points[:, 0], points[:, 1], triangles, color="0.85", lw=0.4)
        moved = points + scale * disp
        ax.triplot(moved[:, 0], moved[:, 1], triangles, color="C0", lw=0.5)
        ax.set_aspect("equal")
        ax.set_title(f"t = {t:g}" + ("" if scale == 1 else f" (displacement x{scale:g})"))
        ax.set_xlabel("x")
        ax.set_ylabel("y")
    fig.tight_layout()
    fig.savefig(path, dpi=110)


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
    """Figures 3 and 4: reactions and displacements of the contact nodes at time t."""
    s = table["x"][:, 0]
    for name, keys, ylabel in (
            ("reactions", (("reaction_nu", "normal reaction $-\\sigma_\\nu$"),
                           ("reaction_tau", "tangential reaction $\\sigma_\\tau$"),
                           ("radius", "friction bound $\\mu p_\\nu(u_\\nu)$")), "traction"),
            ("displacements", (("u_nu", "$u_\\nu$"), ("u_tau", "$u_\\tau$")), "displacement")):
        fig = Figure(figsize=(6.4, 3.8))
        ax = fig.subplots()
        _shade_zones(ax, s, table["status"])
        for i, (key, label) in enumerate(keys):
            style = dict(ls="--", color="k", lw=0.9) if key == "radius" else dict(
                marker="o", ms=3, lw=1, color=f"C{i}")
            ax.plot(s, table[key], label=label, **style)
        if name == "displacements" and np.isfinite(g):
            ax.axhline(g, color="k", ls="--", lw=0.8, label="bound g")
        ax.axhline(0.0, color="k", lw=0.5)
        counts = {st: int(np.sum(table["status"] == i)) for i, st in enumerate(STATUSES)}
        ax.set_title(f"contact boundary at t = {t:g}: "
                     + ", ".join(f"{v} {k}" for k, v in counts.items()))
        ax.set_xlabel("x along the contact boundary")
        ax.set_ylabel(ylabel)
        ax.legend(fontsize=8, loc="best")
        fig.tight_layout()
        fig.savefig(folder / f"contact_{name}.png", dpi=130)
