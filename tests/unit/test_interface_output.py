"""What a run of two bodies in contact writes (obstacle.shape = "body"): each body's resultant
contact force in the step records, the interface tables, the cell field of the bodies.

The two blocks of meshes/two_blocks.py (13 slave against 10 master segments), the lower held
at its bottom, both blocks' sides held in x, a pressure growing in time on the top of the
upper one, or the upper one dragged over the lower with Coulomb friction."""
import numpy as np
import pytest
from mpi4py import MPI

from contactvisco.scene import loader
from contactvisco.solver.time_loop import simulate

pytestmark = pytest.mark.mpi

PRESSURE = 0.01


def blocks(pairing="mortar", friction=False, **extra) -> dict:
    """The two blocks pressed by p min(2 t, 1) on the upper one's top (normal compliance);
    friction: Signorini contact with Coulomb friction, the upper block dragged by its top."""
    raw = {
        "name": "two_blocks",
        "geometry": {"type": "gmsh", "script": "two_blocks",
                     "parameters": {"h_slave": 0.077, "h_master": 0.1}},
        "material": {"model": "plane_strain", "E": 1.0, "nu": 0.3},
        "dirichlet": [{"boundary": "bottom", "components": [1]},
                      {"boundary": "master_sides", "components": [0]},
                      {"boundary": "slave_sides", "components": [0]}],
        "traction": [{"boundary": "top", "value": [0.0, f"-{PRESSURE} * min(2 * t, 1)"]}],
        "body": [{"name": "upper", "cells": "slave_body", "material": {"E": 2.0}},
                 {"name": "lower", "cells": "master_body"}],
        "contact": {"boundary": "slave", "stiffness": 100.0, "pairing": pairing},
        "obstacle": {"shape": "body", "boundary": "master"},
        "time": {"T": 1.0, "steps": 3},
        "output": {"probes": [], "figures": False},
    }
    if friction:
        raw["dirichlet"] = [{"boundary": "bottom", "components": "all"},
                            {"boundary": "top", "components": [0], "value": "0.2 * t"}]
        # dragged by 0.2, past half a master segment (0.05): the records are checked on the
        # reference pairing, kept whatever the sliding
        raw["contact"].update(stiffness=0.0, g=0.0, mu=0.3, friction_law="coulomb",
                              sliding_limit=float("inf"))
    raw.update(extra)
    return raw


def folder(tmp_path_factory, name) -> str:
    comm = MPI.COMM_WORLD
    return comm.bcast(str(tmp_path_factory.mktemp(name)) if comm.rank == 0 else None)


@pytest.mark.parametrize("pairing, friction", [("mortar", False), ("node_to_segment", False),
                                               ("mortar", True)])
def test_step_records_balance_the_bodies(tmp_path_factory, pairing, friction):
    """Every step record says the obstacle is a body (no displacement of its own) and holds
    each body's resultant contact force: action = -reaction to 1e-12 of the load, the slave's
    the load it carries (compliance: (0, p min(2t, 1)) per unit length to 1e-10 p)."""
    out = folder(tmp_path_factory, "records")
    result = simulate(loader.resolve(blocks(pairing, friction)), out=out,
                      comm=MPI.COMM_WORLD, progress=False)
    from contactvisco.io.output import read_summary
    written = read_summary(out)["steps"]
    assert len(result.steps) == len(written) == 4
    for record, stored in zip(result.steps, written):
        entry = record["obstacle"]
        assert stored["obstacle"] == entry
        assert entry["shape"] == "body" and "displacement" not in entry
        assert (entry["slave"], entry["master"], entry["pairing"]) == ("slave", "master",
                                                                       pairing)
        slave, master = np.array(entry["slave_force"]), np.array(entry["master_force"])
        print(f"t = {record['t']:.3f}: slave {slave}, master {master}, "
              f"|sum| {np.abs(slave + master).max():.2e}")
        assert np.abs(slave + master).max() <= 1e-12 * PRESSURE
        if not friction:
            load = PRESSURE * min(2 * record["t"], 1.0)
            assert slave == pytest.approx([0.0, load], abs=1e-10 * PRESSURE)
    if friction:          # the last step slides: the slave is held back by mu p
        assert result.steps[-1]["obstacle"]["slave_force"][0] == pytest.approx(
            -0.3 * result.steps[-1]["obstacle"]["slave_force"][1], rel=1e-8)


def read_table(path) -> dict:
    """A CSV table as {column: array} (numbers as floats, names as strings)."""
    import csv
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    out = {}
    for j, name in enumerate(rows[0]):
        column = [row[j] for row in rows[1:]]
        try:
            out[name] = np.array(column, dtype=float)
        except ValueError:
            out[name] = np.array(column)
    return out


@pytest.mark.parametrize("pairing, friction", [("mortar", True), ("node_to_segment", False)])
def test_interface_tables_match_the_records(tmp_path_factory, pairing, friction):
    """interface_nodes.csv (a row per step and slave node) and interface_master.csv (per
    step and master boundary node), written once whatever the rank count: per step the
    nodal forces add up to the record's resultants (to 1e-12 of the load); each slave node's
    force is its law's, f . (t, -nu) proportional to (sigma_tau, p_nu + R_nu) (the master's
    normal is -y here: f_x / f_y = sigma_tau / (p_nu + R_nu)) wherever it is pressed; a
    pressed node has s > 0 with a compliance and R_nu > 0 with Signorini; every slave node
    projects onto a facet of the master (0..9)."""
    out = folder(tmp_path_factory, "tables")
    result = simulate(loader.resolve(blocks(pairing, friction)), out=out,
                      comm=MPI.COMM_WORLD, progress=False)
    if MPI.COMM_WORLD.rank != 0:
        return
    import pathlib
    slave = read_table(pathlib.Path(out) / "interface_nodes.csv")
    master = read_table(pathlib.Path(out) / "interface_master.csv")
    assert len(slave["step"]) == 4 * 14 and len(master["step"]) == 4 * 11
    assert set(slave["facet"]) <= set(range(10)) and len(set(slave["facet"])) == 10
    for record in result.steps:
        n = record["step"]
        mine, theirs = slave["step"] == n, master["step"] == n
        forces = [np.array([slave["f_x"][mine].sum(), slave["f_y"][mine].sum()]),
                  np.array([master["f_x"][theirs].sum(), master["f_y"][theirs].sum()])]
        for force, key in zip(forces, ("slave_force", "master_force")):
            assert np.abs(force - record["obstacle"][key]).max() <= 1e-12 * PRESSURE
        pressure = slave["p_nu"][mine] + slave["R_nu"][mine]
        pressed = slave["f_y"][mine] > 1e-9 * PRESSURE
        assert np.all(pressure[pressed] > 0) and np.all(slave["status"][mine][pressed]
                                                        != "separated")
        ratio = slave["f_x"][mine][pressed] / slave["f_y"][mine][pressed]
        assert np.abs(ratio - slave["sigma_tau"][mine][pressed] / pressure[pressed]).max(
            initial=0.0) < 1e-9
        if friction:
            assert np.all(slave["R_nu"][mine][pressed] > 0)
        else:
            assert np.all(slave["s"][mine][pressed] > 0)
    assert pressed.sum() >= 10


def test_body_field_tells_the_bodies_apart(tmp_path_factory):
    """Every step of solution.xdmf holds the cell field "body": 0 on the cells of the upper
    block (body[0], y > 0), 1 on those of the lower one (body[1], y < 0), read back from the
    written mesh and field."""
    from contactvisco.io.h5read import check_xdmf
    out = folder(tmp_path_factory, "fields")
    raw = blocks(time={"T": 1.0, "steps": 1})
    simulate(loader.resolve(raw), out=out, comm=MPI.COMM_WORLD, progress=False)
    if MPI.COMM_WORLD.rank != 0:
        return
    import pathlib
    series = check_xdmf(pathlib.Path(out) / "solution.xdmf")
    assert len(series) == 2
    for _, arrays in series:
        cells = arrays["topology"].astype(int)
        y = arrays["geometry"][cells].mean(axis=1)[:, 1]
        body = arrays["body"].ravel()
        assert body.shape == y.shape
        assert np.all(body[y > 0] == 0) and np.all(body[y < 0] == 1)
        assert (body == 0).sum() > 0 and (body == 1).sum() > 0


def test_interface_tables_survive_a_restart(tmp_path_factory, monkeypatch):
    """A run stopped right after its checkpoint of step 2 and restarted writes the interface
    tables of the uninterrupted run, each step's rows once (the rows past the checkpoint are
    cut back); the run's figures draw the two bodies' forces."""
    from helpers import run_stopped_after_checkpoint
    comm = MPI.COMM_WORLD
    whole, stopped = folder(tmp_path_factory, "whole"), folder(tmp_path_factory, "stopped")
    scene = loader.resolve(blocks("mortar", True))
    simulate(scene, out=whole, comm=comm, progress=False)
    run_stopped_after_checkpoint(monkeypatch, 2, lambda: simulate(
        scene, out=stopped, comm=comm, progress=False))
    simulate(scene, out=stopped, comm=comm, progress=False, restart=True)
    if comm.rank != 0:
        return
    import pathlib
    for name in ("interface_nodes.csv", "interface_master.csv"):
        a, b = (read_table(pathlib.Path(f) / name) for f in (whole, stopped))
        assert list(a) == list(b) and np.array_equal(a["step"], b["step"])
        for key in a:
            if a[key].dtype.kind == "f":
                assert np.abs(a[key] - b[key]).max() <= 1e-12 * max(np.abs(a[key]).max(), 1)
            else:
                assert np.array_equal(a[key], b[key])
    from contactvisco.post.figures import build_all
    drawn = dict(build_all(whole))
    axes = drawn["obstacle"].axes
    # A label longer than its axes is broken onto two lines (post.figures.fit_labels).
    assert [" ".join(ax.get_ylabel().split()).split(" (")[0] for ax in axes[:2]] == [
        "contact force on the slave", "contact force on the master"]
    slave_y, master_y = (ax.lines[1].get_ydata() for ax in axes[:2])
    assert np.allclose(slave_y, -np.asarray(master_y), atol=1e-12 * PRESSURE)


def test_check_estimates_the_output_of_two_bodies(tmp_path_factory):
    """contactvisco check's estimate of the folder's records (the fields with the cell field
    "body", the contact and interface tables, the step records) within 15 % of what a run of
    two bodies writes."""
    import pathlib
    from contactvisco import api
    scene = loader.resolve(blocks(time={"T": 1.0, "steps": 6}))
    estimate = api.check(scene)["output_bytes"]
    out = folder(tmp_path_factory, "estimate")
    simulate(scene, out=out, comm=MPI.COMM_WORLD, progress=False)
    if MPI.COMM_WORLD.rank == 0:
        out = pathlib.Path(out)
        written = sum(p.stat().st_size for p in (out / "solution").iterdir())
        written += sum((out / name).stat().st_size for name in (
            "contact_nodes.csv", "steps.jsonl", "solution.xdmf", "interface_nodes.csv",
            "interface_master.csv"))
        assert estimate == pytest.approx(written, rel=0.15)


def test_body_field_without_body_tables():
    """Two bodies without [[body]] tables: the cell field "body" is 0 on the slave's block
    (y > 0) and 1 on the master's (y < 0), the same on any partition."""
    from contactvisco.fem import geometry as geometry_module
    from contactvisco.fem.problem import build
    from contactvisco.io.output import body_field
    raw = blocks()
    del raw["body"]
    scene = loader.resolve(raw)
    problem = build(scene, geometry_module.build(scene, MPI.COMM_WORLD))
    field = body_field(problem)
    space = field.function_space
    y = space.tabulate_dof_coordinates()[:, 1]     # DG0: the cells' midpoints
    values = field.x.array
    assert np.all(values[y > 0] == 0) and np.all(values[y < 0] == 1)
    count = MPI.COMM_WORLD.allreduce(int((values[:space.dofmap.index_map.size_local] == 1)
                                         .sum()), MPI.SUM)
    assert count > 0
