"""Off-screen pyvista renderings of the deformed body coloured by a cell field, with the
undeformed edges in black, as RGB arrays (figures.py frames them with titles and a colour bar,
so no text is drawn here):

    images(points, cells, displacement, values, clim, views, edges)

Where it runs. With Debian's DOLFINx 0.5 loaded first, VTK 9.7 (pyvista 0.49 wheel) aborts in
vtkRenderer::Render (std::bad_alloc, signal 6); importing VTK before DOLFINx, or rendering
before DOLFINx is loaded, works, and so do all four orders with the PyPI DOLFINx 0.11 wheels.
So the rendering runs in this process unless DOLFINx 0.5 is loaded and VTK is not, and then in
a child process (`python -m contactvisco.post.render IN.npz OUT.npz`), whose abort cannot take the
run with it.
"""
from __future__ import annotations

import subprocess
import sys
import tempfile

import numpy as np


def in_process_safe() -> bool:
    """False exactly in the measured failing case: DOLFINx < 0.10 loaded, VTK not yet."""
    if "vtkmodules.vtkRenderingCore" in sys.modules or "dolfinx" not in sys.modules:
        return True
    version = getattr(sys.modules["dolfinx"], "__version__", "0.0")
    return tuple(int(p) for p in version.split(".")[:2] if p.isdigit()) >= (0, 10)


def images(points, cells, displacement, values, clim, views, edges=False):
    """One RGB array per view; views: [(kind, direction)], kind 'iso' (isometric) or 'face'
    (looking at the body from `direction`, a unit vector pointing away from it). None (with a
    warning) when pyvista is missing or the rendering fails."""
    args = dict(points=points, cells=cells, displacement=displacement, values=values,
                clim=np.asarray(clim, float), edges=bool(edges),
                views=np.array([[0, 0, 0] if d is None else d for _, d in views], float),
                kinds=np.array([k for k, _ in views]))
    try:
        import pyvista  # noqa: F401
    except ImportError:
        print("contactvisco: warning: no 3D stress map: pyvista is not installed (the 'viz' "
              "extra)", file=sys.stderr)
        return None
    if in_process_safe():
        return _render(**args)
    with tempfile.TemporaryDirectory() as folder:
        given, taken = f"{folder}/in.npz", f"{folder}/out.npz"
        np.savez(given, **args)
        try:
            proc = subprocess.run([sys.executable, "-m", "contactvisco.post.render", given, taken],
                                  capture_output=True, text=True, timeout=300)
        except subprocess.TimeoutExpired:
            proc = None
        if proc is not None and proc.returncode == 0:
            data = np.load(taken)
            return [data[f"image{i}"] for i in range(len(views))]
    reason = "timed out" if proc is None else (proc.stderr.strip().splitlines() or ["?"])[-1]
    print(f"contactvisco: warning: no 3D stress map: {reason}", file=sys.stderr)
    return None


def _render(points, cells, displacement, values, clim, views, kinds, edges):
    import pyvista
    pyvista.OFF_SCREEN = True
    d = points.shape[1]
    xyz = np.zeros((len(points), 3))
    xyz[:, :d] = points
    kind = pyvista.CellType.TRIANGLE if d == 2 else pyvista.CellType.TETRA
    layout = np.hstack([np.full((len(cells), 1), cells.shape[1]), cells]).ravel()
    reference = pyvista.UnstructuredGrid(layout, np.full(len(cells), kind), xyz)
    deformed = reference.copy()
    deformed.points[:, :d] += displacement
    deformed.cell_data["value"] = values
    outline = reference.extract_feature_edges(boundary_edges=True, feature_edges=d == 3,
                                              manifold_edges=False, non_manifold_edges=False)
    out = []
    for kind_name, direction in zip(kinds, views):
        plotter = pyvista.Plotter(off_screen=True, window_size=(900, 800))
        plotter.set_background("white")
        plotter.add_mesh(deformed, scalars="value", cmap="viridis", clim=list(clim),
                         show_edges=edges, edge_color="dimgray", line_width=0.3,
                         show_scalar_bar=False)
        plotter.add_mesh(outline, color="black", line_width=1.5)
        if str(kind_name) == "face":
            centre = np.array(deformed.center)
            plotter.camera.focal_point = centre
            plotter.camera.position = centre + 3 * deformed.length * np.asarray(direction)
            up = np.roll(np.abs(direction), 1)        # any axis across the view direction
            plotter.camera.up = up
            plotter.reset_camera()
        elif d == 2:
            plotter.view_xy()
        else:
            plotter.view_isometric()
        out.append(plotter.screenshot(return_img=True))
        plotter.close()
    return out


if __name__ == "__main__":
    given = dict(np.load(sys.argv[1]))
    given["edges"] = bool(given["edges"])
    rendered = _render(**given)
    np.savez(sys.argv[2], **{f"image{i}": image for i, image in enumerate(rendered)})
