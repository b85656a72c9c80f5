"""Time grids of [time] (contactvisco.model.time_grid): what each kind makes, how the scene
refuses a bad one, and the paper rule's stability stated per step on a variable grid."""
import math
import os

import numpy as np
import pytest

from contactvisco import api
from contactvisco.errors import SceneError
from contactvisco.model import stability, time_grid
from contactvisco.model.memory import History
from contactvisco.scene.loader import check_given

LOG = {"T": 1e4, "grid": "logarithmic", "first": 1e-3, "per_decade": 20,
       "rule": "exponential"}


def test_uniform_grid_is_the_loop_of_n_times_k():
    """The uniform grid is n (T/N) to the bit, as the loop has always stepped."""
    scene = api.load_scene("paper", time={"T": 0.7, "steps": 9})
    grid = time_grid.times(scene["time"])
    assert grid.tolist() == [n * (0.7 / 9) for n in range(10)]
    assert time_grid.summary(scene["time"]) == (9, 0.7 / 9, 0.7 / 9)


@pytest.mark.parametrize("spec", [{"per_decade": 20}, {"growth": 1.3}])
def test_logarithmic_grid_is_geometric_and_ends_at_T(spec):
    """k_{j+1}/k_j = g for every step, t_N = T, N = ceil(log(1 + (T/k_1)(g - 1)) / log g),
    and the first step k_1 scaled by a factor in (1/g, 1]."""
    time = {"T": 1e4, "grid": "logarithmic", "first": 1e-3, **spec}
    g = time_grid.growth_of(time)
    grid = time_grid.times(time)
    k = np.diff(grid)
    assert grid[0] == 0.0 and grid[-1] == 1e4
    assert np.allclose(k[1:] / k[:-1], g, rtol=1e-9)
    assert len(k) == math.ceil(math.log(1 + 1e4 / 1e-3 * (g - 1)) / math.log(g))
    assert 1e-3 / g < k[0] <= 1e-3
    if "per_decade" in spec:          # m steps per decade once t >> k_1 / (g - 1)
        late = grid[grid > 1.0]
        per_decade = (len(late) - 1) / math.log10(late[-1] / late[0])
        assert per_decade == pytest.approx(20, rel=2e-3)


def test_an_exact_fit_gains_no_step_from_round_off():
    """first = 1, growth 2 over T = 2^10 - 1 is exactly 10 steps 1, 2, ..., 512."""
    time = {"T": 1023.0, "grid": "logarithmic", "first": 1.0, "growth": 2.0}
    k = np.diff(time_grid.times(time))
    assert len(k) == 10 and np.allclose(k, [2.0 ** j for j in range(10)], rtol=1e-12)


def test_piecewise_grid_keeps_the_segment_ends():
    """A fine uniform ramp then a logarithmic hold: each end is a step time (the ramp's kink),
    the ramp's steps uniform, the hold's geometric from its start."""
    scene = api.load_scene("paper", time={
        "T": 1e4, "rule": "exponential", "grid": "piecewise",
        "segments": [{"end": 0.1, "steps": 10},
                     {"end": 1e4, "grid": "logarithmic", "first": 0.01, "per_decade": 10}]})
    grid = time_grid.times(scene["time"])
    k = np.diff(grid)
    assert 0.1 in grid.tolist() and grid[-1] == 1e4
    assert np.allclose(k[:10], 0.01, rtol=1e-12)
    assert np.allclose(k[11:] / k[10:-1], 10 ** 0.1, rtol=1e-9)
    n, least, largest = time_grid.summary(scene["time"])
    assert n == len(grid) - 1 and least == pytest.approx(k.min()) and largest == k.max()


def test_explicit_times_and_a_csv_column(tmp_path):
    """A list (a leading 0 is t_0; T added after the last time) and a CSV column beside the
    scene file give the same grid."""
    scene = api.load_scene("paper", time={"T": 4.0, "grid": "times", "rule": "trapezoid",
                                          "times": [0, 0.5, 1.25, 3.0]})
    assert time_grid.times(scene["time"]).tolist() == [0, 0.5, 1.25, 3.0, 4.0]
    (tmp_path / "samples.csv").write_text("depth,t\n0.0,0\n0.1,0.5\n0.2,1.25\n0.3,3.0\n")
    path = tmp_path / "scene.toml"
    path.write_text('[time]\nT = 4.0\nrule = "trapezoid"\ngrid = "times"\n'
                    'times_file = "samples.csv"\ntimes_column = "t"\n')
    from_file = api.load_scene(str(path))
    assert time_grid.times(from_file["time"]).tolist() == [0, 0.5, 1.25, 3.0, 4.0]
    # checked again where used (solve, check): the file is read again beside the scene
    again = check_given(from_file)
    assert time_grid.times(again["time"]).tolist() == [0, 0.5, 1.25, 3.0, 4.0]


def test_a_time_file_may_not_lead_out_of_the_scene_folder(tmp_path):
    """Absolute names, '..' and a link leading out are refused; so is a column of text or of
    decreasing times, naming the row."""
    inner = tmp_path / "scene"
    inner.mkdir()
    (tmp_path / "outside.csv").write_text("t\n1\n")
    os.symlink(tmp_path / "outside.csv", inner / "link.csv")
    (inner / "bad.csv").write_text("t\n0.5\n0.25\n")
    (inner / "text.csv").write_text("t\n0.5\nsoon\n")
    cases = {"/etc/hostname": "without '..'", "../outside.csv": "without '..'",
             "link.csv": "leads out of the scene file's folder",
             "bad.csv": "bad.csv, row 3: the time 0.25", "text.csv": "row 3"}
    for name, words in cases.items():
        path = inner / "scene.toml"
        path.write_text(f'[time]\nrule = "trapezoid"\ngrid = "times"\ntimes_file = "{name}"\n')
        with pytest.raises(SceneError, match="time.times_file") as err:
            api.load_scene(str(path))
        assert words in str(err.value) and err.value.key == "time.times_file"


@pytest.mark.parametrize("time, key, words", [
    ({"grid": "logarithmic", "per_decade": 10}, "time.first", "needs time.first"),
    ({"grid": "logarithmic", "first": 0.1, "per_decade": 10, "growth": 2.0}, "time.per_decade",
     "one of time.growth"),
    ({"first": 0.1}, "time.first", "belongs to time.grid = 'logarithmic'"),
    ({"grid": "logarithmic", "first": 0.1, "growth": 1.0}, "time.growth", "> 1"),
    ({"grid": "logarithmic", "first": 1e-300, "growth": 1.0000001}, "time.first",
     "more than 1000000 steps"),
    ({"grid": "times", "times": [0.5, 0.5]}, "time.times", "increase"),
    ({"grid": "times", "times": [0.5, 2.0]}, "time.times", "after time.T"),
    ({"grid": "times", "times": [0.5, 0.5 + 1e-14]}, "time.times", "smallest step"),
    ({"grid": "times", "times": [math.nan]}, "time.times", "finite"),
    ({"grid": "piecewise", "segments": [{"end": 0.5, "steps": 2}]}, "time.segments[0].end",
     "not at time.T"),
    ({"grid": "piecewise", "segments": [{"end": 0.5, "steps": 2}, {"end": 0.4, "steps": 2}]},
     "time.segments[1].end", "above the segment's start"),
    ({"grid": "piecewise", "segments": [{"end": 1.0, "steps": 2, "first": 0.1}]},
     "time.segments[0].first", "belongs to a logarithmic segment"),
    ({"grid": "piecewise", "segments": [{"end": 1.0, "grid": "logarithmic", "first": 0.1,
                                         "per_decade": 0.5}]},
     "time.segments[0].per_decade", ">= 1"),
    ({"grid": "piecewise", "segments": [{"end": 1.0, "step": 2}]}, "time.segments[0].step",
     "unknown key"),
])
def test_bad_grids_are_refused_naming_the_key(time, key, words):
    with pytest.raises(SceneError) as err:
        api.load_scene("paper", time={"rule": "trapezoid", **time})
    assert err.value.key == key and words in str(err.value), str(err.value)


def _scalar_paper_rule(steps, m=1.0, alpha=1.0):
    """The scalar analogue m u_n + H_n = m u_0 of the paper's rule with the constant kernel
    alpha (exact solution u_0 exp(-alpha t/m)), H_n from contactvisco.model.memory.History on
    the given steps; |u_n| / |u_0|."""
    history = History([(alpha, math.inf, "full")], rule="paper", d=1)
    u = np.array([1.0])
    out = [1.0]
    history.commit(u, None)
    for k in steps:
        u = 1.0 - history.explicit(k) / m       # m u_n + H_n = m u_0, u_0 = 1
        history.commit(u, k)
        out.append(abs(u[0]))
    return np.array(out)


@pytest.mark.parametrize("kind", ["growing", "alternating"])
def test_paper_rule_stability_is_stated_step_by_step(kind):
    """On a variable grid the bound is the largest mean (b_n + b_{n+1})/2 of consecutive
    steps' numbers (model.stability.grid_number): at 0.9 of it the discrete scalar problem
    decays, at 1.15 it grows without bound (the recursion of History, not the formula)."""
    rng = np.random.default_rng(4)
    base = (np.geomspace(1.0, 1.2, 200) if kind == "growing"
            else np.where(np.arange(200) % 2, 1.0, 0.4) * rng.uniform(0.95, 1.05, 200))
    for scale, grows in ((0.9, False), (1.15, True)):
        numbers = base * scale / stability.grid_number(base)
        assert stability.grid_number(numbers) == pytest.approx(scale)
        u = _scalar_paper_rule(numbers)          # m = alpha = 1: b_n = k_n
        assert (u[-1] > 1e3) == grows, (scale, u[-1])
        assert u[-20:].max() < 1.0 or grows


def test_scene_stability_number_on_a_logarithmic_grid():
    """The scene's number is that of its largest steps: with the constant kernel of the paper
    scene b_n = k_n alpha (1 + nu) / E, the largest consecutive mean at the end of the grid;
    refused with the largest stable step named."""
    time = {"T": 10.0, "grid": "logarithmic", "first": 0.01, "growth": 1.2,
            "rule": "trapezoid"}
    scene = api.load_scene("paper", time=time)
    k = np.diff(time_grid.times(scene["time"]))
    b = (k[-1] + k[-2]) / 2 * 100 * 1.3 / 100
    assert stability.stability_number(scene) == pytest.approx(b, rel=1e-12)
    with pytest.raises(SceneError, match="mean of every two consecutive steps less than") as err:
        api.load_scene("paper", time={**time, "rule": "paper"})
    assert err.value.key == "time.grid"


def test_fractional_kernel_fit_covers_the_grids_steps():
    """The fractional kernel's sum of exponentials is fitted on [k_min / 2^max_cuts, T], k_min
    the grid's smallest step: on a logarithmic grid it holds the kernel to memory.tolerance
    down to the cut halves of the first step (six decades below T), which a fit from the
    uniform step T/N would not reach."""
    from contactvisco.model import kernels
    memory = {"kernel": "fractional", "alpha": -20.0, "beta": 0.5, "part": "deviatoric"}
    scene = api.load_scene("paper", memory=memory, time={
        "T": 1e3, "rule": "trapezoid", "grid": "logarithmic", "first": 1e-3,
        "per_decade": 10})
    cuts = scene["solver"]["max_cuts"]
    history = kernels.history(scene["memory"], scene["time"], cuts, 2)
    least = time_grid.summary(scene["time"])[1]
    assert f"[{least / 2 ** cuts:.3g}, 1000]" in history.note
    s = np.geomspace(least / 2 ** cuts, 1e3, 400)
    exact = -20.0 * s ** -0.5 / math.gamma(0.5)
    fitted = np.exp(-np.multiply.outer(s, history.fit.rates)) @ history.fit.weights
    tolerance = scene["memory"]["tolerance"]
    assert np.abs(fitted / exact - 1).max() <= tolerance
    uniform = kernels.history(scene["memory"], {**scene["time"], "grid": "uniform",
                                                "steps": 60}, cuts, 2)
    assert uniform.fit.rates.max() < history.fit.rates.max() / 100     # it stops far above


def test_output_times_land_on_the_nearest_grid_time():
    """field_times on a logarithmic grid: each lands on the grid time nearest to it, the final
    time always (step 0 by field_every); a uniform grid keeps round(t / k)."""
    from contactvisco.solver.time_loop import FieldSchedule
    time = {"T": 100.0, "grid": "logarithmic", "first": 0.1, "growth": 2.0}
    grid = time_grid.times(time)
    schedule = FieldSchedule(1000, [0.25, 10.0, 60.0], time)
    due = [float(t) for n, t in enumerate(grid) if n and schedule.due(n, float(t))]
    expected = {float(grid[np.argmin(np.abs(grid - t))]) for t in (0.25, 10.0, 60.0)}
    assert due == sorted(expected | {100.0}) and 0.25 < due[0] < 0.5
    assert time_grid.nearest({"T": 1.0, "steps": 10}, [0.25, 0.36, 2.0, -1.0]) == [2, 4, 10, 0]
