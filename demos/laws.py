# ---
# jupyter:
#   jupytext:
#     text_representation:
#       extension: .py
#       format_name: percent
# ---

# %% [markdown]
# # The paper's model with general laws
#
# The paper states its contact conditions for prescribed functions: $p_\nu$ and $p_\tau$ are
# non-negative and vanish for a negative argument (eq 3), and the friction at the bound is
# $F_b = p_\tau(g)$. Its test takes the linear case $p_\nu(s) = c_\nu s_+$,
# $p_\tau = \mu\, p_\nu$. Here the same scene runs with
#
# * a power-law compliance $p_\nu(s) = c\, s_+^{1.5}$, as for a rough surface, with $c$ chosen
#   so that $p_\nu(g)$ is the linear law's $c_\nu g = 5$;
# * a friction bound that saturates, $p_\tau = 0.2 \min(p_\nu, 2.5)$;
# * and then a body that stiffens with strain: Hencky's law
#   $\sigma = K \operatorname{tr}\varepsilon\, I + 2\mu\,\psi\, \operatorname{dev}\varepsilon$,
#   $\psi = (1 + |\operatorname{dev}\varepsilon|^2/e_0^2)^m$ (the memory term stays linear).
#
# The laws are scene keys: `contact.p_nu` and `contact.p_tau` are expressions in the
# penetration `s` (and `p_nu`), `material.law = "hencky"` takes `hencky_exponent` and
# `hencky_strain`.

# %%
import matplotlib.pyplot as plt
import numpy as np

from contactvisco import load_scene, quick, solve

cells = 16 if quick() else 32
c = 5.0 / 0.05**1.5
general = {"stiffness": 0.0, "mu": 0.0, "p_nu": f"{c:.6g} * s**1.5",
           "p_tau": "0.2 * min(p_nu, 2.5)"}
cases = {
    "linear (the paper's)": {},
    "power-law p_nu, saturating p_tau": {"contact": general},
    "the same, Hencky m = 1": {"contact": general,
                               "material": {"law": "hencky", "hencky_exponent": 1.0,
                                            "hencky_strain": 0.02}},
}

# %% [markdown]
# ## The runs
# Each line gives the Newton iterations per step and the contact zones at $T = 1$.

# %%
runs = {}
for name, overrides in cases.items():
    scene = load_scene("paper", geometry={"cells": [cells, cells]}, output={"probes": []},
                       **overrides)
    result = solve(scene)
    runs[name] = result
    print(f"{name:34s} Newton {[s['newton_iterations'] for s in result.steps]}")
    print(f"{'':34s} zones {result.steps[-1]['status_counts']}")

# %% [markdown]
# ## The laws and the reactions at $T = 1$
# Left, the two laws as the contact table reports them at the nodes (the compliance pressure
# against the penetration, the friction bound). Right, the normal and tangential reactions
# along the contact boundary. The power law lies below the linear one for $0 < s < g$ (they
# meet at $g$), so the layer gives way more before the bound; the saturated friction bound
# caps the tangential reaction at $0.2 \times 2.5 = 0.5$, also at the bound, where
# $F_b = p_\tau(g)$.

# %%
fig, (left, right) = plt.subplots(1, 2, figsize=(11, 4), dpi=110)
for name, result in runs.items():
    table = result.contact[-1]
    order = np.argsort(table["penetration"])
    left.plot(table["penetration"][order], table["p_nu"][order], ".-", label=f"p_nu, {name}")
    left.plot(table["penetration"][order], table["radius"][order], ":", label=f"bound, {name}")
    right.plot(table["x"][:, 0], table["reaction_nu"], "o-", ms=3, label=f"normal, {name}")
    right.plot(table["x"][:, 0], -table["reaction_tau"], "s--", ms=3,
               label=f"tangential, {name}")
left.set_xlabel("penetration s [m]")
left.set_ylabel("pressure [N/m]")
left.legend(fontsize=7)
right.set_xlabel("x [m]")
right.set_ylabel("reaction [N/m]")
right.legend(fontsize=7)
plt.tight_layout()
plt.show()

# %% [markdown]
# ## Where the Hencky material stands
# With a nonlinear A every accepted step records the smallest eigenvalue of its tangent
# $\partial^2 W/\partial\varepsilon^2$ over $2\mu$ (`tangent_min`): 1 for the linear law, above
# 1 where this law has stiffened; a value $\le 0$ would be reported as a loss of convexity.

# %%
hencky = runs["the same, Hencky m = 1"]
print("tangent_min per step:", [round(s["tangent_min"], 4) for s in hencky.steps])
