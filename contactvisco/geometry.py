"""Meshes and named boundaries of a scene."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from dolfinx import mesh as dmesh
from mpi4py import MPI

from .scene import SceneError

#: Boundary names of the built-in box: the faces x = lower/upper, y = ..., z = ...
BOX_FACES_2D = {"left": (0, 0), "right": (0, 1), "bottom": (1, 0), "top": (1, 1)}
BOX_FACES_3D = {"left": (0, 0), "right": (0, 1), "front": (1, 0), "back": (1, 1),
                "bottom": (2, 0), "top": (2, 1)}


@dataclass
class Geometry:
    mesh: dmesh.Mesh
    facet_tags: dmesh.MeshTags
    names: dict[str, int]          # boundary name -> facet tag value

    def facets(self, name: str) -> np.ndarray:
        if name not in self.names:
            raise SceneError(f"no boundary named '{name}'; this geometry has "
                             f"{', '.join(sorted(self.names))}")
        return self.facet_tags.find(self.names[name])


def build(scene: dict, comm=MPI.COMM_WORLD) -> Geometry:
    geo = scene["geometry"]
    if geo["type"] != "box":
        raise SceneError(f"geometry.type must be 'box', got '{geo['type']}'")
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
    angle = np.deg2rad(float(geo.get("rotation", 0.0)))
    if angle != 0.0:
        x = mesh.geometry.x
        c, s = np.cos(angle), np.sin(angle)
        x[:, 0], x[:, 1] = c * x[:, 0] - s * x[:, 1], s * x[:, 0] + c * x[:, 1]
    return Geometry(mesh, tags, names)
