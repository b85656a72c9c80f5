"""Off-screen pyvista renderings of the deformed body coloured by a cell field (unlit: the
colours are the colour bar's), with the undeformed edges in black and an x-y-z triad in the
lower left corner, as RGB arrays (figures.py frames them with titles and a colour bar: the
triad's x, y, z are the only text drawn here):

    images(points, cells, displacement, values, clim, views, edges)

Import order: none is needed. Import contactvisco, dolfinx and pyvista in any order (as long
as contactvisco comes before pyvista, or pyvista before dolfinx).

Why there was one. Debian's DOLFINx 0.5 sets the dlopen flags to RTLD_GLOBAL on import and
leaves them so, which makes libdolfinx_real.so's copies of libstdc++ templates global. VTK's
wheel (9.7, built with the old std::string ABI) instantiates the same templates; where the
mangled name does not carry the ABI (std::__detail::_Scanner<char>, the std::regex scanner,
which holds a std::string), VTK loaded after DOLFINx bound to DOLFINx's new-ABI copy, and the
first regex VTK compiles (vtkScalarBarActor's tick format, vtk::is_printf_format) read a
std::string of the other layout: std::bad_alloc, abort (signal 6), seen with LD_DEBUG=bindings.
VTK loaded first bound to its own copies, hence "import pyvista first". The PyPI DOLFINx 0.11
wheels do not make their libraries global and never aborted.

The fix. `import contactvisco` installs a finder (contactvisco.post.vtk_guard, standard
library only) that opens every vtkmodules extension with RTLD_DEEPBIND | RTLD_LOCAL: VTK's
libraries resolve their symbols in themselves and their dependencies before the global scope,
whatever was loaded before. The one order it cannot mend is VTK loaded after DOLFINx 0.5
without contactvisco imported first (e.g. `import dolfinx, pyvista` and only then
contactvisco): there `images` renders in a child process (`python -m contactvisco.post.render
IN.npz OUT.npz`), whose abort cannot take the caller with it; a picture drawn by the caller's
own pyvista calls in that process can still abort.
"""
from __future__ import annotations

import subprocess
import sys
import tempfile

import numpy as np

from contactvisco.post import vtk_guard


def in_process_safe() -> bool:
    """False only where VTK may hold DOLFINx 0.5's template copies: DOLFINx < 0.10 loaded and
    VTK's core module loaded without contactvisco's finder (vtk_guard)."""
    if "dolfinx" not in sys.modules or "vtkmodules.vtkCommonCore" not in sys.modules:
        return True                 # not loaded yet: the finder of `import contactvisco` will
    if vtk_guard.loaded_here():
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
        # lighting=False: every face shows its value's colour as on the colour bar (shading
        # would darken faces turned from the light into other values' colours); the black
        # undeformed edges and the triad give the shape and the orientation.
        plotter.add_mesh(deformed, scalars="value", cmap="viridis", clim=list(clim),
                         show_edges=edges, edge_color="dimgray", line_width=0.3,
                         show_scalar_bar=False, lighting=False)
        plotter.add_mesh(outline, color="black", line_width=1.5)
        plotter.add_axes(color="black", line_width=3, viewport=(0.0, 0.0, 0.26, 0.26))
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
