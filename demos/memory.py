# ---
# jupyter:
#   jupytext:
#     text_representation:
#       extension: .py
#       format_name: percent
# ---

# %% [markdown]
# # The effect of memory
#
# The constitutive law has a long memory,
# $$\sigma(t) = \mathcal{A}\varepsilon(u(t)) + \int_0^t \mathcal{R}(t-s)\,\varepsilon(u(s))\,ds,
# \qquad \mathcal{R} = \alpha I .$$
# Under constant loads the memory term grows with time and stiffens the body, so the body
# recovers part of its shape and nodes leave the bound of the foundation. Here the paper's
# scene is solved for several $\alpha$, from $\alpha = 0$ (linear elasticity, no history
# stored at all) upward.

# %%
import matplotlib.pyplot as plt

from contactvisco import load_scene, quick, solve

alphas = [0.0, 100.0] if quick() else [0.0, 25.0, 50.0, 100.0, 200.0]
cells = 16 if quick() else 32

# %% [markdown]
# ## The runs
# With $\alpha = 0$ the history Function is not even built. Each line says whether it was
# built and gives the contact states at $T = 1$.

# %%
runs = {}
for alpha in alphas:
    memory = {"alpha": alpha} if alpha else {"alpha": alpha, "kernel": "none"}
    scene = load_scene("paper", geometry={"cells": [cells, cells]}, memory=memory,
                       output={"probes": [[0.5, 1.0]]})
    result = solve(scene)
    runs[alpha] = result
    print(f"alpha = {alpha:5.0f}: history built: {result.problem.memory is not None}, "
          f"final states {result.steps[-1]['status_counts']}")

# %% [markdown]
# ## Deflection of the top against time
# At $\alpha = 0$ nothing changes after $t = 0$; the larger $\alpha$, the faster the body
# stiffens. With the paper's time rule, $k = 0.1$ is stable up to
# $\alpha k (1+\nu)/E < 1$, i.e. $\alpha < 770$ here (a run warns beyond).

# %%
fig, ax = plt.subplots(figsize=(6.4, 4), dpi=130)     # dpi: legible inline
for alpha, result in runs.items():
    t = [s["t"] for s in result.steps]
    uy = [s["probes"][0]["u"][1] for s in result.steps]
    ax.plot(t, uy, "o-", ms=3, label=f"alpha = {alpha:g}")
ax.set_xlabel("t [s]")
ax.set_ylabel("$u_y$ at (0.5, 1) [m]")
ax.legend()
plt.show()
