# ---
# jupyter:
#   jupytext:
#     text_representation:
#       extension: .py
#       format_name: percent
# ---

# %% [markdown]
# # A 3D block pressed and sheared on the foundation
#
# The top face of a block is pushed down, more at $x = 1$ than at $x = 0$, and then moved
# sideways along $(3, 1)$. In 3D the friction law projects onto a disc: on a sliding node
# $\sigma_\tau = -\mu\, p_\nu(u_\nu)\, u_\tau / \|u_\tau\|$, a vector in the plane of
# the contact face. The mesh comes from `meshes/box3d.py`, and the memory kernel is exponential.

# %%
import pathlib

import numpy as np
from mpi4py import MPI

from contactvisco import load_scene, quick, show_images, solve

overrides = {"time": {"steps": 4}, "output": {"xdmf": False}} if quick() else {}
scene = load_scene("block3d", **overrides)
out = pathlib.Path("results/demo_block3d")
result = solve(scene, out, progress=True)

# %% [markdown]
# ## Friction on the contact face
# Every sliding node's friction traction lies on the disc of radius $\mu p_\nu$ and points
# against its tangential displacement.

# %%
table = result.contact[-1]
sliding = (np.linalg.norm(table["u_tau_vector"], axis=1) > 1e-8) & (table["radius"] > 0)
direction = table["u_tau_vector"][sliding] / np.linalg.norm(
    table["u_tau_vector"][sliding], axis=1)[:, None]
cosine = np.einsum("ij,ij->i", table["sigma_tau_vector"][sliding], -direction)
print(f"{sliding.sum()} sliding nodes; |sigma_tau| / (mu p_nu) in "
      f"[{np.min(cosine / table['radius'][sliding]):.6f}, "
      f"{np.max(cosine / table['radius'][sliding]):.6f}]")
print("states at T:", result.steps[-1]["status_counts"])

# %% [markdown]
# ## The deformed block and the contact face
# Von Mises stress on the deformed block and on its contact face seen from below (pyvista,
# undeformed edges in black; the colours span the 1st to 99th percentile, as the colour bar
# says), then the contact nodes coloured by state, sized by their normal reaction.

# %%
if MPI.COMM_WORLD.rank == 0:
    show_images(out / "stress.png", out / "contact_status.png", out / "probes.png")
