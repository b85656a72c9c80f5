"""obstacle.xdmf: the surface of a rigid obstacle (plane, cylinder, sphere, cone, punch) at every
step, beside
solution.xdmf, so that ParaView shows it with the body (open both; same time values).

The surface is drawn once in the reference position, large enough to cover the body (a plane:
a segment or square twice the body's size; a cylinder: its length twice the body's; a cone or a
flat punch, which exist in 2D: their profile in the plane, its sides as long as the body's
size, on both sides of their axis), and moved
by the obstacle's displacement d(t) of each step record. The data are written inline (XDMF
XML format): the file is read without HDF5 and grows by one small grid per step, appended in
place before its closing tags like solution.xdmf. A signed-distance surface (`surface`) has no
drawing and another body of the mesh (`body`) is in solution.xdmf already: no file for them.
"""
from __future__ import annotations

import os
import pathlib

import numpy as np

from contactvisco.io import files

OBSTACLE_FILE = "obstacle.xdmf"
#: Segments around a circle.
AROUND = 96
#: The shapes that have a drawing.
DRAWN = ("plane", "cylinder", "sphere", "cone", "punch")


def _unit(v) -> np.ndarray:
    v = np.asarray(v, dtype=float)
    return v / np.linalg.norm(v)


def _frame(n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors orthogonal to the unit vector n and to each other."""
    helper = np.eye(3)[np.argmin(np.abs(n))]
    a = _unit(np.cross(n, helper))
    return a, np.cross(n, a)


def surface(obstacle: dict, lower: np.ndarray, upper: np.ndarray):
    """The obstacle's surface in its reference position, for a body inside [lower, upper].

    Parameters
    ----------
    obstacle : dict
        The scene's [obstacle] table.
    lower, upper : numpy.ndarray
        Corners of the body's bounding box (d values each).

    Returns
    -------
    tuple or None
        (points (n, 3), cells (m, k), XDMF topology type): segments ("Polyline") in 2D,
        quadrilaterals in 3D; None for a shape without a drawing.
    """
    shape = obstacle.get("shape")
    if shape not in DRAWN:
        return None
    d = len(lower)
    pad = np.zeros(3 - d)
    centre_box = np.concatenate([(lower + upper) / 2, pad])
    size = max(float(np.linalg.norm(upper - lower)), 1e-300)
    if shape == "plane":
        point = np.concatenate([np.asarray(obstacle["point"], float), pad])
        n = _unit(np.concatenate([np.asarray(obstacle["normal"], float), pad]))
        # Centred at the box centre's projection onto the plane.
        foot = centre_box - np.dot(centre_box - point, n) * n
        if d == 2:
            t = np.array([-n[1], n[0], 0.0])
            return (np.array([foot - size * t, foot + size * t]), np.array([[0, 1]]),
                    "Polyline")
        a, b = _frame(n)
        corners = [foot + size * (sa * a + sb * b) for sa, sb in ((-1, -1), (1, -1), (1, 1),
                                                                   (-1, 1))]
        return np.array(corners), np.array([[0, 1, 2, 3]]), "Quadrilateral"
    if shape in ("cone", "punch"):     # 2D only (fem.obstacle.indenter_distance)
        tip = np.concatenate([np.asarray(obstacle["point"], float), pad])
        if shape == "cone":            # the two flanks z = |r| cot(alpha) from the tip
            alpha = np.deg2rad(float(obstacle["angle"]))
            flank = size * np.array([np.sin(alpha), np.cos(alpha), 0.0])
            points = [tip + flank * [-1, 1, 0], tip, tip + flank]
        else:                          # the flat end of radius a and the sides above it
            a = float(obstacle["radius"])
            points = [tip + [-a, size, 0], tip + [-a, 0, 0], tip + [a, 0, 0], tip + [a, size, 0]]
        i = np.arange(len(points) - 1)
        return np.array(points), np.stack([i, i + 1], axis=1), "Polyline"
    centre = np.concatenate([np.asarray(obstacle["centre"], float), pad])
    radius = float(obstacle["radius"])
    angle = np.linspace(0.0, 2 * np.pi, AROUND, endpoint=False)
    if d == 2:                  # a circle: the cylinder's section, the sphere's meridian
        points = centre + radius * np.stack([np.cos(angle), np.sin(angle), 0 * angle], axis=1)
        cells = np.stack([np.arange(AROUND), (np.arange(AROUND) + 1) % AROUND], axis=1)
        return points, cells, "Polyline"
    if shape == "cylinder":
        axis = _unit(obstacle["axis"])
        a, b = _frame(axis)
        middle = centre + np.dot(centre_box - centre, axis) * axis
        ring = radius * (np.cos(angle)[:, None] * a + np.sin(angle)[:, None] * b)
        points = np.concatenate([middle - size * axis + ring, middle + size * axis + ring])
        i = np.arange(AROUND)
        cells = np.stack([i, (i + 1) % AROUND, (i + 1) % AROUND + AROUND, i + AROUND], axis=1)
        return points, cells, "Quadrilateral"
    # A sphere: rings of latitude, poles included as degenerate quadrilaterals.
    rings = AROUND // 2 + 1
    polar = np.linspace(0.0, np.pi, rings)
    points = np.concatenate([centre + radius * np.stack(
        [np.sin(p) * np.cos(angle), np.sin(p) * np.sin(angle), np.cos(p) + 0 * angle], axis=1)
        for p in polar])
    i = np.arange(AROUND)
    cells = np.concatenate([np.stack([r * AROUND + i, r * AROUND + (i + 1) % AROUND,
                                      (r + 1) * AROUND + (i + 1) % AROUND,
                                      (r + 1) * AROUND + i], axis=1)
                            for r in range(rings - 1)])
    return points, cells, "Quadrilateral"


def _array(values: np.ndarray, number: str) -> str:
    rows = "\n".join(" ".join(repr(float(v)) if number == "Float" else str(int(v))
                              for v in row) for row in values)
    dims = " ".join(str(n) for n in values.shape)
    precision = ' Precision="8"' if number == "Float" else ""
    return (f'<DataItem Dimensions="{dims}" NumberType="{number}"{precision} Format="XML">\n'
            f"{rows}\n</DataItem>")


class ObstacleFile:
    """obstacle.xdmf, written by one process: a temporal collection with one grid per step,
    the reference surface moved by that step's displacement."""

    HEAD = ('<?xml version="1.0"?>\n<Xdmf Version="3.0">\n  <Domain>\n'
            '    <Grid Name="obstacle" GridType="Collection" CollectionType="Temporal">\n')
    TAIL = "    </Grid>\n  </Domain>\n</Xdmf>\n"

    def __init__(self, path, drawing, records=()):
        """Start the file with a grid for each of `records` (step records with their
        obstacle entry, e.g. the steps a restart keeps).

        Parameters
        ----------
        path : path-like
            The file to write (replaced).
        drawing : tuple
            (points, cells, topology type) of the reference surface (surface()).
        records : iterable of dict
            Step records already written.
        """
        self.path = pathlib.Path(path)
        self.points, self.cells, self.kind = drawing
        body = "".join(self.grid(r) for r in records if "obstacle" in r)
        files.replace(self.path, self.HEAD + body + self.TAIL)
        self.fd = files.open_fd(self.path, "r+")
        self.end = os.fstat(self.fd).st_size - len(self.TAIL)

    def grid(self, record: dict) -> str:
        """The XDMF grid of one step record: time, moved points, cells, and the displacement
        as a point field `displacement` (ParaView's Warp By Vector gives the reference)."""
        d = np.zeros(3)
        shift = record["obstacle"]["displacement"]
        d[:len(shift)] = shift
        per_cell = self.cells.shape[1]
        topology = (f'<Topology TopologyType="{self.kind}" NumberOfElements='
                    f'"{len(self.cells)}"'
                    + (f' NodesPerElement="{per_cell}"' if self.kind == "Polyline" else "")
                    + ">\n" + _array(self.cells, "Int") + "\n</Topology>")
        geometry = ('<Geometry GeometryType="XYZ">\n' + _array(self.points + d, "Float")
                    + "\n</Geometry>")
        field = ('<Attribute Name="displacement" AttributeType="Vector" Center="Node">\n'
                 + _array(np.tile(d, (len(self.points), 1)), "Float") + "\n</Attribute>")
        return (f'      <Grid Name="step {record["step"]}" GridType="Uniform">\n'
                f'<Time Value="{record["t"]!r}"/>\n{topology}\n{geometry}\n{field}\n'
                "      </Grid>\n")

    def append(self, record: dict):
        """Add the grid of a step record (nothing without an obstacle entry)."""
        if "obstacle" not in record:
            return
        data = (self.grid(record) + self.TAIL).encode()
        written = os.pwrite(self.fd, data, self.end)
        if written != len(data):       # a full disk: put the old end back and fail
            os.pwrite(self.fd, self.TAIL.encode(), self.end)
            os.ftruncate(self.fd, self.end + len(self.TAIL))
            raise OSError(28, f"short write to {self.path}")
        self.end += len(data) - len(self.TAIL)

    def close(self):
        """Close the file (idempotent)."""
        if getattr(self, "fd", None) is not None:
            os.close(self.fd)
            self.fd = None
