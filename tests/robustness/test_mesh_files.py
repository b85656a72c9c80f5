"""Meshes that cannot be a body: a .msh file without cells, without physical groups or of the
wrong dimension is refused with the reason and the file named; a gmsh or caller's mesh with
degenerate or inverted (folded) cells is refused with their number and the place of the
first. Every mesh is written with gmsh's own API, then spoiled the way a user would."""
import re

import numpy as np
import pytest
from dolfinx import mesh as dmesh
from mpi4py import MPI

from contactvisco import api
from contactvisco.errors import SceneError
from contactvisco.fem import geometry

COMM = MPI.COMM_WORLD
SCENES = None         # the folder of the scene file for a caller's mesh
pytestmark = pytest.mark.skipif(COMM.size > 1, reason="writes meshes with gmsh on one rank")


def write_mesh(path, dim=2, physical_cells=True, physical_facets=True, mesh=True,
               fold=None):
    """The unit square (or cube) meshed by gmsh, with the named boundaries left and right;
    fold: move the node nearest to this point by the given shift (a folded cell)."""
    import gmsh
    gmsh.initialize()
    gmsh.option.setNumber("General.Terminal", 0)
    try:
        occ = gmsh.model.occ
        body = occ.addRectangle(0, 0, 0, 1, 1) if dim == 2 else occ.addBox(0, 0, 0, 1, 1, 1)
        occ.synchronize()
        if physical_cells:
            gmsh.model.addPhysicalGroup(dim, [body])
        if physical_facets:
            for name, x in (("left", 0.0), ("right", 1.0)):
                tags = [t for _, t in gmsh.model.getEntities(dim - 1)
                        if abs(occ.getCenterOfMass(dim - 1, t)[0] - x) < 1e-9]
                gmsh.model.setPhysicalName(dim - 1,
                                           gmsh.model.addPhysicalGroup(dim - 1, tags), name)
        gmsh.option.setNumber("Mesh.MeshSizeMax", 0.25)
        if mesh:
            gmsh.model.mesh.generate(dim)
        if fold is not None:
            point, shift = fold
            tags, coords, _ = gmsh.model.mesh.getNodes()
            coords = coords.reshape(-1, 3)
            i = int(np.argmin(np.linalg.norm(coords[:, :dim] - point, axis=1)))
            gmsh.model.mesh.setNode(int(tags[i]), list(coords[i] + shift), [])
        gmsh.write(str(path))
    finally:
        gmsh.finalize()
    return path


def scene_on(path, model="plane_strain"):
    """A scene without contact on the mesh file `path` (None: a box, for a caller's mesh),
    held left and pulled right."""
    pull = "[0.1, 0.0]" if model != "3d" else "[0.1, 0.0, 0.0]"
    geometry_table = (f'[geometry]\ntype = "gmsh"\nfile = "{path}"\n' if path is not None
                      else "")
    text = (f'name = "body"\n{geometry_table}[material]\nmodel = "{model}"\n'
            f'[time]\nsteps = 1\n[output]\nfigures = false\n'
            f'[[dirichlet]]\nboundary = "left"\n'
            f'[[traction]]\nboundary = "right"\nvalue = {pull}\n')
    where = (path.parent if path is not None else SCENES) / "body.toml"
    where.write_text(text)
    return api.load_scene(str(where))


@pytest.mark.parametrize("spoil, model, words", [
    (dict(mesh=False), "plane_strain", "has no cells of dimension 2 (no elements at all)"),
    (dict(physical_cells=False, physical_facets=False), "plane_strain",
     "has no physical group of dimension 2 (the body's cells)"),
    (dict(physical_cells=False), "plane_strain", "has no cells of dimension 2 (elements of "
                                                 "dimension 1 only); material.model needs a "
                                                 "2D mesh; gmsh saves only the elements of "
                                                 "physical groups"),
    (dict(physical_facets=False), "plane_strain", "has no named physical groups of dimension 1"),
    (dict(dim=3), "plane_strain", "has cells of dimension 3; material.model needs a 2D mesh"),
    (dict(dim=2), "3d", "has no cells of dimension 3 (elements of dimension 1, 2 only)"),
])
def test_a_malformed_msh_file_is_refused_with_the_reason(tmp_path, spoil, model, words):
    path = write_mesh(tmp_path / "body.msh", **spoil)
    with pytest.raises(SceneError) as err:
        api.check(scene_on(path, model))
    assert words in str(err.value) and str(path) in str(err.value), str(err.value)
    assert err.value.key == "geometry.file"
    assert model == "plane_strain" or "Physical" not in str(err.value)    # no wrong hint


def test_a_sound_msh_file_passes(tmp_path):
    path = write_mesh(tmp_path / "body.msh")
    report = api.check(scene_on(path))
    assert report["cells"] > 16
    path = write_mesh(tmp_path / "cube.msh", dim=3)
    assert api.check(scene_on(path, "3d"))["cells"] > 50


@pytest.mark.parametrize("dim, shift", [(2, [0.6, 0.0, 0.0]), (3, [0.0, 0.0, 0.7])])
def test_an_msh_file_with_a_folded_cell_is_refused_with_its_place(tmp_path, dim, shift):
    centre = np.full(dim, 0.5)
    path = write_mesh(tmp_path / "folded.msh", dim=dim, fold=(centre, shift))
    with pytest.raises(SceneError, match=r"\d+ inverted cell\(s\), folded over") as err:
        api.check(scene_on(path, "plane_strain" if dim == 2 else "3d"))
    first = np.array(str(err.value).split("the first at x = [")[1].split("]")[0].split(","),
                     dtype=float)
    assert np.linalg.norm(first - centre) < 0.75          # next to the moved node
    assert str(path) in str(err.value)


def caller_mesh(n=4):
    mesh = dmesh.create_unit_square(COMM, n, n)
    fdim = 1
    left = dmesh.locate_entities_boundary(mesh, fdim, lambda x: np.isclose(x[0], 0))
    right = dmesh.locate_entities_boundary(mesh, fdim, lambda x: np.isclose(x[0], 1))
    facets = np.concatenate([left, right])
    values = np.concatenate([np.full(len(left), 1, np.int32), np.full(len(right), 2, np.int32)])
    order = np.argsort(facets)
    return mesh, dmesh.meshtags(mesh, fdim, facets[order], values[order])


def _node_near(mesh, point):
    return int(np.argmin(np.linalg.norm(mesh.geometry.x[:, :2] - point, axis=1)))


@pytest.mark.parametrize("spoil, words", [
    ("fold", "inverted cell(s), folded over a neighbour"),
    ("collapse", "degenerate cell(s), of (nearly) zero volume"),
])
def test_a_callers_mesh_with_bad_cells_is_refused(tmp_path, spoil, words):
    global SCENES
    SCENES = tmp_path
    mesh, tags = caller_mesh()
    x = mesh.geometry.x
    i = _node_near(mesh, [0.5, 0.5])
    if spoil == "fold":
        x[i, 0] += 0.4                       # past the next column of nodes
    else:                                    # onto its neighbour: two cells of no area
        x[i] = x[_node_near(mesh, [0.75, 0.5])]
    scene = scene_on(None)
    with pytest.raises(SceneError) as err:
        api.solve(scene, mesh=mesh, facet_tags=tags, boundaries={"left": 1, "right": 2})
    assert words in str(err.value) and "solve(mesh=...)" in str(err.value), str(err.value)
    first = np.array(str(err.value).split("the first at x = [")[1].split("]")[0].split(","),
                     dtype=float)
    assert np.linalg.norm(first - [0.5, 0.5]) < 0.5


def test_a_sound_callers_mesh_and_every_builtin_mesh_pass():
    mesh, tags = caller_mesh(8)
    geometry.check_cells(mesh, "solve(mesh=...)")
    for name in api.builtin_scenes():
        built = geometry.build(api.load_scene(name))
        geometry.check_cells(built.mesh, name)


def test_a_relative_mesh_file_is_found_from_the_scene_folder(tmp_path, monkeypatch):
    """geometry.file = "body.msh" beside the scene file, the scene loaded, checked and its
    mesh read from another folder (the rule of every file a scene names); a missing one is
    named with its resolved path, and an XDMF mesh points to solve(mesh=...)."""
    folder = tmp_path / "scene"
    folder.mkdir()
    write_mesh(folder / "body.msh")
    scene_on(folder / "body.msh")                  # writes scene/body.toml
    toml = folder / "body.toml"
    toml.write_text(toml.read_text().replace(f'file = "{folder / "body.msh"}"',
                                             'file = "body.msh"'))
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    assert api.check(api.load_scene(str(toml)))["cells"] > 16
    for name, words in (("none.msh", f"no mesh file '{folder / 'none.msh'}'"),
                        ("body.xdmf", "solve(scene, mesh=mesh")):
        toml.write_text(toml.read_text().replace('file = "body.msh"', f'file = "{name}"')
                        .replace('file = "none.msh"', f'file = "{name}"'))
        with pytest.raises(SceneError, match=re.escape(words)) as err:
            api.check(api.load_scene(str(toml)))
        assert err.value.key == "geometry.file"
