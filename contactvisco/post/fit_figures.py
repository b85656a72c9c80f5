"""The figures of a material fit (docs/identification.md), drawn from its output folder alone:
``fit.json`` and ``curves.csv`` as ``contactvisco fit`` writes them.

- ``fit.png``: per experiment the measured curve (depth, or force under depth control), the
  FE fit and, where the start came from the closed form, the Lee-Radok fit, with the
  residuals (measured - fitted) below;
- ``fit_moduli.png``: the fitted relaxation functions (G(t), K(t), or E(t)) with their
  confidence band phi(t) +- q sqrt(g(t)^T C_x g(t)), g = dphi(t)/dx the Jacobian of phi in
  the optimizer's variables, C_x their covariance and q the Student quantile of the report's
  level with m - n degrees of freedom (linear propagation, the delta method);
- ``fit_correlation.png``: the parameters' correlation matrix as an image.
"""
from __future__ import annotations

import csv
import json
import math
import pathlib

import matplotlib
import numpy as np
from matplotlib.figure import Figure

from contactvisco.post.figures import PAGE, STYLE, _save, fit_labels

#: Names of the relaxation functions in the report, as drawn.
SYMBOLS = {"shear": "G(t)", "bulk": "K(t)", "young": "E(t)"}
UNITS = " (model units)"


def read(folder) -> tuple[dict, list]:
    """The report (fit.json) and the curves (curves.csv) of a fit's folder.

    Returns
    -------
    tuple
        (report, curves): per experiment a dict of numpy arrays ``t``, ``measured``,
        ``fitted``, ``closed_form`` (None when not fitted) and its ``quantity``.
    """
    folder = pathlib.Path(folder)
    report = json.loads((folder / "fit.json").read_text())
    rows = {}
    with open(folder / "curves.csv", newline="") as f:
        for row in csv.DictReader(f):
            rows.setdefault(int(row["experiment"]), []).append(row)
    curves = []
    for i in sorted(rows):
        r = rows[i]

        def column(name):
            return np.array([float(x[name]) if x.get(name) else math.nan for x in r])
        closed = column("closed_form_depth")
        curves.append({"t": column("t"), "measured": column("measured_depth"),
                       "fitted": column("fitted_depth"),
                       "closed_form": None if np.all(np.isnan(closed)) else closed,
                       "quantity": r[0].get("quantity") or "depth"})
    return report, curves


def band(function: dict, covariance, quantile: float) -> tuple[np.ndarray, np.ndarray]:
    """phi(t) and the half width q sqrt(diag(g C_x g^T)) of its confidence band.

    Parameters
    ----------
    function : dict
        ``value`` (phi at the report's times) and ``jacobian`` (dphi/dx, len(t) x n).
    covariance : array_like
        C_x, n x n (None entries, undetermined, count as 0: the band then covers the
        determined directions only).
    quantile : float
        q, the Student quantile of the level.
    """
    g = np.asarray(function["jacobian"], float)
    C = np.array([[0.0 if c is None else c for c in row] for row in covariance], float)
    variance = np.einsum("ti,ij,tj->t", g, C, g)
    return np.asarray(function["value"], float), quantile * np.sqrt(np.maximum(variance, 0.0))


def curves_figure(curves: list) -> Figure:
    """Per experiment (a column each) the measured, FE-fitted and closed-form curves against t,
    the residuals below; t on a symmetric log axis (linear below the first sample after 0)
    when the samples span more than two decades."""
    n = len(curves)
    fig = Figure(figsize=(min(PAGE, 0.5 * PAGE * max(n, 1) + 0.3), 4.2),
                 layout="constrained")
    axes = fig.subplots(2, n, squeeze=False, sharex="col",
                        gridspec_kw={"height_ratios": (3, 1.3)})
    for i, c in enumerate(curves):
        top, bottom = axes[0, i], axes[1, i]
        top.plot(c["t"], c["measured"], "o", ms=3, color="C0", label="data")
        top.plot(c["t"], c["fitted"], "-", color="C1", lw=1, label="FE fit")
        bottom.plot(c["t"], c["measured"] - c["fitted"], "o-", ms=2.5, lw=0.8, color="C1")
        if c["closed_form"] is not None:
            top.plot(c["t"], c["closed_form"], "--", color="C2", lw=0.9, label="closed form")
            bottom.plot(c["t"], c["measured"] - c["closed_form"], "x--", ms=3, lw=0.6,
                        color="C2")
        positive = c["t"][c["t"] > 0]
        if positive.size and positive.max() > 100.0 * positive.min():
            first, last = float(positive.min()), float(positive.max())
            top.set_xscale("symlog", linthresh=first)
            # 0 and the decades above the linear part: no tick crowds the 0
            top.set_xticks([0.0] + [10.0 ** k for k in range(math.ceil(math.log10(first)),
                                                             math.floor(math.log10(last)) + 1)])
        top.set_title(f"experiment {i}")
        top.set_ylabel(c["quantity"] + UNITS)
        top.legend(frameon=False, fontsize="small")
        bottom.axhline(0.0, color="0.6", lw=0.5)
        bottom.set_xlabel("t" + UNITS)
        bottom.set_ylabel("data - fit" + UNITS)
    return fig


def moduli_figure(report: dict) -> Figure | None:
    """The fitted relaxation functions with their confidence band (module description);
    None when the report holds none."""
    moduli = report.get("moduli")
    if not moduli:
        return None
    level = report["confidence"]["level"]
    quantile = report["confidence"]["quantile"]
    t = np.asarray(moduli["t"], float)
    fig = Figure(figsize=(PAGE / 2, 3.8), layout="constrained")
    top, bottom = fig.subplots(2, 1, sharex=True, gridspec_kw={"height_ratios": (2, 1)})
    for j, name in enumerate(n for n in SYMBOLS if n in moduli):
        value, half = band(moduli[name], report["covariance"], quantile)
        top.plot(t, value, color=f"C{j}", lw=1, label=SYMBOLS[name])
        # a function the fitted parameters do not change has no band
        if math.isfinite(quantile) and np.any(half > 0):
            top.fill_between(t, value - half, value + half, color=f"C{j}", alpha=0.3, lw=0,
                             label=f"{SYMBOLS[name]}: {level:.0%} band")
            # the band is often thinner than the line: its relative half width below
            bottom.plot(t, 100.0 * half / np.abs(value), color=f"C{j}", lw=1)
    top.set_xscale("log")
    top.set_ylabel("relaxation modulus" + UNITS)
    top.legend(frameon=False, fontsize="small")
    bottom.set_xlabel("t" + UNITS)
    bottom.set_ylabel("band half width [%]")
    bottom.set_ylim(bottom=0.0)
    return fig


def correlation_figure(report: dict) -> Figure:
    """The correlation matrix of the parameters as an image (undetermined entries blank)."""
    keys = [p["key"] for p in report["parameters"]]
    corr = np.array([[math.nan if c is None else c for c in row]
                     for row in report["correlation"]], float)
    n = len(keys)
    size = min(PAGE / 2, 1.6 + 0.35 * n)
    fig = Figure(figsize=(size + 2.4, size), layout="constrained")
    ax = fig.subplots()
    image = ax.imshow(corr, vmin=-1.0, vmax=1.0, cmap="RdBu_r")
    for i in range(n):
        for j in range(n):
            if math.isfinite(corr[i, j]):
                ax.text(j, i, f"{corr[i, j]:+.2f}", ha="center", va="center",
                        fontsize="x-small", color="white" if abs(corr[i, j]) > 0.6 else "k")
    ax.set_xticks(range(n), [str(k) for k in range(n)])
    ax.set_yticks(range(n), [f"{key} ({k})" for k, key in enumerate(keys)])
    ax.set_xlabel("parameter (index)")
    fig.colorbar(image, ax=ax, label="correlation", shrink=0.8)
    return fig


def build(folder) -> list[tuple[str, Figure]]:
    """Every figure of a fit's folder as (stem, Figure), in the figures' style."""
    report, curves = read(folder)
    with matplotlib.rc_context(STYLE):
        made = [("fit", curves_figure(curves)), ("fit_moduli", moduli_figure(report)),
                ("fit_correlation", correlation_figure(report))]
        made = [(stem, fig) for stem, fig in made if fig is not None]
        for _, fig in made:
            fit_labels(fig)
    return made


def draw(folder, dpi: int = 150) -> list[pathlib.Path]:
    """Draw the figures of a fit's folder into it as PNG; returns the paths written."""
    folder = pathlib.Path(folder)
    written = []
    with matplotlib.rc_context(STYLE):
        for stem, fig in build(folder):
            path = folder / f"{stem}.png"
            with open(path, "wb") as f:
                _save(fig, f, "png", dpi)
            written.append(path)
    return written
