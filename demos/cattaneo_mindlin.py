# ---
# jupyter:
#   jupytext:
#     text_representation:
#       extension: .py
#       format_name: percent
# ---

# %% [markdown]
# # Cattaneo-Mindlin through a force-controlled plane
#
# Cattaneo's (1938) and Mindlin's (1949) experiment as written: a cylinder of radius $R = 1$
# (plane strain, $E = 200$) is pressed onto a rigid plane by a normal force $P$ without
# friction, then the plane pulls it sideways by a tangential force $Q < \mu P$ with friction
# $\mu = 0.3$ while $P$ is held. The plane is an obstacle under force control in both
# components (its displacement $d$ is an unknown of each Newton step), and the friction
# coefficient is an expression in $t$:
#
# ```toml
# [contact]
# friction_law = "coulomb"
# slip = "increment"
# mu = "conditional(t <= 0.5, 0.0, 0.3)"
#
# [obstacle]
# shape = "plane"
# point = [0.0, 0.0]
# normal = [0.0, 1.0]
# force_components = [0, 1]
# force = ["Q * max(2 * t - 1, 0)", "P * min(2 * t, 1)"]
# ```
#
# Step 1 ($t = 1/2$) presses, step 2 ($t = 1$) pulls. While there is no friction, nothing
# resists a tangential move of the plane, and the force asked there is zero: the plane's
# tangential position, which changes nothing, is held where Newton's first iterate leaves it. The contact normal and the friction plane are the plane's own, not the cylinder's.
#
# With Hertz's half-width $a = \sqrt{4PR/(\pi E^*)}$ and $p_0 = 2P/(\pi a)$, the contact
# sticks on a central zone of half-width
# $$c = a\sqrt{1 - \frac{Q}{\mu P}},$$
# and the tangential traction is
# $$q(x) = \mu p_0\sqrt{1 - x^2/a^2} - [|x| < c]\,\mu p_0 \frac{c}{a}\sqrt{1 - x^2/c^2}.$$
# It assumes that the normal and tangential problems do not couple: Dundurs' constant against
# a rigid plane, $\beta = (1 - 2\nu)/(2(1 - \nu))$, vanishes only at $\nu = 1/2$. The runs take
# $\nu = 0.49$ ($\beta = 0.0098$) and $\nu = 0.3$ ($\beta = 0.29$). Pressed without friction,
# the coupling of $\nu = 0.3$ has no inward slip to leave behind; only the pull's small change
# of the pressure remains, which moves the stick zone off the centre by a few per cent of $a$.

# %%
import matplotlib.pyplot as plt
import numpy as np

from contactvisco import cattaneo_mindlin, cattaneo_obstacle_scene, cattaneo_traction, quick

h = 0.005 if quick() else 0.0025           # mesh size at the contact (a / 11 or a / 22)
P, Q, mu = 0.632, 0.0839, 0.3
results = {}
for nu in (0.49, 0.3):
    raw = cattaneo_obstacle_scene(h, P, Q, nu=nu, mu=mu, frictionless_pressing=True)
    results[nu] = cattaneo_mindlin(h, raw=raw)
for nu, r in results.items():
    print(f"nu = {nu}: P = {r['P']:.6f}, Q = {r['Q']:.6f}, Q / (mu P) = {r['load_ratio']:.3f}, "
          f"a / h = {r['a_over_h']:.1f}, Newton iterations {r['newton']}")

# %% [markdown]
# ## The tangential traction and the stick zone
# Filled markers: nodes that stick; open markers: nodes that slip, where the traction is the
# bound $\mu p$; the dashed line is $\mu p_0\sqrt{1 - x^2/a^2}$, the bound of Hertz's pressure.
# The dotted lines mark the closed form's $\pm c$.

# %%
fig, axes = plt.subplots(1, 2, figsize=(11, 4), dpi=110, sharey=True)
for ax, (nu, r) in zip(axes, results.items()):
    a, c, p0 = r["a"], r["c"], r["p0"]
    xs = np.linspace(-a, a, 400)
    ax.plot(xs / a, cattaneo_traction(xs, a, c, p0, mu) / (mu * p0), "k-",
            label="Cattaneo-Mindlin")
    ax.plot(xs / a, np.sqrt(1 - (xs / a) ** 2), "k--", lw=0.8, label=r"$\mu p$ (Hertz)")
    x, q, stick = r["x"] / a, r["q"] / (mu * p0), r["stick"]
    ax.plot(x[stick], q[stick], "o", ms=5, color="C0", label="stick")
    ax.plot(x[~stick], q[~stick], "o", ms=5, mfc="none", color="C1", label="slip or separated")
    for sign in (-1, 1):
        ax.axvline(sign * c / a, color="k", ls=":", lw=0.8)
    ax.set_xlim(-1.4, 1.4)
    ax.set_title(f"nu = {nu}")
    ax.set_xlabel("x / a")
axes[0].set_ylabel(r"$q / (\mu p_0)$")
axes[0].legend(fontsize=8)
fig.tight_layout()
plt.show()

# %% [markdown]
# ## Against the closed form
# The stick half-width is read midway between the last sticking node and the first sliding
# one, so its error is about half a mesh size ($h/a$ = 9 % at $a/h = 11$). The nodal
# tractions of P1 in nearly incompressible plane strain carry node-to-node noise; the force
# transmitted left of $x$, $\sum_{x_i \le x} w_i q_i$, against the same sum of the closed
# form (relative to $Q$), shows the profile without it.

# %%
for nu, r in results.items():
    print(f"nu = {nu}: c / a = {r['c_h'] / r['a']:.3f} (closed form {r['c'] / r['a']:.3f}, "
          f"error {r['c_error']:.1%} of a), stick zone centred at {r['stick_centre']:+.3f} a")
    print(f"          traction: largest nodal error {r['q_error']:.1%} of mu p0, L2 error "
          f"{r['q_error_l2']:.1%}, transmitted force error {r['F_error']:.1%} of Q")
