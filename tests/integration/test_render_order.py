"""pyvista next to DOLFINx in one process, in the import orders a notebook meets: each order
runs in a child process (an abort there cannot take the test run with it), solves a small
scene, draws result.u warped with pyvista's own scalar bar off screen, and must exit 0 with a
picture that is not blank. With Debian's DOLFINx 0.5, VTK loaded after it used to abort in
vtkScalarBarActor (std::bad_alloc, signal 6): see contactvisco.post.render."""
import os
import subprocess
import sys

import numpy as np
import pytest
from mpi4py import MPI

from helpers import ROOT

SOLVE = """
import numpy as np
from dolfinx import mesh
from mpi4py import MPI
from contactvisco import load_scene, pyvista_grid, solve
domain = mesh.create_unit_square(MPI.COMM_SELF, 6, 6)
sides = {"left": (0, 0.0), "right": (0, 1.0), "bottom": (1, 0.0), "top": (1, 1.0)}
found = [mesh.locate_entities_boundary(domain, 1, lambda x, a=a, p=p: np.isclose(x[a], p))
         for a, p in sides.values()]
facets = np.concatenate(found)
values = np.concatenate([np.full(f.size, tag, np.int32) for tag, f in enumerate(found, 1)])
order = np.argsort(facets)
tags = mesh.meshtags(domain, 1, facets[order], values[order])
result = solve(load_scene("paper", time={"steps": 2}), mesh=domain, facet_tags=tags,
               boundaries={name: tag for tag, name in enumerate(sides, 1)}, comm=MPI.COMM_SELF)
grid = pyvista_grid(result.u)
grid["|u|"] = np.linalg.norm(grid["u"], axis=1)
grid.warp_by_vector("u").plot(off_screen=True, screenshot=SHOT, scalars="|u|",
                              show_scalar_bar=True)
"""

ORDERS = {
    "contactvisco, solve, pyvista": "import contactvisco\n",
    # (a PyPI DOLFINx wheel needs its bundled MPI loaded first: dolfinx_solver, which
    # `import contactvisco` otherwise loads)
    "dolfinx, contactvisco, pyvista": "import importlib.util\n"
                                      "if importlib.util.find_spec('dolfinx_solver'):\n"
                                      "    import dolfinx_solver\n"
                                      "import dolfinx\nimport contactvisco\n",
    "contactvisco, dolfinx, pyvista at the top": "import contactvisco\nimport dolfinx\n"
                                                 "import pyvista\n",
    "pyvista, contactvisco": "import pyvista\nimport contactvisco\n",
}


@pytest.mark.skipif(MPI.COMM_WORLD.size > 1, reason="child processes; run on one rank")
@pytest.mark.parametrize("order", ORDERS)
def test_pyvista_plot_in_any_import_order(order, tmp_path):
    pytest.importorskip("pyvista")
    shot = tmp_path / "u.png"
    script = ORDERS[order] + f"SHOT = {str(shot)!r}\n" + SOLVE
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(
        [str(ROOT)] + [p for p in os.environ.get("PYTHONPATH", "").split(os.pathsep) if p]))
    proc = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                          env=env, cwd=tmp_path, timeout=600)
    assert proc.returncode == 0, f"{order}: exit {proc.returncode}\n{proc.stderr[-2000:]}"
    # Off screen without a display: no X server tried (vtk_guard.headless_rendering).
    assert "bad X server" not in proc.stderr or os.environ.get("DISPLAY"), proc.stderr[-500:]
    from matplotlib import pyplot
    rgb = pyplot.imread(shot)[..., :3]
    assert rgb.std() > 0.05, f"{order}: a blank picture"
    # the mesh is coloured: more than a background and black lines
    assert np.mean(np.ptp(rgb, axis=2) > 0.2) > 0.01, f"{order}: no coloured body"
