# ---
# jupyter:
#   jupytext:
#     text_representation:
#       extension: .py
#       format_name: percent
# ---

# %% [markdown]
# # Signorini contact with Coulomb friction: partial slip of a cylinder
#
# With `contact.friction_law = "coulomb"` the friction ball has the radius $\mu$ times the total
# normal pressure, $\mu\,(p_\nu(u_\nu) + R_\nu)$, instead of the paper's $\mu\,p_\nu(u_\nu)$.
# With $g = 0$ (no compliance layer) this is Signorini contact with Coulomb friction:
# $$s \le 0,\quad \sigma_\nu \le 0,\quad s\,\sigma_\nu = 0,\qquad
# |\sigma_\tau| \le -\mu\sigma_\nu,\quad
# \sigma_\tau = \mu\sigma_\nu \frac{\dot u_\tau}{|\dot u_\tau|} \text{ where it slips.}$$
# With `contact.slip = "increment"` the law acts on the slip of each step,
# $u_\tau - u_\tau(t_{n-1})$ (Coulomb's incremental law), rather than on the total $u_\tau$.
#
# A cylinder of radius $R$ (plane strain, on a rigid plane) is pressed by $P$ and then pulled
# by $Q < \mu P$. Cattaneo (1938) and Mindlin (1949): the contact stays stuck on a central
# zone of half-width
# $$c = a\sqrt{1 - \frac{Q}{\mu P}},$$
# where $a$ is Hertz's half-width, and the tangential traction is
# $$q(x) = \mu p_0\sqrt{1 - x^2/a^2} - [|x| < c]\,\mu p_0 \frac{c}{a}\sqrt{1 - x^2/c^2},
# \qquad p_0 = \frac{2P}{\pi a}.$$
# It holds when the normal and tangential problems do not couple (Dundurs' $\beta = 0$);
# against a rigid plane $\beta = (1 - 2\nu)/(2(1 - \nu))$, which vanishes only at
# $\nu = 1/2$. The run takes $\nu = 0.49$ ($\beta = 0.02$) and then $\nu = 0.3$ to show what the
# coupling does. The mesh is `meshes/half_disk.py` (the whole lower half: the pull breaks the
# symmetry); the top is clamped and moved by $(\delta t, -w)$, and $P$, $Q$ are the contact
# resultants.

# %%
from contactvisco import cattaneo_mindlin, cattaneo_traction, quick

h = 0.005 if quick() else 0.0025          # mesh size at the contact (a / 11 or a / 22)
results = {nu: cattaneo_mindlin(h, nu=nu) for nu in (0.49, 0.3)}
for nu, r in results.items():
    print(f"nu = {nu}: Q / (mu P) = {r['load_ratio']:.3f}, c / a = {r['c_h'] / r['a']:.3f} "
          f"(Cattaneo-Mindlin {r['c'] / r['a']:.3f}), stick zone centred at "
          f"{r['stick_centre']:+.2f} a, Newton iterations {r['newton']}")

# %% [markdown]
# ## Tangential traction and the stick zone
# Filled markers: nodes that stick; open markers: nodes that slip (there the traction is
# $\mu$ times the pressure to round-off); grey: separated nodes. The dashed line is $\mu p$
# of Hertz's pressure, the slip limit. At $\nu = 0.49$ the sticking nodes scatter about the
# closed form: P1 elements lock in nearly incompressible plane strain, and the nodal
# tractions of a sticking zone (reactions, not a law) show it.

# %%
from contactvisco import cattaneo_mindlin_figure, show_figure

show_figure(cattaneo_mindlin_figure(results, cattaneo_traction))

# %% [markdown]
# ## Against the closed form
# The stick half-width is taken midway between the last sticking node and the first sliding
# one. The transmitted force $\sum_{x_i \le x} w_i q_i$ is compared with the same sum of the
# closed form (relative to $Q$): the nodal tractions of P1 carry node-to-node noise at
# $\nu = 0.49$ (nearly incompressible plane strain locks), their partial sums much less.
# `benchmarks/accuracy/coulomb.py` refines the mesh to $a/44$.

# %%
for nu, r in results.items():
    print(f"nu = {nu}: c error {r['c_error']:.1%} of a, transmitted force error "
          f"{r['F_error']:.1%} of Q, pressure error {r['p_error']:.1%} of p0")
