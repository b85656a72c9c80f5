"""The depth of a rigid sphere creeping into a viscoelastic half-space under a force history,
by Lee and Radok's correspondence (a contact that does not shrink; Lee and Radok 1960, Ting
1966): the closed form that starts an identification (docs/identification.md).

The scene's law sigma = A eps + int_0^t R(t - s) P eps(s) ds with Prony terms
R = sum_i alpha_i exp(-t/tau_i) on the deviatoric, volumetric or full strain has, for a strain
step, the relaxation moduli

    G(t) = mu + sum_dev,full alpha_i tau_i (1 - exp(-t/tau_i)) / 2,
    K(t) = K + sum_vol,full alpha_i tau_i (1 - exp(-t/tau_i)) / 3,

Prony series G_inf + sum_i G_i exp(-t/tau_i). In Laplace variables s G~(s) = N(s)/D(s),
D = prod_i (s + b_i), b_i = 1/tau_i, N = G_inf D + sum_i G_i s prod_{j != i} (s + b_j), so the
creep compliance J = L^-1[D / (s N)] is, by partial fractions over the roots r_k of N,

    J(t) = 1/G_inf + sum_k D(r_k) / (r_k N'(r_k)) exp(r_k t).

Hertz's contact compliance 1/E* = 1/(4 G) + 3/(4 (3K + G)) becomes C(t) = J_G(t)/4 +
3 J_M(t)/4, M = 3K + G, and under a force P(t) (piecewise linear, P(0) applied at t = 0)

    a(t)^3 = 3R/4 [C(t) P(0) + int_0^t C(t - s) P'(s) ds],     delta(t) = a(t)^2 / R.
"""
from __future__ import annotations

import math

import numpy as np

from contactvisco.errors import SceneError
from contactvisco.model.material import lame_constants
from contactvisco.model.memory_kernel import memory_terms


def relaxation_moduli(scene: dict) -> tuple:
    """(G_inf, {tau: G_i}, K_inf, {tau: K_i}) of a scene's material and Prony memory (module
    description); SceneError for a memory that does not relax to a positive modulus."""
    mat = scene["material"]
    lam, mu = lame_constants("3d", mat["E"], mat["nu"])
    K = lam + 2.0 * mu / 3.0
    G_terms, K_terms = {}, {}
    G_inf, K_inf = mu, K
    for alpha, tau, part in memory_terms(scene):
        if not math.isfinite(tau):
            raise SceneError("memory: a constant kernel (tau = inf) has no Lee-Radok closed "
                             "form", key="memory")
        if part in ("deviatoric", "full"):
            G_inf += alpha * tau / 2.0
            G_terms[tau] = G_terms.get(tau, 0.0) - alpha * tau / 2.0
        if part in ("volumetric", "full"):
            K_inf += alpha * tau / 3.0
            K_terms[tau] = K_terms.get(tau, 0.0) - alpha * tau / 3.0
    if not (G_inf > 0 and K_inf > 0):
        raise SceneError("viscoelastic: the long-time moduli must be > 0 for the Lee-Radok "
                         "closed form", key="viscoelastic")
    return G_inf, G_terms, K_inf, K_terms


def compliance(infinite: float, terms: dict) -> tuple[float, np.ndarray, np.ndarray]:
    """The creep compliance of the relaxation modulus infinite + sum_tau G_tau exp(-t/tau):
    (1/G_inf, residues rho_k, rates r_k) with J(t) = 1/G_inf + sum_k rho_k exp(r_k t)."""
    items = [(1.0 / tau, g) for tau, g in terms.items() if g != 0.0]
    if not items:
        return 1.0 / infinite, np.zeros(0), np.zeros(0)
    D = np.poly1d([1.0])
    for b, _ in items:
        D = D * np.poly1d([1.0, b])
    N = infinite * D
    for i, (b, g) in enumerate(items):
        others = np.poly1d([1.0])
        for j, (c, _) in enumerate(items):
            if j != i:
                others = others * np.poly1d([1.0, c])
        N = N + g * np.poly1d([1.0, 0.0]) * others
    roots = np.real_if_close(N.roots)
    if np.iscomplexobj(roots) or np.any(roots >= 0):
        raise SceneError("viscoelastic: a relaxation modulus without a monotone creep "
                         "compliance has no Lee-Radok closed form here", key="viscoelastic")
    residues = D(roots) / (roots * N.deriv()(roots))
    return 1.0 / infinite, residues, roots


def contact_compliance(scene: dict):
    """C(t) = J_G(t)/4 + 3 J_M(t)/4 as (c0, residues, rates) (module description)."""
    G_inf, G_terms, K_inf, K_terms = relaxation_moduli(scene)
    M_terms = {tau: 3.0 * K_terms.get(tau, 0.0) + G_terms.get(tau, 0.0)
               for tau in set(G_terms) | set(K_terms)}
    g0, g_res, g_rates = compliance(G_inf, G_terms)
    m0, m_res, m_rates = compliance(3.0 * K_inf + G_inf, M_terms)
    return (g0 / 4.0 + 0.75 * m0, np.concatenate([g_res / 4.0, 0.75 * m_res]),
            np.concatenate([g_rates, m_rates]))


def creep_depth(scene: dict, t: np.ndarray, force: np.ndarray, radius: float) -> np.ndarray:
    """delta(t_j) of a sphere of radius R under the force |P| piecewise linear through the
    samples (t_j, P_j), P_0 applied at t = 0 (module description).

    Parameters
    ----------
    scene : dict
        The resolved scene (its material and Prony memory).
    t, force : numpy.ndarray
        Sample times (increasing, t_0 = 0) and the force's total (its sign is dropped).
    radius : float
        R.

    Returns
    -------
    numpy.ndarray
        The depth at each t_j.
    """
    c0, rho, rates = contact_compliance(scene)
    t, P = np.asarray(t, float), np.abs(np.asarray(force, float))

    def C(u):
        return c0 + np.sum(rho * np.exp(rates * u))

    out = []
    for tj in t:
        total = C(tj - t[0]) * P[0]
        for s0, s1, p0, p1 in zip(t[:-1], t[1:], P[:-1], P[1:]):
            if s0 >= tj:
                break
            end = min(s1, tj)
            slope = (p1 - p0) / (s1 - s0)
            # int_s0^end exp(r (tj - s)) ds, without cancellation for small |r| (expm1)
            segment = np.exp(rates * (tj - end)) * np.expm1(rates * (end - s0)) / rates
            total += slope * (c0 * (end - s0) + np.sum(rho * segment))
        a = (0.75 * radius * total) ** (1.0 / 3.0)
        out.append(a * a / radius)
    return np.array(out)
