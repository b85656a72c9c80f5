"""The memory part of eq (19) on a mesh: the history integrator of the scene's kernel, the
history stress H it sets (a known DG field), the strain it commits and the implicit weights
of the trapezoid rule (or of product integration) in the stress."""
from __future__ import annotations

from dataclasses import dataclass

import ufl
from dolfinx import fem

from contactvisco.fem import compat
from contactvisco.fem.fields import scalar
from contactvisco.fem.kinematics import kinematics
from contactvisco.fem.temperature import reduced_range, reduced_time_history
from contactvisco.model import kernels
from contactvisco.model import time_grid
from contactvisco.model.memory import DirectHistory, History, table_kernel
from contactvisco.model.memory_kernel import memory_power, memory_table, memory_terms


@dataclass(frozen=True)
class MemoryPart:
    """The history of eq (19): the integrator, the history stress H it sets (a known DG
    field), eps(u) interpolated for its commits, and the (Constant, part) weights of the
    implicit term of the trapezoid rule."""
    history: History
    H: fem.Function
    eps_function: fem.Function
    eps_expression: fem.Expression
    tensor_space: fem.FunctionSpace
    implicit_terms: list
    constants: dict                            # memory_implicit_<part>


def build_memory(scene, mesh, u, context=None, updates=None, kin=None) -> MemoryPart | None:
    """The history of eq (19) (None without memory): H, a known DG field, and for the
    trapezoid rule the implicit weights w of w P eps(u) (w = k/2 R(0), or the
    product-integration weight of the fractional kernel: history.implicit), as Constants
    that are zero at t_0, where there is no history yet; prepare(k) sets them."""
    terms, table, power = memory_terms(scene), memory_table(scene), memory_power(scene)
    if not terms and table is None and power is None:
        return None
    time = scene["time"]
    dt = float(time_grid.steps(time).max())      # the uniform step of `advance` (tests)
    kin = kin or kinematics(scene, mesh)
    d = kin.tensor_dim                          # the strain's: 3 in axisymmetry
    tensor_space = kin.tensor_space("DG", kin.history_degree(scene["discretization"]["degree"]))
    visco = scene.get("viscoelastic")
    thermal = visco is not None and visco["temperature"] is not None
    if table is not None:
        history = DirectHistory(table_kernel(*table), dt, time["rule"])
    elif power is not None:
        least, span = reduced_range(scene, mesh, context) if thermal else (1.0, None)
        history = kernels.history(power, time, scene["solver"]["max_cuts"], d, span=span,
                                  least=least)
    else:
        history = History(terms, dt, time["rule"], d)
    if thermal:
        reduced, weights = reduced_time_history(scene, mesh, history, context, updates, kin)
        return memory_part(reduced, weights, kin.strain(u), tensor_space)
    weights = {part: scalar(mesh, 0.0) for part in history.implicit(dt)}
    return memory_part(history, weights, kin.strain(u), tensor_space)


def memory_part(history, weights, eps, tensor_space) -> MemoryPart:
    """The MemoryPart of a history whose implicit weights (by part) are the Constants or
    point fields `weights`, of the strain eps(u) (UFL)."""
    return MemoryPart(
        history=history, H=fem.Function(tensor_space, name="history_stress"),
        eps_function=fem.Function(tensor_space),
        eps_expression=compat.expression(eps, tensor_space),
        tensor_space=tensor_space,
        constants={f"memory_implicit_{part}": c for part, c in weights.items()},
        implicit_terms=[(c, part) for part, c in weights.items()])


def strain_part(eps, part):
    """The part of the strain eps a memory term acts on: full, deviatoric or volumetric
    (tr(eps)/d I, d the dimension of the strain tensor: 3 for an axisymmetric body)."""
    d = eps.ufl_shape[0]
    if part == "deviatoric":
        return ufl.dev(eps)
    if part == "volumetric":
        return ufl.tr(eps) / d * ufl.Identity(d)
    return eps
