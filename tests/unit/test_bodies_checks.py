"""The input checks of two bodies in contact (obstacle.shape = "body"): bodies that overlap in
the reference configuration by more than contact.search_distance, and a body whose rigid motion
neither its Dirichlet conditions nor the interface hold (fem.rigid.check_bodies)."""
import numpy as np
import pytest
from mpi4py import MPI

from contactvisco.errors import SceneError
from contactvisco.fem import compat
from contactvisco.fem import geometry as geometry_module
from contactvisco.fem import rigid
from contactvisco.fem.problem import build
from contactvisco.scene import loader

PRESSURE = 0.01


def blocks(**contact) -> dict:
    """The two blocks of meshes/two_blocks.py: the lower held at its bottom (y), both
    blocks' sides held in x, the upper pressed on its top, normal compliance between them."""
    return {
        "name": "two_blocks",
        "geometry": {"type": "gmsh", "script": "two_blocks",
                     "parameters": {"h_slave": 0.077, "h_master": 0.1}},
        "material": {"model": "plane_strain", "E": 1.0, "nu": 0.3},
        "dirichlet": [{"boundary": "bottom", "components": [1]},
                      {"boundary": "master_sides", "components": [0]},
                      {"boundary": "slave_sides", "components": [0]}],
        "traction": [{"boundary": "top", "value": [0.0, -PRESSURE]}],
        "contact": {"boundary": "slave", "stiffness": 100.0, **contact},
        "obstacle": {"shape": "body", "boundary": "master"},
        "time": {"T": 1.0, "steps": 1},
        "output": {"probes": []},
    }


def shifted_geometry(scene, dy: float):
    """The scene's mesh with the upper block moved by dy in y (into the lower one for
    dy < 0): every geometry node of a cell of "slave_body"."""
    geometry = geometry_module.build(scene, MPI.COMM_WORLD)
    mesh = geometry.mesh
    cells = geometry.cell_tags.find(geometry.cell_names["slave_body"])
    nodes = np.unique(compat.geometry_nodes(mesh)[cells])
    mesh.geometry.x[nodes, 1] += dy
    return geometry


@pytest.mark.mpi
@pytest.mark.parametrize("pairing", ["mortar", "node_to_segment"])
def test_overlap_beyond_the_search_distance_is_refused(pairing):
    """The upper block sunk 0.05 into the lower with contact.search_distance = 0.02: a
    SceneError naming contact.search_distance that says the bodies overlap and by how much;
    sunk 0.01 (within the search distance) the problem builds, its gap h = -0.01 at every
    slave node."""
    scene = loader.resolve(blocks(search_distance=0.02, pairing=pairing))
    with pytest.raises(SceneError) as err:
        build(scene, shifted_geometry(scene, -0.05))
    assert err.value.key == "contact.search_distance"
    assert "overlap" in str(err.value) and "by 0.05" in str(err.value), str(err.value)
    problem = build(scene, shifted_geometry(scene, -0.01))
    nodes = problem.contact.nodes
    h = problem.contact.obstacle.gap.x.array[nodes.nodes[nodes.owned]]
    assert np.allclose(h, -0.01, rtol=0, atol=1e-12)


def refusal(raw) -> str:
    scene = loader.resolve(raw)
    with pytest.raises(SceneError) as err:
        build(scene, geometry_module.build(scene, MPI.COMM_WORLD))
    return str(err.value)


def test_a_slave_free_to_slide_is_refused():
    """Without its sides held and without friction, the upper block may slide along the
    interface: refused, naming the slave body and the translation along x."""
    raw = blocks()
    raw["dirichlet"] = raw["dirichlet"][:2]
    message = refusal(raw)
    assert "the slave body (contact.boundary 'slave'): translation along x" in message
    assert "master body" not in message


@pytest.mark.mpi
def test_bodies_held_only_by_each_other_are_refused():
    """The lower block's bottom not held: the two blocks may move together along y (the
    interface holds only the one relative to the other), which the check of the whole mesh
    against a fixed obstacle did not see; both bodies are named."""
    raw = blocks()
    raw["dirichlet"] = raw["dirichlet"][1:]
    message = refusal(raw)
    assert "the slave body (contact.boundary 'slave'): translation along y" in message
    assert "the master body (obstacle.boundary 'master'): translation along y" in message


@pytest.mark.parametrize("contact", [{}, {"stiffness": 0.0, "g": 0.0},
                                     {"stiffness": 0.0, "g": 0.0, "mu": 0.3,
                                      "friction_law": "coulomb"}])
def test_a_body_held_through_the_interface_is_held(contact):
    """The upper block held only in x (its sides): its motion along y and its rotation are
    held through the interface by a compliance and by Signorini's bound alike; with
    Coulomb friction the sides may go too (the interface holds the sliding)."""
    raw = blocks(**contact)
    if "mu" in contact:
        raw["dirichlet"] = raw["dirichlet"][:2]
    scene = loader.resolve(raw)
    problem = build(scene, geometry_module.build(scene, MPI.COMM_WORLD))
    G, count, _ = rigid.body_gram(problem)
    assert count == 2
    w = np.linalg.eigvalsh(G)
    assert w.min() > 10 * rigid.RESTRAINT_TOLERANCE * w.max()
    assert rigid.free_body_motions(problem) == []


@pytest.mark.mpi
def test_parts_of_the_mesh():
    """The two blocks are two parts of their mesh, the same on every rank: every node of a
    cell of "slave_body" in one, of "master_body" in the other."""
    scene = loader.resolve(blocks())
    geometry = geometry_module.build(scene, MPI.COMM_WORLD)
    problem = build(scene, geometry)
    labels, count = rigid.components(problem.V)
    assert count == 2
    dofs = compat.cell_dofs(problem.V.dofmap)
    for name in ("slave_body", "master_body"):
        cells = geometry.cell_tags.find(geometry.cell_names[name])
        seen = set(labels[dofs[cells]].ravel().tolist())
        seen = set().union(*MPI.COMM_WORLD.allgather(seen))
        assert len(seen) == 1
    assert set(labels.tolist()) <= {0, 1}
