"""The adaptive time grid (time.grid = "adaptive", contactvisco.solver.step_control) on the
homogeneous block under a smooth ramp-and-hold strain against the generalized Maxwell law in
closed form, beside the logarithmic grids of the same accuracy; and a creeping block on the
compliant foundation: restarted in the middle of its adaptive grid, and on 1 and 2 ranks.

Measured (benchmarks/results/adaptive_grid.md): tolerances 1e-2, 1e-3, 1e-4 take 24, 35, 64
steps for stress errors 6.2e-4, 1.5e-4, 2.7e-5, where the logarithmic grids (first step
0.3/m, m per decade) need about 35, 80, 203 steps for the same errors.
"""
import math

import numpy as np
import pytest
from mpi4py import MPI

from contactvisco.solver.time_loop import simulate
import test_time_grids as time_grids
from test_time_grids import WIDE, _probes, block_error


def adaptive(tolerance):
    return {"grid": "adaptive", "first": 0.3 / 20, "tolerance": tolerance}


def test_adaptive_grid_takes_fewer_steps_than_a_logarithmic_grid_of_the_same_error():
    """The block over six decades: the error falls with the tolerance, and the steps stay
    below twice those of the logarithmic family at the adaptive run's error (log-log
    interpolation between m = 10 and m = 20 per decade)."""
    fixed = [block_error(WIDE, 1e4, m, "exponential") for m in (10, 20)]
    (e10, t10), (e20, t20) = fixed
    n10, n20 = len(t10) - 1, len(t20) - 1
    loose, t_loose = block_error(WIDE, 1e4, 0, "exponential", grid=adaptive(1e-2))
    tight, t_tight = block_error(WIDE, 1e4, 0, "exponential", grid=adaptive(1e-3))
    assert tight < 0.5 * loose
    assert e20 <= tight <= e10
    s = math.log(tight / e10) / math.log(e20 / e10)
    fixed_steps = math.exp(math.log(n10) + s * (math.log(n20) - math.log(n10)))
    assert len(t_tight) - 1 <= 2 * fixed_steps
    steps = np.diff(t_tight)
    assert steps.max() > 100 * steps.min()              # it grew over the hold
    assert t_tight[-1] == 1e4


def creep_scene(tolerance=1e-3):
    """The block creeping on the compliant foundation (test_time_grids.creep_scene) on an
    adaptive grid from 1e-2 s to 1e4 s, with a stop at 1 s."""
    return time_grids.creep_scene(time={"grid": "adaptive", "first": 1e-2,
                                        "tolerance": tolerance, "landing_times": [1.0]})


def test_restart_in_the_middle_of_an_adaptive_grid_continues_it(tmp_path_factory,
                                                                monkeypatch):
    """A run stopped after its checkpoint of step 9 and restarted takes the uninterrupted
    run's steps (each k and error estimate) and reaches its displacements; the stop is a
    step time."""
    whole, restarted, _ = time_grids.whole_and_restarted(tmp_path_factory, monkeypatch,
                                                         creep_scene(), 10)
    times = [s["t"] for s in whole.steps]
    assert 1.0 in times and times[-1] == 1e4
    assert [s["t"] for s in restarted.steps] == times[10:]
    assert [s["k"] for s in restarted.steps] == [s["k"] for s in whole.steps[10:]]
    assert np.allclose([s["error"] for s in restarted.steps],
                       [s["error"] for s in whole.steps[10:]], rtol=1e-6, atol=0)
    assert all(s["error"] is not None for s in whole.steps[3:])
    a, b = _probes(whole), _probes(restarted)
    assert np.abs(a[10:] - b).max() <= 1e-12 * np.abs(a).max()


@pytest.mark.mpi
def test_ranks_agree_on_an_adaptive_grid():
    """Over the ranks the controller chooses the steps of the run on one rank."""
    scene = creep_scene()
    everywhere = simulate(scene, comm=MPI.COMM_WORLD, progress=False)
    alone = simulate(scene, comm=MPI.COMM_SELF, progress=False)
    a = np.array([s["t"] for s in everywhere.steps])
    b = np.array([s["t"] for s in alone.steps])
    assert a.tolist() == b.tolist()
    pa, pb = _probes(everywhere), _probes(alone)
    assert np.abs(pa - pb).max() <= 1e-8 * np.abs(pb).max()
