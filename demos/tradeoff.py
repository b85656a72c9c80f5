# ---
# jupyter:
#   jupytext:
#     text_representation:
#       extension: .py
#       format_name: percent
#   kernelspec:
#     display_name: Python 3
#     language: python
#     name: python3
# ---

# %% [markdown]
# # Speed against accuracy on the paper scene
#
# How much does a finer mesh or a smaller time step buy? Each run below measures the error of
# the contact-boundary displacement at $T = 1$ against the finest run, and the wall time of its
# time steps. `benchmarks/tradeoff.py` runs the full grid (up to 128 x 128, P2, both time rules)
# that the presets `fast`, `balanced` and `accurate` were chosen from.

# %%
import matplotlib.pyplot as plt
import numpy as np

from contactvisco import load_scene, quick, solve

meshes = [8, 16, 32] if quick() else [16, 32, 64]
step_counts = [10, 40]


def run(cells, steps, rule="trapezoid"):
    scene = load_scene("paper", geometry={"cells": [cells, cells]},
                       time={"steps": steps, "rule": rule}, output={"probes": []})
    result = solve(scene)
    table = result.contact[-1]
    return {"x": table["x"][:, 0], "u_nu": table["u_nu"], "u_tau": table["u_tau"],
            "s": sum(s["wall_s"] for s in result.steps),
            "newton": np.mean([s["newton_iterations"] for s in result.steps])}


# %%
reference = run(2 * meshes[-1], 40)
rows = []
for cells in meshes:
    for steps in step_counts:
        r = run(cells, steps)
        scale = np.max(np.abs(reference["u_nu"]))
        error = max(np.max(np.abs(r[k] - np.interp(r["x"], reference["x"], reference[k])))
                    for k in ("u_nu", "u_tau")) / scale
        rows.append((cells, steps, error, r["s"], r["newton"]))
        print(f"{cells:4d} cells, {steps:3d} steps: error {error:.2e}, "
              f"{r['s']:.2f} s, {r['newton']:.2f} Newton iterations per step")

# %% [markdown]
# ## Error against time
# Refining the mesh buys accuracy; more steps do not, at these sizes. At the scene's own
# $k = 0.1$ the time error is 20 to 50 times below the space error, which is why no preset
# refines time.

# %%
fig, ax = plt.subplots(figsize=(6.4, 4))
for steps, marker in zip(step_counts, "os"):
    pts = [(s, e) for c, n, e, s, _ in rows if n == steps]
    ax.loglog([p[0] for p in pts], [p[1] for p in pts], marker + "-", label=f"{steps} steps")
for c, n, e, s, _ in rows:
    if n == step_counts[0]:
        ax.annotate(f"{c}x{c}", (s, e), fontsize=8, xytext=(4, 4), textcoords="offset points")
ax.set_xlabel("wall time of the time steps [s]")
ax.set_ylabel("relative error on the contact boundary")
ax.legend()
plt.show()
