"""The relaxation-modulus form ([viscoelastic]): its exact conversion to the (A, R) of eq (7),
the generalized Maxwell stress of a homogeneous block under a prescribed strain history
(closed forms in contactvisco.model.viscoelastic), the DMA experiment, and the refusals."""
import math

import numpy as np
import pytest
from mpi4py import MPI

from contactvisco.errors import SceneError
from contactvisco.model import viscoelastic as ve
from contactvisco.model.memory import project
from contactvisco.scene import loader
from contactvisco.scene.toml_text import scene_text
from contactvisco.studies import relaxation as rl

SHEAR = {"instantaneous": 10.0, "tau": [0.3, 2.0], "fractions": [0.3, 0.2]}
BULK = {"long_term": 20.0, "tau": [0.5], "moduli": [5.0]}
G = ve.series(instantaneous=10.0, taus=[0.3, 2.0], fractions=[0.3, 0.2])
K = ve.series(long_term=20.0, taus=[0.5], moduli=[5.0])
ELASTIC_G = ve.series(instantaneous=10.0)
ELASTIC_K = ve.series(instantaneous=25.0)
#: material -> ([viscoelastic] table, G, K)
MATERIALS = {
    "shear": ({"shear": SHEAR, "bulk": {"instantaneous": 25.0}}, G, ELASTIC_K),
    "bulk": ({"shear": {"instantaneous": 10.0}, "bulk": BULK}, ELASTIC_G, K),
    "both": ({"shear": SHEAR, "bulk": BULK}, G, K),
}
STRAIN_2D = [[0.01, 0.004], [0.004, -0.002]]
STRAIN_3D = [[0.01, 0.004, 0.0], [0.004, -0.002, 0.001], [0.0, 0.001, 0.003]]


def block_error(visco, Gs, Ks, model, history, steps, T=2.0, omega=3.0, comm=MPI.COMM_WORLD):
    strain = STRAIN_3D if model == "3d" else STRAIN_2D
    t, sigma = rl.block_stress(rl.block_scene(visco, model, strain, history, T, steps,
                                              omega=omega), comm)
    exact = rl.maxwell_stress(model, Gs, Ks, strain, history, t, omega=omega)
    return np.abs(sigma - exact).max() / np.abs(exact).max()


def test_plane_strain_conversion_is_the_3d_law_with_eps33_zero():
    """R(t) of the converted terms applied to an in-plane strain equals the in-plane part of
    2 G'(t) dev3 eps + K'(t) tr(eps) I (the dimension factors of plane strain)."""
    _, _, terms = ve.paper_form("plane_strain", G, K)
    eps = np.array(STRAIN_2D)
    E3 = np.zeros((3, 3))
    E3[:2, :2] = eps
    for t in (0.0, 0.4, 3.0):
        R = sum(a * math.exp(-t / tau) * project(eps.ravel(), part, 2).reshape(2, 2)
                for a, tau, part in terms)
        dG = -sum(m / tau * math.exp(-t / tau) for m, tau in zip(G.moduli, G.taus))
        dK = -sum(m / tau * math.exp(-t / tau) for m, tau in zip(K.moduli, K.taus))
        exact = 2 * dG * (E3 - np.trace(E3) / 3 * np.eye(3)) + dK * np.trace(E3) * np.eye(3)
        assert np.allclose(R, exact[:2, :2], rtol=1e-13, atol=1e-15)


@pytest.mark.parametrize("model", ["plane_strain", "3d"])
@pytest.mark.parametrize("material", list(MATERIALS))
@pytest.mark.parametrize("history", ["step", "ramp"])
def test_block_gives_the_maxwell_stress(model, material, history):
    """Second order in k with the trapezoid rule (measured orders 1.99-2.00)."""
    visco, Gs, Ks = MATERIALS[material]
    coarse, fine = (block_error(visco, Gs, Ks, model, history, n) for n in (20, 40))
    order = math.log2(coarse / fine)
    assert abs(order - 2.0) < 0.1, (coarse, fine)
    assert fine < 2e-3


def test_plane_stress_with_young_and_nu():
    """E(t) with a constant nu: shear and bulk relax proportionally, and plane stress is
    converted exactly: the block follows g(t) A0 eps."""
    visco = {"young": {"instantaneous": 30.0, "tau": [0.3, 2.0], "fractions": [0.3, 0.2]},
             "nu": 0.25}
    Ey = ve.series(instantaneous=30.0, taus=[0.3, 2.0], fractions=[0.3, 0.2])
    Gs, Ks = ve.young_series(Ey, 0.25)
    errors = [block_error(visco, Gs, Ks, "plane_stress", "ramp", n) for n in (20, 40)]
    assert abs(math.log2(errors[0] / errors[1]) - 2.0) < 0.1, errors
    scene = loader.resolve(rl.block_scene(visco, "plane_stress", STRAIN_2D, "ramp", 1, 1))
    assert scene["material"]["E"] == pytest.approx(30.0, rel=1e-14)
    assert scene["material"]["nu"] == pytest.approx(0.25, rel=1e-14)


@pytest.mark.convergence
def test_order_of_the_trapezoid_rule():
    """The error of a sine history at T over k, k/2, k/4, k/8: order 2."""
    visco, Gs, Ks = MATERIALS["both"]
    errors = [block_error(visco, Gs, Ks, "plane_strain", "sine", n) for n in (10, 20, 40, 80)]
    orders = [math.log2(a / b) for a, b in zip(errors, errors[1:])]
    assert all(abs(p - 2.0) < 0.05 for p in orders), (errors, orders)


def test_dma_storage_and_loss():
    """A shear strain gamma sin(w t): after the transient (10 tau_max), sigma_12 = 2 gamma
    (G' sin + G'' cos); the least-squares fit over the last period gives G'(w) and G''(w) of
    the series."""
    omega, gamma, T, steps = 2.0, 0.01, 20.0, 800
    strain = [[0.0, gamma], [gamma, 0.0]]
    t, sigma = rl.block_stress(rl.block_scene({"shear": SHEAR, "bulk": {"instantaneous": 25.0}},
                                              "plane_strain", strain, "sine", T, steps,
                                              omega=omega))
    last = t >= T - 2 * math.pi / omega
    basis = np.column_stack([np.sin(omega * t[last]), np.cos(omega * t[last])])
    (storage, loss), *_ = np.linalg.lstsq(basis, sigma[last, 0, 1] / (2 * gamma), rcond=None)
    exact = ve.storage_loss(G, omega)
    assert storage == pytest.approx(float(exact[0]), rel=1e-3)
    assert loss == pytest.approx(float(exact[1]), rel=2e-3)
    assert loss > 0.05 * storage              # the loss is measured, not a zero


def test_equals_the_paper_form_to_round_off():
    """The same material entered as E, nu and memory.terms computed by hand gives the same
    stresses to round-off."""
    visco, _, _ = MATERIALS["both"]
    raw = rl.block_scene(visco, "plane_strain", STRAIN_2D, "ramp", 1.0, 10)
    G0, K0 = 10.0, 25.0
    paper = dict(raw)
    del paper["viscoelastic"]
    paper["material"] = {"model": "plane_strain", "E": 9 * K0 * G0 / (3 * K0 + G0),
                         "nu": (3 * K0 - 2 * G0) / (2 * (3 * K0 + G0))}
    terms = []
    for g, tau in ((3.0, 0.3), (2.0, 2.0)):
        terms += [{"alpha": -2 * g / tau, "tau": tau, "part": "deviatoric"},
                  {"alpha": -2 / 3 * g / tau, "tau": tau, "part": "volumetric"}]
    terms.append({"alpha": -2 * 5.0 / 0.5, "tau": 0.5, "part": "volumetric"})
    paper["memory"] = {"kernel": "prony", "terms": terms}
    _, converted = rl.block_stress(raw)
    _, by_hand = rl.block_stress(paper)
    assert np.abs(converted - by_hand).max() <= 1e-12 * np.abs(by_hand).max()
    assert np.abs(by_hand[-1] - by_hand[0]).max() > 1e-3 * np.abs(by_hand).max()


@pytest.mark.mpi
def test_ranks_agree():
    """The block on a 3 x 3 mesh distributed over the ranks equals the same run on one rank."""
    visco, _, _ = MATERIALS["both"]
    raw = rl.block_scene(visco, "plane_strain", STRAIN_2D, "sine", 1.0, 10, cells=3)
    _, everywhere = rl.block_stress(raw, MPI.COMM_WORLD)
    _, alone = rl.block_stress(raw, MPI.COMM_SELF)
    assert np.abs(everywhere - alone).max() <= 1e-12 * np.abs(alone).max()


def test_round_trip_and_note(tmp_path):
    """The scene written back as TOML holds [viscoelastic] and not the derived keys, and
    reads back to the same converted material."""
    raw = rl.block_scene(MATERIALS["both"][0], "3d", STRAIN_3D, "step", 1.0, 2)
    scene = loader.resolve(raw)
    for every in (False, True):
        path = tmp_path / f"again{every}.toml"
        path.write_text(scene_text(scene, every))
        again = loader.load(str(path))
        assert again["memory"]["terms"] == scene["memory"]["terms"]
        assert again["material"]["E"] == scene["material"]["E"]


def scene_with(**visco):
    return rl.block_scene(visco, "plane_strain", STRAIN_2D, "step", 1.0, 2)


@pytest.mark.parametrize("visco, key, words", [
    ({"shear": {"instantaneous": -1.0}, "bulk": BULK}, "viscoelastic.shear.instantaneous",
     "> 0"),
    ({"shear": {"instantaneous": 1.0, "tau": [1.0], "moduli": [-0.1]}, "bulk": BULK},
     "viscoelastic.shear.moduli", "must be > 0"),
    ({"shear": {"instantaneous": 1.0, "tau": [-1.0], "moduli": [0.1]}, "bulk": BULK},
     "viscoelastic.shear.tau", "relaxation time must be > 0"),
    ({"shear": {"instantaneous": 1.0, "tau": [1.0, 2.0], "fractions": [0.6, 0.4]},
      "bulk": BULK}, "viscoelastic.shear.fractions", "sum to 1"),
    ({"shear": {"instantaneous": 1.0, "tau": [1.0, 2.0], "moduli": [0.6, 0.5]},
      "bulk": BULK}, "viscoelastic.shear.instantaneous", "relaxed (long-term) modulus"),
    ({"shear": SHEAR, "bulk": {"long_term": 1.0, "tau": [1.0, 1.0], "moduli": [1, 2]}},
     "viscoelastic.bulk.tau", "duplicate"),
    ({"shear": SHEAR}, "viscoelastic.bulk", "needs shear and bulk"),
    ({"shear": SHEAR, "bulk": BULK, "nu": 0.3}, "viscoelastic.nu", "goes with"),
    ({"young": {"instantaneous": 1.0}, "nu": 0.5}, "viscoelastic.nu", "(-1, 0.5)"),
    ({"shear": {"instantaneous": 1.0, "tau": [1.0], "moduli": [0.1], "size": 1}, "bulk": BULK},
     "viscoelastic.shear.size", "unknown key"),
])
def test_refused(visco, key, words):
    with pytest.raises(SceneError) as err:
        loader.resolve(scene_with(**visco))
    assert err.value.key == key and words in str(err.value), str(err.value)


def test_step_too_large_for_the_trapezoid_rule():
    """2 G(0) + k/2 R(0) <= 0 for the deviatoric part at k = 2 (R(0) = -2 (3/0.3 + 2/2) =
    -22, 2 G(0) = 20): refused with the limit k < 40/22; at k = 1 it runs."""
    raw = rl.block_scene(MATERIALS["shear"][0], "3d", STRAIN_3D, "step", 4.0, 2)
    with pytest.raises(SceneError, match="take k < 1.818") as err:
        loader.resolve(raw)
    assert err.value.key == "viscoelastic.shear"
    loader.resolve(rl.block_scene(MATERIALS["shear"][0], "3d", STRAIN_3D, "step", 4.0, 4))


def test_plane_stress_needs_proportional_relaxation():
    raw = rl.block_scene(MATERIALS["both"][0], "plane_stress", STRAIN_2D, "step", 1.0, 2)
    with pytest.raises(SceneError, match="3 K~\\(s\\) \\+ 4 G~\\(s\\)") as err:
        loader.resolve(raw)
    assert err.value.key == "viscoelastic.bulk"


@pytest.mark.parametrize("extra", [{"material": {"model": "plane_strain", "E": 2.0}},
                                   {"memory": {"kernel": "constant", "alpha": 1.0}}])
def test_one_form_only(extra):
    raw = dict(scene_with(**MATERIALS["both"][0]), **extra)
    with pytest.raises(SceneError, match="derived from it"):
        loader.resolve(raw)
    with pytest.raises(SceneError, match="derived from it"):
        loader.resolve(scene_with(**MATERIALS["both"][0]), ["material.nu=0.2"])


def test_paper_scene_unchanged():
    """A scene without [viscoelastic] builds what it built: no table, its own E, nu, kernel."""
    scene = loader.load("paper")
    assert scene["viscoelastic"] is None
    assert scene["memory"]["kernel"] == "constant"


# --- Prony tables from CSV files -----------------------------------------------------------

def csv_scene(tmp_path, text, name="shear.csv", **spec):
    (tmp_path / name).write_text(text)
    raw = scene_with(shear={"instantaneous": 10.0, "file": name, **spec},
                     bulk={"instantaneous": 25.0})
    path = tmp_path / "scene.toml"
    from contactvisco.scene.toml_text import document_text
    path.write_text(document_text(raw))
    return str(path)


def test_csv_equals_inline(tmp_path):
    """A file of (tau, fraction) rows, relative to the scene file, gives the inline series;
    time_scale and scale convert the file's units."""
    path = csv_scene(tmp_path, "tau (s),g\n0.3,0.3\n2.0,0.2\n", values="fractions")
    inline = loader.resolve(scene_with(shear=SHEAR, bulk={"instantaneous": 25.0}))
    assert loader.load(path)["memory"]["terms"] == inline["memory"]["terms"]
    path = csv_scene(tmp_path, "tau_ms,G_i_kPa\n300,3000\n2000,2000\n", time_scale=1e-3,
                     scale=1e-3)
    terms = loader.load(path)["memory"]["terms"]
    assert [t["tau"] for t in terms] == pytest.approx([0.3, 0.3, 2.0, 2.0])
    assert [t["alpha"] for t in terms] == pytest.approx(
        [t["alpha"] for t in inline["memory"]["terms"]], rel=1e-14)


@pytest.mark.parametrize("text, words", [
    ("", "empty"),
    ("tau,G\n", "no terms"),
    ("0.3,3\n2,2\n", "row 1: the first row must be a header"),
    ("tau,G\n0.3,3\n2,nan\n", "row 3: values must be finite numbers"),
    ("tau,G\n0.3,3\n2\n", "row 3: needs 2 values"),
    ("tau,G\n2,3\n0.3,2\n", "row 3: tau = 0.3 is below"),
    ("tau,G\n0.3,3\n\n0.3,2\n", "row 4: tau = 0.3 duplicates"),
    ("tau,G\n0.3,-3\n", "row 2: the modulus must be >= 0"),
    ("tau,G\n" + "".join(f"{i + 1},0.01\n" for i in range(101)), "row 102: more than 100"),
])
def test_csv_refused(tmp_path, text, words):
    path = csv_scene(tmp_path, text)
    with pytest.raises(SceneError) as err:
        loader.load(path)
    assert words in str(err.value) and "shear.csv" in str(err.value), str(err.value)
    assert err.value.key == "viscoelastic.shear.file"


def test_csv_missing_and_mixed(tmp_path):
    path = csv_scene(tmp_path, "tau,G\n1,1\n")
    (tmp_path / "shear.csv").unlink()
    with pytest.raises(SceneError, match="no Prony file"):
        loader.load(path)
    path = csv_scene(tmp_path, "tau,G\n1,1\n", tau=[1.0])
    with pytest.raises(SceneError, match="leave out"):
        loader.load(path)


# --- Time-temperature superposition --------------------------------------------------------

WLF = {"shift": "wlf", "T_ref": 50.0, "C1": 17.44, "C2": 51.6}


@pytest.mark.parametrize("theta", [53.0, 45.0])
def test_constant_temperature_is_scaled_time(theta):
    """A constant theta != T_ref runs the T_ref material with time scaled by a_T: the ramp
    eps = t E over [0, T] at theta equals the ramp eps = a_T t E over [0, T/a_T] at T_ref,
    with the same number of steps, to round-off (a_T = 0.110 and 74.3 here)."""
    visco = dict(MATERIALS["both"][0], **WLF)
    a = 10 ** float(ve.log10_shift(visco, theta))
    assert abs(math.log10(a)) > 0.9                   # a real change of time scale
    _, hot = rl.block_stress(rl.block_scene(dict(visco, temperature=theta), "plane_strain",
                                            STRAIN_2D, "ramp", 2.0, 12))
    _, ref = rl.block_stress(rl.block_scene(visco, "plane_strain", STRAIN_2D, "ramp", 2.0 / a,
                                            12, rate=a))
    _, iso = rl.block_stress(rl.block_scene(visco, "plane_strain", STRAIN_2D, "ramp", 2.0, 12))
    assert np.abs(hot - ref).max() <= 1e-13 * np.abs(ref).max()
    assert np.abs(hot - iso).max() > 1e-2 * np.abs(iso).max()


def maxwell_reduced(theta_of, t, tau=0.5, g=0.4, G0=10.0, gamma=0.01, fine=20000):
    """sigma_12 of a shear step gamma at t = 0 for G(xi) = G0 (1 - g + g exp(-xi/tau)), xi(t) =
    int_0^t 1/a_T(theta(s)) ds by Simpson's rule on `fine` intervals (to 1e-14)."""
    s = np.linspace(0.0, t, fine + 1)
    rate = 10.0 ** -ve.log10_shift(WLF, theta_of(s))
    xi = (t / fine / 3) * (rate[0] + rate[-1] + 4 * rate[1:-1:2].sum() + 2 * rate[2:-1:2].sum())
    return 2 * gamma * G0 * (1 - g + g * math.exp(-xi / tau))


def test_temperature_ramp_and_field():
    """A shear step under a temperature rising in t and varying in x (theta = 50 + 2 t +
    1.5 x[0], a_T from 1 to 0.11): at each of the two cells' points, sigma_12 is the single Maxwell term in reduced
    time xi(t) = int dt / a_T; the error decreases with order 2 (the trapezoid rule in xi, and
    in t for xi)."""
    visco = dict(WLF, temperature="50.0 + 2.0 * t + 1.5 * x[0]",
                 shear={"instantaneous": 10.0, "tau": [0.5], "fractions": [0.4]},
                 bulk={"instantaneous": 25.0})
    strain = [[0.0, 0.01], [0.01, 0.0]]
    errors = []
    for steps in (20, 40, 80):
        t, sigma, points = rl.block_stress(rl.block_scene(visco, "plane_strain", strain, "step",
                                                          1.0, steps), MPI.COMM_SELF,
                                           per_point=True)
        exact = [[maxwell_reduced(lambda s, x=p[0]: 50.0 + 2.0 * s + 1.5 * x, tn)
                  for p in points] for tn in t]
        errors.append(np.abs(sigma[:, :, 0, 1] - np.array(exact)).max())
    middle = sigma[len(t) // 4, :, 0, 1]
    assert np.ptp(middle) > 1e-2 * abs(middle[0])   # the points relax differently
    orders = [math.log2(a / b) for a, b in zip(errors, errors[1:])]
    assert all(abs(p - 2.0) < 0.1 for p in orders), (errors, orders)



def test_temperature_ramp_and_field_in_axisymmetry():
    """The axisymmetric twin of test_temperature_ramp_and_field: the cylinder's block
    0 <= r, z <= 1 stretched along the axis by e = 0.01 at t = 0 (u = (0, e z): no hoop
    strain), theta = 50 + 2 t + 1.5 r: at each point sigma_zz - sigma_rr = 2 e G(xi), the
    Maxwell term in the point's reduced time, with the error falling at order 2."""
    visco = dict(WLF, temperature="50.0 + 2.0 * t + 1.5 * x[0]",
                 shear={"instantaneous": 10.0, "tau": [0.5], "fractions": [0.4]},
                 bulk={"instantaneous": 25.0})
    errors = []
    for steps in (20, 40, 80):
        t, sigma, points = rl.block_stress(rl.block_scene(visco, "axisymmetric",
                                                          [[0.0, 0.0], [0.0, 0.01]], "step",
                                                          1.0, steps), MPI.COMM_SELF,
                                           per_point=True)
        assert sigma.shape[2:] == (3, 3)
        exact = [[maxwell_reduced(lambda s, x=p[0]: 50.0 + 2.0 * s + 1.5 * x, tn)
                  for p in points] for tn in t]
        errors.append(np.abs(sigma[:, :, 1, 1] - sigma[:, :, 0, 0] - np.array(exact)).max())
    orders = [math.log2(a / b) for a, b in zip(errors, errors[1:])]
    assert all(abs(p - 2.0) < 0.1 for p in orders), (errors, orders)

@pytest.mark.parametrize("extra, key, words", [
    ({"temperature": 60.0}, "viscoelastic.temperature", "needs a shift function"),
    (dict(WLF, temperature=-10.0), "viscoelastic.temperature", "outside the range of the WLF"),
    (dict(WLF, temperature=0.0), "viscoelastic.temperature", "log10 a_T = 545 is beyond"),
    ({"shift": "wlf", "T_ref": 50.0, "C1": 17.44}, "viscoelastic.C2", "needs viscoelastic.C2"),
    ({"shift": "arrhenius", "T_ref": 300.0, "activation_energy": 1e5, "temperature": -3.0},
     "viscoelastic.temperature", "kelvin"),
    (dict(WLF, activation_energy=1e5), "viscoelastic.activation_energy", "another shift"),
    (dict(WLF, temperature=58.0), "viscoelastic.shear", "stiffness of the trapezoid rule"),
])
def test_temperature_refused(extra, key, words):
    with pytest.raises(SceneError) as err:
        loader.resolve(scene_with(**MATERIALS["both"][0], **extra))
    assert err.value.key == key and words in str(err.value), str(err.value)


def test_wlf_range_at_run_time():
    """An expression that leaves the WLF range during the run stops it with the key and the
    time (every rank): the first time inside the step from 0.75 to 1 where |log10 a_T| passes
    300, before the pole itself at t = 0.86 and the step time 1."""
    visco = dict(MATERIALS["both"][0], **WLF, temperature="50.0 - 60.0 * t")
    raw = rl.block_scene(visco, "plane_strain", STRAIN_2D, "step", 1.0, 4)
    with pytest.raises(SceneError, match=r"is beyond \+-300.*at t = 0\.82\d*, between the "
                                         r"step times 0\.75 and 1\)") as err:
        rl.block_stress(raw)
    assert err.value.key == "viscoelastic.temperature"


# --- The shift table (log10 a_T against temperature) -------------------------------------

def wlf_table(h, lo=48.0, hi=56.0, T_ref=50.0):
    """The WLF curve sampled every h on [lo, hi], as a [viscoelastic] shift table."""
    T = lo + h * np.arange(int(round((hi - lo) / h)) + 1)
    return {"shift": "table", "T_ref": T_ref, "shift_temperatures": T.tolist(),
            "shift_log10_aT": ve.log10_shift(WLF, T).tolist()}


ONE_TERM = {"shear": {"instantaneous": 10.0, "tau": [0.5], "fractions": [0.4]},
            "bulk": {"instantaneous": 25.0}}


def test_shift_table_is_piecewise_linear():
    """Between two points the table is the chord of log10 a_T, exact at the points; its
    error against the sampled WLF curve falls as h^2 (the second derivative of the curve)."""
    errors = []
    fine = np.linspace(48.0, 56.0, 2001)
    for h in (1.0, 0.5, 0.25):
        table = wlf_table(h)
        T = np.array(table["shift_temperatures"])
        assert np.abs(ve.log10_shift(table, T) - ve.log10_shift(WLF, T)).max() == 0.0
        errors.append(np.abs(ve.log10_shift(table, fine) - ve.log10_shift(WLF, fine)).max())
    orders = [math.log2(a / b) for a, b in zip(errors, errors[1:])]
    assert all(abs(p - 2.0) < 0.05 for p in orders), (errors, orders)


def test_shift_table_reproduces_the_wlf_run():
    """A shear step under theta = 50 + 4 t + 1.5 x[0] with the WLF curve tabulated every h
    equals the WLF run (same 20 steps) to the interpolation error, which falls as h^2."""
    strain = [[0.0, 0.01], [0.01, 0.0]]
    temperature = "50.0 + 4.0 * t + 1.5 * x[0]"

    def run(shift):
        return rl.block_stress(rl.block_scene(dict(ONE_TERM, **shift, temperature=temperature),
                                              "plane_strain", strain, "step", 1.0, 20),
                               MPI.COMM_SELF)[1]
    ref = run(WLF)
    errors = [np.abs(run(wlf_table(h)) - ref).max() / np.abs(ref).max()
              for h in (0.5, 0.25, 0.125)]
    orders = [math.log2(a / b) for a, b in zip(errors, errors[1:])]
    assert errors[-1] < 2e-5 and all(abs(p - 2.0) < 0.1 for p in orders), (errors, orders)


@pytest.mark.parametrize("theta", [52.7, 46.5])
def test_constant_temperature_table_is_scaled_time(theta):
    """The scaled-time identity holds for the table too: at a constant theta between two
    points the run equals the T_ref run with time scaled by the interpolated a_T, to
    round-off."""
    visco = dict(MATERIALS["both"][0], **wlf_table(1.0, lo=46.0))
    a = 10 ** float(ve.log10_shift(visco, theta))
    assert abs(math.log10(a)) > 0.5
    _, hot = rl.block_stress(rl.block_scene(dict(visco, temperature=theta), "plane_strain",
                                            STRAIN_2D, "ramp", 2.0, 12))
    _, ref = rl.block_stress(rl.block_scene(visco, "plane_strain", STRAIN_2D, "ramp", 2.0 / a,
                                            12, rate=a))
    assert np.abs(hot - ref).max() <= 1e-13 * np.abs(ref).max()


def test_shift_file_equals_inline(tmp_path):
    """A CSV of (temperature, log10 a_T) rows gives the inline table."""
    table = wlf_table(0.5)
    rows = "".join(f"{T!r},{L!r}\n" for T, L in zip(table["shift_temperatures"],
                                                      table["shift_log10_aT"]))
    (tmp_path / "shift.csv").write_text("T (C),log10 aT\n" + rows)
    raw = scene_with(**MATERIALS["both"][0], shift="table", T_ref=50.0,
                     shift_file="shift.csv", temperature=48.5)
    path = tmp_path / "scene.toml"
    from contactvisco.scene.toml_text import document_text
    path.write_text(document_text(raw))
    from_file = loader.load(str(path))["viscoelastic"]
    inline = loader.resolve(scene_with(**MATERIALS["both"][0], **table, temperature=48.5))
    theta = np.linspace(48.0, 56.0, 17)
    assert np.array_equal(ve.log10_shift(from_file, theta),
                          ve.log10_shift(inline["viscoelastic"], theta))


@pytest.mark.parametrize("extra, key, words", [
    (dict(wlf_table(1.0), temperature=57.0), "viscoelastic.temperature", "outside the shift "
                                                                         "table [48, 56]"),
    (dict(wlf_table(1.0), T_ref=60.0), "viscoelastic.T_ref", "shift table's range"),
    (dict(wlf_table(1.0), T_ref=50.5), "viscoelastic.T_ref", "must be 0"),
    ({"shift": "table", "T_ref": 50.0, "shift_temperatures": [49.0, 51.0, 50.5],
      "shift_log10_aT": [0.5, -0.5, -0.2]}, "viscoelastic.shift_temperatures", "must increase"),
    ({"shift": "table", "T_ref": 50.0, "shift_temperatures": [50.0],
      "shift_log10_aT": [0.0]}, "viscoelastic.shift_temperatures", "at least two"),
    ({"shift": "table", "T_ref": 50.0, "shift_temperatures": [49.0, 51.0],
      "shift_log10_aT": [0.5]}, "viscoelastic.shift_log10_aT", "same length"),
    ({"shift": "table", "T_ref": 50.0, "shift_temperatures": [0.0, 100.0],
      "shift_log10_aT": [400.0, -400.0]}, "viscoelastic.shift_log10_aT", "at most 300"),
    ({"shift": "table", "T_ref": 50.0}, "viscoelastic.shift_temperatures", "needs"),
    (dict(WLF, shift_temperatures=[1.0, 2.0]), "viscoelastic.shift_temperatures", "not of"),
])
def test_shift_table_refused(extra, key, words):
    with pytest.raises(SceneError) as err:
        loader.resolve(scene_with(**MATERIALS["both"][0], **extra))
    assert err.value.key == key and words in str(err.value), str(err.value)


@pytest.mark.parametrize("text, words", [
    ("", "empty"),
    ("T,log10aT\n", "at least two points"),
    ("40,1\n50,0\n", "header"),
    ("T,log10aT\n40,nan\n50,0\n", "row 2: values must be finite"),
    ("T,log10aT\n40,1\n50\n", "row 3: needs 2 values"),
    ("T,log10aT\n50,0\n40,1\n", "row 3: temperature 40.0 is below"),
    ("T,log10aT\n40,1\n40,0\n", "row 3: temperature 40.0 duplicates"),
    ("T,log10aT\n40,1\n50,0\n60,-301\n", "row 4: |log10 a_T|"),
    ("T,log10aT\n" + "".join(f"{i},0\n" for i in range(1001)), "more than 1000 points"),
])
def test_shift_file_refused(tmp_path, text, words):
    (tmp_path / "shift.csv").write_text(text)
    raw = scene_with(**MATERIALS["both"][0], shift="table", T_ref=50.0, shift_file="shift.csv")
    path = tmp_path / "scene.toml"
    from contactvisco.scene.toml_text import document_text
    path.write_text(document_text(raw))
    with pytest.raises(SceneError) as err:
        loader.load(str(path))
    assert err.value.key == "viscoelastic.shift_file", str(err.value)
    assert "shift.csv" in str(err.value) and words in str(err.value), str(err.value)


def test_shift_table_range_at_run_time():
    """A temperature expression that leaves the table during the run stops it on every rank,
    naming the key, the temperature, the point and the time: the first time inside the step
    from 0.5 to 0.75 where it passes 56, not the step time 0.75."""
    visco = dict(ONE_TERM, **wlf_table(0.5), temperature="50.0 + 10.0 * t + 1.5 * x[0]")
    raw = rl.block_scene(visco, "plane_strain", [[0.0, 0.01], [0.01, 0.0]], "step", 1.0, 4)
    with pytest.raises(SceneError, match=r"= 56\.1\d* is outside the shift table \[48, 56\]"
                                         r".*at the point x = \(.*\) \(at t = 0\.51\d*, between "
                                         r"the step times 0\.5 and 0\.75\)") as err:
        rl.block_stress(raw)
    assert err.value.key == "viscoelastic.temperature"


# --- Outputs -------------------------------------------------------------------------------

def test_relaxation_figure_closed_forms():
    """The figure's loss modulus of one Maxwell term peaks at w = 1/tau with G1/2, and at w =
    1/(a_T tau) on the master curve shifted to another temperature; the relaxation modulus
    runs from G(0) to G_inf."""
    from contactvisco.post.figures import relaxation_figure
    visco = dict(WLF, shear={"instantaneous": 10.0, "tau": [0.5], "fractions": [0.4]},
                 bulk={"instantaneous": 25.0})
    scene = loader.resolve(scene_with(**visco))
    omegas = np.geomspace(1e-4, 1e4, 8001)
    fig = relaxation_figure(scene, temperatures=[55.0], omegas=omegas)
    relax, storage, loss = fig.axes
    shear_ref, shear_hot = (line.get_ydata() for line in loss.lines[:2])   # then bulk's
    a = 10 ** float(ve.log10_shift(visco, 55.0))
    for values, peak in ((shear_ref, 1 / 0.5), (shear_hot, 1 / (0.5 * a))):
        assert omegas[np.argmax(values)] == pytest.approx(peak, rel=3e-3)
        assert values.max() == pytest.approx(4.0 / 2, rel=1e-6)
    G = relax.lines[0].get_ydata()
    assert G[0] == pytest.approx(10.0, rel=1e-3) and G[-1] == pytest.approx(6.0, rel=1e-3)
    with pytest.raises(SceneError, match="needs a scene with"):
        relaxation_figure(loader.load("paper"))


@pytest.mark.skipif(MPI.COMM_WORLD.size > 1, reason="starts its own process; run on one rank")
def test_relaxation_command(tmp_path):
    from helpers import run_cli
    path = csv_scene(tmp_path, "tau,G\n0.3,3\n2,2\n")
    out = tmp_path / "moduli.png"
    done = run_cli("relaxation", path, "--out", out, timeout=120)
    assert done.returncode == 0 and out.stat().st_size > 1000, done.stderr
    done = run_cli("relaxation", path, "--temperature", "40", timeout=120)
    assert done.returncode == 2 and "viscoelastic.shift" in done.stderr
