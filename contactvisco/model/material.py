"""Linear elasticity operator A of eq (7) for plane stress, plane strain and 3D."""
from __future__ import annotations

import ufl


def strain(u):
    """eps(u) = (grad u + grad u^T) / 2."""
    return ufl.sym(ufl.grad(u))


def lame_constants(model: str, E: float, nu: float) -> tuple[float, float]:
    """(lambda, mu) such that A eps = lambda tr(eps) I + 2 mu eps.

    Plane stress uses the reduced lambda* = E nu / (1 - nu^2), which is the paper's
    (A tau)_ij = E nu/(1 - nu^2) tr(tau) delta_ij + E/(1 + nu) tau_ij.
    """
    mu = E / (2.0 * (1.0 + nu))
    if model == "plane_stress":
        return E * nu / (1.0 - nu**2), mu
    return E * nu / ((1.0 + nu) * (1.0 - 2.0 * nu)), mu


def elasticity(eps, lmbda, mu):
    """A eps = lambda tr(eps) I + 2 mu eps."""
    d = eps.ufl_shape[0]
    return lmbda * ufl.tr(eps) * ufl.Identity(d) + 2.0 * mu * eps


def dimension(scene: dict) -> int:
    """The space dimension of a scene: 3 for the 3D model, else 2 (plane stress, plane strain)."""
    return 3 if scene["material"]["model"] == "3d" else 2
