# ---
# jupyter:
#   jupytext:
#     text_representation:
#       extension: .py
#       format_name: percent
# ---

# %% [markdown]
# # Two viscoelastic bodies in contact
#
# A half cylinder of radius $R = 1$ rests on a block $[-2, 2] \times [-2, 0]$
# (`meshes/cylinder_on_block.py`); the two bodies share no node. Each is a `[[body]]` table
# with its own elasticity and its own memory kernel, and the block's boundary is the
# cylinder's obstacle:
#
# ```toml
# [[body]]
# name = "cylinder"
# cells = "cylinder"
# material = { E = 1.0, nu = 0.3 }
# memory = { kernel = "exponential", alpha = [-0.3], tau = [1.0] }
#
# [[body]]
# name = "block"
# cells = "block"
# material = { E = 2.0, nu = 0.25 }
# memory = { kernel = "exponential", alpha = [-0.4], tau = [4.0] }
#
# [obstacle]
# shape = "body"
# boundary = "block_top"
# ```
#
# The contact law holds at the cylinder's nodes (the slave side) for the displacement
# relative to the block, $u_i - (\Pi u)_i$, with $\Pi$ the mortar projection of the block's
# boundary; the block receives $-\Pi^T$ of the cylinder's contact forces
# ([the interface](../interface.md)). Signorini contact with Coulomb friction ($\mu = 0.3$).
#
# The cylinder's top is moved down by $w$ over $0 \le t \le 1$, held until $t = 3$ (both
# bodies relax: the force falls at a fixed depth), then dragged sideways by $\delta$ until
# $t = 5$: the stick zone shrinks from the contact's full width as the tangential force
# grows towards $\mu P$.

# %%
import pathlib

import matplotlib.pyplot as plt
import numpy as np

from contactvisco import load_scene, quick, solve

h = 0.02 if quick() else 0.01
steps = 10 if quick() else 40
w, delta = 0.017, 0.004
SCENE = f"""
name = "two_bodies"

[geometry]
type = "gmsh"
script = "cylinder_on_block"
parameters = {{ radius = 1.0, h_contact = {h}, h_far = 0.2, refine = 0.15 }}

[material]
model = "plane_strain"

[[body]]
name = "cylinder"
cells = "cylinder"
material = {{ E = 1.0, nu = 0.3 }}
memory = {{ kernel = "exponential", alpha = [-0.3], tau = [1.0] }}

[[body]]
name = "block"
cells = "block"
material = {{ E = 2.0, nu = 0.25 }}
memory = {{ kernel = "exponential", alpha = [-0.4], tau = [4.0] }}

[[dirichlet]]
boundary = "bottom"
components = "all"

[[dirichlet]]
boundary = "top"
components = "all"
value = ["{delta} * max(t - 3, 0) / 2", "-{w} * min(t, 1)"]

[contact]
boundary = "contact"
g = 0.0
mu = 0.3
friction_law = "coulomb"
augmentation = 1.0

[obstacle]
shape = "body"
boundary = "block_top"

[time]
T = 5.0
steps = {steps}
rule = "trapezoid"

[output]
probes = []
"""
folder = pathlib.Path("results")
folder.mkdir(exist_ok=True)
path = folder / "two_bodies.toml"
path.write_text(SCENE)
scene = load_scene(path)
result = solve(scene)
print(f"{steps} steps, Newton iterations {[s['newton_iterations'] for s in result.steps]}")

# %% [markdown]
# ## Contact width, stick zone and forces over time
# From each step's contact table (at the cylinder's nodes): the half-width of the nodes that
# touch, the half-width of those that stick, and the resultants $P = \sum_i w_i p_i$ and
# $Q = \sum_i w_i q_i$ of the pressure and of the friction traction.


# %%
def half_width(x, inside):
    """Half the extent of the nodes inside (0 for none)."""
    return 0.5 * (x[inside].max() - x[inside].min()) if inside.any() else 0.0


t = np.array([s["t"] for s in result.steps])
P, Q, width, stick = [], [], [], []
for table in result.contact:
    x = table["x"][:, 0]
    touching = table["status"] == 2
    P.append(np.sum(table["weight"] * table["reaction_nu"]))
    Q.append(abs(np.sum(table["weight"] * table["reaction_tau"])))
    width.append(half_width(x, touching))
    stick.append(half_width(x, touching & (table["friction"] == 1)))
P, Q = np.array(P), np.array(Q)
depth = w * np.minimum(t, 1.0)
drag = delta * np.maximum(t - 3.0, 0.0) / 2.0

fig, axes = plt.subplots(1, 3, figsize=(13, 3.8), dpi=110)
axes[0].plot(t, width, "o-", label="contact")
axes[0].plot(t, stick, "s-", label="stick zone")
axes[0].set_xlabel("t")
axes[0].set_ylabel("half-width")
axes[0].legend()
axes[1].plot(t, P, "o-", label="normal force P")
axes[1].plot(t, Q, "s-", label="tangential force Q")
axes[1].plot(t, 0.3 * P, "k:", label=r"$\mu P$")
axes[1].set_xlabel("t")
axes[1].set_ylabel("force per unit length")
axes[1].legend()
loading = t <= 1.0
axes[2].plot(depth[loading], P[loading], "o-", label="pressing: P against the depth")
axes[2].plot(drag[t >= 3.0], Q[t >= 3.0], "s-", label="dragging: Q against the drag")
axes[2].set_xlabel("prescribed displacement of the top")
axes[2].set_ylabel("force per unit length")
axes[2].legend()
fig.tight_layout()
plt.show()
held = (t >= 1.0) & (t <= 3.0)
print(f"held at depth {w}: P falls from {P[held][0]:.4g} to {P[held][-1]:.4g} "
      f"({P[held][-1] / P[held][0] - 1:.1%}) while the contact half-width goes from "
      f"{width[np.flatnonzero(held)[0]]:.3f} to {width[np.flatnonzero(held)[-1]]:.3f}")
print(f"at t = 5: Q/(mu P) = {Q[-1] / (0.3 * P[-1]):.2f}, stick half-width {stick[-1]:.3f} "
      f"of the contact's {width[-1]:.3f}")

# %% [markdown]
# ## The patch test with both pairings
# Two blocks pressed together by a uniform pressure $p$ (`meshes/two_blocks.py`: 13 slave
# segments against 10 master segments, non-matching nodes; frictionless normal compliance).
# The exact interface pressure is $p$ everywhere. The mortar pairing carries it exactly (to
# round-off); node to segment, which pairs each slave node with a point of the master,
# misses it by several percent where the two meshes' nodes are out of step.

# %%
PATCH = """
name = "patch"

[geometry]
type = "gmsh"
script = "two_blocks"
parameters = { h_slave = 0.077, h_master = 0.1 }

[material]
model = "plane_strain"
E = 1.0
nu = 0.3

[[dirichlet]]
boundary = "bottom"
components = [1]

[[dirichlet]]
boundary = "master_sides"
components = [0]

[[dirichlet]]
boundary = "slave_sides"
components = [0]

[[traction]]
boundary = "top"
value = [0.0, -0.01]

[contact]
boundary = "slave"
stiffness = 100.0

[obstacle]
shape = "body"
boundary = "master"

[time]
T = 1.0
steps = 1

[output]
probes = []
"""
path = folder / "patch.toml"
path.write_text(PATCH)
fig, ax = plt.subplots(figsize=(6, 3.5), dpi=110)
for pairing, marker in (("mortar", "o"), ("node_to_segment", "s")):
    run = solve(load_scene(path, contact={"pairing": pairing}))
    table = run.contact[-1]
    pressure = table["reaction_nu"] / 0.01
    ax.plot(table["x"][:, 0], pressure, marker + "-", label=pairing.replace("_", " "))
    print(f"{pairing}: interface pressure / p from {pressure.min():.4f} to "
          f"{pressure.max():.4f} (largest error {np.abs(pressure - 1).max():.1e})")
ax.axhline(1.0, color="k", lw=0.8, ls=":")
ax.set_xlabel("x along the interface")
ax.set_ylabel("pressure / p")
ax.legend()
fig.tight_layout()
plt.show()
