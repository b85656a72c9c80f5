"""The figures of a fit (contactvisco.post.fit_figures, docs/identification.md), drawn from
its output folder alone: the curves with the closed-form fit and the residuals, the shear
relaxation modulus with its 95 % band, the correlation matrix. The band's half width at one
time is computed here independently from the Prony form of sphere_creep's shear modulus,
G(t) = mu_0 (1 - g (1 - exp(-t/tau))), its gradient in x = (ln mu_0, g) and the covariance
fit.json reports; no text of any figure leaves it."""
import csv
import json
import math

import numpy as np
import pytest
from matplotlib.backends.backend_agg import FigureCanvasAgg
from mpi4py import MPI
from scipy.stats import t as student

from contactvisco.post import figures, fit_figures
from contactvisco.studies import identification as ident
from test_figures import _drawn_texts, _inside
from test_identification import COARSE, MU0, FRACTION, P

pytestmark = pytest.mark.skipif(MPI.COMM_WORLD.size > 1, reason="one fit per test, 1 rank")

TIMES = [0.0, 0.25, 0.5, 1.0, 1.5, 2.0, 3.0]
SIGMA = 1e-5


@pytest.fixture(scope="module")
def fitted(tmp_path_factory):
    """mu_0 (log scale) and the fraction from seven noisy samples of creep, both started
    from the closed form, written with ident.write."""
    folder = tmp_path_factory.mktemp("fit")
    (folder / "data.csv").write_text("t,force,depth\n" + "".join(
        f"{t!r},{P!r},0\n" for t in TIMES))
    (folder / "fit.toml").write_text(
        f'[[experiment]]\nscene = "sphere_creep"\ndata = "data.csv"\nset = [\'{COARSE}\']\n'
        f'noise = {SIGMA!r}\n\n'
        '[[parameter]]\nkey = "viscoelastic.shear.instantaneous"\ninitial = "closed-form"\n'
        'bounds = [0.05, 2.0]\nscale = "log"\n\n'
        '[[parameter]]\nkey = "viscoelastic.shear.fractions.0"\ninitial = "closed-form"\n'
        'bounds = [0.05, 0.9]\n')
    spec = ident.read_fit(folder / "fit.toml")
    (experiment,) = spec["experiments"]
    depth = ident.forward(experiment, spec["parameters"], [MU0, FRACTION])
    experiment["depth"] = depth + SIGMA * np.random.default_rng(1).standard_normal(depth.size)
    report = ident.fit(spec)
    out = folder / "out"
    ident.write(report, out)
    return out


def test_the_figures_exist_and_nothing_is_clipped(fitted):
    for stem in ("fit", "fit_moduli", "fit_correlation"):
        assert (fitted / f"{stem}.png").stat().st_size > 0
    with figures.matplotlib.rc_context(figures.STYLE):
        pad = figures.matplotlib.rcParams["savefig.pad_inches"]
        for stem, fig in fit_figures.build(fitted):
            renderer = FigureCanvasAgg(fig).get_renderer()
            fig.draw(renderer)
            inches = fig.dpi_scale_trans.inverted()
            kept = fig.get_tightbbox(renderer).padded(pad)
            for text in _drawn_texts(fig):
                box = text.get_window_extent(renderer).transformed(inches)
                assert _inside(box, fig.bbox_inches) and _inside(box, kept), \
                    f"{stem}: '{text.get_text()}' at {box} beyond the figure"
            assert fig.get_size_inches()[0] <= figures.PAGE + 1e-9


def test_the_curves_show_the_closed_form_fit(fitted):
    """The closed-form curve (Lee-Radok at its own estimates) is drawn and differs from the
    FE fit (its bias), which lies within 4 sigma of the data."""
    report, (curve,) = fit_figures.read(fitted)
    assert curve["closed_form"] is not None
    assert np.max(np.abs(curve["fitted"] - curve["measured"])) < 4 * SIGMA
    assert np.max(np.abs(curve["closed_form"] - curve["fitted"])) > 4 * SIGMA
    (fig,) = [f for stem, f in fit_figures.build(fitted) if stem == "fit"]
    labels = [line.get_label() for line in fig.axes[0].lines]
    assert "closed form" in labels and "FE fit" in labels


def test_the_band_has_the_width_the_covariance_gives(fitted):
    report = json.loads((fitted / "fit.json").read_text())
    with open(fitted / "curves.csv", newline="") as f:
        m = len(list(csv.DictReader(f)))
    mu0, g = (p["estimate"] for p in report["parameters"])
    C = np.array(report["covariance"])
    (fig,) = [f for stem, f in fit_figures.build(fitted) if stem == "fit_moduli"]
    ax = fig.axes[0]
    (line,) = [ln for ln in ax.lines if ln.get_label() == "G(t)"]
    t, G = line.get_xdata(), line.get_ydata()
    polygon = ax.collections[0].get_paths()[0].vertices
    # the band holds the fitted G(t) at every t drawn
    for tk, Gk in zip(t[::20], G[::20]):
        ys = polygon[np.isclose(polygon[:, 0], tk, rtol=1e-12), 1]
        assert ys.min() <= Gk <= ys.max()
    k = int(np.argmin(np.abs(t - 1.0)))
    tk = t[k]
    relaxed = 1.0 - math.exp(-tk)
    assert G[k] == pytest.approx(mu0 * (1.0 - g * relaxed), rel=1e-12)
    gradient = np.array([mu0 * (1.0 - g * relaxed), -mu0 * relaxed])   # d/d ln mu_0, d/dg
    half = student.ppf(0.975, m - 2) * math.sqrt(gradient @ C @ gradient)
    ys = polygon[np.isclose(polygon[:, 0], tk, rtol=1e-12), 1]
    assert (ys.max() - ys.min()) / 2 == pytest.approx(half, rel=1e-6)
    assert half > 1e-4 * G[k]         # a band that shows
    # the parameters' intervals agree with the same quantile
    lo, hi = report["parameters"][1]["interval"]
    se = report["parameters"][1]["standard_error"]
    assert (hi - lo) / 2 == pytest.approx(student.ppf(0.975, m - 2) * se, rel=1e-9)


def test_the_fitted_scene_runs_as_written(fitted):
    """fitted_0.toml, read back as a scene file, holds the estimates of fit.json to the last
    digit, and runs: on its own grid (k = 0.25) its depths at the samples up to t = 0.5, where
    that grid and the fit's (the sample times) coincide, and on the fit's grid at every
    sample, are the fitted depths of curves.csv to the Newton tolerance (sphere_creep holds
    the data's force P from t = 0)."""
    from contactvisco.scene import loader
    from contactvisco.solver.time_loop import simulate
    report, (curve,) = fit_figures.read(fitted)
    estimates = {p["key"]: p["estimate"] for p in report["parameters"]}
    times = ", ".join(repr(float(t)) for t in curve["t"] if t > 0)
    grid = f'time={{grid = "times", times = [{times}]}}'
    for sets, samples in (([], curve["t"] <= 0.5), ([grid], curve["t"] >= 0)):
        scene = loader.load(str(fitted / "fitted_0.toml"), ["output.figures=false", *sets])
        shear = scene["viscoelastic"]["shear"]
        assert shear["instantaneous"] == estimates["viscoelastic.shear.instantaneous"]
        assert shear["fractions"][0] == estimates["viscoelastic.shear.fractions.0"]
        result = simulate(scene, comm=MPI.COMM_WORLD, progress=False)
        depth = {round(s["t"], 9): -s["obstacle"]["displacement"][1] for s in result.steps}
        ran = np.array([depth[round(t, 9)] for t in curve["t"][samples]])
        assert np.max(np.abs(ran - curve["fitted"][samples])) < 1e-8 * np.max(curve["fitted"])
