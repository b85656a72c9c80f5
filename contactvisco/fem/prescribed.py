"""The prescribed functions of the contact law checked where the forms use them: at the contact
nodes (where the nodal contact quadrature evaluates them) and at the time of every staged
state, before that state is solved.

The scene check (contactvisco.scene.tables.check_contact_laws) samples contact.p_nu and
contact.p_tau at x = 0 and at three times only; a law that is negative at another position or
time would otherwise be solved as adhesion. Here, at every contact node x and the staged time
t, with s at the penetrations NODE_SAMPLES * g (g the layer's bound, 1 when it is infinite):

- p_nu(s, x, t) is finite, vanishes at s = 0, is >= 0 and non-decreasing in s;
- p_tau(s, p_nu, x, t) is finite, vanishes at s = 0 and is >= 0;
- a friction coefficient contact.mu given as an expression is finite (negative values are read
  as 0, as documented);
- a gap contact.gap given as an expression is finite.

A violation is a SceneError on every rank alike naming the key, the node, the time and the
value; it is raised while the state is staged, so the states committed before it are kept.
The obstacle's distance is checked the same way by contactvisco.fem.obstacle.
"""
from __future__ import annotations

import numpy as np
import ufl
from dolfinx import fem
from petsc4py import PETSc

from contactvisco.errors import SceneError
from contactvisco.fem import compat

#: The penetrations, as fractions of the layer g, at which the laws are checked at the nodes.
NODE_SAMPLES = (0.0, 1e-6, 1e-3) + tuple(k / 16 for k in range(1, 17))


def first_violation(comm, found):
    """The first violation of the lowest rank that found one, on every rank alike.

    Parameters
    ----------
    comm : mpi4py.MPI.Comm
        The mesh's communicator (collective).
    found : object or None
        This rank's first violation (None if none).

    Returns
    -------
    object or None
        The lowest rank's violation, or None if no rank found one.
    """
    reports = [r for r in comm.allgather(found) if r is not None]
    return reports[0] if reports else None


def _point(x) -> str:
    return "(" + ", ".join(f"{v:g}" for v in x) + ")"


class NodeCheck:
    """The prescribed functions of a [contact] table at the contact nodes (module
    description); calling it checks them at the current time.

    Parameters
    ----------
    contact : dict
        The resolved [contact] table.
    Q : fem.FunctionSpace
        The scalar P1 space of the contact part.
    nodes : numpy.ndarray
        The local P1 indices of the contact nodes.
    context : contactvisco.scene.expressions.Context
        The position and time symbols (context.t is the staged time).
    """

    def __init__(self, contact: dict, Q, nodes, context):
        self.Q, self.nodes, self.t = Q, nodes, context.t
        mesh = Q.mesh
        self.sigma = fem.Constant(mesh, PETSc.ScalarType(0.0))
        g = contact["g"]
        self.upper = g if np.isfinite(g) and g > 0 else 1.0
        # A zero Constant times x keeps the mesh in an expression that is constant in space.
        self._zero = fem.Constant(mesh, PETSc.ScalarType(0.0)) * context.x[0]
        self.checks = []          # (key, expression, kind)
        p = None
        if contact.get("p_nu") is not None and g > 0:
            p = context.scalar(contact["p_nu"], "contact.p_nu", {"s": self.sigma})
            self._add("contact.p_nu", p, "law")
        if contact.get("p_tau") is not None and p is not None:
            self._add("contact.p_tau", context.scalar(contact["p_tau"], "contact.p_tau",
                                                      {"s": self.sigma, "p_nu": p}), "law")
        for key in ("mu", "gap"):
            if isinstance(contact.get(key), str):
                self._add(f"contact.{key}", context.scalar(contact[key], f"contact.{key}"),
                          "finite")
        self.coordinates = Q.tabulate_dof_coordinates()[nodes, :mesh.geometry.dim]

    def _add(self, key, value, kind):
        expression = compat.expression(value + self._zero, self.Q)
        self.checks.append((key, expression, kind))

    def __bool__(self) -> bool:
        return bool(self.checks)

    def _values(self, expression) -> np.ndarray:
        function = fem.Function(self.Q)
        function.interpolate(expression)
        return function.x.array[self.nodes].copy()

    def _violation(self, key, expression, kind):
        """This rank's first violation of one function: (key, node, s, value, rule) or None."""
        samples = NODE_SAMPLES if kind == "law" else (0.0,)
        values = []
        for fraction in samples:
            self.sigma.value = self.upper * fraction
            values.append(self._values(expression))
        values = np.array(values)              # (samples, nodes)
        scale = np.max(np.abs(values), axis=0, initial=0.0, where=np.isfinite(values))
        tol = 1e-12 * scale
        rules = [(~np.isfinite(values), "must be finite")]
        if kind == "law":
            at_zero = np.zeros_like(values, dtype=bool)     # (samples, nodes) as the others
            at_zero[0] = np.abs(values[0]) > tol
            rules += [(at_zero, "must vanish at s = 0"), (values < -tol, "must be >= 0")]
            if key == "contact.p_nu":
                drops = np.zeros_like(values, dtype=bool)
                drops[1:] = values[1:] < values[:-1] - tol
                rules.append((drops, "must be non-decreasing in s"))
        for bad, rule in rules:
            if np.any(bad):
                sample, node = np.argwhere(bad)[0]
                return (key, [float(c) for c in self.coordinates[node]],
                        self.upper * samples[sample], float(values[sample, node]), rule,
                        kind)
        return None

    def __call__(self):
        """Check every function at the current time; a violation raises on every rank."""
        found = None
        for check in self.checks:
            found = self._violation(*check)
            if found is not None:
                break
        report = first_violation(self.Q.mesh.comm, found)
        if report is None:
            return
        key, x, s, value, rule, kind = report
        at = f"s = {s:g}, " if kind == "law" else ""
        raise SceneError(
            f"{key} gives {value:g} at the contact node x = {_point(x)}, {at}t = "
            f"{float(self.t.value):g}: it {rule} at every contact node and time (the "
            "forms evaluate it there); the steps before this time are kept", key=key)

