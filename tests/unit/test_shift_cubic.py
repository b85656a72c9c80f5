"""viscoelastic.shift_interpolation = "monotone_cubic": log10 a_T between the points of a
shift table by the monotone piecewise-cubic Hermite interpolant of Fritsch and Carlson (1980)
(contactvisco.model.viscoelastic.monotone_cubic); linear stays the default."""
import math

import numpy as np
import pytest
from mpi4py import MPI

from contactvisco.errors import SceneError
from contactvisco.model import viscoelastic as ve
from contactvisco.scene import loader
from contactvisco.studies import relaxation as rl

WLF = {"shift": "wlf", "T_ref": 50.0, "C1": 17.44, "C2": 51.6}
ONE_TERM = {"shear": {"instantaneous": 10.0, "tau": [0.5], "fractions": [0.4]},
            "bulk": {"instantaneous": 25.0}}
CUBIC = {"shift_interpolation": "monotone_cubic"}


def wlf_table(h, lo=48.0, hi=56.0, T_ref=50.0, **extra):
    """The WLF curve sampled every h on [lo, hi], as a [viscoelastic] shift table."""
    T = lo + h * np.arange(int(round((hi - lo) / h)) + 1)
    return dict({"shift": "table", "T_ref": T_ref, "shift_temperatures": T.tolist(),
                 "shift_log10_aT": ve.log10_shift(WLF, T).tolist()}, **extra)


def test_nodes_exact_and_lines_reproduced():
    """The interpolant takes the data at the nodes bit for bit (uneven spacing), and data on
    a straight line give that line everywhere (the slopes are then the secant)."""
    x = np.array([40.0, 41.5, 44.0, 45.0, 49.0, 50.0, 53.5, 60.0])
    y = np.array([6.1, 5.0, 3.2, 2.9, 0.8, 0.0, -1.7, -3.9])
    assert np.array_equal(ve.monotone_cubic(x, y, x), y)
    line = 2.0 - 0.3 * (x - 50.0)
    fine = np.linspace(40.0, 60.0, 1001)
    assert np.abs(ve.monotone_cubic(x, line, fine) - (2.0 - 0.3 * (fine - 50.0))).max() < 1e-13


def test_monotone_at_a_sharp_knee():
    """Data flat, then falling steeply, then flat (monotone non-increasing): the unlimited
    three-point cubic overshoots both plateaus and rises in places; the limited one decreases
    everywhere and stays within the data's range."""
    x = np.arange(7.0)
    y = np.array([10.0, 10.0, 10.0, 9.9, 2.0, 0.0, 0.0])
    fine = np.linspace(0.0, 6.0, 6001)
    free = ve.monotone_cubic(x, y, fine, limited=False)
    assert free.max() > 10.3 and free.min() < -0.2 and np.diff(free).max() > 1e-4
    limited = ve.monotone_cubic(x, y, fine)
    assert np.diff(limited).max() <= 1e-12
    assert 0.0 <= limited.min() and limited.max() <= 10.0 + 1e-12


def test_order_against_the_wlf_curve():
    """The WLF curve sampled every h on [48, 56] (monotone, no extremum): the maximum error
    falls as h^3 (the second-order three-point slopes), the linear table's as h^2."""
    fine = np.linspace(48.0, 56.0, 4001)
    exact = ve.log10_shift(WLF, fine)
    cubic, linear = [], []
    for h in (1.0, 0.5, 0.25):
        table = wlf_table(h, **CUBIC)
        cubic.append(np.abs(ve.log10_shift(table, fine) - exact).max())
        linear.append(np.abs(ve.log10_shift(wlf_table(h), fine) - exact).max())
    orders = [math.log2(a / b) for a, b in zip(cubic, cubic[1:])]
    assert all(abs(p - 3.0) < 0.1 for p in orders), (cubic, orders)
    assert cubic[0] < 0.05 * linear[0]


def test_run_and_linear_default():
    """The shear step under theta = 50 + 4 t + 1.5 x[0] with the WLF curve tabulated every
    h = 1 against the WLF run (same 20 steps): the cubic table's difference is 1/100 of the
    linear table's or less; without the key the table is linear (the scene's default, numbers
    as before)."""
    strain = [[0.0, 0.01], [0.01, 0.0]]
    temperature = "50.0 + 4.0 * t + 1.5 * x[0]"

    def run(shift):
        raw = rl.block_scene(dict(ONE_TERM, **shift, temperature=temperature),
                             "plane_strain", strain, "step", 1.0, 20)
        return rl.block_stress(raw, MPI.COMM_SELF)[1]
    ref = run(WLF)
    cubic, linear = (np.abs(run(wlf_table(1.0, **extra)) - ref).max() / np.abs(ref).max()
                     for extra in (CUBIC, {}))
    assert cubic < 1e-2 * linear and linear > 1e-4, (cubic, linear)
    scene = loader.resolve(rl.block_scene(dict(ONE_TERM, **wlf_table(1.0)), "plane_strain",
                                          strain, "step", 1.0, 2))
    assert scene["viscoelastic"]["shift_interpolation"] == "linear"
    between = np.array([50.4, 52.7])
    assert np.array_equal(ve.log10_shift(scene["viscoelastic"], between),
                          np.interp(between, *ve.shift_points(scene["viscoelastic"])))


@pytest.mark.parametrize("extra, key, words", [
    (dict(WLF, shift_interpolation="monotone_cubic"), "viscoelastic.shift_interpolation",
     "interpolates a shift table"),
    (wlf_table(1.0, shift_interpolation="spline"), "viscoelastic.shift_interpolation",
     "linear or monotone_cubic"),
])
def test_refused(extra, key, words):
    raw = rl.block_scene(dict(ONE_TERM, **extra), "plane_strain", [[0.0, 0.01], [0.01, 0.0]],
                         "step", 1.0, 2)
    with pytest.raises(SceneError) as err:
        loader.resolve(raw)
    assert err.value.key == key and words in str(err.value), str(err.value)
