"""Render the deformed body coloured by the von Mises stress, with the undeformed outline
(pyvista, off screen), from a run's snapshots.npz:

    python -m contactvisco.render RUN/snapshots.npz stress.png

Kept free of DOLFINx and PETSc imports: VTK's wheel aborts when it draws in a process that has
loaded them (see contactvisco.figures.stress_rendering).
"""
import sys

import numpy as np


def render(snapshots: str, png: str, index: int = -1):
    import pyvista
    pyvista.OFF_SCREEN = True
    data = np.load(snapshots)
    points, cells = data["points"], data["cells"]
    d = points.shape[1]
    xyz = np.zeros((len(points), 3))
    xyz[:, :d] = points
    kind = pyvista.CellType.TRIANGLE if d == 2 else pyvista.CellType.TETRA
    layout = np.hstack([np.full((len(cells), 1), cells.shape[1]), cells]).ravel()
    reference = pyvista.UnstructuredGrid(layout, np.full(len(cells), kind), xyz)
    deformed = reference.copy()
    deformed.points[:, :d] += data["displacements"][index]
    label = "von Mises stress" + (" (in-plane)" if d == 2 else "")
    deformed.cell_data[label] = data["von_mises"][index]
    plotter = pyvista.Plotter(off_screen=True, window_size=(900, 700))
    plotter.add_mesh(deformed, scalars=label, cmap="viridis", show_edges=d == 2,
                     edge_color="dimgray", line_width=0.3)
    outline = reference.extract_feature_edges(boundary_edges=True, feature_edges=d == 3,
                                              manifold_edges=False, non_manifold_edges=False)
    plotter.add_mesh(outline, color="black", line_width=1.5)
    plotter.add_text(f"t = {data['times'][index]:g} (black: undeformed outline)", font_size=10)
    if d == 2:
        plotter.view_xy()
    else:
        plotter.view_isometric()
    plotter.screenshot(png)
    plotter.close()


if __name__ == "__main__":
    render(sys.argv[1], sys.argv[2])
