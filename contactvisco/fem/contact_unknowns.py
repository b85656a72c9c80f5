"""The unknowns and Constants the contact law of a [contact] table needs: r, g, the stiffness
and mu as they act, the multipliers lambda_nu and lambda_tau, and u(t_{n-1}) for a slip per
step."""
from __future__ import annotations

import math

import ufl
from dolfinx import fem

from contactvisco.fem.fields import interpolator, scalar
from contactvisco.model import contact_law


def has_friction(mu) -> bool:
    """Whether contact.mu asks for friction: a number > 0, or an expression (in x and t).

    Parameters
    ----------
    mu : float or str
        The scene's contact.mu.

    Returns
    -------
    bool
        True for mu > 0 or an expression.
    """
    return isinstance(mu, str) or mu > 0


def _friction_coefficient(mu, Q, context, updates):
    """contact.mu for the forms: a Constant, or for an expression in x and t its P1
    interpolant max(mu(x, t), 0), kept up to date in time (a node's friction coefficient is
    its value at the node, as the nodal contact quadrature sees it)."""
    if not isinstance(mu, str):
        return scalar(Q.mesh, mu)
    value = context.scalar(mu, "contact.mu")
    function = fem.Function(Q, name="mu")
    update = interpolator(function, ufl.max_value(value, 0.0)
                           if not isinstance(value, fem.Constant) else value, Q)
    update()
    if context.depends_on_time(mu):
        updates.append(update)
    return function


def contact_unknowns(contact: dict, u, Q, W, context=None, updates=None):
    """What the law of the [contact] table needs: its Constants by name (r, g when finite,
    stiffness when the compliance term acts, mu when friction acts), the
    multiplier lambda_nu in Q (a finite bound g only), lambda_tau in W (mu > 0 and a pressure
    to bound it: compliance, or Coulomb with a bound) and u(t_{n-1}) for slip = "increment"
    (None where absent)."""
    mesh = Q.mesh
    g = contact["g"]
    constants = {"r": scalar(mesh, contact["augmentation"]),
                 "g": scalar(mesh, g) if math.isfinite(g) else None}
    if contact["stiffness"] > 0 and g > 0:
        constants["stiffness"] = scalar(mesh, contact["stiffness"])
    lambda_nu = fem.Function(Q, name="lambda_nu") if math.isfinite(g) else None
    compliance = "stiffness" in constants or (contact.get("p_nu") is not None and g > 0)
    has_pressure = (compliance
                    or (contact["friction_law"] == "coulomb" and lambda_nu is not None))
    lambda_tau = u_previous = None
    friction = has_friction(contact["mu"]) or (contact.get("p_tau") is not None
                                               and compliance)
    if friction and has_pressure:
        if has_friction(contact["mu"]):
            constants["mu"] = _friction_coefficient(contact["mu"], Q, context, updates)
        lambda_tau = fem.Function(W, name="lambda_tau")
        if contact_law.ZERO_BALL == "guarded" and contact["friction_law"] != "coulomb":
            # The side of a ball of radius 0 (contact_law.ZERO_BALL): 1 free, 0 stick. The
            # condensed Newton system sets it in every solve; the others keep the stick side.
            constants["free_ball"] = scalar(mesh, 0.0)
        if contact["slip"] == "increment":
            # Slip measured from the previous step's state: u_tau - u_tau(t_{n-1}).
            u_previous = fem.Function(u.function_space, name="u_previous")
    return constants, lambda_nu, lambda_tau, u_previous
