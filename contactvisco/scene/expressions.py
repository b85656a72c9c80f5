"""Scene values that may depend on position and time.

A value is a number, or a string in `x` (the position, x[0], x[1], x[2]) and `t` (the time),
with the CONSTANTS and FUNCTIONS below; a vector value is a list of such components. Constant
values become DOLFINx Constants (no recompilation when they change); expressions become UFL
expressions compiled into the forms, with `t` a Constant set at each step.

    value = [0.0, "-20 * min(t, 1)"]
    value = [0.0, "-50 * exp(-((x[0] - 0.2 - 0.6 * t) / 0.08)**2)"]

An expression is data, never code: its syntax tree is walked node by node against a whitelist
(numbers, x[i] with a literal index, t, + - * / ** and unary -, comparisons inside
conditional, the constants and functions below) and nothing else is ever evaluated; no
attribute, no other subscript or call. The text is at most MAX_LENGTH characters and the tree
at most MAX_DEPTH levels deep.

Some keys allow more variables than x and t, each a plain name given by the caller (the
penetration `s` of contact.p_nu, the invariants of the strain in material.energy): they are
data in the same way and add no other syntax. The same walk computes a value from floats
(value_at), which the scene checks use to sample such a function before any mesh exists.
"""
from __future__ import annotations

import ast
import math
import numbers
import operator

import ufl

from contactvisco.errors import SceneError
from contactvisco.scene.limits import MODULUS_RANGE

#: UFL's two-argument arctangent (ufl.atan_2 before UFL 2023).
_ATAN2 = getattr(ufl, "atan2", None) or getattr(ufl, "atan_2")

#: Constants and functions an expression may use, with the number of arguments of each.
CONSTANTS = {"pi": math.pi, "e": math.e}
FUNCTIONS = {
    "sin": (ufl.sin, 1), "cos": (ufl.cos, 1), "tan": (ufl.tan, 1), "exp": (ufl.exp, 1),
    "ln": (ufl.ln, 1), "log": (ufl.ln, 1), "sqrt": (ufl.sqrt, 1), "abs": (abs, 1),
    "atan2": (_ATAN2, 2), "min": (ufl.min_value, 2), "max": (ufl.max_value, 2),
    "conditional": (ufl.conditional, 3),
}
#: The same functions on plain numbers: a constant sub-expression is computed once, and
#: overflow, division by zero or a domain error is caught when the scene is loaded.
FLOAT_FUNCTIONS = {"sin": math.sin, "cos": math.cos, "tan": math.tan, "exp": math.exp,
                   "ln": math.log, "log": math.log, "sqrt": math.sqrt, "abs": abs,
                   "atan2": math.atan2, "min": min, "max": max}

#: Longest expression text and deepest expression tree accepted.
MAX_LENGTH = 1000
MAX_DEPTH = 50

_BINARY = {ast.Add: operator.add, ast.Sub: operator.sub, ast.Mult: operator.mul,
           ast.Div: operator.truediv, ast.Pow: operator.pow}
_COMPARE = {ast.Lt: ufl.lt, ast.LtE: ufl.le, ast.Gt: ufl.gt, ast.GtE: ufl.ge,
            ast.Eq: ufl.eq, ast.NotEq: ufl.ne}
_COMPARE_FLOAT = {ast.Lt: operator.lt, ast.LtE: operator.le, ast.Gt: operator.gt,
                  ast.GtE: operator.ge, ast.Eq: operator.eq, ast.NotEq: operator.ne}


def allowed(d: int = 3, names=()) -> str:
    """What an expression may contain (for error messages); names: the further variables."""
    xs = ", ".join(f"x[{i}]" for i in range(d)) + "".join(f", {name}" for name in names)
    functions = ", ".join(f"{name}({arity} args)" if arity > 1 else name
                          for name, (_, arity) in FUNCTIONS.items())
    return (f"allowed: numbers, {xs}, t, + - * / ** and unary -, comparisons < <= > >= == != "
            f"(with and, or, not) as the first argument of conditional, the constants "
            f"{', '.join(CONSTANTS)} and the functions {functions}")


def parse(text: str, where: str, d: int = 3, names=()) -> ast.Expression:
    """The syntax tree of an expression text, checked against the whitelist of node types
    (see :func:`allowed`; `names` the further variables allowed) without evaluating
    anything; a SceneError names what is refused."""
    if not isinstance(text, str):
        raise SceneError(f"{where} must be a number or an expression string, got {text!r}",
                         key=where)
    if len(text) > MAX_LENGTH:
        raise SceneError(f"{where}: the expression has {len(text)} characters; at most "
                         f"{MAX_LENGTH} are allowed", key=where)
    try:
        tree = ast.parse(text, mode="eval")
    except SyntaxError as err:
        raise SceneError(f"{where} = '{text}' is not a valid expression: {err.msg}",
                         key=where) from None
    except (RecursionError, MemoryError, ValueError):
        raise SceneError(f"{where}: the expression is nested too deeply (at most {MAX_DEPTH} "
                         "levels)", key=where) from None
    _Walker(text, where, d, None, dict.fromkeys(names)).value(tree.body, 0)
    return tree


def evaluate(text: str, where: str, x, t, d: int, names=None):
    """The value of an expression: a float when it depends on neither x nor t (nor the
    further variables), else a UFL expression in the SpatialCoordinate x, the Constant t and
    the UFL values of `names` (a dict: variable name -> value)."""
    names = names or {}
    tree = parse(text, where, d, tuple(names))
    return _Walker(text, where, d, (x, t), names).value(tree.body, 0)


def value_at(text: str, where: str, d: int, x, t: float, names=None) -> float:
    """The value of an expression on numbers: x a sequence of d floats, t a float, `names`
    a dict of further variables -> float. Overflow, a domain error or a complex value is a
    SceneError naming `where`."""
    names = {key: float(value) for key, value in (names or {}).items()}
    tree = parse(text, where, d, tuple(names))
    point = tuple(float(c) for c in x)
    return float(_Walker(text, where, d, (point, float(t)), names).value(tree.body, 0))


class _Walker:
    """Walks an expression tree, refusing every node type that is not on the whitelist. With
    symbols = (x, t) it builds the value; with None it checks, computing only the constant
    sub-expressions (None stands for a value that depends on x or t).

    It is longer than most classes here because the whitelist is the class: one short method
    per accepted node type, so that what an expression may contain is read in one place."""

    def __init__(self, text, where, d, symbols, names=None):
        self.text, self.where, self.d, self.symbols = text, where, d, symbols
        self.names = names or {}

    def refuse(self, what):
        raise SceneError(f"{self.where} = '{self.text}': {what} is not allowed; "
                         f"{allowed(self.d, tuple(self.names))}", key=self.where)

    def value(self, node, depth):
        if depth > MAX_DEPTH:
            raise SceneError(f"{self.where}: the expression is nested too deeply (at most "
                             f"{MAX_DEPTH} levels)", key=self.where)
        build = self.symbols is not None
        if isinstance(node, ast.Constant):
            if isinstance(node.value, bool) or not isinstance(node.value, (int, float)):
                self.refuse(f"the constant {node.value!r}")
            value = self.finite(float(node.value))
            if abs(value) > MODULUS_RANGE:
                # A form squares and multiplies its constants (a gradient's length): beyond
                # this the compiled code holds inf, and the C compiler refuses it.
                raise SceneError(f"{self.where} = '{self.text}': the number {value:g} is too "
                                 f"large; numbers in an expression lie within +-"
                                 f"{MODULUS_RANGE:g}, so that no product or square of them "
                                 "overflows (change the units)", key=self.where)
            return value
        if isinstance(node, ast.Name):
            if node.id == "t":
                return self.symbols[1] if build else None
            if node.id in self.names:
                return self.names[node.id] if build else None
            if node.id in CONSTANTS:
                return CONSTANTS[node.id]
            if node.id == "x":
                self.refuse("x without an index")
            if node.id in FUNCTIONS:
                self.refuse(f"the function {node.id} without a call")
            self.refuse(f"the name '{node.id}'")
        if isinstance(node, ast.Subscript):
            index = node.slice
            if not (isinstance(node.value, ast.Name) and node.value.id == "x"
                    and isinstance(index, ast.Constant) and type(index.value) is int
                    and 0 <= index.value < self.d):
                self.refuse(f"the subscript '{ast.unparse(node)}' (only x[0]..x[{self.d - 1}] "
                            f"of the {self.d}D position)")
            return self.symbols[0][index.value] if build else None
        if isinstance(node, ast.BinOp) and type(node.op) in _BINARY:
            a, b = self.value(node.left, depth + 1), self.value(node.right, depth + 1)
            if a is None or b is None:
                return None
            return self.arithmetic(_BINARY[type(node.op)], a, b)
        if isinstance(node, ast.UnaryOp) and isinstance(node.op, (ast.USub, ast.UAdd)):
            a = self.value(node.operand, depth + 1)
            return None if a is None else -a if isinstance(node.op, ast.USub) else a
        if isinstance(node, ast.Call):
            return self.call(node, depth)
        if isinstance(node, (ast.Compare, ast.BoolOp)) or (
                isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.Not)):
            self.refuse("a comparison outside conditional(...)")
        self.refuse(f"'{ast.unparse(node)}' (Python syntax of type {type(node).__name__})")

    def condition(self, node, depth):
        """The first argument of conditional: comparisons joined by and, or, not."""
        build = self.symbols is not None
        if depth > MAX_DEPTH:
            raise SceneError(f"{self.where}: the expression is nested too deeply (at most "
                             f"{MAX_DEPTH} levels)", key=self.where)
        if isinstance(node, ast.Compare):
            operands = [self.value(node.left, depth + 1)] + [
                self.value(c, depth + 1) for c in node.comparators]
            for op in node.ops:
                if type(op) not in _COMPARE:
                    self.refuse(f"the comparison '{type(op).__name__}'")
            if not build:
                return None
            if all(isinstance(a, float) for a in operands):
                return all(_COMPARE_FLOAT[type(op)](a, b)
                           for op, a, b in zip(node.ops, operands, operands[1:]))
            parts = [(_COMPARE[type(op)], a, b)
                     for op, a, b in zip(node.ops, operands, operands[1:])]
            conditions = [f(ufl.as_ufl(a), ufl.as_ufl(b)) for f, a, b in parts]
            out = conditions[0]
            for c in conditions[1:]:
                out = ufl.And(out, c)
            return out
        if isinstance(node, ast.BoolOp):
            values = [self.condition(v, depth + 1) for v in node.values]
            if not build:
                return None
            if all(isinstance(v, bool) for v in values):
                return all(values) if isinstance(node.op, ast.And) else any(values)
            join = ufl.And if isinstance(node.op, ast.And) else ufl.Or
            out = values[0]
            for v in values[1:]:
                out = join(out, v)
            return out
        if isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.Not):
            c = self.condition(node.operand, depth + 1)
            if isinstance(c, bool):
                return not c
            return ufl.Not(c) if build else None
        self.refuse(f"'{ast.unparse(node)}' as a condition (conditional needs a comparison)")

    def call(self, node, depth):
        if not (isinstance(node.func, ast.Name) and node.func.id in FUNCTIONS):
            self.refuse(f"the call '{ast.unparse(node.func)}(...)'")
        name = node.func.id
        function, arity = FUNCTIONS[name]
        if node.keywords or len(node.args) != arity or any(
                isinstance(a, ast.Starred) for a in node.args):
            self.refuse(f"'{ast.unparse(node)}' ({name} takes {arity} positional "
                        f"argument{'s' if arity > 1 else ''})")
        if name == "conditional":
            args = [self.condition(node.args[0], depth + 1)] + [
                self.value(a, depth + 1) for a in node.args[1:]]
            if isinstance(args[0], bool):              # on numbers (value_at)
                return args[1] if args[0] else args[2]
        else:
            args = [self.value(a, depth + 1) for a in node.args]
        if name != "conditional" and all(isinstance(a, float) for a in args):
            return self.arithmetic(FLOAT_FUNCTIONS[name], *args)
        if self.symbols is None:
            return None
        return function(*args)

    def arithmetic(self, function, *args):
        """function(*args); on floats the result must be a finite real number."""
        floats = all(isinstance(a, float) for a in args)
        try:
            result = function(*args)
        except OverflowError:
            raise SceneError(f"{self.where} = '{self.text}' overflows", key=self.where) from None
        except (ArithmeticError, ValueError) as err:
            raise SceneError(f"{self.where} = '{self.text}' cannot be evaluated: "
                             f"{err}", key=self.where) from None
        if floats:
            if isinstance(result, complex) or not isinstance(result, numbers.Real):
                raise SceneError(f"{self.where} = '{self.text}' gives a complex number",
                                 key=self.where)
            return self.finite(float(result))
        return result

    def finite(self, value: float) -> float:
        if not math.isfinite(value):
            raise SceneError(f"{self.where} = '{self.text}' overflows (gives {value})",
                             key=self.where)
        return value


class Context:
    """Position and time symbols of one mesh; `t.value` is the current time."""

    def __init__(self, mesh):
        self.mesh = mesh
        self.x = ufl.SpatialCoordinate(mesh)
        self.t = _constant(mesh, 0.0)

    def depends_on_time(self, value) -> bool:
        items = value if isinstance(value, (list, tuple)) else [value]
        return any(isinstance(v, str) and "t" in _names(v, "value") for v in items)

    def scalar(self, value, where: str, names=None):
        """A number -> Constant; a string -> UFL expression (in x, t and the further
        variables `names`: a dict name -> UFL value)."""
        if isinstance(value, bool) or not isinstance(value, (numbers.Real, str)):
            raise SceneError(f"{where} must be a number or an expression string, got {value!r}",
                             key=where)
        if isinstance(value, str):
            value = self._evaluate(value, where, names)
            if not isinstance(value, float):
                return value
        if not math.isfinite(value):
            raise SceneError(f"{where} must be finite, got {value}", key=where)
        return _constant(self.mesh, value)

    def vector(self, value, where: str, d: int):
        """A list of d numbers -> vector Constant; with any string -> UFL vector."""
        if not isinstance(value, (list, tuple)) or len(value) != d:
            raise SceneError(f"{where} must be a list of {d} components (the mesh is {d}D), "
                             f"got {value!r}", key=where)
        if all(isinstance(v, numbers.Real) and not isinstance(v, bool) for v in value):
            if not all(math.isfinite(v) for v in value):
                raise SceneError(f"{where} must be finite, got {value}", key=where)
            return _constant(self.mesh, tuple(float(v) for v in value))
        return ufl.as_vector([self._evaluate(v, f"{where}[{i}]") if isinstance(v, str)
                              else self._number(v, f"{where}[{i}]")
                              for i, v in enumerate(value)])

    def _number(self, value, where):
        if isinstance(value, bool) or not isinstance(value, numbers.Real) \
                or not math.isfinite(value):
            raise SceneError(f"{where} must be a finite number or an expression, got {value!r}",
                             key=where)
        return float(value)

    def _evaluate(self, text: str, where: str, names=None):
        d = self.mesh.geometry.dim
        result = evaluate(text, where, self.x, self.t, d, names)
        if isinstance(result, numbers.Real):
            return float(result)
        if not isinstance(result, ufl.core.expr.Expr) or result.ufl_shape != ():
            raise SceneError(f"{where} = '{text}' must give a scalar", key=where)
        return result


def _constant(mesh, value):
    # dolfinx is imported here so that checking a scene's expressions does not need it.
    from dolfinx import fem
    from petsc4py import PETSc
    return fem.Constant(mesh, PETSc.ScalarType(value))


def _names(text: str, where: str) -> set[str]:
    tree = parse(text, where)
    return {node.id for node in ast.walk(tree) if isinstance(node, ast.Name)}
