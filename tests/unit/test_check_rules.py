"""What `contactvisco check` says of the time rule's stability beyond the paper's number b: the
smallest stiffness of a step A + w P of the implicit rules (w the implicit weight of
eps_{n+1}) per mode of A, in reduced time at the hottest step time, and the exponential rule
of relaxing terms, whose step stiffness stays above the long-term modulus for every k."""
import math

import pytest

from contactvisco import api
from contactvisco.model import viscoelastic as ve
from contactvisco.model.material import lame_constants
from contactvisco.scene import loader as scene_module

SMALL = ["geometry.cells=[4, 4]", "output.probes=[]"]
WLF = {"shift": "wlf", "T_ref": 50.0, "C1": 17.44, "C2": 51.6}


def elastic(scene):
    """(2 mu, d lambda + 2 mu) of the scene's A, d = 2."""
    lam, mu = lame_constants(scene["material"]["model"], scene["material"]["E"],
                             scene["material"]["nu"])
    return 2.0 * mu, 2.0 * lam + 2.0 * mu


@pytest.mark.parametrize("steps", [10, 1])
def test_trapezoid_step_stiffness_of_the_constant_kernel(steps):
    """The paper's scene with alpha = -500: deviatoric 2 mu + k/2 alpha, volumetric
    2 lambda + 2 mu + k/2 alpha (part full); one step of k = 1 loses the deviatoric
    stiffness (2 mu = 76.9 < 250), ten keep it."""
    scene = scene_module.load("paper", SMALL + ["memory.alpha=-500.0", "time.rule='trapezoid'",
                                                f"time.steps={steps}"])
    report = api.check(scene)
    k = scene["time"]["T"] / steps
    dev, vol = elastic(scene)
    margins = report["implicit_stiffness"]
    assert margins["deviatoric"] == pytest.approx((dev - 250.0 * k, dev), rel=1e-12)
    assert margins["volumetric"] == pytest.approx((vol - 250.0 * k, vol), rel=1e-12)
    assert (margins["deviatoric"][0] > 0) == (steps == 10)
    assert not report["unconditionally_stable"]


@pytest.mark.parametrize("memory, stable", [
    (["memory.kernel='exponential'", "memory.alpha=[-300.0]", "memory.tau=[0.05]"], True),
    (["memory.alpha=-300.0"], False),                 # tau = inf: the trapezoid's k/2
])
def test_exponential_rule_unconditionally_stable_for_relaxing_terms(memory, stable):
    """time.rule = 'exponential' with one step of k = 1 >> tau = 0.05: the weight alpha w1 is
    close to alpha tau = -15 (not alpha k/2 = -150), the stiffness stays above 2 mu - 15 > 0
    and the rule is unconditionally stable; the constant kernel's weight is k/2 alpha."""
    scene = scene_module.load("paper", SMALL + memory + ["time.rule='exponential'",
                                                         "time.steps=1"])
    report = api.check(scene)
    dev, _ = elastic(scene)
    assert report["unconditionally_stable"] is stable
    least = report["implicit_stiffness"]["deviatoric"][0]
    if stable:
        assert dev - 15.0 < least < dev - 15.0 * (1.0 - 2.0 * 0.05)  # w1 = tau (1 - phi1)
    else:
        assert least == pytest.approx(dev - 150.0, rel=1e-12)


@pytest.mark.parametrize("temperature", [45.0, "50.0 + 2.0 * t"])
def test_fractional_step_stiffness_in_reduced_time(temperature):
    """The fractional kernel (alpha = -20, beta = 0.5, deviatoric) with a temperature: the
    weight alpha dxi^(1-beta) / Gamma(3 - beta) at dxi = k / a_T, at the hottest step time for
    theta = 50 + 2 t (a_T(52) = 0.19; theta = 45: a_T = 74.3, a slower clock, a stiffer step)."""
    overrides = [f"{key}={value!r}" for key, value in WLF.items()]
    scene = scene_module.load("paper", SMALL + [
        "memory.kernel='fractional'", "memory.alpha=-20.0", "memory.beta=0.5",
        "memory.part='deviatoric'", "time.rule='trapezoid'", "time.steps=4"]
        + [f"viscoelastic.{o}" for o in overrides]
        + [f"viscoelastic.temperature={temperature!r}"])
    report = api.check(scene)
    margins = report["implicit_stiffness"]
    assert report["history_bytes"] > 0                 # the fit's exponentials, per point
    hottest = temperature if isinstance(temperature, float) else 52.0
    dxi = 0.25 * 10.0 ** -float(ve.log10_shift(WLF, hottest))
    dev, _ = elastic(scene)
    assert set(margins) == {"deviatoric"}
    assert margins["deviatoric"][0] == pytest.approx(
        dev - 20.0 * dxi ** 0.5 / math.gamma(2.5), rel=1e-10)
