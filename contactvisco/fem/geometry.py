"""Meshes and named boundaries of a scene: a structured box made in memory, or a gmsh mesh
(a script in meshes/ run on first use and cached, or a .msh file) with named physical groups."""
from __future__ import annotations

import hashlib
import importlib.util
import json
import os
import pathlib
import sys
from dataclasses import dataclass

import numpy as np
from dolfinx import mesh as dmesh
from mpi4py import MPI

from contactvisco.fem import compat
from contactvisco.errors import SceneError
from contactvisco.model.material import dimension
from contactvisco.scene.tables import MESH_DIR


def _cache_dir() -> pathlib.Path:
    """Made meshes are cached per user (CONTACTVISCO_MESH_CACHE, else the XDG cache folder)."""
    if os.environ.get("CONTACTVISCO_MESH_CACHE"):
        return pathlib.Path(os.environ["CONTACTVISCO_MESH_CACHE"])
    base = os.environ.get("XDG_CACHE_HOME") or pathlib.Path.home() / ".cache"
    return pathlib.Path(base) / "contactvisco" / "meshes"


CACHE_DIR = _cache_dir()

#: Boundary names of the built-in box: the faces x = lower/upper, y = ..., z = ...
BOX_FACES_2D = {"left": (0, 0), "right": (0, 1), "bottom": (1, 0), "top": (1, 1)}
BOX_FACES_3D = {"left": (0, 0), "right": (0, 1), "front": (1, 0), "back": (1, 1),
                "bottom": (2, 0), "top": (2, 1)}


@dataclass
class Geometry:
    mesh: dmesh.Mesh
    facet_tags: dmesh.MeshTags
    names: dict[str, int]          # boundary name -> facet tag value
    cell_tags: dmesh.MeshTags | None = None     # the mesh's cell tags (gmsh physical groups)
    cell_names: dict | None = None              # cell tag name -> cell tag value

    def facets(self, name: str, where: str = "boundary") -> np.ndarray:
        """The local facets of a named boundary; a name that is unknown, has no facet, or
        names facets inside the body is a scene error naming the key `where`."""
        if name not in self.names:
            raise SceneError(f"{where}: no boundary named '{name}'; this geometry has "
                             f"{', '.join(sorted(self.names))}", key=where)
        found = self.facet_tags.find(self.names[name])
        comm = self.mesh.comm
        if comm.allreduce(found.size, MPI.SUM) == 0:
            raise SceneError(f"{where}: boundary '{name}' has no facets in this mesh", key=where)
        # A facet with two cells (ghosts included) is inside the body; a boundary facet never
        # has two, and an inner one has two on at least one rank.
        fdim = self.mesh.topology.dim - 1
        self.mesh.topology.create_connectivity(fdim, fdim + 1)
        cells_per_facet = np.diff(self.mesh.topology.connectivity(fdim, fdim + 1).offsets)
        inside = comm.allreduce(int(np.sum(cells_per_facet[found] == 2)), MPI.SUM)
        if inside:
            raise SceneError(f"{where}: boundary '{name}' has facets inside the body, not "
                             "on its boundary", key=where)
        return found


def build(scene: dict, comm=MPI.COMM_WORLD) -> Geometry:
    geo = scene["geometry"]
    geometry = _box(geo, comm) if geo["type"] == "box" else _gmsh(geo, dimension(scene), comm)
    angle = np.deg2rad(float(geo.get("rotation", 0.0)))
    if angle != 0.0:
        x = geometry.mesh.geometry.x
        c, s = np.cos(angle), np.sin(angle)
        x[:, 0], x[:, 1] = c * x[:, 0] - s * x[:, 1], s * x[:, 0] + c * x[:, 1]
    check_probes(geometry.mesh, scene["output"]["probes"])
    return geometry


def check_ranks(mesh) -> None:
    """Refuse, once and on every rank, a mesh with a rank that owns no cell: a scene's checks
    take the extent, the boundaries and the contact nodes on every rank.

    Parameters
    ----------
    mesh : dolfinx.mesh.Mesh
        The distributed mesh (collective).

    Raises
    ------
    SceneError
        Naming the mesh's cell count and the rank count.
    """
    comm = mesh.comm
    tdim = mesh.topology.dim
    owned = mesh.topology.index_map(tdim).size_local
    counts = comm.allgather(int(owned))
    if min(counts) == 0:
        raise SceneError(f"geometry: the mesh has {sum(counts)} cell(s) for {comm.size} MPI "
                         f"ranks, and {counts.count(0)} rank(s) would hold none; run on fewer "
                         "ranks, or refine the mesh")


def check_probes(mesh, points) -> None:
    """Every probe point lies in a cell of the mesh (on some rank), else a scene error naming
    the point and the mesh's bounding box."""
    if not points:
        return
    d = mesh.geometry.dim
    xyz = np.zeros((len(points), 3))
    for i, p in enumerate(points):
        xyz[i, :len(p)] = p
    found = (np.array(compat.colliding_cells(mesh, xyz)) >= 0).astype(np.int32)
    mesh.comm.Allreduce(MPI.IN_PLACE, found, op=MPI.MAX)
    if found.all():
        return
    x = mesh.geometry.x[:, :d]
    lower, upper = np.empty(d), np.empty(d)
    mesh.comm.Allreduce(x.min(axis=0) if len(x) else np.full(d, np.inf), lower, op=MPI.MIN)
    mesh.comm.Allreduce(x.max(axis=0) if len(x) else np.full(d, -np.inf), upper, op=MPI.MAX)
    i = int(np.flatnonzero(found == 0)[0])
    raise SceneError(f"output.probes[{i}] = {list(points[i])} is outside the body (the mesh "
                     f"spans {np.round(lower, 6).tolist()} to {np.round(upper, 6).tolist()})",
                     key=f"output.probes[{i}]")


#: A cell is degenerate when its volume is below this times its longest edge to the power d.
DEGENERATE = 1e-10


def check_cells(mesh, source: str) -> None:
    """Refuse a mesh with degenerate cells (|det J| of a cell, from its vertices, below
    DEGENERATE h_max^d: the stiffness matrix is singular there) or inverted cells (a cell
    folded over a neighbour: the vertices opposite an interior facet shared by two cells lie
    on the same side of it, sign(det[f_1 - f_0, ..., p - f_0]) equal for both cells), naming
    their number and the location of the first. Collective over the mesh's communicator.

    Parameters
    ----------
    mesh : dolfinx.mesh.Mesh
        The mesh (its vertices are the first d + 1 geometry nodes of each cell).
    source : str
        What the mesh came from, for the message (a file, "solve(mesh=...)").
    """
    d = mesh.topology.dim
    if mesh.geometry.dim != d:
        return
    x = mesh.geometry.x[:, :d]
    nodes = compat.geometry_nodes(mesh)[:, :d + 1]
    owned = mesh.topology.index_map(d).size_local
    edges = x[nodes[:, 1:]] - x[nodes[:, :1]]               # (cells, d, d)
    volume = _det(edges)
    longest = np.zeros(len(nodes))
    for i in range(d + 1):
        for j in range(i + 1, d + 1):
            longest = np.maximum(longest, np.linalg.norm(x[nodes[:, i]] - x[nodes[:, j]],
                                                         axis=1))
    degenerate = np.flatnonzero(np.abs(volume[:owned]) <= DEGENERATE * longest[:owned] ** d)
    folded = _folded(mesh, x, nodes, owned, d)
    for cells, what, why in ((degenerate, "degenerate", "of (nearly) zero volume: the "
                              "stiffness is singular there"),
                             (folded, "inverted", "folded over a neighbour (the vertices "
                              "opposite a shared facet lie on the same side of it)")):
        count = mesh.comm.allreduce(len(cells))
        if not count:
            continue
        first = x[nodes[cells[0]]].mean(axis=0).round(6).tolist() if len(cells) else None
        first = next(p for p in mesh.comm.allgather(first) if p is not None)
        raise SceneError(f"{source}: {count} {what} cell(s), {why}; the first at x = {first}; "
                         "remesh it", key=source if "." in source else None)


def _det(m: np.ndarray) -> np.ndarray:
    """Determinants of a stack of 1x1, 2x2 or 3x3 matrices, written out (numpy's batched LU
    is ten times slower on small matrices)."""
    if m.shape[1] == 1:
        return m[:, 0, 0]
    if m.shape[1] == 2:
        return m[:, 0, 0] * m[:, 1, 1] - m[:, 0, 1] * m[:, 1, 0]
    return (m[:, 0, 0] * (m[:, 1, 1] * m[:, 2, 2] - m[:, 1, 2] * m[:, 2, 1])
            - m[:, 0, 1] * (m[:, 1, 0] * m[:, 2, 2] - m[:, 1, 2] * m[:, 2, 0])
            + m[:, 0, 2] * (m[:, 1, 0] * m[:, 2, 1] - m[:, 1, 1] * m[:, 2, 0]))


def _folded(mesh, x, nodes, owned, d) -> np.ndarray:
    """The owned cells folded over a neighbour across an interior facet that this rank
    sees with both of its cells."""
    fdim = d - 1
    mesh.topology.create_connectivity(fdim, d)
    f2c = mesh.topology.connectivity(fdim, d)
    counts = np.diff(f2c.offsets)
    pairs = f2c.array[np.repeat(counts, counts) == 2].reshape(-1, 2)
    if not len(pairs):
        return np.zeros(0, dtype=np.int64)
    a, b = nodes[pairs[:, 0]], nodes[pairs[:, 1]]
    in_b = (a[:, :, None] == b[:, None, :]).any(axis=2)     # a's nodes shared with b
    in_a = (b[:, :, None] == a[:, None, :]).any(axis=2)
    keep = (in_b.sum(axis=1) == d) & (in_a.sum(axis=1) == d)
    a, b, in_b, in_a, pairs = a[keep], b[keep], in_b[keep], in_a[keep], pairs[keep]
    shared = a[in_b].reshape(-1, d)
    p = a[~in_b]
    q = b[~in_a]
    base = x[shared[:, 0]]
    span = x[shared[:, 1:]] - base[:, None, :]               # (pairs, d - 1, d)
    side_p = _det(np.concatenate([span, (x[p] - base)[:, None, :]], axis=1))
    side_q = _det(np.concatenate([span, (x[q] - base)[:, None, :]], axis=1))
    bad = side_p * side_q > 0
    cells = np.unique(pairs[bad].ravel())
    return cells[cells < owned]


def _box(geo, comm) -> Geometry:
    lower, upper, cells = geo["lower"], geo["upper"], geo["cells"]
    d = len(lower)
    if d == 2:
        diagonal = getattr(dmesh.DiagonalType, geo["diagonal"])
        mesh = dmesh.create_rectangle(comm, [np.array(lower, float), np.array(upper, float)],
                                      cells, dmesh.CellType.triangle, diagonal=diagonal)
        faces = BOX_FACES_2D
    else:
        mesh = dmesh.create_box(comm, [np.array(lower, float), np.array(upper, float)],
                                cells, dmesh.CellType.tetrahedron)
        faces = BOX_FACES_3D
    fdim = d - 1
    size = max(u - l for u, l in zip(upper, lower))
    tol = 1e-10 * size
    indices, values, names = [], [], {}
    for tag, (name, (axis, side)) in enumerate(faces.items(), start=1):
        plane = (lower, upper)[side][axis]
        found = dmesh.locate_entities_boundary(
            mesh, fdim, lambda x, a=axis, p=plane: np.abs(x[a] - p) < tol)
        indices.append(found)
        values.append(np.full(found.size, tag, dtype=np.int32))
        names[name] = tag
    indices = np.concatenate(indices)
    values = np.concatenate(values)
    # A corner facet cannot lie on two faces of a box, so indices are unique.
    order = np.argsort(indices)
    tags = dmesh.meshtags(mesh, fdim, indices[order], values[order])
    return Geometry(mesh, tags, names)


def mesh_file(geo) -> pathlib.Path:
    """The .msh file of a gmsh geometry; a script's mesh is made on first use (rank 0 only,
    written atomically) and cached under a hash of the script and its parameters."""
    if geo["file"] is not None:
        # One path rule for every file a scene names: relative to the scene file's folder.
        path = pathlib.Path(geo["file"])
        scene_path = getattr(getattr(geo, "provenance", None), "path", None)
        if not path.is_absolute() and scene_path is not None:
            path = scene_path.parent / path
        if path.suffix != ".msh":
            raise SceneError(f"geometry.file must be a gmsh .msh file, got '{path}' (a .geo "
                             "file is a gmsh script, which can run commands)", key="geometry.file")
        if not path.is_file():
            raise SceneError(f"geometry.file: no mesh file '{path.absolute()}' (a path "
                             "relative to the scene file's folder, or absolute)",
                             key="geometry.file")
        return path
    name = geo["script"]
    script = MESH_DIR / f"{name}.py"
    if not (isinstance(name, str) and name.isidentifier()) or not script.is_file():
        names = sorted(p.stem for p in MESH_DIR.glob("*.py") if p.stem != "refinement")
        raise SceneError(f"geometry.script: no mesh script '{geo['script']}' in {MESH_DIR} "
                         f"(there are: {', '.join(names)})", key="geometry.script")
    # The hash covers the shared helper too, so editing it remakes the cached meshes, and the
    # gmsh version, whose releases write the same mesh with last-digit differences.
    import gmsh
    key = hashlib.sha1(script.read_bytes() + (MESH_DIR / "refinement.py").read_bytes()
                       + json.dumps(geo["parameters"], sort_keys=True).encode()
                       + gmsh.__version__.encode()).hexdigest()
    return CACHE_DIR / f"{geo['script']}-{key[:12]}.msh"


def _generate(geo, path: pathlib.Path, d: int):
    import gmsh
    script = MESH_DIR / f"{geo['script']}.py"
    spec = importlib.util.spec_from_file_location(f"contactvisco_mesh_{geo['script']}", script)
    module = importlib.util.module_from_spec(spec)
    sys.path.insert(0, str(MESH_DIR))          # for the scripts' shared helper
    try:
        spec.loader.exec_module(module)
    finally:
        sys.path.remove(str(MESH_DIR))
    gmsh.initialize()
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.model.add(geo["script"])
        try:
            module.build(gmsh, **geo["parameters"])
        except TypeError as err:
            raise SceneError(f"geometry.parameters do not fit meshes/{geo['script']}.py: "
                             f"{err}", key="geometry.parameters") from None
        except Exception as err:    # gmsh reports a geometry it cannot mesh as an Exception
            raise SceneError(f"geometry.parameters: gmsh cannot mesh meshes/"
                             f"{geo['script']}.py with {geo['parameters']}: {err}",
                             key="geometry.parameters") from None
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_suffix(f".{os.getpid()}.msh")
        gmsh.write(str(tmp))
        os.replace(tmp, path)
    finally:
        gmsh.finalize()


def _header_error(path: pathlib.Path) -> str | None:
    """Why a file is not a gmsh mesh, from its first bytes (gmsh would read a large file of
    anything else to its end before giving up), or None."""
    try:
        with open(path, "rb") as f:
            head = f.read(64)
    except OSError as err:
        return f"geometry.file: cannot read mesh file {path}: {err.strerror}"
    if not head.lstrip().startswith(b"$MeshFormat"):
        return (f"geometry.file: cannot read mesh file {path}: not a gmsh .msh file (it does "
                "not start with $MeshFormat)")
    return None


def _gmsh(geo, d: int, comm) -> Geometry:
    import gmsh
    path = mesh_file(geo)
    error = None
    if comm.rank == 0 and not path.exists():
        try:
            _generate(geo, path, d)
        except SceneError as err:
            error = (str(err), err.key)
    error = comm.bcast(error, root=0)
    if error:
        raise SceneError(*error)
    source = "geometry.file" if geo["file"] is not None else "geometry.script"
    names = cell_names = None
    if comm.rank == 0:
        names = _header_error(path)
    if comm.rank == 0 and names is None:
        gmsh.initialize()
        gmsh.option.setNumber("General.Terminal", 0)
        try:
            gmsh.merge(str(path))
            names = {gmsh.model.getPhysicalName(d - 1, tag): tag
                     for _, tag in gmsh.model.getPhysicalGroups(d - 1)}
            cell_names = {gmsh.model.getPhysicalName(d, tag): tag
                          for _, tag in gmsh.model.getPhysicalGroups(d)}
        except Exception as err:   # gmsh reports a bad file as a plain Exception
            names = f"geometry.file: cannot read mesh file {path}: {err}"
            gmsh.finalize()
    names = comm.bcast(names, root=0)
    if isinstance(names, str):
        raise SceneError(names, key=source)
    if not isinstance(names, str) and comm.rank == 0:
        names = _model_error(gmsh, path, d) or names
        if isinstance(names, str):
            gmsh.finalize()
    names = comm.bcast(names, root=0)
    if isinstance(names, str):
        raise SceneError(names, key=source)
    cell_names = comm.bcast(cell_names if comm.rank == 0 else None, root=0)
    mesh, cell_tags, facet_tags = compat.model_to_tagged_mesh(gmsh.model, comm, 0, gdim=d)
    if comm.rank == 0:
        gmsh.finalize()
    check_cells(mesh, f"{source} {path}" if geo["file"] is not None else source)
    return Geometry(mesh, facet_tags, names, cell_tags, cell_names)


def _model_error(gmsh, path, d: int) -> str | None:
    """Why the merged gmsh model cannot be a d-dimensional body with named boundaries, or
    None: cells of dimension d, a physical group of them, named physical groups of facets."""
    dims = sorted({dim for dim in range(4)
                   if len(gmsh.model.mesh.getElements(dim)[0])})
    if d not in dims:
        found = f"elements of dimension {', '.join(map(str, dims))} only" if dims else \
            "no elements at all"
        hint = ("; gmsh saves only the elements of physical groups when there are any: mark "
                "the body with a Physical Surface (2D) or Volume (3D)"
                if gmsh.model.getPhysicalGroups() and not gmsh.model.getPhysicalGroups(d)
                and gmsh.model.getEntities(d) else "")
        return (f"geometry.file: mesh file {path} has no cells of dimension {d} ({found}); "
                f"material.model needs a {d}D mesh{hint}")
    if max(dims) > d:
        return (f"geometry.file: mesh file {path} has cells of dimension {max(dims)}; "
                f"material.model needs a {d}D mesh (set material.model = '3d' for a 3D body)")
    if not gmsh.model.getPhysicalGroups(d):
        return (f"geometry.file: mesh file {path} has no physical group of dimension {d} (the "
                "body's cells); mark the body with a Physical Surface (2D) or Volume (3D)")
    if not gmsh.model.getPhysicalGroups(d - 1):
        return (f"geometry.file: mesh file {path} has no named physical groups of dimension "
                f"{d - 1} (the boundaries a scene refers to)")
    return None
