"""A temperature in the memory of eq (19): the temperature field at the stress's points, the
reduced time xi = int 1/a_T(theta) dt that the history advances in, the range of reduced time a
fitted kernel must cover, and the checks of the shift a_T between and at the step times
(contactvisco.model.viscoelastic)."""
from __future__ import annotations

import numpy as np
from dolfinx import fem
from mpi4py import MPI

from contactvisco.errors import SceneError
from contactvisco.fem import compat
from contactvisco.fem.fields import interpolator
from contactvisco.model import time_grid
from contactvisco.model.memory import (FractionalHistory, ReducedFractionalHistory,
                                       ReducedTimeHistory)


def temperature_field(scene, mesh, context):
    """The temperature as a DG field at the stress's points: (space, Function, a callable
    that interpolates viscoelastic.temperature at the context's time)."""
    scalars = compat.scalar_space(mesh, "DG", scene["discretization"]["degree"] - 1)
    theta = fem.Function(scalars, name="temperature")
    follow = interpolator(theta, context.scalar(scene["viscoelastic"]["temperature"],
                                                 "viscoelastic.temperature"), scalars)
    return scalars, theta, follow


#: Margin of the reduced-time span of a fitted kernel over its bound from the step times.
SPAN_MARGIN = 1.1


def reduced_range(scene, mesh, context) -> tuple[float, float]:
    """(least, span) that the fit of a power or fractional kernel must cover in reduced time:
    the reduced end time xi(T) (the span) and the least 1/a_T, which scales the shortest
    reduced step (least k / 2^max_cuts). At a constant temperature, 1/a_T and T / a_T (exactly
    the T_ref run of T / a_T); for an expression, over the points and the step times
    t_n of the grid, min(1, 1/a_T) / SPAN_MARGIN and SPAN_MARGIN T max(1, 1/a_T) (xi(T) <=
    T max 1/a_T; the run stops if a step would pass the span)."""
    from contactvisco.model.viscoelastic import inverse_shift, log10_shift
    visco, T = scene["viscoelastic"], scene["time"]["T"]
    theta = visco["temperature"]
    if isinstance(theta, (int, float)) and not isinstance(theta, bool):
        inverse = 10.0 ** -float(log10_shift(visco, theta))
        return inverse, T * inverse
    _, field, follow = temperature_field(scene, mesh, context)
    start, least, largest = float(context.t.value), 1.0, 1.0
    for t in time_grid.times(scene["time"]):
        context.t.value = t
        follow()
        inverse, error = inverse_shift(visco, field.x.array)
        if error is None and inverse.size:     # an error stops the run at its step
            least = min(least, float(inverse.min()))
            largest = max(largest, float(inverse.max()))
    context.t.value = start
    return (mesh.comm.allreduce(least, op=MPI.MIN) / SPAN_MARGIN,
            SPAN_MARGIN * T * mesh.comm.allreduce(largest, op=MPI.MAX))


def reduced_time_history(scene, mesh, history, context, updates, kin):
    """The history of a scene with a temperature: the Prony history advanced in reduced
    time (ReducedTimeHistory), 1/a_T(theta) taken at each point whenever the time moves
    (a callable added to `updates`), and the implicit weights as fields (one value per point).
    Returns the reduced history and its weights by part."""
    from contactvisco.model.viscoelastic import inverse_shift
    d = kin.tensor_dim
    fractional = isinstance(history, FractionalHistory)
    reduced = (ReducedFractionalHistory if fractional else ReducedTimeHistory)(history, d * d)
    visco = scene["viscoelastic"]
    scalars, theta, follow = temperature_field(scene, mesh, context)
    reduced.owned = scalars.dofmap.index_map.size_local    # points of this rank (then ghosts)
    span = getattr(history, "span", None)
    dt = float(time_grid.steps(scene["time"]).max())     # the largest step of the grid
    staged = []                                 # the last staged time (none yet)
    moving = context.depends_on_time(visco["temperature"])

    def stage():
        owned = reduced.owned                   # ghosts: taken along, never an error
        now = float(context.t.value)
        error = (_between_steps(visco, theta, follow, context, staged[0], now, owned)
                 if moving and staged else None)
        staged[:] = [now]
        follow()
        inverse, at_time = inverse_shift(visco, theta.x.array[:owned])
        if error is None and at_time:
            error = (f"{_at_point(at_time, visco, theta.x.array[:owned], scalars)} "
                     f"(at t = {now:g})")
        elif error is None and span is not None and reduced.reduced_time is not None and owned:
            # a step (at most dt) from the committed state: xi_n + dt max 1/a_T bounds xi_n+1
            reach = float(np.max(reduced.reduced_time[:owned]
                                 + dt * np.maximum(reduced.committed[:owned], inverse)))
            if reach > span * (1.0 + 1e-9):
                error = (f"viscoelastic.temperature: the reduced time would reach {reach:.6g}, "
                         f"beyond {span:.6g}, the span of the kernel's sum of exponentials "
                         f"(fitted from the temperature at the step times) (at t = {now:g})")
        inverse = np.concatenate([inverse, inverse_shift(visco, theta.x.array[owned:])[0]])
        error = next((e for e in mesh.comm.allgather(error) if e), None)   # every rank stops
        if error:
            raise SceneError(error, key="viscoelastic.temperature")
        reduced.stage(inverse, theta.x.array)

    updates.append(stage)
    weights = {part: fem.Function(scalars) for part in reduced.implicit(0.0)}
    return reduced, weights


#: The times inside a step at which a temperature in t is checked against its shift's range.
BETWEEN_STEPS = 16


def _between_steps(visco, theta, follow, context, before: float, now: float, owned: int):
    """Why the shift cannot be taken at a time strictly between two staged times (WLF's
    C2 + T - T_ref crossing zero inside a step, which the step times alone do not see): the
    temperature at BETWEEN_STEPS times inside the interval, at this rank's points; None if
    none. The reduced time integrates 1/a_T over the whole step."""
    from contactvisco.model.viscoelastic import inverse_shift
    error = None
    for j in range(1, BETWEEN_STEPS + 1):
        context.t.value = before + (now - before) * j / (BETWEEN_STEPS + 1)
        follow()
        _, error = inverse_shift(visco, theta.x.array[:owned])
        if error:
            error = (f"{_at_point(error, visco, theta.x.array[:owned], theta.function_space)}"
                     f" (at t = {float(context.t.value):g}, between the step times "
                     f"{before:g} and {now:g})")
            break
    context.t.value = now
    return error


def _at_point(error: str, visco, values, space) -> str:
    """The shift error with the point where it arises (its coordinates)."""
    from contactvisco.model.viscoelastic import first_error_point, shift_error
    i = first_error_point(visco, values)
    if i is None:
        return error
    error = shift_error(visco, values[i])
    x = space.tabulate_dof_coordinates()[i]
    where = ", ".join(f"{c:.6g}" for c in x[:space.mesh.geometry.dim])
    return f"{error} at the point x = ({where})"
