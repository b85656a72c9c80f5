# ---
# jupyter:
#   jupytext:
#     text_representation:
#       extension: .py
#       format_name: percent
# ---

# %% [markdown]
# # The cheapest run that reaches a target
#
# `contactvisco tradeoff SCENE --target TOL` climbs a ladder of discretizations of a scene:
# mesh levels (1/4, 1/2, 1 and 2 times the scene's own mesh), at each level N/2, N and 2N time
# steps, and P2 below the top level. Each run's error is estimated against the finest run of
# the ladder, plus that run's own error by Richardson extrapolation, and the cheapest run
# whose estimate is below the target is recommended, as `--set` lines and as a scene file.
# Here the same is done from Python on the paper scene, for the contact pressure.

# %%
import matplotlib.pyplot as plt
from mpi4py import MPI

from contactvisco import quick, tradeoff

base = ["geometry.cells=[16,16]", "time.steps=4"] if quick() else []
levels = 3 if quick() else 4
target = 0.05
result = tradeoff.tradeoff("paper", target, base, measure="contact_pressure", levels=levels,
                           degrees=(1,) if quick() else (1, 2), comm=MPI.COMM_WORLD)
print("\n".join(tradeoff.summary_lines(result)))

# %% [markdown]
# ## Error against wall time
# Filled markers are on the Pareto front: no other run is both faster and more accurate.
# On this scene the mesh sets the error: at a given mesh the step counts lie on top of each
# other, so the front runs along the mesh levels at the fewest steps.

# %%
fig = plt.figure(dpi=130)     # dpi: legible inline
tradeoff.draw(result, fig)
plt.show()

# %% [markdown]
# ## Is the recommendation right?
# The recommended run against a reference finer than the whole ladder: one more mesh level
# and twice the largest step count.

# %%
if result["recommended"] is not None:
    reference = tradeoff.finer_reference("paper", base, levels, 0.25)
    check = tradeoff.verify("paper", base, result["recommended"]["set"], "contact_pressure",
                            reference)
    print(f"estimated {result['recommended']['estimated_error']:.3g}, measured against "
          f"{' '.join(reference)}: {check['error']:.3g} (target {target})")
