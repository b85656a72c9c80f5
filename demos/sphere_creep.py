# ---
# jupyter:
#   jupytext:
#     text_representation:
#       extension: .py
#       format_name: percent
# ---

# %% [markdown]
# # Sphere creep: a rigid sphere pressed into an axisymmetric viscoelastic block
#
# The built-in scene `sphere_creep` presses a rigid sphere ($R = 1$) with a force $P$ held from
# $t = 0$ into a block of revolution meshed in its meridian half-plane $(r, z)$
# (`material.model = "axisymmetric"`: the hoop strain $u_r/r$, every integral weighted by
# $2\pi r$, forces as totals over the full circle). The shear modulus relaxes to half its value
# (one deviatoric Prony term, $\tau = 1$), the bulk modulus stays. Lee and Radok's closed form
# (`docs/axisymmetric.md`) gives the contact radius and the depth,
# $$a(t)^3 = \tfrac34 R P\, C(t), \qquad \delta(t) = a(t)^2 / R,$$
# $C$ the creep function of Hertz's contact modulus, and at every time Hertz's pressure under
# the sphere for the current radius, $p(r) = p_0 \sqrt{1 - r^2/a^2}$, $p_0 = 3P/(2\pi a^2)$.
# We run to ten relaxation times, where $C$ has reached its long-time value.

# %%
import matplotlib.pyplot as plt
import numpy as np

from contactvisco import SphereLeeRadok, load_scene, quick, solve

steps = 10 if quick() else 40
scene = load_scene("sphere_creep", sets=["time.T=10.0", f"time.steps={steps}",
                                         "output.figures=false", "output.xdmf=false"])
result = solve(scene)

# %% [markdown]
# ## Creep depth and contact radius against the closed form
# The depth is the sphere's displacement under force control; the contact radius of the mesh
# is taken from the nodal forces $F_i$ (ring forces) as Hertz's moment
# $a_m^2 = \tfrac52 \sum_i F_i r_i^2 / P$, which equals $a$ for Hertz's pressure.

# %%
P = -scene["obstacle"]["force"][0]
R = scene["obstacle"]["radius"]
shear = scene["viscoelastic"]["shear"]
closed = SphereLeeRadok(scene["material"]["E"], scene["material"]["nu"],
                        -2.0 * shear["fractions"][0] * shear["instantaneous"],
                        shear["tau"][0], R)
t = np.array([step["t"] for step in result.steps])
depth = -np.array([step["obstacle"]["displacement"][1] for step in result.steps])


def moment_radius(table):
    force = table["reaction_nu"] * table["weight"]
    return np.sqrt(2.5 * np.sum(force * table["x"][:, 0] ** 2) / np.sum(force))


radius = np.array([moment_radius(table) for table in result.contact])
ts = np.linspace(0.0, t[-1], 200)
fig, (left, right) = plt.subplots(1, 2, figsize=(10, 3.8), dpi=130)
left.plot(ts, closed.radius(P, ts) ** 2 / R, "k-", label="Lee-Radok")
left.plot(t, depth, "o", ms=4, label="contactvisco")
left.set_xlabel("t / tau")
left.set_ylabel("depth delta")
left.legend()
right.plot(ts, closed.radius(P, ts), "k-", label="Lee-Radok")
right.plot(t, radius, "o", ms=4, label="contactvisco (a_m)")
right.set_xlabel("t / tau")
right.set_ylabel("contact radius a")
right.legend()
plt.tight_layout()
plt.show()
exact = closed.radius(P, t) ** 2 / R
print(f"creep ratio delta(T)/delta(0): {depth[-1] / depth[0]:.4f} "
      f"(closed form {exact[-1] / exact[0]:.4f})")
print(f"depth error: {np.max(np.abs(depth / exact - 1)):.2%} at most "
      f"(the exact sphere against Hertz's paraboloid: about 0.18 a/R, and the mesh)")

# %% [markdown]
# ## The pressure under the sphere at t = 0+ and at long times
# Both against Hertz's ellipse of the closed-form radius at that time: the pressure spreads
# over a wider contact and its peak falls as $a^{-2}$.

# %%
fig, ax = plt.subplots(figsize=(6.4, 4), dpi=130)
for index, label in ((0, "t = 0+"), (-1, f"t = {t[-1]:g}")):
    table = result.contact[index]
    r, p = table["x"][:, 0], table["reaction_nu"]
    a = float(np.ravel(closed.radius(P, t[index]))[0])
    p0 = 3 * P / (2 * np.pi * a * a)
    rs = np.linspace(0.0, a, 200)
    line, = ax.plot(rs, p0 * np.sqrt(1 - (rs / a) ** 2), "-", label=f"Hertz, {label}")
    near = r < 1.6 * a
    ax.plot(r[near], p[near], "o", ms=3, color=line.get_color(), label=f"contactvisco, {label}")
    print(f"{label}: a = {a:.4f}, peak {p[np.argmin(r)]:.4f} against Hertz's p0 = {p0:.4f}")
ax.set_xlabel("r")
ax.set_ylabel("contact pressure")
ax.legend()
plt.show()
