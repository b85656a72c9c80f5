"""The fit description of docs/identification.md read and checked without a solve, the
measured force as a piecewise-linear force(t), and the statistics at an optimum against the
textbook formulas of linear least squares."""
import math

import numpy as np
import pytest

from contactvisco.errors import SceneError
from contactvisco.scene import expressions
from contactvisco.studies import identification as ident

DATA = "t,force,depth\n0,-0.0015,0.01\n1,-0.0015,0.011\n2,-0.0015,0.012\n"
FIT = """
[[experiment]]
scene = "sphere_creep"
data = "data.csv"
noise = 1e-5

[[parameter]]
key = "viscoelastic.shear.fractions.0"
initial = 0.4
bounds = [0.05, 0.9]
"""


def written(tmp_path, fit=FIT, data=DATA):
    (tmp_path / "data.csv").write_text(data)
    (tmp_path / "fit.toml").write_text(fit)
    return tmp_path / "fit.toml"


def test_a_fit_description_is_read_with_its_data_and_weights(tmp_path):
    spec = ident.read_fit(written(tmp_path))
    (experiment,) = spec["experiments"]
    assert experiment["w"] == pytest.approx(1e5)
    assert experiment["t"].tolist() == [0.0, 1.0, 2.0]
    assert experiment["depth"].tolist() == [0.01, 0.011, 0.012]
    assert spec["parameters"][0]["path"] == ["viscoelastic", "shear", "fractions", "0"]
    assert spec["fit"]["difference"] == "central"


@pytest.mark.parametrize("change, key, words", [
    (("key = \"viscoelastic.shear.fractions.0\"", "key = \"contact.mew\""),
     "parameter[0].key", "unknown scene key"),
    (("key = \"viscoelastic.shear.fractions.0\"", "key = \"contact.boundary\""),
     "parameter[0].key", "not a number"),
    (("bounds = [0.05, 0.9]", "bounds = [0.9, 0.05]"), "parameter[0].bounds", "below"),
    (("initial = 0.4", "initial = 1.4"), "parameter[0].initial", "outside the bounds"),
    (("bounds = [0.05, 0.9]", "bounds = [0.0, 0.9]\nscale = \"log\""),
     "parameter[0].bounds", "> 0"),
    (("noise = 1e-5", "noise = 1e-5\nweight = 2.0"), "experiment[0].noise", "either"),
    (("data = \"data.csv\"", "data = \"../data.csv\""), "experiment[0].data", ".."),
    (("noise = 1e-5", "nois = 1e-5"), "experiment[0].nois", "allowed here"),
    (("[[experiment]]", "[fit]\nmax_evaluations = true\n\n[[experiment]]"),
     "fit.max_evaluations", "integer"),
    (("[[experiment]]", "[fit]\njacobian = \"exact\"\n\n[[experiment]]"),
     "fit.jacobian", "finite-differences"),
    (("noise = 1e-5", "noise = 1e-5\ncontrol = \"stress\""), "experiment[0].control",
     "depth"),
    (("[[experiment]]", "[fit]\nregularization = -1.0\n\n[[experiment]]"),
     "fit.regularization", ">= 0"),
    (("initial = 0.4", "initial = 0.4\nprior = 0.5"), "parameter[0].prior",
     "fit.regularization > 0"),
])
def test_bad_fit_descriptions_name_the_key(tmp_path, change, key, words):
    with pytest.raises(SceneError) as caught:
        ident.read_fit(written(tmp_path, FIT.replace(*change)))
    assert key in str(caught.value) and words in str(caught.value)


@pytest.mark.parametrize("parameter, key, words", [
    ('key = "viscoelastic.shear.fractions.0"\ninitial = 0.4\nbounds = [0.05, 0.9]\n'
     'prior = 0.95', "parameter[0].prior", "outside the bounds"),
    ('key = "contact.mu"\ninitial = 0.1\nbounds = [0.01, 0.9]', "fit.regularization",
     "no parameter is one"),
])
def test_bad_regularizations_name_the_key(tmp_path, parameter, key, words):
    text = "[fit]\nregularization = 1.0\n" + FIT[:FIT.index("[[parameter]]")] + \
        "[[parameter]]\n" + parameter + "\n"
    with pytest.raises(SceneError) as caught:
        ident.read_fit(written(tmp_path, text))
    assert key in str(caught.value) and words in str(caught.value)


REDUCED = 'key = "viscoelastic.shear.fractions.0"\ninitial = 0.4\nbounds = [0.0, 0.9]'


@pytest.mark.parametrize("fit, parameters, key, words", [
    ("reduction = true\nregularization = 1.0", [REDUCED], "fit.reduction",
     "fit.regularization = 1.0"),
    ("reduction = true", [REDUCED, 'key = "viscoelastic.shear.tau.0"\ninitial = 1.0\n'
                                   'bounds = [0.1, 10.0]'], "fit.reduction",
     "parameter[1].key = 'viscoelastic.shear.tau.0' frees one"),
    ("reduction = true", ['key = "contact.mu"\ninitial = 0.1\nbounds = [0.0, 0.9]'],
     "fit.reduction", "no parameter is one"),
    ("reduction = true", [REDUCED.replace("[0.0,", "[0.01,")], "parameter[0].bounds",
     "lower bound of a Prony modulus is 0"),
    ("reduction = true", [REDUCED.replace("[0.0,", "[0.01,") + '\nscale = "log"'],
     "parameter[0].scale", "linear scale"),
    ("reduction = true", [REDUCED.replace("0.4", "0.0")], "parameter[0].initial", "> 0"),
    ("reduction = 1", [REDUCED], "fit.reduction", "true or false"),
    ("reduction = true\nreduction_threshold = 1.0", [REDUCED], "fit.reduction_threshold",
     "(0, 1)"),
])
def test_bad_reductions_name_the_key(tmp_path, fit, parameters, key, words):
    """fit.reduction is refused with free relaxation times, with Tikhonov rows, without a
    Prony modulus, and on a modulus that cannot reach its bound 0."""
    text = f"[fit]\n{fit}\n" + FIT[:FIT.index("[[parameter]]")] + "".join(
        f"[[parameter]]\n{p}\n\n" for p in parameters)
    with pytest.raises(SceneError) as caught:
        ident.read_fit(written(tmp_path, text))
    assert key in str(caught.value) and words in str(caught.value)


def test_a_reduction_fit_description_is_accepted(tmp_path):
    text = "[fit]\nreduction = true\n" + FIT[:FIT.index("[[parameter]]")] + \
        f"[[parameter]]\n{REDUCED}\n"
    spec = ident.read_fit(written(tmp_path, text))
    assert spec["fit"]["reduction"] is True and spec["fit"]["reduction_threshold"] == 1e-4


def test_the_groups_of_ranks_per_fit_communicators(tmp_path):
    """shared: one group; split: min(P, n); auto: split from 2 ranks and 2 experiments; any
    other fit.communicators is refused with the allowed values."""
    assert [ident.groups_of("shared", 4, 3), ident.groups_of("split", 4, 3),
            ident.groups_of("split", 2, 3), ident.groups_of("auto", 2, 1),
            ident.groups_of("auto", 1, 3), ident.groups_of("auto", 2, 2)] == [1, 3, 2, 1, 1, 2]
    with pytest.raises(SceneError, match="fit.communicators.*auto, shared, split"):
        ident.read_fit(written(tmp_path, "[fit]\ncommunicators = \"world\"\n" + FIT))


def test_relaxation_needs_a_force_column(tmp_path):
    with pytest.raises(SceneError, match="experiment\\[0\\].data") as caught:
        ident.read_fit(written(tmp_path, FIT.replace("noise = 1e-5",
                                                     "noise = 1e-5\ncontrol = \"depth\""),
                               data="t,depth\n0,0\n1,0.01\n"))
    assert "'force' column" in str(caught.value)


def test_sensitivities_asked_for_a_key_they_do_not_cover_name_it(tmp_path):
    """fit.jacobian = "sensitivities" with the sphere's radius as a parameter: refused before
    any solve, naming fit.jacobian and the key; "auto" would take finite differences."""
    fit = FIT.replace("[[experiment]]", "[fit]\njacobian = \"sensitivities\"\n\n"
                      "[[experiment]]").replace(
        'key = "viscoelastic.shear.fractions.0"\ninitial = 0.4\nbounds = [0.05, 0.9]',
        'key = "obstacle.radius"\ninitial = 1.0\nbounds = [0.5, 2.0]')
    spec = ident.read_fit(written(tmp_path, fit))
    with pytest.raises(SceneError) as caught:
        ident.fit(spec)
    assert "fit.jacobian" in str(caught.value) and "obstacle.radius" in str(caught.value)


@pytest.mark.parametrize("data, words", [
    ("t,force,depth\n0,-1,0\n0,-1,0\n", "row 3: the times must be >= 0 and increase"),
    ("t,force,depth\n0,-1,0\n1,nan,0\n", "row 3: a value is not finite"),
    ("t,force\n0,-1\n1,-1\n", "no column 'depth'"),
])
def test_bad_data_files_name_the_row(tmp_path, data, words):
    with pytest.raises(SceneError, match="experiment\\[0\\].data") as caught:
        ident.read_fit(written(tmp_path, data=data))
    assert words in str(caught.value)


def test_the_measured_force_is_piecewise_linear_through_the_samples():
    """A ramp and hold sampled at 7 times is two terms; the expression reproduces every
    sample and the linear interpolant between them; a held force is one number."""
    t = np.array([0.0, 0.5, 1.0, 2.0, 3.0, 4.0, 5.0])
    force = np.minimum(t, 1.0) * -2.0
    text = ident.force_expression(t, force)
    assert text.count("min(") == 2
    s = np.linspace(-1.0, 6.0, 57)
    value = [expressions.value_at(text, "force", 2, [0.0, 0.0], v) for v in s]
    assert np.allclose(value, np.interp(s, t, force), rtol=0, atol=1e-15)
    assert ident.force_expression(t, np.full(7, -0.5)) == -0.5
    noisy = -1.0 - 1e-3 * np.sin(np.arange(200.0))
    with pytest.raises(SceneError, match="kinks"):
        ident.force_expression(np.arange(200.0), noisy)


def test_standard_errors_of_a_straight_line_are_the_textbook_ones():
    """For y = a + b t (linear scale) the covariance s^2 (J^T J)^-1 is numpy.polyfit's
    (cov='unscaled' times s^2), and a third parameter with a zero column is not identifiable
    (infinite standard error) rather than fitted."""
    rng = np.random.default_rng(1)
    t = np.linspace(0.0, 1.0, 30)
    y = 0.3 + 2.0 * t + 0.01 * rng.standard_normal(t.size)
    coef, cov = np.polyfit(t, y, 1, cov=True)
    J = np.column_stack([np.ones_like(t), t, np.zeros_like(t)])
    residual = coef[1] + coef[0] * t - y
    params = [{"key": k, "scale": "linear"} for k in ("a", "b", "c")]
    stats = ident.statistics(J, residual, params, np.array([coef[1], coef[0], 1.0]))
    # polyfit scales by the m - n of its two parameters; the third adds a column of zeros
    # and one to n.
    expected = np.sqrt(np.diag(cov)[::-1] * (t.size - 2) / (t.size - 3))
    assert np.allclose(stats["standard_error"][:2], expected, rtol=1e-10)
    assert stats["standard_error"][2] == math.inf
    assert stats["identifiable"] == [True, True, False]
    assert stats["rank"] == 2
    assert stats["correlation"][0][1] == pytest.approx(
        cov[0, 1] / math.sqrt(cov[0, 0] * cov[1, 1]), rel=1e-10)
    assert any(w.startswith("c: not identifiable") for w in stats["warnings"])


def test_a_data_file_that_is_not_text_is_refused(tmp_path):
    path = written(tmp_path)
    (tmp_path / "data.csv").write_bytes(b"t,force,depth\n0,1,\xff\n")
    with pytest.raises(SceneError, match="experiment\\[0\\].data.*not a UTF-8 text file"):
        ident.read_fit(path)


def test_the_closed_form_start_needs_a_creep_experiment(tmp_path):
    """initial = "closed-form" fits the creep experiments only: with every experiment under
    depth control there is none, and the parameter's key is named."""
    text = FIT.replace("noise = 1e-5", 'noise = 1e-5\ncontrol = "depth"').replace(
        "initial = 0.4", 'initial = "closed-form"')
    spec = ident.read_fit(written(tmp_path, text))
    with pytest.raises(SceneError) as caught:
        ident._closed_form_start(spec["experiments"], spec["parameters"])
    assert "parameter[0].initial" in str(caught.value) and "creep" in str(caught.value)
