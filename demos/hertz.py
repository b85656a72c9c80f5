# ---
# jupyter:
#   jupytext:
#     text_representation:
#       extension: .py
#       format_name: percent
# ---

# %% [markdown]
# # Hertz contact: a cylinder on a rigid foundation
#
# With $g = 0$ the layer has no thickness and the contact law is pure Signorini,
# $s = u_\nu - h \le 0$, $\sigma_\nu \le 0$, $s\,\sigma_\nu = 0$, where $h(x) = x_1$ is the
# initial gap of the circular profile. For a cylinder of radius $R$ under a load $P$ per unit
# length (plane strain), Hertz's theory gives the half-width and the pressure
# $$a = \sqrt{\frac{4PR}{\pi E^*}}, \qquad p(x) = p_0\sqrt{1 - x^2/a^2},
# \qquad p_0 = \frac{2P}{\pi a}, \qquad E^* = \frac{E}{1-\nu^2}.$$
# A quarter of the section is modelled (mesh from `meshes/quarter_disk.py`, refined near the
# contact point).

# %%
import matplotlib.pyplot as plt
import numpy as np

from contactvisco import hertz, load_scene, quick, solve

scene = load_scene("hertz", preset="fast" if quick() else None)
print(scene["geometry"]["parameters"])
result = solve(scene)

# %% [markdown]
# ## Pressure along the contact boundary

# %%
E, nu = scene["material"]["E"], scene["material"]["nu"]
R, q = 1.0, -scene["traction"][0]["value"][1]
P = 2 * q * R
a = np.sqrt(4 * P * R / (np.pi * E / (1 - nu**2)))
p0 = 2 * P / (np.pi * a)
table = result.contact[-1]
x, p = table["x"][:, 0], table["reaction_nu"]
near = x < 2 * a
fig, ax = plt.subplots(figsize=(6.4, 4), dpi=130)     # dpi: legible inline
xs = np.linspace(0, a, 200)
ax.plot(xs, p0 * np.sqrt(1 - (xs / a) ** 2), "k-", label="Hertz")
ax.plot(x[near], p[near], "o", ms=4, label="contactvisco (nodal pressure)")
ax.axvline(a, color="k", ls=":", lw=0.8)
ax.set_xlabel("x")
ax.set_ylabel("contact pressure")
ax.legend()
plt.show()

# %% [markdown]
# ## Against the closed form
# The half-width is taken midway between the last node in contact and the next; the pressure
# at the centre is the nodal value. `benchmarks/accuracy/verification.py` refines the contact mesh.

# %%
summary = hertz(scene=scene)
print(f"a  = {summary['a']:.4f} (Hertz {summary['a_exact']:.4f}, error {summary['a_error']:.1%})")
print(f"p0 = {summary['p0']:.3f} (Hertz {summary['p0_exact']:.3f}, "
      f"error {summary['p0_error']:.2%})")
