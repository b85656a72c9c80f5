"""Identification on synthetic indentation curves (docs/identification.md): creep of a rigid
sphere into an axisymmetric block (the scene sphere_creep on a coarse mesh: h = 0.04 at the
contact, a block 10 R wide, a/R = 0.1), its depth made by the project's own forward model with
known parameters, then fitted from a start 20-40 % off.

- Noise-free data: the only misfit is the solver's (Newton tolerance), so the identified
  parameters match the true ones to 1e-6 relative, and a parameter that does not change the
  converged solution (the augmentation r of the contact law) is reported as not identifiable.
- Gaussian noise sigma on the depth: the truth lies within 4 standard errors of the estimate
  (a miss has probability below 1e-4 per parameter under the linearized model) and the
  residual variance s^2 estimates sigma^2 (s^2 / sigma^2 inside its chi-square band of m - n
  degrees of freedom at 1e-3 either side).
"""
import pathlib

import numpy as np
import pytest
from mpi4py import MPI

from contactvisco.studies import identification as ident

pytestmark = pytest.mark.skipif(MPI.COMM_WORLD.size > 1, reason="one fit per test, 1 rank")

COARSE = ('geometry.parameters={radius = 10.0, height = 10.0, h_contact = 0.04, h_far = 3.0, '
          'refine = 0.3, growth = 0.15}')
MU0, FRACTION, AUGMENTATION = 0.38461538461538464, 0.5, 60.0
P = -0.0015
PARAMETERS = {
    "mu0": ('key = "viscoelastic.shear.instantaneous"\ninitial = 0.3\nbounds = [0.05, 2.0]\n'
            'scale = "log"'),
    "fraction": 'key = "viscoelastic.shear.fractions.0"\ninitial = 0.4\nbounds = [0.05, 0.9]',
    "tau": 'key = "viscoelastic.shear.tau.0"\ninitial = 1.3\nbounds = [0.1, 10.0]\nscale = "log"',
    "augmentation": ('key = "contact.augmentation"\ninitial = 40.0\nbounds = [10.0, 200.0]\n'
                     'scale = "log"'),
}
TRUE = {"mu0": MU0, "fraction": FRACTION, "augmentation": AUGMENTATION, "tau": 1.0}


def synthetic(folder: pathlib.Path, names, times, sigma=None, seed=0, difference="central",
              jacobian="auto", initial=None):
    """A fit description of `names` with its data made at the true values (noise sigma)."""
    (folder / "data.csv").write_text("t,force,depth\n" + "".join(f"{float(t)!r},{P!r},0\n"
                                                                 for t in times))
    noise = f"noise = {sigma!r}" if sigma else "weight = 1e10"
    text = (f'[fit]\ndifference = "{difference}"\njacobian = "{jacobian}"\n\n'
            f'[[experiment]]\nscene = "sphere_creep"\n'
            f'data = "data.csv"\nset = [\'{COARSE}\']\n{noise}\n\n'
            + "".join(f"[[parameter]]\n{PARAMETERS[n]}\n\n" for n in names))
    (folder / "fit.toml").write_text(text)
    spec = ident.read_fit(folder / "fit.toml")
    for p, value in zip(spec["parameters"], initial or []):
        p["initial"] = value
    (experiment,) = spec["experiments"]
    depth = ident.forward(experiment, spec["parameters"], [TRUE[n] for n in names])
    if sigma:
        depth = depth + sigma * np.random.default_rng(seed).standard_normal(depth.size)
    experiment["depth"] = depth
    return spec


def test_one_modulus_is_recovered_from_noise_free_creep(tmp_path):
    """The relaxing fraction of the shear modulus from three samples of a creep curve, forward
    differences: recovered to 1e-6 relative, with a standard error far below it."""
    spec = synthetic(tmp_path, ["fraction"], [0.0, 1.0, 3.0], difference="forward")
    report = ident.fit(spec)
    (fraction,) = report["parameters"]
    assert report["success"]
    assert fraction["estimate"] == pytest.approx(FRACTION, rel=1e-6)
    assert fraction["standard_error"] < 1e-6 * FRACTION
    assert fraction["identifiable"]


@pytest.mark.slow
def test_moduli_are_recovered_and_an_inert_parameter_is_flagged(tmp_path):
    """mu_0, the relaxing fraction and the contact law's augmentation from seven samples of
    noise-free creep: the moduli to 1e-6 relative; the augmentation changes the converged
    solution by no more than the Newton tolerance, so it is not identifiable (an infinite
    standard error, a warning naming it) and J has rank 2."""
    spec = synthetic(tmp_path, ["mu0", "fraction", "augmentation"],
                     [0.0, 0.25, 0.5, 1.0, 1.5, 2.0, 3.0])
    report = ident.fit(spec)
    mu0, fraction, augmentation = report["parameters"]
    assert mu0["estimate"] == pytest.approx(MU0, rel=1e-6)
    assert fraction["estimate"] == pytest.approx(FRACTION, rel=1e-6)
    assert mu0["identifiable"] and fraction["identifiable"]
    assert not augmentation["identifiable"]
    assert augmentation["standard_error"] == float("inf")
    assert report["rank"] == 2
    assert any(w.startswith("contact.augmentation: not identifiable")
               for w in report["warnings"])


@pytest.mark.slow
def test_with_noise_the_truth_is_within_a_few_standard_errors(tmp_path):
    """mu_0 and the relaxing fraction from 13 samples with noise sigma = 1e-5 (0.1 % of the
    depth); the estimates are off by about their standard errors, not more."""
    sigma = 1e-5
    times = np.linspace(0.0, 3.0, 13)
    spec = synthetic(tmp_path, ["mu0", "fraction"], times, sigma=sigma, seed=0)
    report = ident.fit(spec)
    m, n = len(times), 2
    assert 0.29 < report["s2"] < 2.8              # chi-square(11)/11 at 1e-3 and 1 - 1e-3
    for p, name in zip(report["parameters"], ["mu0", "fraction"]):
        assert p["identifiable"]
        assert 0 < p["standard_error"] < 0.05 * TRUE[name]
        assert abs(p["estimate"] - TRUE[name]) < 4 * p["standard_error"]
    assert report["residual_rms"] < 2 * sigma * np.sqrt(m / (m - n))


def test_sensitivities_recover_three_parameters_from_a_start_30_percent_off(tmp_path):
    """mu_0, the relaxing fraction and its relaxation time from seven samples of noise-free
    creep, each started 30 % off, with the Jacobian of the forward sensitivities: all three to
    1e-6 relative, in one forward run (with its sensitivities) per evaluation."""
    names = ["mu0", "fraction", "tau"]
    start = [0.7 * MU0, 0.7 * FRACTION, 1.3]
    spec = synthetic(tmp_path, names, [0.0, 0.25, 0.5, 1.0, 1.5, 2.0, 3.0],
                     jacobian="sensitivities", initial=start)
    report = ident.fit(spec)
    assert report["success"]
    assert report["jacobian"]["rule"] == "sensitivities"
    for p, name in zip(report["parameters"], names):
        assert p["estimate"] == pytest.approx(TRUE[name], rel=1e-6), name
        assert p["identifiable"]
    # the Jacobian comes with the residual's run at the same parameters: no extra runs
    assert report["evaluations"] == report["residual_evaluations"]


@pytest.mark.slow
def test_two_temperatures_recover_wlf_constants_with_a_modulus(tmp_path):
    """WLF C1, C2 and the relaxing fraction from noise-free creep at two temperatures
    (T_ref - 3 and T_ref + 3, one experiment each, its temperature a fixed scene change),
    each started 30 % off, with the sensitivities through the shift: all three to 1e-6
    relative; C1 and C2 are reported as strongly correlated (two temperatures fix two values
    of log a_T, and C1 C2 nearly sets both near T_ref)."""
    true = {"viscoelastic.C1": 17.44, "viscoelastic.C2": 51.6,
            "viscoelastic.shear.fractions.0": FRACTION}
    start = {"viscoelastic.C1": 1.3 * 17.44, "viscoelastic.C2": 0.7 * 51.6,
             "viscoelastic.shear.fractions.0": 0.7 * FRACTION}
    bounds = {"viscoelastic.C1": [5.0, 40.0], "viscoelastic.C2": [20.0, 200.0],
              "viscoelastic.shear.fractions.0": [0.05, 0.9]}
    (tmp_path / "data.csv").write_text("t,force,depth\n" + "".join(
        f"{t!r},{P!r},0\n" for t in [0.0, 0.5, 1.0, 2.0, 3.0]))
    text = '[fit]\njacobian = "sensitivities"\n\n'
    for temperature in (47.0, 53.0):
        sets = [COARSE, 'viscoelastic.shift="wlf"', "viscoelastic.T_ref=50.0",
                "viscoelastic.C1=17.0", "viscoelastic.C2=50.0",
                f"viscoelastic.temperature={temperature!r}"]
        text += ('[[experiment]]\nscene = "sphere_creep"\ndata = "data.csv"\nset = ['
                 + ", ".join(f"'{s}'" for s in sets) + ']\nweight = 1e10\n\n')
    for key in true:
        text += (f'[[parameter]]\nkey = "{key}"\ninitial = {start[key]!r}\n'
                 f'bounds = {bounds[key]!r}\n\n')
    (tmp_path / "fit.toml").write_text(text)
    spec = ident.read_fit(tmp_path / "fit.toml")
    for experiment in spec["experiments"]:
        experiment["depth"] = ident.forward(experiment, spec["parameters"], list(true.values()))
    report = ident.fit(spec)
    assert report["success"] and report["jacobian"]["rule"] == "sensitivities"
    for p in report["parameters"]:
        assert p["estimate"] == pytest.approx(true[p["key"]], rel=1e-6), p["key"]
    assert any("viscoelastic.C2 and viscoelastic.C1: correlated" in w
               for w in report["warnings"])


def test_relaxation_under_a_measured_depth_recovers_three_parameters(tmp_path):
    """control = "depth": the measured depth (a ramp to 0.01 over t = 0.5, then held) drives the
    sphere as a displacement and the force is fitted. mu_0, the fraction and tau from
    noise-free relaxation, each started 30 % off, with the sensitivities of the reaction
    force: all three to 1e-6 relative."""
    times = [0.0, 0.25, 0.5, 1.0, 1.5, 2.0, 3.0]
    depth = [0.01 * min(t / 0.5, 1.0) for t in times]
    (tmp_path / "data.csv").write_text("t,force,depth\n" + "".join(
        f"{t!r},0,{d!r}\n" for t, d in zip(times, depth)))
    names = ["mu0", "fraction", "tau"]
    text = (f'[fit]\njacobian = "sensitivities"\n\n[[experiment]]\nscene = "sphere_creep"\n'
            f'data = "data.csv"\ncontrol = "depth"\nset = [\'{COARSE}\']\nweight = 1e10\n\n'
            + "".join(f"[[parameter]]\n{PARAMETERS[n]}\n\n" for n in names))
    (tmp_path / "fit.toml").write_text(text)
    spec = ident.read_fit(tmp_path / "fit.toml")
    for p, value in zip(spec["parameters"], [0.7 * MU0, 0.7 * FRACTION, 1.3]):
        p["initial"] = value
    (experiment,) = spec["experiments"]
    force = ident.forward(experiment, spec["parameters"], [TRUE[n] for n in names])
    assert 0 < abs(force[-1]) < 0.8 * abs(force[2])    # it relaxes under the held depth
    experiment["force"] = force
    report = ident.fit(spec)
    assert report["success"] and report["jacobian"]["rule"] == "sensitivities"
    assert report["curves"][0]["quantity"] == "force"
    for p, name in zip(report["parameters"], names):
        assert p["estimate"] == pytest.approx(TRUE[name], rel=1e-6), name


@pytest.mark.slow
def test_the_closed_form_start_and_its_bias(tmp_path):
    """initial = "closed-form" for mu_0 and the fraction. On depths made by the Lee-Radok
    closed form itself (studies.lee_radok) its fit returns the true values (to 1e-8); on the
    forward model's depths (a sphere of finite a/R on a finite block) it is biased, and the
    FE fit started there recovers the truth to 1e-6 with the closed-form values reported
    beside the estimates."""
    from contactvisco.studies import lee_radok
    names = ["mu0", "fraction"]
    times = [0.0, 0.25, 0.5, 1.0, 1.5, 2.0, 3.0]
    spec = synthetic(tmp_path, names, times, jacobian="sensitivities")
    for p in spec["parameters"]:
        p["closed_form"] = True
    (experiment,) = spec["experiments"]
    fe_depth = experiment["depth"]
    true = [TRUE[n] for n in names]
    experiment["depth"] = lee_radok.creep_depth(
        ident._scene(experiment, spec["parameters"], true), experiment["t"],
        experiment["force"], 1.0)
    closed, (curve,) = ident._closed_form_start(spec["experiments"], spec["parameters"])
    assert list(closed.values()) == pytest.approx(true, rel=1e-8)
    # the closed form's curve at its estimates is the data it was fitted to
    assert np.max(np.abs(curve - experiment["depth"])) < 1e-8 * np.max(experiment["depth"])
    experiment["depth"] = fe_depth
    for p in spec["parameters"]:
        p["initial"] = p["bounds"][0] * 1.5
    report = ident.fit(spec)
    bias = [p["closed_form"] / TRUE[n] - 1 for p, n in zip(report["parameters"], names)]
    assert max(abs(b) for b in bias) > 1e-3       # the closed form's bias is visible
    for p, name in zip(report["parameters"], names):
        assert p["estimate"] == pytest.approx(TRUE[name], rel=1e-6), name
        assert p["initial"] == p["closed_form"]


@pytest.mark.slow
def test_tikhonov_pulls_the_moduli_the_data_cannot_fix_to_their_prior(tmp_path):
    """Five fixed relaxation times (0.5, 2, 1e3, 1e4, 1e5) and creep sampled on [0, 3]: the
    data fix the fractions of the first two, not those of the three slow terms (the plain fit
    names them not identifiable). With fit.regularization = w the fit minimizes
    1/2 |r(x)|^2 + w/2 |x - x0|^2, so at its optimum, with r linear near the truth x* of
    noise-free data, (J^T J + w I) (x - x*) = w (x0 - x*): the estimates are the truth plus
    that bias, J^T J + w I = s^2 C_x^-1 from the report itself; the slow fractions sit at
    their prior 0.05, the fast two stay within 1e-3 of the truth."""
    taus, true = [0.5, 2.0, 1e3, 1e4, 1e5], [0.3, 0.2, 0.02, 0.02, 0.02]
    prior = np.array([0.25, 0.25, 0.05, 0.05, 0.05])
    (tmp_path / "data.csv").write_text("t,force,depth\n" + "".join(
        f"{t!r},{P!r},0\n" for t in [0.0, 0.25, 0.5, 1.0, 1.5, 2.0, 3.0]))
    shear = (f"viscoelastic.shear={{instantaneous = {MU0!r}, tau = {taus}, "
             f"fractions = {true}}}")
    reports = {}
    for weight in (0.0, 1.0):
        (tmp_path / "fit.toml").write_text(
            f"[fit]\nregularization = {weight!r}\n\n[[experiment]]\nscene = \"sphere_creep\"\n"
            f"data = \"data.csv\"\nset = ['{COARSE}', '{shear}']\nnoise = 1e-5\n\n" + "".join(
                f'[[parameter]]\nkey = "viscoelastic.shear.fractions.{i}"\n'
                f'initial = {float(g)!r}\nbounds = [0.001, 0.4]\n\n' for i, g in enumerate(prior)))
        spec = ident.read_fit(tmp_path / "fit.toml")
        (experiment,) = spec["experiments"]
        experiment["depth"] = ident.forward(experiment, spec["parameters"], true)
        reports[weight] = ident.fit(spec)
    plain, regular = reports[0.0], reports[1.0]
    assert [p["identifiable"] for p in plain["parameters"]] == [True] * 2 + [False] * 3
    assert regular["regularization"] == {"weight": 1.0, "rows": 5}
    assert all(p["identifiable"] for p in regular["parameters"])
    estimate = np.array([p["estimate"] for p in regular["parameters"]])
    normal = regular["s2"] * np.linalg.inv(np.array(regular["covariance"]))
    predicted = true + np.linalg.solve(normal, 1.0 * (prior - true))
    assert np.max(np.abs(estimate - predicted)) < 1e-6
    assert np.max(np.abs(estimate[:2] - true[:2])) < 1e-3
    assert np.max(np.abs(estimate[2:] - prior[2:])) < 2e-3


def _grid_fit(folder: pathlib.Path, fit_table: str, taus, start, true, times, bounds=(0.0, 0.6),
              extra=""):
    """A fit of the fractions of a fixed-tau shear grid on the coarse sphere_creep, its data
    made by the forward model with the fractions `true` (0 leaves a term out of the data)."""
    (folder / "data.csv").write_text("t,force,depth\n" + "".join(
        f"{float(t)!r},{P!r},0\n" for t in times))
    shear = f"viscoelastic.shear={{instantaneous = {MU0!r}, tau = {list(taus)}, fractions = {start}}}"
    (folder / "fit.toml").write_text(
        f"[fit]\n{fit_table}\n\n[[experiment]]\nscene = \"sphere_creep\"\n"
        f"data = \"data.csv\"\nset = ['{COARSE}', '{shear}']\nnoise = 1e-5\n\n" + "".join(
            f'[[parameter]]\nkey = "viscoelastic.shear.fractions.{i}"\n'
            f'initial = {float(g)!r}\nbounds = {list(bounds)}\n{extra}\n' for i, g in enumerate(start)))
    spec = ident.read_fit(folder / "fit.toml")
    (experiment,) = spec["experiments"]
    kept = [i for i, g in enumerate(true) if g > 0]
    truth = (f"viscoelastic.shear={{instantaneous = {MU0!r}, tau = {[taus[i] for i in kept]}, "
             f"fractions = {[true[i] for i in kept]}}}")
    made = dict(experiment, set=[COARSE, truth])
    experiment["depth"] = ident.forward(made, [], [])
    return spec


@pytest.mark.slow
def test_reduction_keeps_exactly_the_true_terms_of_a_fixed_tau_grid(tmp_path):
    """Non-negative fractions on the fixed grid tau = 0.1, 0.3, 1, 3 (TRF bounds [0, 0.6]),
    noise-free creep made with the two terms at 0.3 and 3 alone (fractions 0.3 and 0.2): the
    fractions at 0.1 and 1 reach the bound 0 and are dropped (below 1e-4 of the sum), the refit
    on the two kept terms recovers them to 1e-6 relative and drops nothing more; the report
    names the dropped terms with their tau and the fitted scene holds the kept ones only."""
    taus, true = [0.1, 0.3, 1.0, 3.0], [0.0, 0.3, 0.0, 0.2]
    spec = _grid_fit(tmp_path, "reduction = true", taus, [0.1, 0.1, 0.1, 0.1], true,
                     [0.0, 0.1, 0.2, 0.4, 0.7, 1.0, 1.5, 2.0, 3.0])
    report = ident.fit(spec)
    assert report["success"]
    dropped = report["reduction"]["dropped"]
    assert sorted(d["tau"] for d in dropped) == [0.1, 1.0]
    assert sorted(d["key"] for d in dropped) == ["viscoelastic.shear.fractions.0",
                                                 "viscoelastic.shear.fractions.2"]
    assert all(d["estimate"] <= 1e-4 * d["sum"] for d in dropped)
    kept = report["parameters"]
    assert [p["key"] for p in kept] == ["viscoelastic.shear.fractions.0",
                                        "viscoelastic.shear.fractions.1"]
    assert [p["description_key"] for p in kept] == ["viscoelastic.shear.fractions.1",
                                                    "viscoelastic.shear.fractions.3"]
    for p, g in zip(kept, [0.3, 0.2]):
        assert p["estimate"] == pytest.approx(g, rel=1e-6)
    assert report["reduction"]["rounds"] == 2
    (scene,) = report["fitted_scene"]
    assert "viscoelastic.shear.tau=[0.3, 3.0]" in scene["set"]
    ident.write(report, tmp_path / "out")
    import json
    written = json.loads((tmp_path / "out" / "fit.json").read_text())
    assert [d["tau"] for d in written["reduction"]["dropped"]] == [d["tau"] for d in dropped]


def test_a_power_kernel_is_fitted_with_sensitivities(tmp_path):
    """alpha and beta of a power memory kernel alpha (1 + t/tau)^-beta (sphere_creep with E = 1,
    nu = 0.3 and the kernel on the deviatoric strain instead of its Prony table) from seven
    samples of noise-free creep, 30 % off: fit.jacobian = "auto" takes the sensitivities (the
    sum of exponentials with its rates kept), and both are recovered to 1e-6 relative though
    the data come from whole runs with the sum fitted at the truth."""
    import contactvisco
    text = (pathlib.Path(contactvisco.__file__).parent / "scenes" / "sphere_creep.toml").read_text()
    text = (text[:text.index("[viscoelastic]")] + 'E = 1.0\nnu = 0.3\n\n[memory]\nkernel = '
            '"power"\nalpha = -0.2\nbeta = 0.5\ntau = 0.5\npart = "deviatoric"\n\n'
            + text[text.index("[[dirichlet]]"):])
    (tmp_path / "power_creep.toml").write_text(text)
    (tmp_path / "data.csv").write_text("t,force,depth\n" + "".join(
        f"{t!r},{P!r},0\n" for t in [0.0, 0.25, 0.5, 1.0, 1.5, 2.0, 3.0]))
    (tmp_path / "fit.toml").write_text(
        f"[[experiment]]\nscene = \"power_creep.toml\"\ndata = \"data.csv\"\n"
        f"set = ['{COARSE}']\nweight = 1e10\n\n"
        '[[parameter]]\nkey = "memory.alpha"\ninitial = -0.14\nbounds = [-1.0, -0.01]\n\n'
        '[[parameter]]\nkey = "memory.beta"\ninitial = 0.65\nbounds = [0.1, 0.9]\n')
    spec = ident.read_fit(tmp_path / "fit.toml")
    (experiment,) = spec["experiments"]
    experiment["depth"] = ident.forward(experiment, spec["parameters"], [-0.2, 0.5])
    report = ident.fit(spec)
    assert report["jacobian"]["rule"] == "sensitivities"
    alpha, beta = report["parameters"]
    assert alpha["estimate"] == pytest.approx(-0.2, rel=1e-6)
    assert beta["estimate"] == pytest.approx(0.5, rel=1e-6)
