"""The displacement system's direct solver keeps its factorization across a change of step
size (contactvisco.solver.newton.enable_nearby): a uniaxially creeping block on a
logarithmic grid gives the displacements of the run that factorizes every new matrix (to
1e-10), with a quarter of its factorizations (15 of 61 measured); a uniform grid with no more
(benchmarks/results/log_grid_cost.md)."""
import numpy as np
import pytest

from contactvisco.scene import loader
from contactvisco.solver import newton
from contactvisco.solver.time_loop import simulate

TAUS = [1e-2, 1e-1, 1.0, 10.0, 100.0, 1000.0]


def _run(monkeypatch, nearby, grid):
    monkeypatch.setattr(newton, "NEARBY", nearby)
    visco = {"shear": {"instantaneous": 10.0, "tau": TAUS, "fractions": [0.12] * 6},
             "bulk": {"instantaneous": 25.0}}
    scene = loader.resolve({
        "name": "nearby",
        "geometry": {"lower": [0.0, 0.0], "upper": [1.0, 1.0], "cells": [12, 12]},
        "material": {"model": "plane_strain"}, "viscoelastic": visco,
        "dirichlet": [{"boundary": "bottom", "components": [1]},
                      {"boundary": "left", "components": [0]}],
        "traction": [{"boundary": "top", "value": [0.0, "-0.1 * (1 + x[0])"]}],
        "time": {"T": 1e4, "rule": "exponential", **grid},
        "solver": {"linear_solver": "direct"},
        "output": {"probes": [[1.0, 1.0], [0.5, 1.0]], "xdmf": False, "figures": False}})
    result = simulate(scene, progress=False)
    u = np.array([[p["u"] for p in s["probes"]] for s in result.steps])
    return u, sum(s["preconditioner_setups"] for s in result.steps[1:]), result.steps


@pytest.mark.parametrize("grid", [{"grid": "logarithmic", "first": 1e-3, "per_decade": 10},
                                  {"steps": 40}])
def test_factors_kept_across_step_sizes_give_the_same_displacements(monkeypatch, grid):
    every, setups_every, steps = _run(monkeypatch, False, grid)
    kept, setups_kept, _ = _run(monkeypatch, True, grid)
    assert np.abs(kept - every).max() <= 1e-10 * np.abs(every).max()
    assert abs(every[-1, 0, 1]) > 1.2 * abs(every[1, 0, 1])           # it crept
    if "grid" in grid:
        assert setups_every == len(steps) - 1                 # each new k, before
        assert setups_kept <= setups_every / 3
    else:                            # uniform: no more than before
        assert setups_kept <= setups_every
