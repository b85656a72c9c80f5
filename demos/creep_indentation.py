# ---
# jupyter:
#   jupytext:
#     text_representation:
#       extension: .py
#       format_name: percent
# ---

# %% [markdown]
# # Creep indentation: a cylinder under a constant force on a viscoelastic layer
#
# A rigid cylinder of radius $R$ is pushed into a layer $[0, 2] \times [0, 1]$ (plane strain,
# $E = 200$, $\nu = 0.3$, its top held) by a force $P$ per unit length, applied at $t = 0$ and
# then held. The cylinder is an obstacle under force control: its displacement $d$ is an
# unknown of each Newton step and the resultant of the contact pressure is $P$,
#
# ```toml
# [obstacle]
# shape = "cylinder"
# centre = [1.0, -1.0]
# radius = 1.0
# force_components = [1]
# force = [0.3]
# ```
#
# The layer's memory is one softening deviatoric term,
# $\sigma = A\varepsilon + \int_0^t \alpha e^{-(t-s)/\tau} \operatorname{dev}\varepsilon(s)\,ds$
# with $\alpha = -60$, $\tau = 1$: the shear modulus falls from $\mu$ to
# $\mu + \alpha\tau/2$, and the cylinder sinks while the contact widens.
#
# By the correspondence principle (Lee and Radok 1960), while the contact width does not
# decrease, Hertz's $a^2 = 4PR/(\pi E^*)$ holds with $1/E^*$ replaced by the creep compliance
# $C(t)$ of the plane-strain modulus,
# $$a(t)^2 = \frac{4PR}{\pi}\,C(t), \qquad C(t) = A_0 + A_1 e^{-\beta t},
# \qquad \beta = \frac{1}{\tau} + \frac{\alpha}{2\mu},$$
# with $A_0 + A_1 = 1/E^*$ (the derivation is in `contactvisco.LeeRadok`). The pressure is
# then a superposition of Hertz ellipses, and the width compared is that of its second moment,
# $a_m^2 = 4\int p\,x^2 / \int p$, the same moment of the closed form.
#
# The depth of a plane-strain cylinder has no closed form (2D Hertz has no local depth: it
# depends on the whole layer, and here on Poisson's ratio, which changes as the shear modulus
# relaxes). What is exact is its two ends: at $t = 0$ the elastic layer, and as
# $t \to \infty$ the elastic layer of the long-time constants.

# %%
import matplotlib.pyplot as plt
import numpy as np

from contactvisco import LeeRadok, creep_indentation, elastic_indentation, quick

E, nu, alpha, tau, P, R = 200.0, 0.3, -60.0, 1.0, 0.3, 1.0
h, steps, T = (0.01, 12, 6.0) if quick() else (0.005, 24, 6.0)
run = creep_indentation(h, steps, T=T, E=E, nu=nu, alpha=alpha, tau=tau, P=P, R=R)
exact = LeeRadok(E, nu, alpha, tau, P, R)
E_long, nu_long = exact.long_time()
start = elastic_indentation(h, E=E, nu=nu, P=P, R=R)
end = elastic_indentation(h, E=E_long, nu=nu_long, P=P, R=R)
print(f"contact mesh a/h = {run['a_exact'][0] / h:.1f}, {steps} steps on [0, {T:g}], "
      f"Newton iterations {run['newton']}")
print(f"long-time constants E = {E_long:.2f}, nu = {nu_long:.3f}; "
      f"creep time 1/beta = {1 / exact.beta:.2f}")
print(f"recorded force: {run['force'].min():.12f} to {run['force'].max():.12f} (P = {P})")

# %% [markdown]
# ## Width and depth against time
# Left: the width of the computed pressure's second moment (markers) against the same moment
# of Lee-Radok's pressure, and Lee-Radok's contact half-width $a(t)$ itself. Right: the
# cylinder's depth $d_y(t)$ between the elastic depths of the instantaneous and the
# long-time layer; the dashed line is a guide, not a closed form: the depth scaled like the
# compliance, $d_0 + (d_\infty - d_0)\,(C(t) - C(0))/(A_0 - C(0))$.

# %%
ts = np.linspace(0, T, 200)
fig, (left, right) = plt.subplots(1, 2, figsize=(10, 4), dpi=110)
left.plot(ts, [exact.moment_width(t) for t in ts], "k-", label="Lee-Radok, $a_m(t)$")
left.plot(ts, [exact.width(t) for t in ts], "k:", label="Lee-Radok, $a(t)$")
left.plot(run["t"], run["a_m"], "o", ms=5, label="contactvisco, $a_m$")
left.set_xlabel("t")
left.set_ylabel("contact half-width")
left.legend()
C = exact.compliance(ts)
C0 = float(exact.compliance(0.0))
guide = start["depth"] + (end["depth"] - start["depth"]) * (C - C0) / (exact.A0 - C0)
right.plot(ts, guide, "k--", lw=0.8, label="compliance-shaped guide")
right.axhline(start["depth"], color="grey", ls=":", label="elastic, t = 0")
right.axhline(end["depth"], color="grey", ls="-.", label=r"elastic, $t \to \infty$")
right.plot(run["t"], run["depth"], "o", ms=5, label="contactvisco, $d_y$")
right.set_xlabel("t")
right.set_ylabel("indentation depth")
right.legend()
fig.tight_layout()
plt.show()

# %% [markdown]
# ## The errors
# The width's error is the largest over the steps; the depth is compared at $t = 0$ with the
# elastic layer (the same discrete problem: round-off), and at $T$ with the long-time layer,
# which the compliance has reached but for $e^{-\beta T}$ of its course. What remains is the
# time step's error (trapezoid rule, $k = T/N$).

# %%
width_error = np.abs(run["a_m"] - run["a_m_exact"]) / run["a_m_exact"]
worst = run["t"][np.argmax(width_error)]
grown, grown_exact = (run[k][-1] / run[k][0] - 1 for k in ("a_m", "a_m_exact"))
print(f"width a_m: largest error {width_error.max():.2%} (at t = {worst:g}); "
      f"it grows by {grown:.1%} (Lee-Radok {grown_exact:.1%})")
print(f"long-time width: elastic layer {end['a_m']:.5f}, Lee-Radok "
      f"{np.sqrt(4 * P * R * exact.A0 / np.pi):.5f}")
creep = end["depth"] - start["depth"]
print(f"depth at t = 0: {run['depth'][0]:.6e}, elastic {start['depth']:.6e} "
      f"(difference {abs(run['depth'][0] - start['depth']) / start['depth']:.1e})")
print(f"depth at T: {run['depth'][-1]:.6e}, long-time {end['depth']:.6e}: the run has "
      f"{(run['depth'][-1] - start['depth']) / creep:.1%} of the creep, the compliance "
      f"{1 - np.exp(-exact.beta * T):.1%}")
shaped = start["depth"] + creep * (exact.compliance(run["t"]) - C0) / (exact.A0 - C0)
print(f"depth against the guide: largest difference "
      f"{np.max(np.abs(run['depth'] - shaped)) / creep:.1%} of the creep")
