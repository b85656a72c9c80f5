"""What differs between the DOLFINx versions: the fields of a degree-2 run reach the XDMF output
on every version (DOLFINx 0.6 on writes only fields of the mesh's degree, so they are
interpolated into P1 and DG0 there), and that interpolation is exact where it must be."""
import pathlib
import tempfile
import xml.etree.ElementTree as ElementTree

import numpy as np
import pytest
import ufl
from dolfinx import fem
from dolfinx import mesh as dmesh
from mpi4py import MPI

from contactvisco.fem import compat
from contactvisco.scene import loader as scene_module
from contactvisco.io.h5read import check_xdmf
from contactvisco.io.output import xdmf_field
from contactvisco.solver.time_loop import simulate


def test_p2_and_dg1_fields_become_p1_and_dg0_exactly():
    """A quadratic P2 field keeps its vertex values in P1; a linear DG1 tensor gives its value
    at each cell's centroid in DG0."""
    comm = MPI.COMM_WORLD
    mesh = dmesh.create_unit_square(comm, 4, 3)
    x = ufl.SpatialCoordinate(mesh)
    u = fem.Function(compat.vector_space(mesh, "CG", 2), name="u")
    quadratic = ufl.as_vector([x[0] ** 2 - x[1], x[0] * x[1]])
    u.interpolate(fem.Expression(quadratic, compat.interpolation_points(u.function_space)))
    u1 = xdmf_field(u, {}, convert=True)
    assert compat.element_degree(u1.function_space) == 1 and u1.name == "u"
    points = u1.function_space.tabulate_dof_coordinates()
    expected = np.column_stack([points[:, 0] ** 2 - points[:, 1], points[:, 0] * points[:, 1]])
    assert np.max(np.abs(u1.x.array.reshape(-1, 2) - expected)) < 1e-12

    sigma = fem.Function(compat.tensor_space(mesh, "DG", 1), name="sigma")
    linear = ufl.as_matrix([[1 + 2 * x[0], x[1]], [x[1], 3 * x[0] - x[1]]])
    sigma.interpolate(fem.Expression(linear, compat.interpolation_points(sigma.function_space)))
    sigma0 = xdmf_field(sigma, {}, convert=True)
    assert compat.element_degree(sigma0.function_space) == 0
    centroids = sigma0.function_space.tabulate_dof_coordinates()
    cx, cy = centroids[:, 0], centroids[:, 1]
    expected = np.stack([1 + 2 * cx, cy, cy, 3 * cx - cy], axis=1)
    assert np.max(np.abs(sigma0.x.array.reshape(-1, 4) - expected)) < 1e-12
    # A field of the mesh's degree is written as it is.
    assert xdmf_field(u1, {}, convert=True) is u1


@pytest.mark.mpi
def test_degree_two_run_writes_every_step():
    """A P2 run (Gauss contact quadrature) writes u and sigma at every time of the series."""
    comm = MPI.COMM_WORLD
    scene = scene_module.load("paper", ["geometry.cells=[6, 6]", "time.steps=2",
                                        "discretization.degree=2",
                                        "discretization.contact_quadrature='gauss'",
                                        "output.figures=false", "output.checkpoint=false"])
    folder = comm.bcast(tempfile.mkdtemp() if comm.rank == 0 else None, root=0)
    result = simulate(scene, folder, comm=comm, progress=False)
    assert len(result.steps) == 3
    if comm.rank == 0:
        xdmf = pathlib.Path(folder) / "solution.xdmf"
        series = _series(xdmf)
        assert series["u"] == series["sigma"] == [0.0, 0.5, 1.0], series
        # every dataset reads back with the shape the XDMF gives: u at the mesh's nodes
        steps = check_xdmf(xdmf)
        nodes = result.problem.geometry.mesh.geometry.index_map().size_global
        assert all(arrays["u"].shape[0] in (nodes, result.problem.count_unknowns()["u"] // 2)
                   for _, arrays in steps)


def _series(xdmf: pathlib.Path) -> dict:
    """Per attribute name of an XDMF file, the times at which it is written."""
    root = ElementTree.parse(xdmf).getroot()
    series = {}
    for grid in root.iter("Grid"):
        time = grid.find("Time")
        if time is None:
            continue
        for attribute in grid.findall("Attribute"):
            series.setdefault(attribute.get("Name"), []).append(float(time.get("Value")))
    return series


def _arguments_across_a_compilation(settle: bool):
    """A test function made before FFCx first compiles a form on a new mesh, one made after,
    and a form holding both. The form's integrand has a power no other form has, so that the
    JIT cache misses and FFCx does compile it. On one rank each: the refused form of the
    control must not leave other ranks waiting in the JIT's collective compilation."""
    comm = MPI.COMM_SELF
    mesh = dmesh.create_unit_square(comm, 3, 2)
    if settle:
        compat.settle_coordinate_element(mesh)
    V = compat.vector_space(mesh, "CG", 1)
    before = ufl.TestFunction(V)
    x = ufl.SpatialCoordinate(mesh)
    power = int(np.random.default_rng().integers(1000, 10 ** 9))
    dx = ufl.dx(metadata={"quadrature_degree": 2})      # the degree does not follow power
    fem.form(ufl.inner(ufl.TrialFunction(V), before) * x[0] ** power * dx)
    after = ufl.TestFunction(V)
    return before, after, ufl.inner(ufl.TrialFunction(V), before + after) * ufl.dx


def test_arguments_made_before_and_after_the_first_compilation_are_one():
    """A problem's forms mix test functions made when the problem is built with ones made
    later (a solver's extra terms): they must stay the same Argument across FFCx's first
    compilation on the mesh, whatever the JIT cache holds. Where FFCx changes the mesh's
    coordinate element on compiling (DOLFINx 0.5), the unsettled control shows the split."""
    before, after, form = _arguments_across_a_compilation(settle=True)
    assert before == after and hash(before) == hash(after)
    fem.form(form)                                  # compiles: one Argument per number
    before, after, form = _arguments_across_a_compilation(settle=False)
    if hash(before) != hash(after):                 # the control: FFCx changed the mesh
        with pytest.raises(Exception, match="different Arguments with same number"):
            fem.form(form)
