# ---
# jupyter:
#   jupytext:
#     text_representation:
#       extension: .py
#       format_name: percent
# ---

# %% [markdown]
# # The paper's test: a viscoelastic square on a layered foundation
#
# This demo reproduces section 4 of Y. Ouafik, *Numerical solution of a viscoelastic contact
# problem with normal compliance and unilateral constraint* (2024).
#
# A body $\Omega = (0,1)^2$ with long memory,
# $$\sigma = \mathcal{A}\varepsilon(u) + \int_0^t \mathcal{R}(t-s)\,\varepsilon(u(s))\,ds,
# \qquad \mathcal{R} = \alpha I,$$
# is clamped at $x = 0$, held by a roller ($u_x = 0$) at $x = 1$, loaded by
# $f_0 = (0,-10)$ and $f_N = (0,-20)$ on the top, and rests at $y = 0$ on a rigid foundation
# covered by a soft layer of thickness $g$:
# $$u_\nu \le g,\quad \sigma_\nu + p_\nu(u_\nu) \le 0,\quad
# (u_\nu - g)(\sigma_\nu + p_\nu(u_\nu)) = 0,\quad
# \|\sigma_\tau\| \le \mu\, p_\nu(u_\nu),\quad
# -\sigma_\tau = \mu\, p_\nu(u_\nu)\,\frac{u_\tau}{\|u_\tau\|}\ \text{if } u_\tau \ne 0,$$
# with $p_\nu(s) = c_\nu \max(0, s)$. While $0 < u_\nu < g$ the layer pushes back
# (normal compliance); at $u_\nu = g$ the rigid part adds what is needed (the bound).
#
# The scheme: eq. (19) for the memory integral (trapezoid rule with a left-point rule on the
# last sub-interval, so the history is known at each step), a penalty for the compliance, an
# augmented Lagrangian for the bound and for friction, and one generalized Newton method
# (PETSc SNES) at each time step. With the nodal contact quadrature the multipliers
# $\lambda_\nu, \lambda_\tau$ are eliminated node by node, so Newton's unknowns are the
# displacements alone (the condensed system; `solver.linear_system = "coupled"` keeps
# $(u, \lambda_\nu, \lambda_\tau)$ as unknowns). The first line of the run says which.

# %%
import pathlib

from mpi4py import MPI

from contactvisco import load_scene, quick, read_results, show_images, solve

# %% [markdown]
# ## The scene
# Every parameter lives in the built-in scene `paper` (a TOML file). The paper prints
# $g = -0.05$ while defining $g > 0$ as a thickness; the scene uses $g = 0.05$.

# %%
scene = load_scene("paper", output={"xdmf": not quick()})
for table in ("material", "memory", "contact", "time"):
    print(f"{table:9s}", scene[table])

# %% [markdown]
# ## The run
# P1 on a structured 32 x 32 mesh, $T = 1$, $k = 0.1$. Each line shows the Newton iterations
# and the number of contact nodes in each state.

# %%
out = pathlib.Path("results/demo_paper")
result = solve(scene, out, progress=True)

# %% [markdown]
# ## Zones at $T = 1$
# The paper reports a zone AB of 13 nodes in normal compliance and a zone BC of 19 nodes at
# the bound, all sliding. The node at $x = 0$ is clamped and carries no contact force.

# %%
counts = result.steps[-1]["status_counts"]
print(counts)
summary = read_results(out)      # summary.json with the step records of steps.jsonl
for step in (summary["steps"][1], summary["steps"][-1]):
    print(f"t = {step['t']:.1f}:", {tuple(p["x"]): round(p["u"][1], 5) for p in step["probes"]})

# %% [markdown]
# ## Figures 2-4 of the paper
# The deformed mesh at $t = 0.1$ and $t = 1$: the memory term stiffens the body, which
# recovers much of its shape under constant loads. Then the reactions and the displacements
# of the contact nodes at $T = 1$, with the zones shaded.

# %%
if MPI.COMM_WORLD.rank == 0:
    show_images(*(out / f"{name}.png" for name in ("deformed_mesh", "contact_reactions",
                                                   "contact_displacements", "stress")))
