"""The contact law on Gamma_C (eqs 11-12) and its discretization (eqs 20-21), written once.

Signs: nu is the outward unit normal, u_nu = u.nu (> 0 means penetration into the layer),
sigma_nu = (sigma nu).nu (< 0 in compression). The foundation's normal reaction is
-sigma_nu = p_nu(u_nu) + R_nu with R_nu >= 0 the rigid part's reaction at the bound u_nu = g.

Friction: sigma_tau lies in the ball of radius mu p_nu(u_nu) (friction_law = "compliance", the
paper's) or mu (p_nu(u_nu) + R_nu) = -mu sigma_nu (friction_law = "coulomb": Coulomb on the
total normal pressure), and opposes the slip where it reaches the bound. The slip is u_tau
(the paper's) or the step's u_tau - u_tau(t_{n-1}) (Coulomb's incremental law).

General laws (contact.p_nu, contact.p_tau: the paper's eq 3 with prescribed functions) enter
as callables `laws` of law_terms: p_nu = laws["p_nu"](sigma) and p_tau = laws["p_tau"](sigma, p_nu)
with sigma = max(0, min(s, g)) the saturated penetration, so that they vanish for s < 0 and
the bound's friction is F_b = p_tau(g). The linear law (stiffness, mu) stays its own short
form.

Every function takes the array namespace `ops` it is evaluated in: UFL (the forms of
contactvisco.fem.contact_terms) or NUMPY (the node values of the contact table, one row per node,
vectors as (n, d) arrays). The law is thus one set of expressions for both.

The kinks and Newton's derivative there. The law is piecewise smooth; Newton differentiates
each piece, and where an iterate sits exactly on a kink, both pieces give the same value but
different slopes, each an element of the generalized (B-)differential of the semismooth
Newton method (Qi and Sun 1993; Hintermueller, Ito and Kunisch 2002). The side taken is
written out, a conditional with its comparison, rather than left to ufl.min_value or
ufl.max_value (whose UFL derivative takes the side of the second argument at a tie):

- the bound, min(s, g) at s = g (saturate): the compliance side, slope 1 (BOUND_TIE). The
  augmented-Lagrangian step of a node on the bound puts it at s = g up to round-off, so the
  tie is met at every iterate after such a step, and so is a node the predictor releases
  from the bound (contactvisco.solver.predictor). At a free node (r (s - g) < lambda_nu:
  released) the side is therefore taken for s within TIE_SLACK of the displacement's size
  of g, not at s = g exactly: otherwise the last bit of s decides it, and two Newton solvers
  that agree to round-off (the coupled and the condensed system, 1 and 2 ranks, MUMPS with
  1 or 2 threads) take different steps from such a node. The value there is s instead of g,
  an error of at most that round-off. A node held at the bound keeps the exact tie: its
  u_nu is constrained, so the side changes entries of the Newton matrix but not the step
  (the direct solver's counts are the same either way), while widening it there too changed
  the loose solves' paths of the iterative solver and cost the paper scene Newton
  iterations (docs/scaling.md). With the bound side (slope 0) a node that leaves the bound
  for the compliance zone has no normal stiffness from p_nu in the next Newton matrix, and
  the step takes one more iteration: in most steps of the paper scene (docs/scaling.md; an
  independent semismooth Newton solver in GetFEM, whose min takes the slope 1 at a tie, has
  the compliance side's counts);
- the positive part, s_+ at s = 0 (p_nu at u_nu = 0, R_nu where r (u_nu - g) = lambda_nu):
  the active side, slope 1, so a body resting at u_nu = 0 still has a non-singular Newton
  matrix (slope 0 costs an iteration at t_0 of the paper scene);
- the friction ball, |z| = radius in project_ball: the stick side, the identity, which is
  defined at z = 0 where the slip side's z/|z| is not (a node with no pressure and no slip);
  also on a ball of radius 0 (a node without pressure) unless ZERO_BALL = "free", where P_B = 0
  with derivative 0, so that such a node carries no friction force in the Newton matrix either
  (never under Coulomb's law, whose radius depends on the multiplier). "free" takes block3d's
  first loaded step in 5 Newton iterations instead of 8 but makes Newton cycle on other
  scenes (docs/scaling.md), so "stick" is the default; "guarded" takes the free side and
  falls back to the stick side where Newton stalls (ZERO_BALL).
"""
from __future__ import annotations

import numpy as np
import ufl


class UFL:
    """UFL operations: the forms."""
    where_ge = staticmethod(lambda a, b, x, y: ufl.conditional(ufl.ge(a, b), x, y))
    where_le = staticmethod(lambda a, b, x, y: ufl.conditional(ufl.le(a, b), x, y))
    minimum = staticmethod(ufl.min_value)
    maximum = staticmethod(ufl.max_value)
    sqrt = staticmethod(ufl.sqrt)
    dot = staticmethod(ufl.dot)
    times = staticmethod(lambda s, v: s * v)          # scalar times vector
    divide = staticmethod(lambda v, s: v / s)         # vector over scalar


def _per_node(condition, x):
    """A per-node condition (n,) broadcast to x's shape ((n,) or (n, d))."""
    condition = np.asarray(condition)
    return condition[..., None] if np.ndim(x) > condition.ndim else condition


class NUMPY:
    """numpy operations on node arrays: scalars (n,), vectors (n, d)."""
    where_ge = staticmethod(lambda a, b, x, y: np.where(_per_node(np.asarray(a) >= b, x), x, y))
    where_le = staticmethod(lambda a, b, x, y: np.where(_per_node(np.asarray(a) <= b, x), x, y))
    minimum = staticmethod(np.minimum)
    maximum = staticmethod(np.maximum)
    sqrt = staticmethod(np.sqrt)
    dot = staticmethod(lambda a, b: np.einsum("...i,...i->...", a, b))
    times = staticmethod(lambda s, v: _per_node(s, v) * v)
    divide = staticmethod(lambda v, s: v / _per_node(s, v))


#: The side of min(s, g) whose derivative Newton takes at s = g (module description):
#: "compliance" (slope 1, s <= g) or "bound" (slope 0, s >= g, ufl.min_value's choice).
BOUND_TIE = "compliance"
BOUND_TIES = ("compliance", "bound")

#: At a node free of the bound, a penetration s within this fraction of |u| + |h| + |g| (the
#: displacement, the initial gap and the bound: the size of s's round-off) of the bound g is
#: at the bound's tie (module description).
TIE_SLACK = 1e-12


def saturate(s, g, ops=UFL, tie=None, slack=0.0):
    """The penetration saturated at the bound, min(s, g), with the side of its derivative at
    s = g chosen.

    Parameters
    ----------
    s : UFL expression or numpy.ndarray
        The penetration.
    g : float or Constant
        The bound.
    ops : class, optional
        The array namespace, UFL or NUMPY.
    tie : str, optional
        The side taken at s = g: "compliance", d/ds min(s, g) = 1 for s <= g (and 0 for
        s > g), or "bound", d/ds = 0 for s >= g (and 1 for s < g). None: BOUND_TIE.
    slack : float or UFL expression or numpy.ndarray, optional
        The tie is |s - g| <= slack: the compliance side takes s <= g + slack, the bound side
        s >= g - slack (law_terms passes TIE_SLACK times the size of s's round-off).

    Returns
    -------
    UFL expression or numpy.ndarray
        min(s, g), the same value for either side, up to `slack`.
    """
    tie = BOUND_TIE if tie is None else tie
    if tie == "compliance":
        return ops.where_le(s, g + slack, s, g)
    if tie == "bound":
        return ops.where_ge(s, g - slack, g, s)
    raise ValueError(f"tie = {tie!r}: allowed are {', '.join(BOUND_TIES)}")


def positive_part(s, ops=UFL):
    """s_+ = max(0, s), with slope 1 taken at s = 0 so a body resting at u_nu = 0 still has a
    non-singular Newton matrix."""
    return ops.where_ge(s, 0.0, s, 0.0 * s)


def normal_part(u, nu, ops=UFL):
    """u_nu = u . nu."""
    return ops.dot(u, nu)


def tangential_part(u, nu, ops=UFL):
    """u_tau = u - u_nu nu."""
    return u - ops.times(ops.dot(u, nu), nu)


def law_argument(u_nu, g=None, ops=UFL, slack=0.0):
    """The argument of the prescribed functions: max(0, min(s, g)) (max(0, s) when g is
    None: no bound), min by saturate with its tie `slack`."""
    s = u_nu if g is None else saturate(u_nu, g, ops, slack=slack)
    return positive_part(s, ops)


def p_nu(u_nu, stiffness, g=None, ops=UFL, law=None, slack=0.0):
    """Normal compliance p_nu(s) = c_nu s_+, saturated at the bound: p_nu(min(s, g)).

    The paper's [s]_g (zero above g) would switch the force off at nodes that round-off puts
    at g + 1e-17; saturating gives the same converged solution without that trap.

    Parameters
    ----------
    u_nu : UFL expression or numpy.ndarray
        The penetration s.
    stiffness : float or Constant
        c_nu of the linear law (unused when `law` is given).
    g : float or Constant, optional
        The bound (None: no bound).
    ops : class, optional
        The array namespace, UFL or NUMPY.
    law : callable, optional
        A prescribed p_nu(sigma) of sigma = max(0, min(s, g)) (eq 3), in place of c_nu sigma.
    slack : float or UFL expression or numpy.ndarray, optional
        The width of the bound's tie (saturate).

    Returns
    -------
    UFL expression or numpy.ndarray
        p_nu(max(0, min(s, g))).
    """
    if law is not None:
        return law(law_argument(u_nu, g, ops, slack))
    s = u_nu if g is None else saturate(u_nu, g, ops, slack=slack)
    return stiffness * positive_part(s, ops)


def reaction_argument(lambda_nu, u_nu, g, r):
    """r (u_nu - g) - lambda_nu: >= 0 where the node is held at the bound (R_nu > 0 or its
    tie), < 0 where it is free of it."""
    return r * (u_nu - g) - lambda_nu


def unilateral_reaction(lambda_nu, u_nu, g, r, ops=UFL):
    """R_nu = (lambda_nu - r (u_nu - g))_-, the augmented-Lagrangian reaction of eq (20)."""
    return positive_part(reaction_argument(lambda_nu, u_nu, g, r), ops)


#: The side of P_B's derivative at z = 0 on a ball of radius 0 (the module description):
#: "free" (P_B = 0 there, derivative 0), "stick" (the identity) or "guarded" (free, but the
#: solve starts again from its first iterate with the stick side when the residual finds no
#: new minimum in newton.GUARD_WINDOW iterations or the free solve fails: the condensed Newton
#: system switches the Constant `free_ball` of the forms; other systems keep the stick side).
#: "stick" by default: "free" saves block3d 3 to 6 Newton iterations at its first loaded step
#: but makes Newton cycle at t_0 of the paper scene with contact.stiffness = 1e8, where
#: "guarded" converges in 4 more iterations than "stick" (docs/scaling.md).
ZERO_BALL_TIES = ("free", "stick", "guarded")
ZERO_BALL = "stick"


def project_ball(z, radius, ops=UFL, zero_ball=None, free=None):
    """P_B(z): projection of the vector z onto the ball of centre 0 and the given radius,

        P_B(z) = z if |z| <= radius, radius z / |z| otherwise,

    and, on a ball of radius 0, the identity's side (`zero_ball` "stick", the default
    ZERO_BALL) or P_B(z) = 0 with derivative 0 ("free"); "guarded" takes the free side where
    the number (or Constant) `free` is >= 0.5 and the stick side otherwise (the stick side
    without `free`). The value is the same on every side."""
    tie = ZERO_BALL if zero_ball is None else zero_ball
    norm = ops.sqrt(ops.dot(z, z))
    projected = ops.where_le(norm, radius, z,
                             ops.divide(ops.times(radius, z), ops.maximum(norm, 1e-300)))
    if tie not in ZERO_BALL_TIES:
        raise ValueError(f"contact_law.ZERO_BALL must be one of {', '.join(ZERO_BALL_TIES)}, "
                         f"got {tie!r}")
    if tie == "stick" or (tie == "guarded" and free is None):
        return projected
    released = ops.times(0.0, z)
    if tie == "guarded":
        released = ops.where_ge(free, 0.5, released, projected)
    return ops.where_le(radius, 0.0, released, projected)


def friction_radius(mu, p, R, friction_law):
    """The friction ball's radius: mu p_nu (friction_law "compliance", the paper's), or
    mu (p_nu + R_nu) ("coulomb": Coulomb's law on the total normal pressure; with g = 0:
    Signorini-Coulomb). p or R may be None where the scene has no such term; None if there
    is no pressure at all."""
    pressure = p
    if friction_law == "coulomb" and R is not None:
        pressure = R if p is None else p + R
    return None if pressure is None else mu * pressure


def friction_force(lambda_tau, slip, nu, radius, r, ops=UFL, zero_ball=None, free=None):
    """sigma_tau = P_B(lambda_tau - r slip) with B the ball of the given radius (eq 20);
    slip is the tangential motion the law acts on (u_tau or its increment); zero_ball and
    free as in project_ball."""
    return project_ball(tangential_part(lambda_tau, nu, ops) - r * slip, radius, ops,
                        zero_ball, free)


def law_terms(ops, u, nu, gap, lambda_nu, lambda_tau, u_previous, constants, friction_law,
              laws=None):
    """The law's quantities at u with normal nu (eqs 20-21): s_nu = u . nu - h (the
    penetration past the initial gap h), p_nu, R_nu, the normal force p_nu + R_nu, the
    friction radius, the slip and sigma_tau; None where the scene has no such term.

    constants: r, g (None for no bound), stiffness (absent without compliance), mu (the
    friction coefficient, absent without friction); UFL Constants or numbers. friction_law:
    "compliance" or "coulomb" (friction_radius). laws: the prescribed functions by name,
    "p_nu" (sigma -> p_nu) in place of stiffness, "p_tau" ((sigma, p_nu) -> radius) in place
    of mu p_nu, sigma = max(0, min(s, g)) (module description)."""
    laws = laws or {}
    s_nu = normal_part(u, nu, ops) - gap
    g = constants.get("g")
    slack = 0.0 if g is None else TIE_SLACK * (ops.sqrt(ops.dot(u, u)) + abs(gap) + abs(g))
    if g is not None and lambda_nu is not None:
        # A node held at the bound keeps the exact tie (module description).
        held = reaction_argument(lambda_nu, s_nu, g, constants["r"])
        slack = ops.where_ge(held, 0.0, 0.0 * slack, slack)
    if "p_nu" in laws:
        p = p_nu(s_nu, None, g, ops, law=laws["p_nu"], slack=slack)
    else:
        p = (p_nu(s_nu, constants["stiffness"], g, ops, slack=slack)
             if "stiffness" in constants else None)
    R = (unilateral_reaction(lambda_nu, s_nu, g, constants["r"], ops)
         if lambda_nu is not None else None)
    normal_force = p if R is None else (R if p is None else p + R)
    moved = u if u_previous is None else u - u_previous
    slip = tangential_part(moved, nu, ops)
    radius = sigma_tau = None
    if "p_tau" in laws and p is not None:
        radius = laws["p_tau"](law_argument(s_nu, g, ops, slack), p)
    elif "mu" in constants:
        radius = friction_radius(constants["mu"], p, R, friction_law)
    if lambda_tau is not None and radius is not None:
        # Coulomb's radius mu (p_nu + R_nu) depends on the multiplier through R_nu: releasing
        # a node whose R_nu is 0 in an iterate made Newton cycle on Signorini-Coulomb scenes
        # (r = 1e4, tests/integration/test_coulomb.py), so it keeps the stick side.
        sigma_tau = friction_force(lambda_tau, slip, nu, radius, constants["r"], ops,
                                   "stick" if friction_law == "coulomb" else None,
                                   constants.get("free_ball"))
    return {"s_nu": s_nu, "p_nu": p, "R_nu": R, "normal_force": normal_force,
            "radius": radius, "slip": slip, "sigma_tau": sigma_tau}
