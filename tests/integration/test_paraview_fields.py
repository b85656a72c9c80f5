"""What ParaView finds in the paper run's solution.xdmf without reading the docs: the contact
fields by name (contact_pressure, gap, normal and tangential traction, slip, the contact and
friction states) and von Mises, written by default, with the values of the contact table at
the contact nodes; and the contact table's contact_pressure column, positive in compression."""
import csv
import xml.etree.ElementTree as ET

import numpy as np
import pytest
from mpi4py import MPI

from contactvisco import load_scene, solve
from contactvisco.io import h5read, output

COMM = MPI.COMM_WORLD
#: The paper's scene with friction, output.fields left at its default.
OVERRIDES = dict(contact={"mu": 0.4}, time={"steps": 3}, geometry={"cells": [8, 8]},
                 output={"figures": False, "checkpoint": False})


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """The paper's scene with friction, written to a folder shared by the ranks."""
    out = COMM.bcast(str(tmp_path_factory.mktemp("paraview")) if COMM.rank == 0 else None)
    result = solve(load_scene("paper", **OVERRIDES), out=out)
    return result, out


def by_position(points):
    return {tuple(p): i for i, p in enumerate(np.round(points / 1e-9).astype(np.int64))}


@pytest.mark.mpi
def test_the_index_names_the_contact_fields_and_von_mises(run):
    """solution.xdmf, the file ParaView opens, lists every contact field and von_mises as a
    scalar on the nodes at every step."""
    _, out = run
    if COMM.rank != 0:
        return
    grids = ET.parse(f"{out}/solution.xdmf").getroot().iter("Grid")
    steps = [g for g in grids if g.get("GridType") == "Uniform"]
    assert len(steps) == 4
    for grid in steps:
        kinds = {a.get("Name"): (a.get("AttributeType"), a.get("Center"))
                 for a in grid.iter("Attribute")}
        for name in output.CONTACT_FIELDS:
            assert kinds.get(name) == ("Scalar", "Node"), (name, kinds)
        assert kinds["von_mises"][0] == "Scalar"


@pytest.mark.mpi
def test_the_contact_fields_hold_the_contact_table(run):
    """At T, read back from the HDF5: at each contact node the table's contact pressure
    (> 0 where pressed), gap h - u_nu, sigma_nu = -pressure, sigma_tau, slip and the state
    codes; off the contact boundary 0, and -1 for the states, stored as 32-bit integers."""
    result, out = run
    if COMM.rank != 0:
        return
    t, arrays = h5read.check_xdmf(f"{out}/solution.xdmf")[-1]
    assert t == result.steps[-1]["t"]
    table = result.contact[-1]
    points = arrays["geometry"][:, :2]
    at = by_position(points)
    rows = [at[key] for key in by_position(table["x"])]
    off = np.setdiff1d(np.arange(len(points)), rows)
    value = {name: arrays[name][:, 0] for name in output.CONTACT_FIELDS}
    assert np.allclose(value["contact_pressure"][rows], table["reaction_nu"], rtol=1e-12,
                       atol=1e-14)
    pressed = table["status"] > 0
    assert np.all(value["contact_pressure"][rows][pressed] > 0)
    assert np.allclose(value["normal_traction"], -value["contact_pressure"], atol=0)
    assert np.allclose(value["gap"][rows], table["gap"] - table["u_nu"], atol=1e-14)
    assert np.allclose(value["tangential_traction"][rows], table["reaction_tau"], atol=1e-14)
    # 2D: the slip along t is u_tau (contact.slip = "total").
    assert np.allclose(value["slip"][rows], table["u_tau"], atol=1e-14)
    assert np.ptp(table["u_tau"]) > 1e-3
    for name, codes in (("contact_state", table["status"]),
                        ("friction_state", table["friction"])):
        assert np.array_equal(value[name][rows], codes), name
        assert np.array_equal(value[name][off], -np.ones(len(off))), name
    assert set(table["status"]) == {0, 1, 2} and 2 in set(table["friction"])
    for name in ("contact_pressure", "gap", "slip", "tangential_traction"):
        assert np.all(value[name][off] == 0), name


@pytest.mark.mpi
def test_the_contact_table_has_a_contact_pressure_column(run):
    """contact_nodes.csv's contact_pressure is -sigma_nu: positive where pressed, the
    table's reaction_nu, the compliance pressure p_nu plus the bound's reaction."""
    result, out = run
    table = result.contact[-1]
    assert np.array_equal(table["contact_pressure"], table["reaction_nu"])
    at_bound = table["status"] == 2
    assert np.all(table["contact_pressure"][at_bound] >= table["p_nu"][at_bound])
    if COMM.rank != 0:
        return
    with open(f"{out}/contact_nodes.csv", newline="") as f:
        rows = [row for row in csv.DictReader(f) if int(row["step"]) == len(result.steps) - 1]
    pressure = np.array([float(row["contact_pressure"]) for row in rows])
    assert np.array_equal(pressure, table["contact_pressure"])
    assert pressure.max() > 0 and pressure.min() >= 0


@pytest.mark.mpi
def test_the_state_codes_are_stored_as_integers(run):
    """Every step's contact_state and friction_state are int32 datasets that the index
    declares NumberType="Int", holding only the codes -1, 0, 1, 2; VTK's XDMF reader (what
    ParaView uses) lists every contact field by name and gives the states as integers at the
    last step, the same values."""
    result, out = run
    if COMM.rank != 0:
        return
    root = ET.parse(f"{out}/solution.xdmf").getroot()
    seen = 0
    for attribute in root.iter("Attribute"):
        if attribute.get("Name") not in ("contact_state", "friction_state"):
            continue
        item = attribute.find("DataItem")
        assert (item.get("NumberType"), item.get("Precision")) == ("Int", "4")
        file, _, dataset = item.text.strip().partition(":")
        assert h5read.stored_type(f"{out}/{file}", dataset) == np.dtype("i4")
        values = h5read.read_dataset(f"{out}/{file}", dataset)
        assert set(np.unique(values)) <= {-1, 0, 1, 2} and -1 in values
        seen += 1
    assert seen == 2 * len(result.steps)
    pv = pytest.importorskip("pyvista")
    reader = pv.get_reader(f"{out}/solution.xdmf")
    reader.set_active_time_value(reader.time_values[-1])
    mesh = reader.read()
    mesh = mesh[0] if isinstance(mesh, pv.MultiBlock) else mesh
    assert set(output.CONTACT_FIELDS) <= set(mesh.point_data.keys())
    _, arrays = h5read.check_xdmf(f"{out}/solution.xdmf")[-1]
    for name in ("contact_state", "friction_state"):
        assert np.issubdtype(mesh.point_data[name].dtype, np.integer), name
        assert np.array_equal(mesh.point_data[name].ravel(), arrays[name][:, 0]), name
