"""The elasticity operator A of eq (7) for plane stress, plane strain and 3D: linear, or the
derivative of a strain-energy density W (the paper's "possibly nonlinear" A)."""
from __future__ import annotations

import numpy as np
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
    """The space dimension of a scene: 3 for the 3D model, else 2 (plane stress, plane strain,
    and the meridian half-plane (r, z) of an axisymmetric body)."""
    return 3 if scene["material"]["model"] == "3d" else 2


def strain_dimension(model: str) -> int:
    """The dimension of the strain tensor of a material.model: 3 in 3D and for an
    axisymmetric body (eps_rr, eps_zz, eps_rz and the hoop strain eps_theta), else 2.

    Parameters
    ----------
    model : str
        material.model.

    Returns
    -------
    int
        d of the d x d strain, the d of the projections tr(eps)/d I.
    """
    return 3 if model in ("3d", "axisymmetric") else 2


#: material.law: the linear A, a Hencky-type power law, or a strain-energy expression.
LAWS = ("linear", "hencky", "energy")
#: The variables of material.energy besides x and t: the invariants of eps and the Lame
#: constants (lambda* in plane stress).
ENERGY_NAMES = ("tr_eps", "eps2", "dev_eps2", "lmbda", "mu_lame")


def strain_basis(d: int) -> list[np.ndarray]:
    """The orthonormal basis E_a of the symmetric d x d tensors (Mandel's).

    Parameters
    ----------
    d : int
        The dimension.

    Returns
    -------
    list of numpy.ndarray
        d (d + 1) / 2 symmetric matrices with E_a : E_b = delta_ab: e_i (x) e_i, and
        (e_i (x) e_j + e_j (x) e_i) / sqrt 2 for i < j.
    """
    basis = []
    for i in range(d):
        for j in range(i, d):
            e = np.zeros((d, d))
            e[i, j] = e[j, i] = 1.0 if i == j else 2 ** -0.5
            basis.append(e)
    return basis


def invariants(eps) -> dict:
    """The invariants material.energy is written in.

    Parameters
    ----------
    eps : UFL expression or numpy.ndarray
        A symmetric d x d strain.

    Returns
    -------
    dict
        tr_eps = tr(eps), eps2 = eps : eps and dev_eps2 = dev(eps) : dev(eps), with
        dev(eps) = eps - tr(eps) I / d (d the dimension of the strain, 2 in plane models).
    """
    if isinstance(eps, np.ndarray):
        d = eps.shape[0]
        tr = float(np.trace(eps))
        dev = eps - tr / d * np.eye(d)
        return {"tr_eps": tr, "eps2": float(np.sum(eps * eps)),
                "dev_eps2": float(np.sum(dev * dev))}
    d = eps.ufl_shape[0]
    dev = eps - ufl.tr(eps) / d * ufl.Identity(d)
    return {"tr_eps": ufl.tr(eps), "eps2": ufl.inner(eps, eps),
            "dev_eps2": ufl.inner(dev, dev)}


def hencky_energy(eps, lmbda, mu, exponent, strain_scale):
    """The Hencky-type power-law energy (material.law = "hencky").

    W(eps) = K/2 tr(eps)^2 + mu e_0^2 / (m + 1) [(1 + |dev eps|^2 / e_0^2)^(m + 1) - 1],
    K = lambda + 2 mu / d, so that sigma = dW/deps = K tr(eps) I + 2 mu psi dev(eps) with
    the secant shear modulus mu psi, psi = (1 + |dev eps|^2 / e_0^2)^m: the Hencky material
    sigma = K tr(eps) I + 2 psi(|dev eps|^2) dev(eps) of deformation theory (J. Necas and
    I. Hlavacek, Mathematical Theory of Elastic and Elasto-Plastic Bodies, Elsevier 1981),
    the usual example of a nonlinear elasticity operator in the contact literature (W. Han and
    M. Sofonea, Quasistatic Contact Problems in Viscoelasticity and Viscoplasticity, AMS
    2002), here with a power law: stiffening for m > 0, softening for -1/2 < m < 0, linear for m = 0
    (A eps = lambda tr(eps) I + 2 mu eps exactly). W is convex for m > -1/2 (psi > 0 and
    psi + 2 r psi'(r) > 0).

    Parameters
    ----------
    eps : UFL expression
        The strain (a UFL variable when differentiated).
    lmbda, mu : float or Constant
        The Lame constants of the small-strain limit.
    exponent : float
        m.
    strain_scale : float
        e_0, the deviatoric strain at which the secant modulus has changed by 2^m.

    Returns
    -------
    UFL expression
        W(eps).
    """
    d = eps.ufl_shape[0]
    inv = invariants(eps)
    K = lmbda + 2.0 * mu / d
    e0 = strain_scale
    if exponent == 0:
        return 0.5 * K * inv["tr_eps"] ** 2 + mu * inv["dev_eps2"]
    return (0.5 * K * inv["tr_eps"] ** 2 + mu * e0 ** 2 / (exponent + 1.0)
            * ((1.0 + inv["dev_eps2"] / e0 ** 2) ** (exponent + 1.0) - 1.0))


def energy_stress(eps, energy):
    """sigma = dW/deps, the stress of a strain-energy density (UFL's derivative).

    Parameters
    ----------
    eps : UFL expression
        The strain eps(u).
    energy : callable
        eps (a UFL variable) -> W(eps).

    Returns
    -------
    tuple
        (sigma, C): the stress dW/deps and the tangent d^2W/deps^2 (a fourth-order UFL
        tensor) at eps.
    """
    e = ufl.variable(eps)
    sigma = ufl.diff(energy(e), e)
    return sigma, ufl.diff(sigma, e)
