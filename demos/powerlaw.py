# ---
# jupyter:
#   jupytext:
#     text_representation:
#       extension: .py
#       format_name: percent
# ---

# %% [markdown]
# # Power-law memory against exponential memory
#
# An exponential kernel forgets: $\int_0^\infty \alpha e^{-t/\tau}\,dt = \alpha\tau$ is finite,
# so under constant loads the history stress settles. A power-law kernel
# $$\mathcal{R}(t) = \alpha\,(1 + t/\tau)^{-\beta} I$$
# has a total weight that grows without bound for $\beta \le 1$: the body keeps stiffening.
# Here the paper's scene is run with both, the exponential one chosen to match the power law at
# $t = 0$ (the same $\alpha$) and at $t = 1$:
# $\alpha e^{-1/\tau_e} = \alpha (1 + 1/\tau)^{-\beta}$, i.e.
# $\tau_e = 1 / (\beta \log(1 + 1/\tau))$. Both cost O(1) per step: the power law runs as a sum
# of exponentials whose number and measured error the run prints.

# %%
import math

import matplotlib.pyplot as plt
import numpy as np

from contactvisco import load_scene, quick, solve

alpha, tau, beta = 100.0, 0.1, 0.5
tau_e = 1.0 / (beta * math.log(1.0 + 1.0 / tau))
T = 20.0
steps = 40 if quick() else 200
cells = 8 if quick() else 32
print(f"exponential kernel matching at t = 1: tau_e = {tau_e:.4f}")

# %% [markdown]
# ## The two kernels
# Equal at $t = 0$ and $t = 1$; by $t = 20$ the power law is still $\alpha/14$ while the
# exponential has fallen below $10^{-8}\alpha$.

# %%
t = np.geomspace(1e-3, T, 200)
fig, ax = plt.subplots(figsize=(6.4, 4), dpi=130)     # dpi: legible inline
ax.loglog(t, alpha * (1 + t / tau) ** -beta, label=fr"power, $\tau = {tau}$, $\beta = {beta}$")
ax.loglog(t, alpha * np.exp(-t / tau_e), label=fr"exponential, $\tau_e = {tau_e:.3f}$")
ax.axvline(1.0, color="gray", lw=0.8, ls=":")
ax.set_ylim(1e-3 * alpha, 2 * alpha)
ax.set_xlabel("t")
ax.set_ylabel("R(t)")
ax.legend()
plt.show()

# %% [markdown]
# ## The runs
# The paper's scene (plane stress, loads constant in time, normal compliance with a bound and
# friction) to $T = 20$, with the trapezoid rule.

# %%
kernels = {
    "power": {"kernel": "power", "alpha": alpha, "tau": tau, "beta": beta,
              "tolerance": 1e-6},
    "exponential": {"kernel": "exponential", "alpha": [alpha], "tau": [tau_e]},
}
runs = {}
for name, memory in kernels.items():
    scene = load_scene("paper", geometry={"cells": [cells, cells]},
                       time={"T": T, "steps": steps, "rule": "trapezoid"},
                       output={"probes": [[0.5, 1.0]]}, memory=memory)
    runs[name] = solve(scene)
    history = runs[name].problem.memory.history
    note = getattr(history, "note", f"{len(history.terms)} exponential term(s)")
    print(f"{name:12s} {note}")
    print(f"{'':12s} at t = {T:g}: {runs[name].steps[-1]['status_counts']}")

# %% [markdown]
# ## Contact zones against time
# Nodes in the bound (u_nu = g), in the compliant layer (0 < u_nu < g) and separated. With the
# exponential kernel the zones stop changing after a few tau_e; with the power law the memory
# keeps stiffening the body, its deflection keeps shrinking and nodes keep leaving the bound.

# %%
fig, axes = plt.subplots(1, 2, figsize=(11, 4), dpi=90)   # ~1000 px wide inline
for name, style in (("power", "-"), ("exponential", "--")):
    steps_ = runs[name].steps
    times = [s["t"] for s in steps_]
    for state, color in (("bound", "C3"), ("compliance", "C0"), ("separated", "C2")):
        axes[0].plot(times, [s["status_counts"][state] for s in steps_], style, color=color,
                     label=f"{state} ({name})")
    axes[1].plot(times, [-s["probes"][0]["u"][1] for s in steps_], style,
                 label=name)
axes[0].set_xscale("symlog", linthresh=0.5)
axes[0].set_xlabel("t")
axes[0].set_ylabel("contact nodes")
axes[0].legend(fontsize=7, ncol=2)
axes[1].set_xscale("symlog", linthresh=0.5)
axes[1].set_xlabel("t")
axes[1].set_ylabel("deflection of the top centre, -u_y(0.5, 1)")
axes[1].legend()
plt.show()

# %% [markdown]
# ## Numbers
# The states at a few times, and how much the deflection still changes over the last half of
# the run: near zero for the exponential kernel, clearly not for the power law.

# %%
for name in runs:
    steps_ = runs[name].steps
    picks = [steps_[0], steps_[len(steps_) // 8], steps_[len(steps_) // 2], steps_[-1]]
    print(name, "; ".join(f"t = {s['t']:g}: {s['status_counts']}" for s in picks))
    half, end = (-steps_[len(steps_) // 2]["probes"][0]["u"][1],
                 -steps_[-1]["probes"][0]["u"][1])
    print(f"{'':12s} deflection at T/2 {half:.5f}, at T {end:.5f}: change "
          f"{100 * (end - half) / half:+.2f} %")
