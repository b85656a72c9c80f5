"""The contact law on Gamma_C (eqs 11-12) and its discretization (eqs 20-21) in UFL.

Signs: nu is the outward unit normal, u_nu = u.nu (> 0 means penetration into the layer),
sigma_nu = (sigma nu).nu (< 0 in compression). The foundation's normal reaction is
-sigma_nu = p_nu(u_nu) + R_nu with R_nu >= 0 the rigid part's reaction at the bound u_nu = g.
"""
from __future__ import annotations

import ufl


def positive_part(s):
    """s_+ = max(0, s), with slope 1 taken at s = 0 so a body resting at u_nu = 0 still has a
    non-singular Newton matrix."""
    return ufl.conditional(ufl.ge(s, 0.0), s, 0.0)


def normal_part(u, n):
    """u_nu = u . nu."""
    return ufl.dot(u, n)


def tangential_part(u, n):
    """u_tau = u - u_nu nu."""
    return u - ufl.dot(u, n) * n


def p_nu(u_nu, stiffness, g=None):
    """Normal compliance p_nu(s) = c_nu s_+, saturated at the bound: p_nu(min(s, g)).

    The paper's [s]_g (zero above g) would switch the force off at nodes that round-off puts
    at g + 1e-17; saturating gives the same converged solution without that trap.
    """
    s = u_nu if g is None else ufl.min_value(u_nu, g)
    return stiffness * positive_part(s)


def unilateral_reaction(lambda_nu, u_nu, g, r):
    """R_nu = (lambda_nu - r (u_nu - g))_-, the augmented-Lagrangian reaction of eq (20)."""
    return positive_part(r * (u_nu - g) - lambda_nu)


def project_ball(z, radius):
    """P_B(z): projection of the vector z onto the ball of centre 0 and the given radius."""
    norm = ufl.sqrt(ufl.dot(z, z))
    return ufl.conditional(ufl.le(norm, radius), z, radius * z / ufl.max_value(norm, 1e-300))


def friction_force(lambda_tau, u_tau, n, radius, r):
    """sigma_tau = P_B(lambda_tau - r u_tau) with B the ball of radius p_tau(u_nu) (eq 20)."""
    return project_ball(tangential_part(lambda_tau, n) - r * u_tau, radius)
