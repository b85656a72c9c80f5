# ---
# jupyter:
#   jupytext:
#     text_representation:
#       extension: .py
#       format_name: percent
# ---

# %% [markdown]
# # The paper's scene on a mesh of your own
#
# A scene describes the physics (material, memory kernel, loads, contact law, time grid) and,
# in its `geometry` table, a mesh. `solve` also takes a DOLFINx mesh made in the notebook,
# with its facets tagged: a dict `boundaries` then maps the boundary names the scene uses
# (`left`, `right`, `top`, `bottom` in the paper's scene) to the tag values.
#
# Here: the unit square of section 4 of Ouafik (2024), meshed with DOLFINx, friction
# coefficient $\mu = 0.4$ instead of the paper's 0.2.

# %%
# contactvisco first: a DOLFINx wheel from PyPI needs its MPI libraries loaded before dolfinx.
from contactvisco import load_scene, pyvista_grid, quick, solve

import numpy as np  # noqa: E402
from dolfinx import mesh as dmesh  # noqa: E402
from mpi4py import MPI  # noqa: E402

n = 8 if quick() else 32
domain = dmesh.create_unit_square(MPI.COMM_WORLD, n, n, dmesh.CellType.triangle,
                                  diagonal=dmesh.DiagonalType.right)

# %% [markdown]
# ## Tag the boundary
# One tag value per side, as `dolfinx.mesh.meshtags` wants it: sorted facet indices.

# %%
sides = {"left": (0, 0.0), "right": (0, 1.0), "bottom": (1, 0.0), "top": (1, 1.0)}
fdim = domain.topology.dim - 1
facets, values = [], []
for tag, (axis, position) in enumerate(sides.values(), start=1):
    found = dmesh.locate_entities_boundary(
        domain, fdim, lambda x, a=axis, p=position: np.isclose(x[a], p))
    facets.append(found)
    values.append(np.full(found.size, tag, dtype=np.int32))
facets, values = np.concatenate(facets), np.concatenate(values)
order = np.argsort(facets)
facet_tags = dmesh.meshtags(domain, fdim, facets[order], values[order])
boundaries = {name: tag for tag, name in enumerate(sides, start=1)}
print(boundaries)

# %% [markdown]
# ## Load the scene, change mu, solve
# Overrides are Python values nested by table; a misspelled key or a value out of range is a
# `SceneError` that says what is allowed. `on_step` sees every accepted step.

# %%
scene = load_scene("paper", contact={"mu": 0.4}, time={"steps": 4 if quick() else 10})


def report(record):
    if MPI.COMM_WORLD.rank == 0:
        print(f"t = {record['t']:.2f}: {record['status_counts']}")


result = solve(scene, mesh=domain, facet_tags=facet_tags, boundaries=boundaries,
               on_step=report)

# %% [markdown]
# ## The displacement
# `result.u` is the DOLFINx displacement at the final time; `pyvista_grid` turns this rank's
# part into a pyvista grid (warped by 5 u here, so that the contact zone shows).

# %%
import pathlib  # noqa: E402

import pyvista  # noqa: E402
from IPython.display import Image, display  # noqa: E402

grid = pyvista_grid(result.u)
grid["|u|"] = np.linalg.norm(grid["u"], axis=1)
plotter = pyvista.Plotter(off_screen=True, window_size=(900, 650))
plotter.set_background("white")
plotter.add_mesh(grid.warp_by_vector("u", factor=5.0), scalars="|u|", show_edges=True,
                 lighting=False,
                 scalar_bar_args={"title": "magnitude of u", "color": "black",
                                  "vertical": True, "position_x": 0.84, "position_y": 0.15,
                                  "height": 0.7, "width": 0.08})
plotter.view_xy()
plotter.camera.zoom(0.9)
if MPI.COMM_WORLD.size == 1:
    picture = pathlib.Path("results/own_mesh_u.png")     # results/: ignored by git
    picture.parent.mkdir(exist_ok=True)
    plotter.screenshot(picture)
    display(Image(filename=str(picture), width=600))
plotter.close()
del plotter        # released now, while pyvista is whole (not among the module's teardown)
print("largest |u|:", np.abs(result.u.x.array).max())

# %% [markdown]
# ## The contact table
# `result.contact[i]` holds, at step i, every contact node's values (on every rank, sorted by
# position): `x`, the normal displacement `u_nu`, the compliance pressure `p_nu`, the
# multiplier `lambda_nu` of the bound, the reactions and the states.

# %%
table = result.contact[-1]
statuses = ("separated", "compliance", "bound")
for x, u_nu, p_nu, status in zip(table["x"][::max(1, n // 8)], table["u_nu"][::max(1, n // 8)],
                                 table["p_nu"][::max(1, n // 8)],
                                 table["status"][::max(1, n // 8)]):
    print(f"x = {x[0]:.3f}  u_nu = {u_nu:+.4f}  p_nu = {p_nu:7.3f}  {statuses[status]}")
print("at the final time:", result.final["status_counts"])
