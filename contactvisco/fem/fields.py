"""Small tools of the discrete problem's fields and forms: a Constant of the mesh, a field
that follows a UFL value in time, a linear form's assembled node values, the vertex rule of
the contact quadrature and the mesh's length scale."""
from __future__ import annotations

import numpy as np
import ufl
from dolfinx import fem
from dolfinx.fem.petsc import assemble_vector
from mpi4py import MPI
from petsc4py import PETSc

from contactvisco.fem import compat


def scalar(mesh, value):
    """A Constant of the mesh with the value `value`."""
    return fem.Constant(mesh, PETSc.ScalarType(value))


def interpolator(function, value, space):
    """A callable that sets `function` to the UFL value or Constant `value`."""
    if isinstance(value, fem.Constant):
        return lambda: function.x.array.__setitem__(slice(None), value.value)
    if ufl.domain.extract_unique_domain(value) is None:
        # A value in t alone (e.g. [d * t, -w]) has no mesh: fem.Expression needs one. A zero
        # Constant times x gives it one (a float zero would be simplified away).
        x = ufl.SpatialCoordinate(space.mesh)
        zero = scalar(space.mesh, 0.0)
        value = value + zero * (x[0] if value.ufl_shape == ()
                                else ufl.as_vector([x[0]] * value.ufl_shape[0]))
    expression = compat.expression(value, space)
    return lambda: function.interpolate(expression)


def assembled_values(form) -> np.ndarray:
    """The assembled vector of a linear form at every local dof, ghosts included (their
    contributions summed on the owner, then sent back; collective). The PETSc vector is
    destroyed here: dropped on several ranks, it would wait for a collective clean-up."""
    vec = assemble_vector(form)
    vec.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
    vec.ghostUpdate(addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)
    with vec.localForm() as local:
        values = local.array.copy()
    vec.destroy()
    return values


def nodal_rule(d: int) -> dict:
    """Quadrature metadata for the vertex rule on a facet (trapezoid rule for intervals): the
    contact conditions then hold node by node. FFCx 0.5's own "vertex" rule fails on
    intervals, so the rule is given as a custom one (tuples keep the form signature exact)."""
    if d == 2:
        points, weights = ((0.0,), (1.0,)), (0.5, 0.5)
    else:
        points, weights = ((0.0, 0.0), (1.0, 0.0), (0.0, 1.0)), (1 / 6, 1 / 6, 1 / 6)
    return {"quadrature_rule": "custom", "quadrature_points": points,
            "quadrature_weights": weights}


def length_scale(mesh) -> float:
    """The largest extent of the mesh's bounding box (collective)."""
    d = mesh.geometry.dim
    x = mesh.geometry.x[:, :d]
    upper, lower = np.empty(d), np.empty(d)
    mesh.comm.Allreduce(x.max(axis=0), upper, op=MPI.MAX)
    mesh.comm.Allreduce(x.min(axis=0), lower, op=MPI.MIN)
    return float(np.max(upper - lower))
