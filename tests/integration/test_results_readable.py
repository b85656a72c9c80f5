"""Results a reader can follow without the code list: the contact states by name in the
contact table and in contact_nodes.csv, with the columns docs/running.md lists; the stress
components, the von Mises stress and the contact state as named XDMF fields."""
import csv
import re

import numpy as np
import pytest
from mpi4py import MPI

from contactvisco import load_scene, solve
from contactvisco.fem import compat
from contactvisco.fem.contact_state import STATUSES, STICK_SLIP_STATES
from contactvisco.io import h5read, output
from helpers import ROOT

COMM = MPI.COMM_WORLD
OVERRIDES = dict(contact={"mu": 0.4}, time={"steps": 3}, geometry={"cells": [8, 8]},
                 output={"figures": False, "checkpoint": False,
                         "fields": ["u", "sigma", "stress_components", "von_mises",
                                    "contact_status"]})


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """The paper's scene with friction, written to a folder shared by the ranks."""
    out = COMM.bcast(str(tmp_path_factory.mktemp("readable")) if COMM.rank == 0 else None)
    result = solve(load_scene("paper", **OVERRIDES), out=out)
    return result, out


@pytest.mark.mpi
def test_contact_states_have_names_next_to_their_codes(run):
    result, _ = run
    table = result.contact[-1]
    # The integer codes stay (demos and tests compare them with numbers).
    assert table["status"].dtype.kind == "i" and table["friction"].dtype.kind == "i"
    assert list(table["status_name"]) == [STATUSES[c] for c in table["status"]]
    assert list(table["friction_name"]) == [STICK_SLIP_STATES[c] for c in table["friction"]]
    # A real check: the final state has nodes separated, in compliance and at the bound,
    # and the counts of the names are the run's status counts.
    counts = {name: int(np.sum(table["status_name"] == name)) for name in STATUSES}
    assert counts == result.final["status_counts"] and min(counts.values()) > 0
    assert "slip" in set(table["friction_name"])


@pytest.mark.mpi
def test_contact_csv_has_the_documented_columns_and_state_names(run):
    result, out = run
    if COMM.rank != 0:
        return
    with open(f"{out}/contact_nodes.csv", newline="") as f:
        rows = list(csv.reader(f))
    header, body = rows[0], rows[1:]
    # docs/running.md's output-folder row lists the columns in order.
    doc = (ROOT / "docs" / "running.md").read_text()
    line = next(text for text in doc.splitlines() if text.startswith("| `contact_nodes.csv`"))
    columns = line.split("in the columns")[1].split(":")[0]
    documented = re.findall(r"`([a-z_]+)`", columns)
    assert [c for c in documented if c != "z"] == header        # a 2D scene: no z
    last = [row for row in body if int(row[0]) == len(result.steps) - 1]
    table = result.contact[-1]
    assert [row[header.index("status")] for row in last] == list(table["status_name"])
    assert [row[header.index("friction")] for row in last] == list(table["friction_name"])
    assert np.allclose([float(row[header.index("u_nu")]) for row in last], table["u_nu"],
                       rtol=0, atol=1e-15)


def cell_stress(problem, comm):
    """On rank 0: (centroids, stress (m, d, d)) of every cell of the mesh at the last step,
    from the run's own stress expression."""
    from dolfinx import fem
    sigma = fem.Function(problem.tensor_space)
    sigma.interpolate(problem.sigma_expression)
    mesh = problem.geometry.mesh
    d = mesh.geometry.dim
    cells = mesh.topology.index_map(d).size_local
    vertices = compat.cell_dofs(problem.V.dofmap)[:cells, :d + 1]
    x = problem.V.tabulate_dof_coordinates()[:, :d]
    dofs = compat.cell_dofs(sigma.function_space.dofmap)[:cells]
    stress = sigma.x.array.reshape(-1, d, d)[dofs].mean(axis=1)
    parts = comm.gather((x[vertices].mean(axis=1), stress), root=0)
    if comm.rank == 0:
        return np.concatenate([p[0] for p in parts]), np.concatenate([p[1] for p in parts])
    return None


def by_position(points):
    return {tuple(p): i for i, p in enumerate(np.round(points / 1e-9).astype(np.int64))}


@pytest.mark.mpi
def test_xdmf_holds_named_stress_components_and_the_contact_status(run):
    """The fields read back from the HDF5 of the last step: sigma_xx, sigma_yy, sigma_xy and
    von_mises are the run's stress cell by cell, contact_status is the contact table's status
    at the contact nodes and 0 elsewhere."""
    result, out = run
    stress = cell_stress(result.problem, COMM)
    if COMM.rank != 0:
        return
    t, arrays = h5read.check_xdmf(f"{out}/solution.xdmf")[-1]
    assert t == result.steps[-1]["t"]
    points, topology = arrays["geometry"], arrays["topology"].astype(int)
    centroids, sigma = stress
    where = by_position(centroids)
    order = [where[key] for key in by_position(points[topology].mean(axis=1))]
    sigma = sigma[order]
    for name, (i, j) in {"sigma_xx": (0, 0), "sigma_yy": (1, 1), "sigma_xy": (0, 1)}.items():
        assert np.allclose(arrays[name][:, 0], sigma[:, i, j], rtol=1e-12, atol=1e-12), name
    assert np.allclose(arrays["von_mises"][:, 0], output.von_mises(sigma), rtol=1e-12)
    assert np.ptp(arrays["sigma_xy"]) > 0.1          # not a constant stress
    table = result.contact[-1]
    status = np.zeros(len(points))
    at = by_position(points)
    status[[at[key] for key in by_position(table["x"])]] = table["status"]
    assert np.array_equal(arrays["contact_status"][:, 0], status)
    assert set(status) == {0, 1, 2}


@pytest.mark.mpi
def test_gathered_grid_is_the_whole_mesh_on_rank_0(run):
    """pyvista_grid(u, gather=True): on rank 0 every point and cell of the mesh once (the
    cells tile the unit square) and the displacement of a run on one rank, point by point;
    None on the other ranks."""
    pytest.importorskip("pyvista")
    from contactvisco import pyvista_grid
    result, _ = run
    grid = pyvista_grid(result.u, gather=True)
    if COMM.rank != 0:
        assert grid is None
        return
    V = result.u.function_space
    assert grid.n_points == V.dofmap.index_map.size_global
    assert grid.n_cells == result.problem.geometry.mesh.topology.index_map(2).size_global
    areas = grid.compute_cell_sizes(length=False, area=True, volume=False)["Area"]
    assert np.all(areas > 0) and abs(np.sum(areas) - 1.0) < 1e-12
    alone = solve(load_scene("paper", **{**OVERRIDES, "output": {}}), comm=MPI.COMM_SELF)
    local = pyvista_grid(alone.u)
    assert local.n_points == grid.n_points
    mine = np.lexsort(np.round(np.asarray(grid.points) / 1e-9).T[::-1])
    theirs = np.lexsort(np.round(np.asarray(local.points) / 1e-9).T[::-1])
    assert np.allclose(grid.points[mine], local.points[theirs], rtol=0, atol=1e-14)
    u_all, u_one = grid.point_data["u"][mine], local.point_data["u"][theirs]
    assert np.abs(u_one).max() > 1e-3
    assert np.allclose(u_all, u_one, rtol=0, atol=1e-10 * np.abs(u_one).max())


# ---- what a run prints ----

def test_a_failure_message_is_short_and_keeps_the_whole_history():
    """Newton held to 2 iterations on the first state of the paper scene on 4 x 4 cells (it
    leaves |F| at a fiftieth of its start, eight orders above the tolerance): the message
    names the initial state,
    gives the first and last residual norms and their count on one short line, and the
    failure carries every norm."""
    from contactvisco import NewtonFailure
    scene = load_scene("paper", geometry={"cells": [4, 4]}, time={"steps": 1},
                       solver={"petsc_options": {"snes_max_it": 2}})
    with pytest.raises(NewtonFailure) as caught:
        solve(scene)
    message, residuals = str(caught.value), caught.value.residuals
    assert message.startswith("the initial state (t = 0): Newton did not converge")
    assert len(residuals) == 3 and residuals[0] > residuals[-1] > 0
    assert (f"after 2 iterations; residual history |F| {residuals[0]:.2e} -> "
            f"{residuals[-1]:.2e} (3 values)") in message
    assert "[" not in message and len(message) < 300


def test_run_names_its_folder_and_verbose_prints_every_newton_iteration(tmp_path):
    """contactvisco run: the first line names the output folder; -v adds one line per
    Newton iteration whose norms are the residual_history of steps.jsonl; --quiet prints
    nothing; --quiet with -v is refused."""
    import json
    import subprocess
    import sys
    if COMM.size > 1:
        pytest.skip("runs the command line on one rank")
    args = ["run", "paper", "--set", "time.steps=2", "--set", "geometry.cells=[4, 4]",
            "--set", "output.figures=false"]
    runs = {}
    for flag in ("-v", "--quiet", ""):
        out = tmp_path / (flag.strip("-") or "plain")
        proc = subprocess.run([sys.executable, "-m", "contactvisco", *args, "--out", str(out)]
                              + ([flag] if flag else []), capture_output=True, text=True,
                              timeout=300, cwd=ROOT)
        assert proc.returncode == 0, proc.stderr
        steps = [json.loads(line) for line in (out / "steps.jsonl").read_text().splitlines()]
        runs[flag] = proc.stdout.splitlines(), steps
    lines, steps = runs["-v"]
    assert lines[0] == f"writing to {tmp_path / 'v'}"
    printed = [float(line.split("=")[1]) for line in lines if line.startswith("  Newton")]
    history = [r for step in steps for r in step["residual_history"]]
    assert len(printed) == len(history) > len(steps)
    assert np.allclose(printed, history, rtol=1e-3, atol=0)
    plain, _ = runs[""]
    assert plain[0] == f"writing to {tmp_path / 'plain'}"
    # the folder, the header, a line per state and the closing line
    assert not any(line.startswith("  Newton") for line in plain) and len(plain) == 6
    assert runs["--quiet"][0] == []
    refused = subprocess.run([sys.executable, "-m", "contactvisco", *args, "-v", "--quiet"],
                             capture_output=True, text=True, timeout=60, cwd=ROOT)
    assert refused.returncode == 2 and "not allowed with" in refused.stderr
