"""Scene values that may depend on position and time.

A value is a number, or a string in `x` (the position, x[0], x[1], x[2]) and `t` (the time),
with the functions of NAMESPACE; a vector value is a list of such components. Constant values
become DOLFINx Constants (no recompilation when they change); expressions become UFL
expressions compiled into the forms, with `t` a Constant set at each step.

    value = [0.0, "-20 * min(t, 1)"]
    value = [0.0, "-50 * exp(-((x[0] - 0.2 - 0.6 * t) / 0.08)**2)"]
"""
from __future__ import annotations

import ast
import math
import numbers

import ufl
from dolfinx import fem
from petsc4py import PETSc

from . import compat
from .scene import SceneError

NAMESPACE = {
    "pi": math.pi, "e": math.e,
    "sin": ufl.sin, "cos": ufl.cos, "tan": ufl.tan, "exp": ufl.exp, "ln": ufl.ln,
    "log": ufl.ln, "sqrt": ufl.sqrt, "abs": abs, "atan2": compat.atan2,
    "min": ufl.min_value, "max": ufl.max_value, "conditional": ufl.conditional,
}


class Context:
    """Position and time symbols of one mesh; `t.value` is the current time."""

    def __init__(self, mesh):
        self.mesh = mesh
        self.x = ufl.SpatialCoordinate(mesh)
        self.t = fem.Constant(mesh, PETSc.ScalarType(0.0))

    def depends_on_time(self, value) -> bool:
        items = value if isinstance(value, (list, tuple)) else [value]
        return any(isinstance(v, str) and "t" in _names(v, "value") for v in items)

    def scalar(self, value, where: str):
        """A number -> Constant; a string -> UFL expression."""
        if isinstance(value, bool) or not isinstance(value, (numbers.Real, str)):
            raise SceneError(f"{where} must be a number or an expression string, got {value!r}")
        if isinstance(value, str):
            value = self._evaluate(value, where)
            if not isinstance(value, float):
                return value
        if not math.isfinite(value):
            raise SceneError(f"{where} must be finite, got {value}")
        return fem.Constant(self.mesh, PETSc.ScalarType(value))

    def vector(self, value, where: str, d: int):
        """A list of d numbers -> vector Constant; with any string -> UFL vector."""
        if not isinstance(value, (list, tuple)) or len(value) != d:
            raise SceneError(f"{where} must be a list of {d} components (the mesh is {d}D), "
                             f"got {value!r}")
        if all(isinstance(v, numbers.Real) and not isinstance(v, bool) for v in value):
            if not all(math.isfinite(v) for v in value):
                raise SceneError(f"{where} must be finite, got {value}")
            return fem.Constant(self.mesh, PETSc.ScalarType(tuple(float(v) for v in value)))
        return ufl.as_vector([self._evaluate(v, f"{where}[{i}]") if isinstance(v, str)
                              else self._number(v, f"{where}[{i}]")
                              for i, v in enumerate(value)])

    def _number(self, value, where):
        if isinstance(value, bool) or not isinstance(value, numbers.Real) \
                or not math.isfinite(value):
            raise SceneError(f"{where} must be a finite number or an expression, got {value!r}")
        return float(value)

    def _evaluate(self, text: str, where: str):
        unknown = _names(text, where) - set(NAMESPACE) - {"x", "t"}
        if unknown:
            raise SceneError(f"{where} = '{text}': unknown name(s) {', '.join(sorted(unknown))};"
                             f" allowed: x, t, {', '.join(sorted(NAMESPACE))}")
        try:
            result = eval(compile(text, where, "eval"), {"__builtins__": {}},
                          dict(NAMESPACE, x=self.x, t=self.t))
        except Exception as err:   # any error in a user expression is a scene error
            raise SceneError(f"{where} = '{text}' cannot be evaluated: {err}") from None
        if isinstance(result, numbers.Real):
            return float(result)
        if not isinstance(result, ufl.core.expr.Expr) or result.ufl_shape != ():
            raise SceneError(f"{where} = '{text}' must give a scalar")
        return result


def _names(text: str, where: str) -> set[str]:
    try:
        tree = ast.parse(text, mode="eval")
    except SyntaxError as err:
        raise SceneError(f"{where} = '{text}' is not a valid expression: {err.msg}") from None
    return {node.id for node in ast.walk(tree) if isinstance(node, ast.Name)}
