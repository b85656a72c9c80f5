"""The contact law on Gamma_C (eqs 11-12) and its discretization (eqs 20-21) in UFL.

Signs: nu is the outward unit normal, u_nu = u.nu (> 0 means penetration into the layer),
sigma_nu = (sigma nu).nu (< 0 in compression). The foundation's normal reaction is
-sigma_nu = p_nu(u_nu) + R_nu with R_nu >= 0 the rigid part's reaction at the bound u_nu = g.

Friction: sigma_tau lies in the ball of radius mu p_nu(u_nu) (the paper's law) or
mu (p_nu(u_nu) + R_nu) = -mu sigma_nu (Coulomb on the total normal pressure), and opposes the
slip where it reaches the bound. The slip is u_tau (the paper's) or the step's
u_tau - u_tau(t_{n-1}) (Coulomb's incremental law); friction_force takes either.
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
    """sigma_tau = P_B(lambda_tau - r u_tau) with B the ball of the given radius (eq 20);
    u_tau is the slip the law acts on."""
    return project_ball(tangential_part(lambda_tau, n) - r * u_tau, radius)
