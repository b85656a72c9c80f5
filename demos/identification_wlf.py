# ---
# jupyter:
#   jupytext:
#     text_representation:
#       extension: .py
#       format_name: percent
# ---

# %% [markdown]
# # Identifying WLF constants with the moduli from creep at two temperatures
#
# Time-temperature superposition: at a temperature $T$ the material relaxes as at the
# reference $T_\mathrm{ref}$ with its times scaled by the shift $a_T$, by Williams, Landel and
# Ferry's law
# $$\log_{10} a_T = -\frac{C_1 (T - T_\mathrm{ref})}{C_2 + T - T_\mathrm{ref}}.$$
# A rigid sphere creeps into the axisymmetric block of the built-in scene `sphere_creep`
# (coarse mesh; shear modulus $G(t) = \mu_0 (1 - g (1 - e^{-t/\tau}))$, $\tau = 1$ at
# $T_\mathrm{ref} = 50$) under a held force, at $T = 42$ and $T = 58$: the same material
# creeps about 2000 times slower at the first and 200 times faster at the second, so the
# samples run on a logarithmic grid from $10^{-3}$ to $10^4$. From
# both curves (synthetic, by the forward model, 1 % noise) `contactvisco.fit` identifies
# $C_1$, $C_2$, $\mu_0$ and $g$ together; the sensitivities run through the shift
# (docs/identification.md).

# %%
import csv
import pathlib

import numpy as np

from contactvisco import fit, load_scene, show_images, solve

COARSE = ("geometry.parameters={radius = 10.0, height = 10.0, h_contact = 0.04, "
          "h_far = 3.0, refine = 0.3, growth = 0.15}")
C1, C2, MU0, FRACTION = 17.44, 51.6, 0.38461538461538464, 0.5
SHIFT = ['viscoelastic.shift="wlf"', "viscoelastic.T_ref=50.0"]
times = [float(f"{t:.3g}") for t in np.geomspace(1e-3, 1e4, 15)]
temperatures = (42.0, 58.0)
folder = pathlib.Path("identification_wlf_demo")
folder.mkdir(exist_ok=True)
rng = np.random.default_rng(3)
sigma = {}
for T in temperatures:
    scene = load_scene("sphere_creep", sets=[
        COARSE, *SHIFT, f"viscoelastic.C1={C1!r}", f"viscoelastic.C2={C2!r}",
        f"viscoelastic.temperature={T!r}", 'time.grid="times"', f"time.times={times}",
        "time.T=1e4", "output.figures=false", "output.xdmf=false",
        "output.checkpoint=false"])
    result = solve(scene)
    t = np.array([s["t"] for s in result.steps])
    force = np.array([s["obstacle"]["force"][1] for s in result.steps])
    depth = -np.array([s["obstacle"]["displacement"][1] for s in result.steps])
    sigma[T] = float(0.01 * np.mean(depth))                # 1 % noise
    noisy = depth + sigma[T] * rng.standard_normal(t.size)
    with open(folder / f"creep_{T:g}.csv", "w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(["t", "force", "depth"])
        writer.writerows([repr(float(a)), repr(float(b)), repr(float(c))]
                         for a, b, c in zip(t, force, noisy))
    print(f"T = {T:g}: depth from {depth[0]:.4f} to {depth[-1]:.4f}, sigma = {sigma[T]:.2g}")

# %% [markdown]
# ## The fit description
# One experiment per temperature (its temperature a fixed change of the scene; the scene's
# C1 and C2 are the fitted ones, set at their start), the WLF constants and the moduli
# started 20-30 % off.

# %%
experiments = "".join(
    f'[[experiment]]\nscene = "sphere_creep"\ndata = "creep_{T:g}.csv"\n'
    f"set = ['{COARSE}', " + ", ".join(f"'{s}'" for s in SHIFT)
    + f", 'viscoelastic.temperature={T!r}', 'viscoelastic.C1=13.0', 'viscoelastic.C2=65.0']"
    f"\nnoise = {sigma[T]!r}\n\n" for T in temperatures)
parameters = """[[parameter]]
key = "viscoelastic.C1"
initial = 13.0
bounds = [5.0, 40.0]

[[parameter]]
key = "viscoelastic.C2"
initial = 65.0
bounds = [20.0, 200.0]

[[parameter]]
key = "viscoelastic.shear.instantaneous"
initial = 0.3
bounds = [0.1, 1.0]
scale = "log"

[[parameter]]
key = "viscoelastic.shear.fractions.0"
initial = 0.4
bounds = [0.1, 0.8]
"""
(folder / "fit.toml").write_text(experiments + parameters)
print((folder / "fit.toml").read_text())

# %%
report = fit(folder / "fit.toml", out=folder / "out")
print(f"{report['evaluations']} forward runs, {report['wall_s']:.1f} s, "
      f"s^2 = {report['s2']:.2f}")
for p, true in zip(report["parameters"], (C1, C2, MU0, FRACTION)):
    lo, hi = p["interval"]
    print(f"{p['key']:34s} true {true:8.4f}  fit {p['estimate']:8.4f}  95 % interval "
          f"[{lo:.4f}, {hi:.4f}]  {'contains' if lo <= true <= hi else 'MISSES'} the truth")
for warning in report["warnings"]:
    print("warning:", warning)
for T in temperatures:
    dT = T - 50.0
    fitted = -report["parameters"][0]["estimate"] * dT / (report["parameters"][1]["estimate"]
                                                          + dT)
    print(f"log10 a_T at T = {T:g}: true {-C1 * dT / (C2 + dT):+.4f}, fitted {fitted:+.4f}")

# %% [markdown]
# Two temperatures fix two values of $\log_{10} a_T$, so $C_1$ and $C_2$ are determined, but
# along a narrow valley: a larger $C_1$ with a larger $C_2$ gives nearly the same two shifts.
# Their correlation (below) shows it, and their intervals are much wider than those of the
# moduli; more temperatures, or temperatures farther apart, narrow them.

# %%
show_images(*(folder / "out" / f"{stem}.png"
              for stem in ("fit", "fit_moduli", "fit_correlation")))
