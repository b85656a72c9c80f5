# ---
# jupyter:
#   jupytext:
#     text_representation:
#       extension: .py
#       format_name: percent
# ---

# %% [markdown]
# # An asphalt mixture given by its published Prony series
#
# Asphalt mixtures and polymers are characterised by a generalized Maxwell model fitted to a
# relaxation test or to a DMA master curve, a Prony series
# $$E(t) = E_\infty + \sum_i E_i\, e^{-t/\tau_i}, \qquad E_i = g_i E(0),$$
# at a reference temperature $T_\mathrm{ref}$, with a shift function $a_T(\theta)$ for other
# temperatures (time-temperature superposition: every $\tau_i$ becomes $a_T \tau_i$). The
# `[viscoelastic]` table takes the material in this form and converts it exactly to the
# paper's law, $\sigma = \mathcal{A}\varepsilon(u(t)) + \int_0^t
# \mathcal{R}(t-s)\,\varepsilon(u(s))\,ds$ with $\mathcal{A} = E(0)$ and
# $\mathcal{R}(t) = E'(t)$ per part.
#
# **The series.** The asphalt mixture SBS-AC13 at 20 °C, $E(0) = 1550$ MPa, nine terms with
# $\tau_i = 10^{-5} \dots 10^{3}$ s, from "Multiple Reflective Cracks in Semirigid Base
# Asphalt Pavement under Traffic Load Using XFEM", Advances in Civil Engineering, vol. 2022,
# article ID 9405338 (Hindawi), Table 2 ("Prony parameters of each asphalt mixture",
# parameters at 20 °C). It lies beside this demo in `data/sbs_ac13_prony.csv` (a header,
# then $\tau_i$ [s] and $g_i$ per row), and the scene reads it with `file = ...`.
# $\sum_i g_i = 0.98627$, so $E_\infty = 0.01373\,E(0) = 21.3$ MPa.
#
# **What we assume.** The source gives the $g_i$ as relative moduli in the Abaqus
# convention (relative shear moduli, the same $g_i$ applied to the instantaneous modulus). We
# take them as normalized fractions of $E(t)$ with a constant Poisson ratio $\nu = 0.35$ (a
# usual value for asphalt concrete, not from the source): shear and bulk then relax
# together. The source gives no shift function: we use WLF,
# $\log_{10} a_T = -C_1 (\theta - T_\mathrm{ref}) / (C_2 + \theta - T_\mathrm{ref})$, with the
# "universal" constants $C_1 = 17.44$, $C_2 = 51.6$ K of Williams, Landel & Ferry (J. Am.
# Chem. Soc. 77 (1955) 3701) referred to $T_\mathrm{ref} = 20$ °C: an assumption for the
# illustration, not this mixture's measured shift. Units: mm, N, s, so stresses are in MPa.

# %%
import pathlib

import matplotlib.pyplot as plt
import numpy as np

from contactvisco import (SceneError, load_scene, quick, relaxation_figure, show_figure,
                          solve)

cells = 16 if quick() else 32
steps = 12 if quick() else 30      # over T = 60 s: k = 5 s, or 2 s
temperatures = [15.0, 25.0]        # 5 degrees below and above T_ref

# The Prony table beside this demo: a script knows its file; a notebook has none and runs
# in the folder it was started from, demos/ or the repository's root.
here = pathlib.Path(__file__).parent if "__file__" in globals() else pathlib.Path.cwd()
prony_csv = next(folder / "data" / "sbs_ac13_prony.csv"
                 for folder in (here, here / "demos")
                 if (folder / "data" / "sbs_ac13_prony.csv").is_file()).resolve()
print(prony_csv.read_text())

# %% [markdown]
# ## The scene
# The layout of the paper's square, scaled to a pavement: a 100 mm square of asphalt (plane
# stress), clamped on the left, on a roller on the right, under its weight (24 kN/m$^3$)
# and a tyre pressure of 0.7 MPa on top, resting on a compliant base with a reaction
# $p_\nu = 0.5$ MPa/mm $\times$ penetration, a bound $g = 0.5$ mm and friction $\mu = 0.2$.
# The geometry, loads and base are illustrative (chosen so that the contact zones change as
# the asphalt relaxes); the material is the published one. The material is stated in
# `[viscoelastic]` only (`material.E`, `nu` and `[memory]` are derived from it).
#
# **The time rule.** The fastest term has $\tau_1 = 10^{-5}$ s, so $|\mathcal{R}(0)| =
# \sum_i E_i/\tau_i \approx 5 \cdot 10^7$ MPa/s: the trapezoid rule's stiffness $E(0) +
# k/2\,\mathcal{R}(0)$ stays positive only for $k < 6 \cdot 10^{-5}$ s, and the paper's rule
# is stable only for $k < 10^{-5}$ s (its check $b = k |\mathcal{R}(0)| (1 + \nu)/E < 1$).
# `time.rule = "exponential"` integrates each term exactly against the strain taken linear
# over the step: its stiffness stays between $E_\infty$ and $E(0)$ for every step, and the
# run takes steps of seconds.

# %%
text = f"""name = "asphalt_on_a_base"

[geometry]
type = "box"
lower = [0.0, 0.0]
upper = [100.0, 100.0]
cells = [{cells}, {cells}]

[material]
model = "plane_stress"

[viscoelastic]
young = {{ instantaneous = 1550.0, file = "{prony_csv.as_posix()}", values = "fractions" }}
nu = 0.35
shift = "wlf"
T_ref = 20.0
C1 = 17.44
C2 = 51.6

[[dirichlet]]
boundary = "left"
components = "all"

[[dirichlet]]
boundary = "right"
components = [0]

[body_force]
value = [0.0, -2.4e-5]          # N/mm^3

[[traction]]
boundary = "top"
value = [0.0, -0.7]             # MPa

[contact]
boundary = "bottom"
stiffness = 0.5                 # MPa/mm
g = 0.5                         # mm
mu = 0.2

[time]
T = 60.0
steps = {steps}
rule = "exponential"

[units]
length = "mm"
force = "N"
time = "s"

[output]
probes = [[50.0, 100.0]]
"""
path = pathlib.Path("results/asphalt_on_a_base.toml")     # results/: ignored by git
path.parent.mkdir(parents=True, exist_ok=True)
path.write_text(text)
scene = load_scene(path)
print(f"A: E = {scene['material']['E']:.6g} MPa, nu = {scene['material']['nu']:.6g}")
print(f"R: {len(scene['memory']['terms'])} terms (deviatoric and volumetric), tau from "
      f"{min(t['tau'] for t in scene['memory']['terms']):g} to "
      f"{max(t['tau'] for t in scene['memory']['terms']):g} s")
try:
    load_scene(path, time={"rule": "trapezoid"})
except SceneError as error:
    print("time.rule = 'trapezoid':", error)

# %% [markdown]
# ## Relaxation modulus, storage and loss moduli at three temperatures
# $E(t)$ falls from $E(0) = 1550$ MPa to $E_\infty = 21.3$ MPa over eight decades of time; the
# storage modulus $E'(\omega) = E_\infty + \sum_i E_i \omega^2\tau_i^2/(1+\omega^2\tau_i^2)$
# rises between the same bounds and the loss modulus $E''(\omega) = \sum_i E_i
# \omega\tau_i/(1 + \omega^2\tau_i^2)$ is broad, one hump per decade. At 10 and 30 °C the
# curves at 20 °C move by $\log_{10} a_T = 4.19$ and $-2.83$ decades (the assumed WLF).

# %%
show_figure(relaxation_figure(scene, temperatures=[10.0, 30.0]))

# %% [markdown]
# ## The contact problem at two temperatures
# At $t = 0$ the asphalt answers with $E(0)$ and carries most of the load to its clamped
# side; as it relaxes it sinks into the base, which takes more of the load, and nodes reach
# the bound. At 25 °C ($a_T = 0.029$) nearly all of this happens within the first seconds; at
# 15 °C ($a_T = 74$) it goes on over the whole minute. The elastic constants do not depend
# on temperature, so both runs start from the same state.

# %%
runs = {}
for theta in temperatures:
    result = solve(load_scene(path, viscoelastic={"temperature": theta}))
    runs[theta] = result
    print(f"theta = {theta:g} C: Newton {[s['newton_iterations'] for s in result.steps]}")
    print(f"{'':13s}zones at t = 0: {result.steps[0]['status_counts']}, "
          f"at T: {result.steps[-1]['status_counts']}")

# %% [markdown]
# ## Zones and reactions against time
# Left: the number of contact nodes in each zone (in compliance, at the bound) against time.
# Middle: the resultant of the normal reaction on the contact boundary,
# $\sum_i w_i\, \mathrm{reaction}_\nu$ [N/mm, per mm of thickness], out of the 70.2 N/mm of
# load and weight; and the deflection of the top. Right: the normal reaction along the
# contact boundary at $T$.

# %%
fig, (zones, forces, profile) = plt.subplots(1, 3, figsize=(13, 3.8), dpi=110)
top = forces.twinx()
for j, (theta, result) in enumerate(runs.items()):
    t = [s["t"] for s in result.steps]
    style = {"color": f"C{j}", "ms": 3}
    for state, marker in (("compliance", "o-"), ("bound", "s--")):
        zones.plot(t, [s["status_counts"].get(state, 0) for s in result.steps], marker,
                   label=f"{state}, {theta:g} C", **style)
    resultant = [float(np.sum(table["weight"] * table["reaction_nu"]))
                 for table in result.contact]
    forces.plot(t, resultant, "o-", label=f"contact force, {theta:g} C", **style)
    top.plot(t, [s["probes"][0]["u"][1] for s in result.steps], "^:",
             label=f"$u_y$(50, 100), {theta:g} C", **style)
    final = result.contact[-1]
    profile.plot(final["x"][:, 0], final["reaction_nu"], "o-", label=f"{theta:g} C", **style)
zones.set_xlabel("t [s]")
zones.set_ylabel("contact nodes")
zones.legend(fontsize=7)
forces.set_xlabel("t [s]")
forces.set_ylabel("normal contact force [N/mm]")
top.set_ylabel("$u_y$ at (50, 100) [mm]")
lines = forces.get_legend_handles_labels(), top.get_legend_handles_labels()
forces.legend(lines[0][0] + lines[1][0], lines[0][1] + lines[1][1], fontsize=7,
              loc="center right", bbox_to_anchor=(1.0, 0.3))       # where the curves leave room
profile.set_xlabel("x [mm]")
profile.set_ylabel("normal reaction at T [MPa]")
profile.legend(fontsize=7)
plt.tight_layout()
plt.show()

# %%
for theta, result in runs.items():
    uy = [s["probes"][0]["u"][1] for s in result.steps]
    force = [float(np.sum(table["weight"] * table["reaction_nu"])) for table in result.contact]
    print(f"theta = {theta:g} C: the top sinks from {-uy[0]:.3f} to {-uy[-1]:.3f} mm, the "
          f"base carries {force[0]:.1f} then {force[-1]:.1f} N/mm")

# %% [markdown]
# The run at 15 °C is the 20 °C run on the time scale $t / a_T$: its minute is 0.8 s of the
# material at 20 °C, where $E \approx 66$ MPa; at 25 °C the minute is 35 min at 20 °C, where
# only $E_\infty$ and the slowest term remain. A temperature varying in $x$ and $t$
# (`viscoelastic.temperature = "20 + 0.1 * t"`) runs in the reduced time
# $\xi = \int_0^t ds / a_T(\theta)$ at each point, with the same rule.
