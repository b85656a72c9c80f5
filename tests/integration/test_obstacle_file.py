"""obstacle.xdmf beside solution.xdmf: the rigid obstacle's surface at every step, moved by the
displacement of the step record, on the obstacle (every drawn point at the obstacle's
distance), with the times of solution.xdmf; VTK's XDMF reader opens it."""
import json
import xml.etree.ElementTree as ET

import numpy as np
import pytest
from mpi4py import MPI

from contactvisco import load_scene, solve
from contactvisco.io import obstacle_file

COMM = MPI.COMM_WORLD


def grids(path) -> list[tuple[float, np.ndarray]]:
    """(t, points) of every grid of an XDMF file with inline data."""
    out = []
    for grid in ET.parse(path).getroot().iter("Grid"):
        if grid.get("GridType") != "Uniform":
            continue
        text = grid.find("Geometry/DataItem").text
        out.append((float(grid.find("Time").get("Value")),
                    np.array(text.split(), dtype=float).reshape(-1, 3)))
    return out


@pytest.mark.mpi
def test_a_sphere_on_a_block_writes_its_surface_at_every_step(tmp_path_factory):
    """sphere_creep (axisymmetric: the sphere's meridian, a circle in the r-z plane) on 3
    steps: a grid per step record, at its time, each point at the radius from the centre
    moved by the record's displacement, which changes (the sphere sinks under its force)."""
    out = COMM.bcast(str(tmp_path_factory.mktemp("obstacle")) if COMM.rank == 0 else None)
    scene = load_scene("sphere_creep", time={"steps": 3}, output={"figures": False})
    solve(scene, out=out)
    if COMM.rank != 0:
        return
    records = [json.loads(line) for line in open(f"{out}/steps.jsonl")]
    drawn = grids(f"{out}/obstacle.xdmf")
    assert [t for t, _ in drawn] == [r["t"] for r in records]
    centre, radius = np.array(scene["obstacle"]["centre"]), scene["obstacle"]["radius"]
    for (t, points), record in zip(drawn, records):
        moved = centre + np.array(record["obstacle"]["displacement"])
        assert np.allclose(np.linalg.norm(points[:, :2] - moved, axis=1), radius, rtol=1e-12)
        assert np.all(points[:, 2] == 0)
    depth = [r["obstacle"]["displacement"][1] for r in records]
    assert depth[-1] < depth[1] < 0
    solution = [float(g.find("Time").get("Value"))
                for g in ET.parse(f"{out}/solution.xdmf").getroot().iter("Grid")
                if g.get("GridType") == "Uniform"]
    assert solution == [t for t, _ in drawn]
    vtk = pytest.importorskip("vtk")
    reader = vtk.vtkXdmfReader()
    reader.SetFileName(f"{out}/obstacle.xdmf")
    reader.UpdateInformation()
    times = reader.GetOutputInformation(0).Get(vtk.vtkStreamingDemandDrivenPipeline.TIME_STEPS())
    assert list(times) == solution
    reader.Update()
    assert reader.GetOutputDataObject(0).GetNumberOfCells() == obstacle_file.AROUND


@pytest.mark.parametrize("obstacle, distance", [
    ({"shape": "plane", "point": [0, 0, -0.1], "normal": [0, 0, 1]},
     lambda p: p[:, 2] + 0.1),
    ({"shape": "cylinder", "centre": [0.5, 0.5, 1.5], "radius": 0.5, "axis": [1, 0, 0]},
     lambda p: np.linalg.norm(p[:, 1:] - [0.5, 1.5], axis=1) - 0.5),
    ({"shape": "sphere", "centre": [0.5, 0.5, 2.0], "radius": 1.0},
     lambda p: np.linalg.norm(p - [0.5, 0.5, 2.0], axis=1) - 1.0),
    ({"shape": "plane", "point": [0, -0.1], "normal": [0, 1]}, lambda p: p[:, 1] + 0.1),
    ({"shape": "cone", "point": [0.0, 1.0], "angle": 70.3},
     lambda p: np.abs(p[:, 0]) * np.cos(np.deg2rad(70.3))
     - (p[:, 1] - 1.0) * np.sin(np.deg2rad(70.3))),
    ({"shape": "punch", "point": [0.0, 1.0], "radius": 0.25},
     lambda p: np.minimum(np.abs(p[:, 1] - 1.0) + (np.abs(p[:, 0]) > 0.25),
                          np.abs(np.abs(p[:, 0]) - 0.25) + (p[:, 1] < 1.0))),
], ids=["plane-3d", "cylinder-3d", "sphere-3d", "plane-2d", "cone-2d", "punch-2d"])
def test_the_drawn_surfaces_lie_on_the_obstacle_and_cover_the_body(obstacle, distance):
    """Every point of a drawing is on the obstacle; planes and cylinders reach beyond the
    body's box [0, 1]^d along the surface."""
    d = len(obstacle.get("point", obstacle.get("centre")))
    points, cells, _ = obstacle_file.surface(obstacle, np.zeros(d), np.ones(d))
    assert np.allclose(distance(points[:, :d] if d == 2 else points), 0, atol=1e-12)
    assert cells.max() == len(points) - 1 and cells.min() == 0
    if obstacle["shape"] not in ("sphere", "punch"):
        spread = np.ptp(points[:, :d], axis=0)
        assert np.sort(spread)[-1] > 2.0


def test_shapes_without_a_drawing_write_no_file():
    assert obstacle_file.surface({"shape": "surface", "distance": "z"}, np.zeros(3),
                                 np.ones(3)) is None
