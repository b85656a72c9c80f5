"""Step cutting as a function: `run.advance` yields accepted states that tile the step with
halved sizes, each one converged, and a step that may not be cut leaves the unknowns as they
were. On COMM_SELF: where Newton needs the most iterations depends on the partition."""
import numpy as np
import pytest
from mpi4py import MPI

from contactvisco import load_scene
from contactvisco.fem import geometry as geometry_module
from contactvisco.fem.problem import build
from contactvisco.scene import loader as scene_module
from contactvisco.solver import newton as solver_module
from contactvisco.solver.time_loop import StepFailed, advance
from helpers import HARD_IRONING, newton_limit

STEPS = 5


def quiet(text):
    """What advance says about a cut step, dropped."""


def ironing(max_newton=None):
    """The moving load of the ironing scene in 5 large steps (HARD_IRONING), with at most
    `max_newton` Newton iterations per state (None: the scene's limit)."""
    options = [] if max_newton is None else [f"solver.petsc_options={{snes_max_it={max_newton}}}"]
    scene = scene_module.load("ironing", HARD_IRONING + options)
    problem = build(scene, geometry_module.build(scene, MPI.COMM_SELF))
    return scene, problem, solver_module.create(problem, MPI.COMM_SELF)


def step_ends(scene) -> list[float]:
    """t_0, t_1, ..., t_N as the tests step through them."""
    return [n * scene["time"]["T"] / STEPS for n in range(STEPS + 1)]


def hard_limit() -> int:
    """newton_limit of the uncut states t_0 .. t_N, taken one by one by advance."""
    scene, problem, snes = ironing()
    try:
        iterations = [state.iterations for t_to in step_ends(scene)
                      for state in advance(problem, snes, t_to, 0, quiet)]
    finally:
        snes.destroy()
    return newton_limit(iterations)


def test_cut_states_tile_the_step_and_converge():
    limit = hard_limit()
    scene, problem, snes = ironing(limit)
    try:
        t, cut = 0.0, 0
        for n, t_to in enumerate(step_ends(scene)):
            states = []
            for state in advance(problem, snes, t_to, 4, quiet):
                # Converged: the residual fell by 1e6 at least (or was already at round-off).
                assert snes.residuals[-1] <= 1e-6 * max(snes.residuals[0], 1e-8)
                assert state.iterations <= limit
                states.append(state)
            if n == 0:                                    # the initial state: never cut
                assert len(states) == 1 and states[0].k is None and states[0].t == 0.0
                continue
            times = [t] + [s.t for s in states]
            assert times[-1] == t_to                       # the step's end, exactly
            assert all(b > a for a, b in zip(times, times[1:]))
            for a, b, s in zip(times, times[1:], states):
                assert s.k == pytest.approx(b - a, abs=1e-15)     # the exact size for eq (19)
                halvings = np.log2((t_to - t) / s.k)
                assert abs(halvings - round(halvings)) < 1e-9 and 0 <= halvings <= 4
                assert s.cuts >= round(halvings)
            cut += len(states) > 1
            t = t_to
        assert cut >= 1                                   # some step was cut
    finally:
        snes.destroy()


def test_a_step_that_may_not_be_cut_restores_the_unknowns():
    scene, problem, snes = ironing(hard_limit())
    try:
        ends = step_ends(scene)
        list(advance(problem, snes, ends[0], 0, quiet))
        failures = 0
        for t_from, t_to in zip(ends, ends[1:]):
            before = [f.x.array.copy() for f in problem.unknowns]
            try:
                list(advance(problem, snes, t_to, 0, quiet))
            except StepFailed as failed:
                failures += 1
                assert failed.cuts == 0
                assert failed.failure.reason < 0 and failed.t_to == t_to
                assert failed.t_from == t_from == problem.time.committed
                for f, values in zip(problem.unknowns, before):
                    assert np.array_equal(f.x.array, values)
                # From the restored state the step goes through when it may be cut.
                states = list(advance(problem, snes, t_to, 4, quiet))
                assert states[-1].t == t_to and all(s.t > t_from for s in states)
        assert failures >= 1
    finally:
        snes.destroy()


def test_only_the_last_checkpoint_is_synced_to_the_disk(tmp_path, monkeypatch):
    """A checkpoint every step, fsynced only at the end of the run (a kill of the process
    loses nothing unsynced; the sync costs milliseconds per file): the files synced under
    checkpoint/ are the last state's part and meta.json, and every step's checkpoint was
    written (the last one read back holds the final count)."""
    import json
    import os

    from contactvisco.solver.time_loop import simulate
    synced = []
    fsync = os.fsync

    def recording_fsync(fd):
        synced.append(os.readlink(f"/proc/self/fd/{fd}"))
        fsync(fd)

    monkeypatch.setattr(os, "fsync", recording_fsync)
    scene = load_scene("paper", geometry={"cells": [4, 4]}, time={"steps": 3},
                       output={"figures": False, "xdmf": False, "checkpoint_every": 1})
    simulate(scene, tmp_path, comm=MPI.COMM_SELF, progress=False)
    checkpoints = sorted(os.path.relpath(p, tmp_path / "checkpoint") for p in synced
                         if p.startswith(str(tmp_path / "checkpoint")))
    assert checkpoints == ["meta.tmp.json", "state-000004/part-0.tmp.npz"]
    meta = json.loads((tmp_path / "checkpoint" / "meta.json").read_text())
    assert meta["count"] == 4
