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
        path = pathlib.Path(geo["file"])
        if path.suffix != ".msh":
            raise SceneError(f"geometry.file must be a gmsh .msh file, got '{path}' (a .geo "
                             "file is a gmsh script, which can run commands)", key="geometry.file")
        if not path.is_file():
            raise SceneError(f"geometry.file: no mesh file '{path}'", key="geometry.file")
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
    names = None
    if comm.rank == 0:
        names = _header_error(path)
    if comm.rank == 0 and names is None:
        gmsh.initialize()
        gmsh.option.setNumber("General.Terminal", 0)
        try:
            gmsh.merge(str(path))
            names = {gmsh.model.getPhysicalName(d - 1, tag): tag
                     for _, tag in gmsh.model.getPhysicalGroups(d - 1)}
        except Exception as err:   # gmsh reports a bad file as a plain Exception
            names = f"geometry.file: cannot read mesh file {path}: {err}"
            gmsh.finalize()
    names = comm.bcast(names, root=0)
    if isinstance(names, str):
        raise SceneError(names, key=source)
    mesh, facet_tags = compat.model_to_mesh(gmsh.model, comm, 0, gdim=d)
    if comm.rank == 0:
        gmsh.finalize()
    if not names:
        raise SceneError(f"{path}: the mesh has no named physical groups of dimension {d - 1} "
                         "(the boundaries a scene refers to)", key=source)
    return Geometry(mesh, facet_tags, names)
