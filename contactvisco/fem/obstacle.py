"""A rigid obstacle with a shape of its own: the gap and the contact direction at the contact
nodes, taken from the obstacle rather than from the body's facets.

The obstacle is given by a signed distance phi (> 0 on the body's side, 0 on its surface) and
moves by a rigid translation d(t): a point y of space is at the distance phi_0(y - d) from the
moved obstacle. A contact node at x (reference configuration) displaced by u must stay outside:
phi_0(x + u - d) >= 0. Linearized about the reference position y_ref = x - d_ref, d_ref the
obstacle's position staged for the step (small deformation: |u - d + d_ref| small against the
obstacle's radius of curvature),

    phi_0(x + u - d) = phi_0(y_ref) + grad phi_0(y_ref) . (u - d + d_ref),

so with nu = -grad phi_0(y_ref) / |grad phi_0(y_ref)| (the obstacle's closest-point normal,
pointing into the obstacle) and w = u - d the displacement relative to the obstacle,

    s_nu = w . nu - h <= 0,    h = phi_0(y_ref) / |grad phi_0(y_ref)| - nu . d_ref,

which is the law of contactvisco.model.contact_law with u replaced by w and the gap by h;
friction acts on w's part in the obstacle's tangent plane (nu's orthogonal complement). For a
plane h = phi_0(x) whatever d_ref, and the condition is exact in d; for a curved obstacle the
closest point and normal are re-evaluated at every step (d_ref = d(t)), which leaves the
linearization in u only. Dividing by |grad phi| makes h the first-order distance for any level
set, and the exact one for a signed distance (|grad phi| = 1).

nu and h are P1 fields (interpolated at the nodes), so the conditions hold node by node as with
the body's own normal; the obstacle's displacement d is a P1 vector field of uniform value.

The contact direction is taken from grad phi, so it must be defined where it is used: at every
contact node and every position of the obstacle (each step, and each Newton update of a
force-controlled obstacle), phi must be finite and |grad phi| must lie in
[GRADIENT_BOUNDS[0], GRADIENT_BOUNDS[1]]. A signed distance has |grad phi| = 1; a level set
that is not a distance keeps a defined first-order distance phi / |grad phi| as long as its
gradient stays within three orders of magnitude of that. A gradient that vanishes at a node
(abs(x[1]) or x[1]**2 on their zero set, a node at a cylinder's centre) gives no direction:
the run would see every such node "separated" and the body pass through the obstacle, so it is
refused instead, naming the key, the node, the time and the value.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import ufl
from dolfinx import fem
from mpi4py import MPI
from petsc4py import PETSc

from contactvisco.errors import SceneError
from contactvisco.fem import compat
from contactvisco.fem.prescribed import first_violation
from contactvisco.scene import expressions

#: Added under the square root of a distance to a centre or an axis: keeps the closest-point
#: normal finite at the centre itself (a point deep inside the obstacle, never a contact node).
_TINY = 1e-300

#: The push into the body, as a fraction of its size, of a force-controlled obstacle's first
#: guess at each step (ObstaclePart._touch).
TOUCH = 1e-8

#: The range of |grad phi| accepted at a contact node (module description): a distance has 1.
GRADIENT_BOUNDS = (1e-3, 1e3)

#: The key that gives each shape's distance, named when it is not defined at a contact node.
_DISTANCE_KEY = {"plane": "obstacle.normal", "cylinder": "obstacle.centre",
                 "sphere": "obstacle.centre", "surface": "obstacle.distance"}


def signed_distance(obstacle: dict, y, t, d: int):
    """The obstacle's signed distance phi_0(y) as UFL (> 0 on the body's side).

    Parameters
    ----------
    obstacle : dict
        The [obstacle] table: shape "plane" (point p, outward normal n: phi = (y - p) . n/|n|),
        "cylinder" (centre c, radius R, in 3D axis a: phi = |r| - R with r = y - c without its
        part along a), "sphere" (phi = |y - c| - R) or "surface" (phi = the expression
        obstacle.distance with x replaced by y).
    y : UFL vector
        The point, in the obstacle's reference frame.
    t : fem.Constant
        The time of the expressions.
    d : int
        The space dimension.

    Returns
    -------
    UFL expression
        phi_0(y).
    """
    shape = obstacle["shape"]
    if shape == "plane":
        n = np.asarray(obstacle["normal"], float)
        n = ufl.as_vector(n / np.linalg.norm(n))
        return ufl.dot(y - ufl.as_vector(obstacle["point"]), n)
    if shape in ("cylinder", "sphere"):
        r = y - ufl.as_vector(obstacle["centre"])
        if shape == "cylinder" and d == 3:
            a = np.asarray(obstacle["axis"], float)
            a = ufl.as_vector(a / np.linalg.norm(a))
            r = r - ufl.dot(r, a) * a
        return ufl.sqrt(ufl.dot(r, r) + _TINY) - obstacle["radius"]
    return expressions.evaluate(obstacle["distance"], "obstacle.distance", y, t, d)


def displacement_at(obstacle: dict, t: float, d: int) -> np.ndarray:
    """The prescribed translation d(t) of the obstacle (zero if none is given).

    Parameters
    ----------
    obstacle : dict
        The [obstacle] table; ``displacement`` is a list of d numbers or expressions in t.
    t : float
        The time.
    d : int
        The space dimension.

    Returns
    -------
    numpy.ndarray
        d(t), shape (d,).
    """
    values = obstacle["displacement"]
    if values is None:
        return np.zeros(d)
    out = np.empty(d)
    for j, value in enumerate(values):
        if isinstance(value, str):
            value = expressions.evaluate(value, f"obstacle.displacement[{j}]", None,
                                         float(t), d)
        out[j] = float(value)
    return out


@dataclass
class ObstaclePart:
    """The obstacle of a problem: nu (``normal``, W), h (``gap``, Q), the displacement d and
    d(t_{n-1}) as uniform P1 vector fields (``D``, ``D_previous``; the law acts on u - d and,
    with slip = "increment", on u - d - (u - d)(t_{n-1})), and the staged position d_ref
    (``reference``) at which nu and h are evaluated."""
    scene: dict
    normal: fem.Function
    gap: fem.Function
    D: fem.Function
    D_previous: fem.Function
    reference: fem.Constant
    nodes: object                      # contact_terms.ContactNodes: their normals follow nu
    t: fem.Constant
    _normal_expression: fem.Expression
    _gap_expression: fem.Expression
    _size_expression: fem.Expression | None = None   # |grad phi_0(y)|, checked at the nodes
    committed: np.ndarray | None = None    # d at the last committed state
    force_forms: dict | None = None        # force_forms() (force control only)
    rigid: bool = True                     # a position d of its own, kept in checkpoints

    @property
    def dim(self) -> int:
        return self.D.function_space.mesh.geometry.dim

    def displacement(self) -> np.ndarray:
        """The obstacle's current displacement d, shape (dim,)."""
        d = self.dim
        values = self.D.x.array.reshape(-1, d)
        if len(values):
            return values[0].copy()
        return np.asarray(self.reference.value, float).copy()

    def set_displacement(self, d: np.ndarray):
        """Set d (the uniform field D) without moving the reference position."""
        self.D.x.array.reshape(-1, self.dim)[:] = d

    def place(self, d: np.ndarray):
        """Put the obstacle at d: D = d, d_ref = d, and nu, h re-evaluated there (the contact
        nodes' normals follow)."""
        self.set_displacement(d)
        self.reference.value[:] = d
        self.normal.interpolate(self._normal_expression)
        self.gap.interpolate(self._gap_expression)
        self._check_defined()
        nodes, dim = self.nodes, self.dim
        nodes.normals[:] = self.normal.x.array.reshape(-1, dim)[nodes.nodes]
        if nodes.tangents is not None:
            nodes.tangents[:] = np.column_stack([-nodes.normals[:, 1], nodes.normals[:, 0]])

    def _check_defined(self):
        """Refuse, on every rank alike, an obstacle whose distance or gradient is not defined
        at a contact node (module description): the first such node of the lowest rank."""
        if self._size_expression is None:
            return
        Q = self.gap.function_space
        size = fem.Function(Q)
        size.interpolate(self._size_expression)
        nodes = self.nodes.nodes
        gap, length = self.gap.x.array[nodes], size.x.array[nodes]
        low, high = GRADIENT_BOUNDS
        with np.errstate(invalid="ignore"):
            bad = ~(np.isfinite(gap) & np.isfinite(length) & (length >= low) & (length <= high))
        found = None
        if np.any(bad):
            k = int(np.flatnonzero(bad)[0])
            x = Q.tabulate_dof_coordinates()[nodes[k], :self.dim]
            found = ([float(v) for v in x], float(gap[k]), float(length[k]))
        report = first_violation(Q.mesh.comm, found)
        if report is None:
            return
        x, gap_value, length_value = report
        obstacle = self.scene["obstacle"]
        key = _DISTANCE_KEY.get(obstacle["shape"], "obstacle.shape")
        point = ", ".join(f"{v:g}" for v in x)
        raise SceneError(
            f"{key}: the obstacle's distance is not defined at the contact node x = ({point}) "
            f"at t = {float(self.t.value):g} (obstacle at d = "
            f"{np.round(np.asarray(self.reference.value, float), 12).tolist()}): "
            f"phi / |grad phi| = {gap_value:g}, |grad phi| = {length_value:g}; the contact direction is "
            f"-grad phi / |grad phi|, so at every contact node phi must be finite and |grad phi| "
            f"between {low:g} and {high:g} (1 for a signed distance). Give a signed distance "
            f"whose gradient does not vanish on the contact boundary (e.g. 'x[1]', not "
            f"'abs(x[1])' or 'x[1]**2')", key=key)

    @property
    def controlled(self) -> list[int]:
        """The force-controlled components of d (unknowns), in the order of obstacle.force."""
        return list(self.scene["obstacle"]["force_components"])

    def move_to(self):
        """The prescribed position at the time t of the expressions; a force-controlled
        component keeps the last equilibrium's value (Newton's first guess),
        except at the first state, where it starts from obstacle.displacement at t."""
        d = displacement_at(self.scene["obstacle"], float(self.t.value), self.dim)
        if self.committed is not None:
            for j in self.controlled:
                d[j] = self.committed[j]
        self.place(d)

    def _touch(self) -> np.ndarray:
        """A push of TOUCH times the body's size into the body (along the mean of -nu over the
        contact nodes), added to a force-controlled obstacle's first guess: an equilibrium
        that left it touching the body at zero force (an interference pushed out by F = 0)
        has every node at a gap of round-off, possibly all "separated", and then no node to
        carry the next force; pushed, the nearest one is in contact. Collective."""
        nodes = self.nodes
        local = -(nodes.weights[nodes.owned, None] * nodes.normals[nodes.owned]).sum(axis=0)
        comm = self.gap.function_space.mesh.comm
        total = np.zeros_like(local)
        comm.Allreduce(local, total, op=MPI.SUM)
        x = self.gap.function_space.mesh.geometry.x[:, :self.dim]
        upper, lower = np.full(self.dim, -np.inf), np.full(self.dim, np.inf)
        if len(x):
            upper, lower = x.max(axis=0), x.min(axis=0)
        comm.Allreduce(upper.copy(), upper, op=MPI.MAX)
        comm.Allreduce(lower.copy(), lower, op=MPI.MIN)
        size = np.linalg.norm(total)
        if not size > 0:
            return np.zeros(self.dim)
        return TOUCH * float(np.max(upper - lower)) * total / size

    def force_at(self, t: float) -> np.ndarray:
        """The prescribed resultant contact force F(t) on the force-controlled components
        (the force of the obstacle on the body), shape (len(controlled),)."""
        values = self.scene["obstacle"]["force"]
        return np.array([float(expressions.evaluate(v, f"obstacle.force[{j}]", None,
                                                    float(t), self.dim))
                         if isinstance(v, str) else float(v) for j, v in enumerate(values)])

    def prepare(self, t_committed: float):
        """The origin of the step's slip: d at the committed time; under force control, the
        first guess of d (the last equilibrium pushed by _touch). Collective."""
        d = (self.committed if self.committed is not None
             else displacement_at(self.scene["obstacle"], t_committed, self.dim))
        self.D_previous.x.array.reshape(-1, self.dim)[:] = d
        if self.committed is not None and self.controlled:
            # Newton's first guess: the last equilibrium, pushed into contact (_touch)
            guess = self.displacement()
            push = self._touch()
            for j in self.controlled:
                guess[j] = self.committed[j] + push[j]
            self.place(guess)

    def commit(self):
        """Keep the converged d (the slip's origin of the next step)."""
        self.committed = self.displacement()


def build(scene: dict, Q, W, nodes, t) -> ObstaclePart:
    """The obstacle of a scene with an [obstacle] table, placed at d(t) for the current t.

    Parameters
    ----------
    scene : dict
        The resolved scene.
    Q, W : fem.FunctionSpace
        The scalar and vector P1 spaces of the contact part.
    nodes : contactvisco.fem.contact_terms.ContactNodes
        The contact nodes; their normals (and 2D tangents) are set to the obstacle's.
    t : fem.Constant
        The time of the expressions.

    Returns
    -------
    ObstaclePart
        nu = -grad phi_0(y) / |grad phi_0(y)| and h = phi_0(y) / |grad phi_0(y)| - nu . d_ref
        at y = x - d_ref (module description).
    """
    mesh = Q.mesh
    d = mesh.geometry.dim
    reference = fem.Constant(mesh, PETSc.ScalarType((0.0,) * d))
    x = ufl.SpatialCoordinate(mesh)
    y = x - reference
    # A zero Constant times x keeps the mesh in expressions that end up constant in space (a
    # plane's normal, a constant distance): fem.Expression and ufl.grad need one.
    zero = fem.Constant(mesh, PETSc.ScalarType(0.0))
    phi = signed_distance(scene["obstacle"], y, t, d) + zero * x[0]
    gradient = ufl.grad(phi)
    size = ufl.sqrt(ufl.dot(gradient, gradient) + _TINY)
    nu = -gradient / size + zero * x
    h = phi / size - ufl.dot(nu, reference) + zero * x[0]
    part = ObstaclePart(
        scene=scene, normal=fem.Function(W, name="obstacle_normal"),
        gap=fem.Function(Q, name="gap"), D=fem.Function(W, name="obstacle_displacement"),
        D_previous=fem.Function(W), reference=reference, nodes=nodes, t=t,
        _normal_expression=compat.expression(nu, W),
        _gap_expression=compat.expression(h, Q),
        _size_expression=compat.expression(
            ufl.sqrt(ufl.dot(gradient, gradient)) + zero * x[0], Q))
    part.move_to()
    return part


def force_forms(part: ObstaclePart, contact_terms, v, unknowns: list, residuals: list) -> dict:
    """The UFL forms of force control: for each force-controlled component j, with e_j the
    uniform unit vector field, the contact part of F_u tested with e_j,

        g_j = int_C (p_nu + R_nu) e_j . nu - sigma_tau . (e_j)_tau = -(force on the body)_j,

    so that G_j = g_j + F_j(t) = 0 prescribes the force; and the derivatives of the bordered
    Newton system: ``B[j][i]`` = dF_i/dd_j (the residual blocks F_i of the unknowns, through
    u - d), ``C[j][i]`` = dg_j/dw_i (w_i the unknowns), ``E[j][k]`` = dg_j/dd_k.

    Parameters
    ----------
    part : ObstaclePart
        The obstacle (its field D is d).
    contact_terms : UFL form
        The contact terms of F_u (linear in the test function v).
    v : ufl.Argument
        F_u's test function.
    unknowns : list of fem.Function
        u and the multipliers.
    residuals : list of UFL forms
        Their residual blocks F_i (F_u first).

    Returns
    -------
    dict
        ``g``, ``B``, ``C``, ``E`` (UFL forms, lists indexed by the controlled components).
    """
    V, W = v.ufl_function_space(), part.D.function_space
    d = part.dim
    e_u, e_w = [], []
    for j in part.controlled:
        unit_u, unit_w = fem.Function(V), fem.Function(W)
        unit_u.x.array.reshape(-1, d)[:, j] = 1.0
        unit_w.x.array.reshape(-1, d)[:, j] = 1.0
        e_u.append(unit_u)
        e_w.append(unit_w)
    g = [ufl.replace(contact_terms, {v: unit}) for unit in e_u]
    derivative = ufl.algorithms.expand_derivatives
    B = [[derivative(ufl.derivative(F, part.D, unit)) for F in residuals] for unit in e_w]
    C = [[derivative(ufl.derivative(g_j, w, ufl.TestFunction(w.function_space)))
          for w in unknowns] for g_j in g]
    E = [[derivative(ufl.derivative(g_j, part.D, unit)) for unit in e_w] for g_j in g]
    return {"g": g, "B": B, "C": C, "E": E, "units": e_u + e_w}
