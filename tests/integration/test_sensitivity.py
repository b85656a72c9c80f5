"""Forward sensitivities through the time loop (contactvisco.solver.sensitivity,
docs/identification.md) against central differences of whole forward runs, on creep of a rigid
sphere into an axisymmetric Prony block (the scene sphere_creep on a coarse mesh, four steps):

- every parameter kind the sensitivities cover: the shear modulus mu_0, a relaxing fraction,
  a relaxation time, the bulk modulus, the friction coefficient, the compliance stiffness
  and the shift's constants;
- the contact at the bound (Signorini, g = 0), with Coulomb friction on the total pressure,
  and a compliant layer with a bound (g > 0) and friction on the compliance pressure;
- a temperature with its shift: WLF C1 and C2 under a temperature rising through the run,
  an Arrhenius energy at a held temperature (the history in reduced time);

each derivative of the depth at every step to 1e-6 of its largest value (the differences'
own error, O(h^2) with h = 1e-4 relative, is about 1e-8 here). The forward model, built once
and run again, gives the depth of a whole run (simulate) to the Newton tolerance.
"""
import numpy as np
import pytest
from mpi4py import MPI

from contactvisco.scene import loader
from contactvisco.solver.sensitivity import ForwardModel, unsupported_key
from contactvisco.solver.time_loop import simulate

COARSE = ('geometry.parameters={radius = 10.0, height = 10.0, h_contact = 0.04, h_far = 3.0, '
          'refine = 0.3, growth = 0.15}')
BASE = [COARSE, "time.steps=4", "output.figures=false"]
MODULI = {"viscoelastic.shear.instantaneous": 0.38461538461538464,
          "viscoelastic.shear.fractions.0": 0.5, "viscoelastic.shear.tau.0": 1.0,
          "viscoelastic.bulk.instantaneous": 0.8333333333333334}
#: WLF with a temperature rising through the run (T_ref = 50, theta = 50 + t): the history in
#: reduced time, its rates 1/a_T moving from step to step.
WLF = ['viscoelastic.shift="wlf"', "viscoelastic.T_ref=50.0", "viscoelastic.temperature='50 + t'"]
CASES = {
    "bound": ([], MODULI),
    "coulomb": (["contact.friction_law='coulomb'"], {**MODULI, "contact.mu": 0.3}),
    "compliance": (["contact.g=0.004"], {**MODULI, "contact.stiffness": 0.5,
                                          "contact.mu": 0.2}),
    "wlf": (WLF, {"viscoelastic.C1": 17.44, "viscoelastic.C2": 51.6,
                  "viscoelastic.shear.fractions.0": 0.5, "viscoelastic.shear.tau.0": 1.0}),
    "arrhenius": (['viscoelastic.shift="arrhenius"', "viscoelastic.T_ref=300.0",
                   "viscoelastic.temperature=303.0"],
                  {"viscoelastic.activation_energy": 1e5,
                   "viscoelastic.shear.instantaneous": 0.38461538461538464}),
}


def scene(sets, values):
    return loader.load("sphere_creep", BASE + sets + [f"{k}={v!r}" for k, v in values.items()])


def central_scenes(sets, theta, step=1e-5):
    """(scene at theta_k + h, scene at theta_k - h, 2 h) for each parameter k, h = step theta_k:
    the central differences that ForwardModel.run takes as tangents."""
    return [(scene(sets, {**theta, key: v + step * v}), scene(sets, {**theta, key: v - step * v}),
             2 * step * v) for key, v in theta.items()]


@pytest.mark.mpi
@pytest.mark.parametrize("case", ["bound", "wlf",
                                  pytest.param("coulomb", marks=pytest.mark.slow),
                                  pytest.param("compliance", marks=pytest.mark.slow),
                                  pytest.param("arrhenius", marks=pytest.mark.slow)])
def test_sensitivities_match_central_differences(case):
    sets, theta = CASES[case]
    model = ForwardModel(scene(sets, theta), MPI.COMM_WORLD)
    try:
        tangents = central_scenes(sets, theta)
        out = model.run(scene(sets, theta), tangents)
        assert out["d_depth"].shape == (5, len(theta))
        for i, (key, v) in enumerate(theta.items()):
            h = 1e-4 * v
            plus = model.run(scene(sets, {**theta, key: v + h}))["depth"]
            minus = model.run(scene(sets, {**theta, key: v - h}))["depth"]
            difference = (plus - minus) / (2 * h)
            scale = np.abs(difference).max()
            assert scale * v > 1e-7, key       # the parameter moves the depth
            assert np.abs(out["d_depth"][:, i] - difference).max() < 1e-6 * scale, key
    finally:
        model.destroy()


@pytest.mark.mpi
@pytest.mark.parametrize("thermal", [False, True])
def test_the_forward_model_reruns_as_a_whole_run(thermal):
    """Built at one shear modulus (and WLF C1), run twice at another: the depth of simulate()
    there (a state left by the first run would show in the second)."""
    sets = WLF + ["viscoelastic.C1=17.44", "viscoelastic.C2=51.6"] if thermal else []
    theta = dict(MODULI)
    model = ForwardModel(scene(sets, theta), MPI.COMM_WORLD)
    try:
        other = {**theta, "viscoelastic.shear.instantaneous": 0.3,
                 "viscoelastic.shear.tau.0": 0.5, **({"viscoelastic.C1": 12.0} if thermal
                                                     else {})}
        model.run(scene(sets, other))
        depth = model.run(scene(sets, other))["depth"]
        result = simulate(scene(sets, other), progress=False)
        reference = -np.array([s["obstacle"]["displacement"][1] for s in result.steps])
        assert np.abs(depth - reference).max() < 1e-8 * reference.max()
        assert model.runs == 2
    finally:
        model.destroy()


def test_keys_outside_the_sensitivities_are_named():
    assert unsupported_key("viscoelastic.shear.fractions.0") is None
    assert unsupported_key("contact.mu") is None
    reason = unsupported_key("obstacle.radius")
    assert reason is not None and "obstacle.radius" in reason


@pytest.mark.mpi
def test_force_sensitivities_under_a_held_depth():
    """Relaxation: the sphere pressed to a depth 0.01 over t = 0.5 and held (displacement
    control). The observed force (-g_c, the residual tested with the unit field along the axis)
    is the run's recorded force to round-off, and its sensitivities in the four moduli match
    central differences to 1e-6."""
    sets = ["obstacle.force_components=[]", "obstacle.force=[]",
            'obstacle.displacement=[0.0, "-0.01*min(t / 0.5, 1)"]']
    theta = dict(MODULI)
    model = ForwardModel(scene(sets, theta), MPI.COMM_WORLD, component=1)
    try:
        tangents = central_scenes(sets, theta)
        out = model.run(scene(sets, theta), tangents)
        recorded = np.array([s["obstacle"]["force"][1]
                             for s in simulate(scene(sets, theta), progress=False).steps])
        assert np.abs(out["force"] - recorded).max() < 1e-9 * np.abs(recorded).max()
        for i, (key, v) in enumerate(theta.items()):
            h = 1e-4 * v
            difference = (model.run(scene(sets, {**theta, key: v + h}))["force"]
                          - model.run(scene(sets, {**theta, key: v - h}))["force"]) / (2 * h)
            scale = np.abs(difference).max()
            assert scale * v > 1e-7, key
            assert np.abs(out["d_force"][:, i] - difference).max() < 1e-6 * scale, key
    finally:
        model.destroy()


def power_scene(folder, values):
    """sphere_creep with the [viscoelastic] table replaced by E = 1, nu = 0.3 and a power
    memory kernel alpha (1 + t/tau)^-beta on the deviatoric strain (its sum of exponentials)."""
    import pathlib

    import contactvisco
    path = folder / "power_creep.toml"
    if not path.exists():
        text = (pathlib.Path(contactvisco.__file__).parent / "scenes" /
                "sphere_creep.toml").read_text()
        start = text.index("[viscoelastic]")
        end = text.index("[[dirichlet]]")
        text = (text[:start] + 'E = 1.0\nnu = 0.3\n\n[memory]\nkernel = "power"\n'
                'alpha = -0.2\nbeta = 0.5\ntau = 0.5\npart = "deviatoric"\n\n' + text[end:])
        path.write_text(text)
    return loader.load(str(path), BASE + [f"{k}={v!r}" for k, v in values.items()])


@pytest.mark.mpi
def test_power_kernel_sensitivities_match_central_differences(tmp_path_factory):
    """The power kernel's sum of exponentials with its rates kept and its coefficients
    refitted (model.kernels.PowerTerms): the depth's derivatives in alpha, beta, tau and E
    match central differences of forward runs to 1e-6 of their largest value, and the forward
    model at the built parameters gives simulate()'s depth."""
    folder = tmp_path_factory.mktemp("power")
    theta = {"memory.alpha": -0.2, "memory.beta": 0.5, "memory.tau": 0.5, "material.E": 1.0}
    model = ForwardModel(power_scene(folder, theta), MPI.COMM_WORLD)
    try:
        assert model.memory_reason is None and model.power is not None
        tangents = [(power_scene(folder, {**theta, k: v + 1e-5 * v}),
                     power_scene(folder, {**theta, k: v - 1e-5 * v}), 2e-5 * v)
                    for k, v in theta.items()]
        out = model.run(power_scene(folder, theta), tangents)
        result = simulate(power_scene(folder, theta), progress=False)
        reference = -np.array([s["obstacle"]["displacement"][1] for s in result.steps])
        assert np.abs(out["depth"] - reference).max() < 1e-8 * reference.max()
        for i, (key, v) in enumerate(theta.items()):
            h = 1e-4 * v
            difference = (model.run(power_scene(folder, {**theta, key: v + h}))["depth"]
                          - model.run(power_scene(folder, {**theta, key: v - h}))["depth"]) / (
                2 * h)
            scale = np.abs(difference).max()
            assert scale * abs(v) > 1e-7, key
            assert np.abs(out["d_depth"][:, i] - difference).max() < 1e-6 * scale, key
    finally:
        model.destroy()
