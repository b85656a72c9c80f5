# ---
# jupyter:
#   jupytext:
#     text_representation:
#       extension: .py
#       format_name: percent
# ---

# %% [markdown]
# # A polymer given by its relaxation modulus
#
# Polymers are characterised by a generalized Maxwell model fitted to a relaxation test or to
# a DMA master curve, a Prony series
# $$E(t) = E_\infty + \sum_i E_i\, e^{-t/\tau_i}, \qquad E_i = g_i E(0),$$
# at a reference temperature $T_\mathrm{ref}$, with a shift function $a_T(\theta)$ for other
# temperatures (time-temperature superposition: every $\tau_i$ becomes $a_T \tau_i$; here
# WLF, $\log_{10} a_T = -C_1 (\theta - T_\mathrm{ref}) / (C_2 + \theta - T_\mathrm{ref})$).
# The `[viscoelastic]` table takes the material in this form and converts it exactly to the
# paper's law, $\sigma = \mathcal{A}\varepsilon(u(t)) + \int_0^t
# \mathcal{R}(t-s)\,\varepsilon(u(s))\,ds$ with $\mathcal{A} = E(0)$ and
# $\mathcal{R}(t) = E'(t)$ per part.
#
# **The numbers are illustrative, not a measured material**: three terms,
# $g = (0.25, 0.2, 0.15)$ at $\tau = (0.5, 2, 10)$ s and $E(0) = 100$ N/m$^2$ (the paper's
# $E$), $\nu = 0.3$ constant, and the WLF constants $C_1 = 17.44$, $C_2 = 51.6$ with
# $T_\mathrm{ref} = 50$, chosen so that the relaxation falls within the paper's time interval.
# For a real polymer put the $(\tau_i, g_i)$ of its fit in a CSV file
# (`young = { instantaneous = ..., file = "prony.csv", values = "fractions" }`) and its shift
# function (WLF, Arrhenius or a table of $\log_{10} a_T$, `shift = "table"`).

# %%
import pathlib

import matplotlib.pyplot as plt
import numpy as np

from contactvisco import load_scene, quick, relaxation_figure, show_figure, solve

cells = 16 if quick() else 32
steps = 10 if quick() else 20
temperatures = [50.0, 53.0]          # T_ref, and 3 degrees above it

# %% [markdown]
# ## The scene
# The paper's square (plane stress, clamped on the left, a roller on the right, pressed by its
# weight and a load on top onto a compliant layer of thickness $g$ with friction), with the
# constant kernel of the paper replaced by the polymer: the material is stated in
# `[viscoelastic]` only (`material.E`, `nu` and `[memory]` are derived from it). The trapezoid
# rule is the time rule that stays stable when $a_T < 1$ shortens the relaxation times.

# %%
text = f"""name = "polymer_on_a_layer"

[geometry]
type = "box"
lower = [0.0, 0.0]
upper = [1.0, 1.0]
cells = [{cells}, {cells}]

[material]
model = "plane_stress"

[viscoelastic]
young = {{ instantaneous = 100.0, tau = [0.5, 2.0, 10.0], fractions = [0.25, 0.2, 0.15] }}
nu = 0.3
shift = "wlf"
T_ref = 50.0
C1 = 17.44
C2 = 51.6

[[dirichlet]]
boundary = "left"
components = "all"

[[dirichlet]]
boundary = "right"
components = [0]

[body_force]
value = [0.0, -10.0]

[[traction]]
boundary = "top"
value = [0.0, -20.0]

[contact]
boundary = "bottom"
stiffness = 100.0
g = 0.05
mu = 0.2

[time]
T = 1.0
steps = {steps}
rule = "trapezoid"

[units]
length = "m"
force = "N"
time = "s"

[output]
probes = [[0.5, 1.0]]
"""
path = pathlib.Path("results/polymer_on_a_layer.toml")     # results/: ignored by git
path.parent.mkdir(parents=True, exist_ok=True)
path.write_text(text)
scene = load_scene(path)
print(f"A: E = {scene['material']['E']:.6g}, nu = {scene['material']['nu']:.6g}")
for term in scene["memory"]["terms"]:
    print(f"R += {term['alpha']:.6g} exp(-t/{term['tau']:g}) {term['part']}")

# %% [markdown]
# ## Relaxation modulus, master curve, storage and loss moduli
# $E(t)$ falls from $E(0) = 100$ to $E_\infty = 40$; the storage modulus
# $E'(\omega) = E_\infty + \sum_i E_i \omega^2\tau_i^2/(1+\omega^2\tau_i^2)$ rises between
# the same bounds and the loss modulus $E''(\omega) = \sum_i E_i \omega\tau_i/(1 +
# \omega^2\tau_i^2)$ peaks near $1/\tau_i$. At 45 and 55 degrees the master curve is the one
# at $T_\mathrm{ref}$ shifted by $\log_{10} a_T$ along the log-time (log-frequency) axis.

# %%
show_figure(relaxation_figure(scene, temperatures=[45.0, 55.0]))

# %% [markdown]
# ## The contact problem at two temperatures
# At $\theta = 53$, $a_T = 10^{-0.96} = 0.11$: the material relaxes nine times faster, so
# the square sinks further into the layer and more nodes reach the bound. The elastic
# constants do not depend on temperature, so both runs start from the same state at $t = 0$.

# %%
runs = {}
for theta in temperatures:
    result = solve(load_scene(path, viscoelastic={"temperature": theta}))
    runs[theta] = result
    print(f"theta = {theta:g}: Newton {[s['newton_iterations'] for s in result.steps]}")
    print(f"{'':13s}zones at t = 0: {result.steps[0]['status_counts']}, "
          f"at T: {result.steps[-1]['status_counts']}")

# %% [markdown]
# ## Zones and reactions against time
# Left: the number of contact nodes in each zone (in compliance, at the bound) against time.
# Middle: the resultant of the normal reaction on the contact boundary,
# $\sum_i w_i\, \mathrm{reaction}_\nu$, which grows as the softening body passes more of
# its load to the layer rather than to the clamped side; and the deflection of the top.
# Right: the normal reaction along the contact boundary at $T$.

# %%
fig, (zones, forces, profile) = plt.subplots(1, 3, figsize=(13, 3.8), dpi=110)
top = forces.twinx()
for j, (theta, result) in enumerate(runs.items()):
    t = [s["t"] for s in result.steps]
    style = {"color": f"C{j}", "ms": 3}
    for state, marker in (("compliance", "o-"), ("bound", "s--")):
        zones.plot(t, [s["status_counts"].get(state, 0) for s in result.steps], marker,
                   label=f"{state}, theta = {theta:g}", **style)
    resultant = [float(np.sum(table["weight"] * table["reaction_nu"]))
                 for table in result.contact]
    forces.plot(t, resultant, "o-", label=f"contact force, theta = {theta:g}", **style)
    top.plot(t, [s["probes"][0]["u"][1] for s in result.steps], "^:",
             label=f"$u_y$(0.5, 1), theta = {theta:g}", **style)
    final = result.contact[-1]
    profile.plot(final["x"][:, 0], final["reaction_nu"], "o-", label=f"theta = {theta:g}",
                 **style)
zones.set_xlabel("t [s]")
zones.set_ylabel("contact nodes")
zones.legend(fontsize=7)
forces.set_xlabel("t [s]")
forces.set_ylabel("normal contact force [N/m]")
top.set_ylabel("$u_y$ at (0.5, 1) [m]")
forces.legend(loc="upper left", fontsize=7)
top.legend(loc="lower right", fontsize=7)
profile.set_xlabel("x [m]")
profile.set_ylabel("normal reaction at T [N/m$^2$]")
profile.legend(fontsize=7)
plt.tight_layout()
plt.show()

# %%
for theta, result in runs.items():
    uy = [s["probes"][0]["u"][1] for s in result.steps]
    print(f"theta = {theta:g}: the top sinks by {uy[0] - uy[-1]:.4f} m after t = 0")

# %% [markdown]
# At $T_\mathrm{ref}$ the modulus has fallen to $E(1\,\mathrm{s}) = 69$ (the term of
# $\tau = 0.5$ s has relaxed by 86 %, the slower ones by 39 % and 10 %); three degrees higher,
# with $\tau_i a_T = (0.055, 0.22, 1.1)$ s, to $46$, near $E_\infty = 40$: the top sinks
# several times further after $t = 0$ and the bound zone grows. A run at a constant $\theta$ is the $T_\mathrm{ref}$ run on the time scale
# $t / a_T$ (checked to round-off in the tests); a temperature varying in $x$ and $t$
# (`viscoelastic.temperature = "50 + 2 * t"`) runs in the reduced time
# $\xi = \int_0^t ds / a_T(\theta)$ at each point.
