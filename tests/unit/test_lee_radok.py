"""The Lee-Radok closed form of a fit's start (contactvisco.studies.lee_radok) against the
project's one-term formula (studies.indentation.SphereLeeRadok), Hertz, and the limits of a
creep compliance of several Prony terms."""
import numpy as np
import pytest

from contactvisco.scene import loader
from contactvisco.studies import lee_radok
from contactvisco.studies.indentation import SphereLeeRadok


def test_one_deviatoric_term_is_the_sphere_formula():
    scene = loader.load("sphere_creep", [])
    ((alpha, tau, part),) = [(t["alpha"], t["tau"], t["part"]) for t in scene["memory"]["terms"]]
    assert part == "deviatoric"
    t = np.linspace(0.0, 3.0, 7)
    depth = lee_radok.creep_depth(scene, t, np.full(7, -0.0015), 1.0)
    reference = SphereLeeRadok(scene["material"]["E"], scene["material"]["nu"], alpha, tau,
                               1.0).radius(0.0015, t) ** 2
    assert np.abs(depth / reference - 1).max() < 1e-12


def test_an_elastic_body_under_a_ramp_follows_hertz():
    """A relaxation time of 1e12 (an elastic body over t <= 2): a^3 = 3 R P(t) / (4 E*) at
    every time of a ramp, E* = E / (1 - nu^2) of the instantaneous moduli."""
    scene = loader.load("sphere_creep", ["viscoelastic.shear.tau=[1e12]"])
    t = np.linspace(0.0, 2.0, 9)
    force = -0.002 * np.minimum(t + 0.1, 1.0)
    E, nu = scene["material"]["E"], scene["material"]["nu"]
    a = (3.0 * 2.0 * np.abs(force) / (4.0 * E / (1.0 - nu ** 2))) ** (1.0 / 3.0)
    assert lee_radok.creep_depth(scene, t, force, 2.0) == pytest.approx(a * a / 2.0,
                                                                          rel=1e-9)


def test_a_compliance_of_several_terms_has_its_limits():
    """J(0) = 1/G(0), J(inf) = 1/G_inf, and J grows monotonically, for three terms."""
    infinite, terms = 0.2, {0.1: 0.3, 1.0: 0.2, 10.0: 0.1}
    c0, rho, rates = lee_radok.compliance(infinite, terms)
    J = lambda t: c0 + np.sum(rho * np.exp(rates * t))     # noqa: E731
    assert J(0.0) == pytest.approx(1.0 / (infinite + sum(terms.values())), rel=1e-12)
    assert J(1e4) == pytest.approx(1.0 / infinite, rel=1e-12)
    values = [J(t) for t in np.logspace(-3, 3, 50)]
    assert np.all(np.diff(values) >= 0) and values[-1] > 1.5 * values[0]
