# ---
# jupyter:
#   jupytext:
#     text_representation:
#       extension: .py
#       format_name: percent
# ---

# %% [markdown]
# # Identifying a Prony series from creep and relaxation indentation
#
# A rigid sphere ($R = 1$) indents an axisymmetric block (the built-in scene `sphere_creep`
# on a coarse mesh) whose shear modulus relaxes with three Prony terms,
# $$G(t) = \mu_0 \Big(1 - \sum_{i=1}^{3} g_i \big(1 - e^{-t/\tau_i}\big)\Big),
# \qquad \tau_i = 0.1,\ 1,\ 10,$$
# with $\mu_0 = 0.3846$ and $g = (0.2, 0.3, 0.2)$, and an elastic bulk modulus. Two
# synthetic experiments are made by the forward model itself, each with 1 % Gaussian noise:
# **creep** (a force held from $t = 0$, the depth measured) and **relaxation** (a depth held
# from $t = 0$, the force measured). `contactvisco.fit` then identifies $\mu_0$ and the three
# fractions (the relaxation times fixed on their grid) by weighted least squares with the
# contact solver in the loop (docs/identification.md): Jacobians from forward sensitivities,
# the start from Lee and Radok's closed form for the creep curve, 95 % intervals from the
# covariance $s^2 (J^T J)^{-1}$.

# %%
import csv
import pathlib

import numpy as np

from contactvisco import fit, load_scene, show_images, solve

COARSE = ("geometry.parameters={radius = 10.0, height = 10.0, h_contact = 0.04, "
          "h_far = 3.0, refine = 0.3, growth = 0.15}")
MU0, TAUS, FRACTIONS = 0.38461538461538464, [0.1, 1.0, 10.0], [0.2, 0.3, 0.2]
SHEAR = (f"viscoelastic.shear={{instantaneous = {MU0!r}, tau = {TAUS}, "
         f"fractions = {FRACTIONS}}}")
times = [0.05, 0.1, 0.2, 0.5, 1.0, 2.0, 5.0, 10.0, 20.0, 40.0]
common = [COARSE, SHEAR, 'time.grid="times"', f"time.times={times}", "time.T=40.0",
          "output.figures=false", "output.xdmf=false", "output.checkpoint=false"]
held_depth = ["obstacle.force_components=[]", "obstacle.force=[]",
              "obstacle.displacement=[0.0, -0.012]"]
creep = solve(load_scene("sphere_creep", sets=common))
relaxation = solve(load_scene("sphere_creep", sets=common + held_depth))

folder = pathlib.Path("identification_demo")
folder.mkdir(exist_ok=True)
rng = np.random.default_rng(2)
sigma = {}
for name, result in (("creep", creep), ("relaxation", relaxation)):
    t = np.array([s["t"] for s in result.steps])
    force = np.array([s["obstacle"]["force"][1] for s in result.steps])
    depth = -np.array([s["obstacle"]["displacement"][1] for s in result.steps])
    measured = depth if name == "creep" else force
    sigma[name] = float(0.01 * np.mean(np.abs(measured)))    # 1 % noise
    noisy = measured + sigma[name] * rng.standard_normal(t.size)
    with open(folder / f"{name}.csv", "w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(["t", "force", "depth"])
        for row in zip(t, noisy if name == "relaxation" else force,
                       noisy if name == "creep" else depth):
            writer.writerow([repr(float(v)) for v in row])
    print(f"{name}: {t.size} samples, noise sigma = {sigma[name]:.3g}")

# %% [markdown]
# ## The fit description
# One experiment per curve, each with its noise level as weight ($w_e = 1/\sigma_e$); the
# relaxation experiment is driven by its measured depth (`control = "depth"`) and fits the
# force. $\mu_0$ is fitted in log scale; each fraction starts from the closed-form fit of the
# creep curve.

# %%
experiments = "".join(
    f'[[experiment]]\nscene = "sphere_creep"\ndata = "{name}.csv"\n'
    f"set = ['{COARSE}', '{SHEAR}']\nnoise = {sigma[name]!r}\n"
    + ('control = "depth"\n' if name == "relaxation" else "") + "\n"
    for name in ("creep", "relaxation"))
parameters = ('[[parameter]]\nkey = "viscoelastic.shear.instantaneous"\n'
              'initial = "closed-form"\nbounds = [0.1, 1.0]\nscale = "log"\n\n' + "".join(
                  f'[[parameter]]\nkey = "viscoelastic.shear.fractions.{i}"\n'
                  f'initial = "closed-form"\nbounds = [0.02, 0.45]\n\n' for i in range(3)))
(folder / "fit.toml").write_text(experiments + parameters)
print((folder / "fit.toml").read_text())

# %%
report = fit(folder / "fit.toml", out=folder / "out")
truth = [MU0, *FRACTIONS]
print(f"{report['evaluations']} forward runs, {report['wall_s']:.1f} s, s^2 = "
      f"{report['s2']:.2f} (near 1: the model fits to the noise)")
print(f"{'parameter':36s} {'true':>8s} {'closed form':>11s} {'FE fit':>8s} "
      f"{'95 % interval':>20s}")
for p, true in zip(report["parameters"], truth):
    lo, hi = p["interval"]
    inside = "yes" if lo <= true <= hi else "NO"
    print(f"{p['key']:36s} {true:8.4f} {p['closed_form']:11.4f} {p['estimate']:8.4f} "
          f"[{lo:.4f}, {hi:.4f}] {inside}")
for warning in report["warnings"]:
    print("warning:", warning)

# %% [markdown]
# ## The figures of the fit
# Drawn from the output folder: the curves (data, the FE fit, the closed-form fit of the
# creep curve and the residuals), the shear relaxation modulus $G(t)$ with its 95 % band
# (the covariance propagated through $G$ linearly, $\operatorname{var} G(t) = g^T C_x g$,
# $g = \partial G(t) / \partial x$) and the correlation matrix of the parameters.

# %%
show_images(*(folder / "out" / f"{stem}.png"
              for stem in ("fit", "fit_moduli", "fit_correlation")))
