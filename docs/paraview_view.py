"""The picture of docs/paraview.md (`make figures` runs it): a rigid sphere pressed into the 3D
block and dragged along x, run into build/figures/sphere_block/, then its solution.xdmf and
obstacle.xdmf read back with VTK's XDMF reader (the one ParaView uses, through pyvista) at
the last step and rendered off screen as ParaView shows them: the body warped by u and
coloured by von_mises with the sphere beside it, and the contact face coloured by
contact_pressure, by friction_state.

    python docs/paraview_view.py        -> docs/figures/paraview_sphere_block.png
"""
import pathlib
import shutil
import sys

HERE = pathlib.Path(__file__).resolve().parent
OUT = HERE.parent / "build" / "figures" / "sphere_block"
PICTURE = HERE / "figures" / "paraview_sphere_block.png"

#: The 3D block held at its bottom, a rigid sphere of radius 1 touching its top face at
#: (0.5, 0.5), pushed 0.04 down and dragged 0.02 along x; Signorini contact with Coulomb
#: friction (mu = 0.3).
OVERRIDES = dict(
    contact={"boundary": "top", "g": 0.0, "mu": 0.3, "friction_law": "coulomb",
             "augmentation": 100.0},
    dirichlet=[{"boundary": "bottom", "components": "all", "value": ["0", "0", "0"]}],
    obstacle={"shape": "sphere", "centre": [0.5, 0.5, 1.5], "radius": 1.0,
              "displacement": ["0.02 * t", "0", "-0.04 * t"]},
    output={"figures": False, "checkpoint": False})


def run():
    from contactvisco import load_scene, solve
    if OUT.exists():
        shutil.rmtree(OUT)
    return solve(load_scene("block3d", **OVERRIDES), out=OUT, progress=False)


def last_step(path):
    import pyvista
    reader = pyvista.get_reader(str(path))
    reader.set_active_time_value(reader.time_values[-1])
    data = reader.read()
    return data[0] if isinstance(data, pyvista.MultiBlock) else data


def render(path=PICTURE):
    import pyvista
    pyvista.OFF_SCREEN = True
    body = last_step(OUT / "solution.xdmf")
    sphere = last_step(OUT / "obstacle.xdmf")
    warped = body.warp_by_vector("u", factor=1.0)
    face = warped.extract_surface(algorithm="dataset_surface").threshold(-0.5, scalars="contact_state")
    bar = dict(vertical=True, position_x=0.84, position_y=0.08, width=0.06, height=0.7,
               color="black", title_font_size=15, label_font_size=15, fmt="%.2g")
    plotter = pyvista.Plotter(shape=(1, 3), off_screen=True, window_size=(1800, 620),
                              border=False)
    plotter.set_background("white")
    plotter.subplot(0, 0)
    plotter.add_text("solution.xdmf: von_mises, warped by u;\nobstacle.xdmf: the sphere",
                     font_size=11, color="black")
    plotter.add_mesh(warped, scalars="von_mises", cmap="viridis",
                     scalar_bar_args=dict(title="von_mises", **bar))
    plotter.add_mesh(sphere, color="lightgray", opacity=0.45, show_edges=True,
                     edge_color="gray", line_width=0.5)
    plotter.camera_position = "iso"
    plotter.reset_camera(bounds=warped.bounds)      # the block, the sphere cut by the view
    plotter.camera.zoom(0.75)
    for column, name, cmap in ((1, "contact_pressure", "magma"),
                               (2, "friction_state", None)):
        plotter.subplot(0, column)
        plotter.add_text(f"top face (contact_state >= 0)"
                         + ("\n0 no friction (grey), 1 stick (blue), 2 slip (orange)"
                            if name == "friction_state" else ""), font_size=11, color="black")
        if name == "friction_state":
            plotter.add_mesh(face, scalars=name, categories=True, cmap=["#bbbbbb", "#1f77b4",
                                                                       "#ff7f0e"],
                             clim=[0, 2], show_edges=True, edge_color="white",
                             scalar_bar_args=dict(title="friction_state", n_labels=3,
                                                  **{**bar, "fmt": "%.0f"}))
        else:
            plotter.add_mesh(face, scalars=name, cmap=cmap, show_edges=True,
                             clim=[0, face[name].max()], edge_color="white",
                             scalar_bar_args=dict(title=name, **bar))
        plotter.view_xy()
        plotter.camera.zoom(0.8)
    plotter.screenshot(str(path))
    plotter.close()
    return path


if __name__ == "__main__":
    import contactvisco  # noqa: F401  (before pyvista: contactvisco.post.render explains)
    if "--render-only" not in sys.argv:
        run()
    print(render())
