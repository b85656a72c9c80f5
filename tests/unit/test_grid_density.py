"""A grid made f times as dense (contactvisco.model.time_grid.scaled), as presets and the
trade-off's ladder ask, on every kind of grid."""
import pytest

from contactvisco.model import time_grid
from contactvisco.scene import loader


@pytest.mark.parametrize("time, factor, expected_steps", [
    ({"T": 10.0, "steps": 7}, 2.0, 14),
    ({"T": 1e4, "grid": "logarithmic", "first": 1e-3, "per_decade": 10}, 2.0, None),
    ({"T": 1e4, "grid": "logarithmic", "first": 1e-3, "growth": 1.5}, 0.5, None),
    ({"T": 1e4, "grid": "piecewise", "segments": [
        {"end": 0.1, "steps": 5},
        {"end": 1e4, "grid": "logarithmic", "first": 0.01, "per_decade": 10}]}, 2.0, None),
])
def test_a_denser_grid_has_about_f_times_the_steps(time, factor, expected_steps):
    """N f steps for a uniform grid; about N f (within 2 steps per logarithmic part) for the
    others, whose segment ends stay step times."""
    before = time_grid.count(time)
    after = time_grid.count({**time, **time_grid.scaled(time, factor)})
    if expected_steps is not None:
        assert after == expected_steps
    else:
        assert abs(after - factor * before) <= 2 + 0.02 * factor * before
    if time.get("grid") == "piecewise":
        grid = time_grid.times({**time, **time_grid.scaled(time, factor)})
        assert 0.1 in grid.tolist()


def test_given_times_stay_and_an_adaptive_grid_tightens_its_tolerance():
    """Given times are data; an adaptive grid takes k_1/f and tol/f^3 (steps ~ tol^(-1/3))."""
    assert time_grid.scaled({"T": 1.0, "grid": "times", "times": [0.5]}, 2.0) == {}
    adaptive = {"T": 1.0, "grid": "adaptive", "first": 0.01, "tolerance": 1e-3}
    assert time_grid.scaled(adaptive, 2.0) == {"first": 0.005, "tolerance": 1e-3 / 8}
    assert time_grid.scaled(adaptive, 1.0) == {}


def test_a_preset_scales_every_kind_of_grid(monkeypatch):
    """A preset of twice the steps doubles a logarithmic grid's density; on an adaptive grid
    it keeps the exponential rule its estimate belongs to."""
    monkeypatch.setitem(loader.PRESETS, "accurate", dict(loader.PRESETS["accurate"], steps=2.0))
    memory = {"kernel": "exponential", "alpha": -1.0, "tau": 1.0}
    log = loader.resolve({"name": "a", "preset": "accurate", "memory": memory, "time": {
        "T": 100.0, "grid": "logarithmic", "first": 0.01, "per_decade": 8}})
    assert (log["time"]["first"], log["time"]["per_decade"]) == (0.005, 16.0)
    adaptive = loader.resolve({"name": "a", "preset": "accurate", "memory": memory, "time": {
        "T": 100.0, "grid": "adaptive", "first": 0.01, "tolerance": 1e-3,
        "rule": "exponential"}})
    assert adaptive["time"]["rule"] == "exponential"
    assert adaptive["time"]["tolerance"] == pytest.approx(1.25e-4)
