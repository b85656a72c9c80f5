"""Two deformable bodies in 3D: two boxes of tetrahedra (meshes/two_boxes.py) whose interface
triangulations do not match (unstructured triangles of sizes 0.25 and 0.34 on the unit
square), paired by the mortar operator of Puso and Laursen's clipping or by node to segment.

The patch test: the upper (slave) box pressed by a uniform pressure p on its top onto the
lower (master) box, held at its bottom in z, every side face of both boxes held in its normal
component: the exact solution has uniform stresses sigma_zz = -p,
sigma_xx = sigma_yy = -p nu / (1 - nu), no shear, and the uniform interface pressure p.
"""
import numpy as np
import pytest
from dolfinx import fem
from mpi4py import MPI

from contactvisco.fem import geometry as geometry_module
from contactvisco.fem.problem import build
from contactvisco.scene import loader
from contactvisco.solver.newton import create

pytestmark = pytest.mark.mpi

PRESSURE, NU = 0.01, 0.3


def boxes_scene(pairing="mortar", **contact) -> dict:
    """The two boxes under the pressure p on the slave's top (module description), the
    interface law given by `contact` (a normal compliance 100 by default)."""
    return {
        "name": "patch3d",
        "geometry": {"type": "gmsh", "script": "two_boxes",
                     "parameters": {"h_slave": 0.25, "h_master": 0.34}},
        "material": {"model": "3d", "E": 1.0, "nu": NU},
        "dirichlet": [{"boundary": "bottom", "components": [2]},
                      {"boundary": "master_x", "components": [0]},
                      {"boundary": "slave_x", "components": [0]},
                      {"boundary": "master_y", "components": [1]},
                      {"boundary": "slave_y", "components": [1]}],
        "traction": [{"boundary": "top", "value": [0.0, 0.0, -PRESSURE]}],
        "contact": {"boundary": "slave", "stiffness": 100.0, "pairing": pairing, **contact},
        "obstacle": {"shape": "body", "boundary": "master"},
        "time": {"T": 1.0, "steps": 1},
        "solver": {"petsc_options": {"snes_rtol": 1e-14, "snes_atol": 1e-15}},
        "output": {"probes": []},
    }


def _contact(snes, problem):
    """The slave's nodal contact forces at its owned contact nodes, their weights, and what
    the master receives (the whole vector, reshaped per node)."""
    system = getattr(snes, "system", snes)
    c = system.contact_forces().array.reshape(-1, 3).copy()
    share = system.master_share().array.reshape(-1, 3).copy()
    nodes = problem.contact.nodes
    own = nodes.nodes[nodes.owned]
    return c[own], nodes.weights[nodes.owned], share


#: A normal compliance (no multiplier) and Signorini (the condensed system).
LAWS = {"compliance": {}, "signorini": {"stiffness": 0.0, "g": 0.0}}


@pytest.mark.parametrize("pairing", ["mortar", "node_to_segment"])
@pytest.mark.parametrize("law", LAWS)
def test_3d_patch_test(pairing, law):
    """Mortar passes the 3D patch test on non-matching triangulations: the stresses of both
    boxes and the interface pressure are uniform to 1e-12 of p (measured 1e-14); node to
    segment misses (measured 15 to 18 % of p). Both balance: the master receives the
    opposite of the slave's resultant, which is the load (to 1e-12 of p)."""
    comm = MPI.COMM_WORLD
    scene = loader.resolve(boxes_scene(pairing, **LAWS[law]))
    problem = build(scene, geometry_module.build(scene, comm))
    snes = create(problem, comm)
    problem.time.stage(1.0)
    iterations = snes.solve()
    sigma = fem.Function(problem.tensor_space)
    sigma.interpolate(problem.sigma_expression)
    owned = problem.tensor_space.dofmap.index_map.size_local
    values = sigma.x.array.reshape(-1, 3, 3)[:owned]
    z = problem.tensor_space.tabulate_dof_coordinates()[:owned, 2]
    lateral = -PRESSURE * NU / (1 - NU)
    deviation = np.abs(values - np.diag([lateral, lateral, -PRESSURE])).max(axis=(1, 2))
    blocks = [comm.allreduce(float(deviation[side].max(initial=0.0)), MPI.MAX) / PRESSURE
              for side in (z > 0, z < 0)]
    c, weight, share = _contact(snes, problem)
    spread = comm.allreduce(float(np.abs(-c[:, 2] / weight / PRESSURE - 1).max(initial=0.0)),
                            MPI.MAX)
    slave = comm.allreduce(c.sum(axis=0), MPI.SUM)
    master = comm.allreduce(-share.sum(axis=0), MPI.SUM)
    print(f"3D patch, {pairing}, {law}: stress deviation (slave, master) / p {blocks}, "
          f"pressure {spread:.2e}, Newton iterations {iterations}")
    assert np.allclose(slave + master, 0.0, atol=1e-12 * PRESSURE)
    assert slave == pytest.approx([0.0, 0.0, -PRESSURE], abs=1e-12 * PRESSURE)
    if pairing == "mortar":
        assert max(blocks) < 1e-12 and spread < 1e-12
    else:
        assert max(blocks) > 1e-3


@pytest.mark.parametrize("pairing", ["mortar", "node_to_segment"])
def test_3d_box_pressed_then_sheared(pairing):
    """Coulomb friction (mu = 0.3, Signorini) between the boxes: the lower box clamped at its
    bottom, the upper one pressed by p (t = 0, no shear) and then dragged by its top along x
    (u_x = 0.2 t, t = 0.5 and 1): every step converges, the upper box slides (every pressed
    slave node carries |c_tau| = mu |c_nu| to 1e-10, its friction against the drag), the slave's
    resultant is (mu p, 0, -p) per unit area (its x part to 1e-4, its y part within 1 % of
    mu p) and the master receives its opposite."""
    mu = 0.3
    raw = boxes_scene(pairing, stiffness=0.0, g=0.0, mu=mu, friction_law="coulomb")
    raw["dirichlet"] = [{"boundary": "bottom", "components": "all"},
                        {"boundary": "top", "components": [0, 1], "value": ["0.2 * t", 0.0]}]
    comm = MPI.COMM_WORLD
    scene = loader.resolve(raw)
    problem = build(scene, geometry_module.build(scene, comm))
    snes = create(problem, comm)
    iterations = []
    for t in (0.0, 0.5, 1.0):
        problem.time.stage(t)
        iterations.append(snes.solve())
        problem.time.commit()
    c, weight, share = _contact(snes, problem)
    pressed = np.abs(c[:, 2]) > 1e-12 * PRESSURE
    tangential = np.linalg.norm(c[pressed, :2], axis=1)
    worst = comm.allreduce(float(np.abs(tangential / np.abs(c[pressed, 2]) - mu)
                                 .max(initial=0.0)), MPI.MAX)
    count = comm.allreduce(int(pressed.sum()), MPI.SUM)
    slave = comm.allreduce(c.sum(axis=0), MPI.SUM)
    master = comm.allreduce(-share.sum(axis=0), MPI.SUM)
    print(f"3D sliding, {pairing}: Newton iterations {iterations}, {count} pressed slave "
          f"nodes, largest ||c_tau|/|c_nu| - mu| {worst:.2e}, slave resultant {slave}")
    assert count >= 10 and worst < 1e-10
    assert slave[2] == pytest.approx(-PRESSURE, rel=1e-10)
    # The slip at each node turns a little off the drag (Poisson's contraction under an
    # unstructured mesh): measured 1e-3 of mu p across the drag.
    assert slave[0] == pytest.approx(mu * PRESSURE, rel=1e-4)
    assert abs(slave[1]) < 1e-2 * mu * PRESSURE
    assert np.allclose(slave + master, 0.0, atol=1e-12 * PRESSURE)
