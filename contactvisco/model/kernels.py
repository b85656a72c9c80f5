"""Power-law memory kernels as sums of exponentials, and the Mittag-Leffler function.

Two kernels with a power-law tail (P the full, deviatoric or volumetric part):

    power:       R(t) = alpha (1 + t/tau)^(-beta) P                 finite at 0
    fractional:  R(t) = alpha t^(-beta) / Gamma(1 - beta) P          0 < beta < 1

Both are completely monotone: with u^(-beta) = 1/Gamma(beta) int_0^inf s^(beta-1) e^(-s u) ds,

    u^(-beta) = 1/Gamma(beta) int_R exp(beta x - e^x u) dx          (s = e^x).

:func:`soe_power` discretizes this integral into a sum of exponentials (SOE)
sum_j w_j exp(-s_j u) with a relative error below `tol` on [lo, hi]:
- the trapezoid rule in x = log s with step h (Beylkin & Monzon, Appl. Comput.
  Harmon. Anal. 28 (2010) 131-149; McLean, "Exponential sum approximations for t^(-beta)",
  in: Contemporary Computational Mathematics, Springer 2018, 911-930): the integrand is
  analytic for |Im x| < pi/2, so the error falls like exp(-pi^2/h); the range of x is cut
  where the dropped terms add less than tol/10;
- the slow terms, s < e^(x_c) = 0.14/hi (nearly constant over [lo, hi]; about
  log(1/tol)/(beta h) of them), are replaced by the Gauss rule of their discrete measure with a
  few nodes (it keeps their first moments; the model reduction of McLean 2018, which uses
  Prony's method, and the role of the Gauss-Jacobi panel of Jiang, Zhang, Zhang & Zhang,
  Commun. Comput. Phys. 21 (2017) 650-678).
h and the Gauss order are refined until the error measured on 4000 points of [lo, hi]
(logarithmically spaced) is below tol; that measured error is returned. The number of terms is
about (log(hi/lo) + log log(1/tol)) / h + const: it grows like log(T/k) for a fixed tol.

mittag_leffler() computes E_gamma(-x), x >= 0, 0 < gamma <= 1, from the integral
representation (Gorenflo & Mainardi 1997; Gorenflo, Loutchko & Luchko, Fract. Calc. Appl.
Anal. 5 (2002) 491-518)

    E_gamma(-t^gamma) = int_0^inf exp(-r t) K(r) dr,
    K(r) = sin(gamma pi)/pi  r^(gamma-1) / (r^(2 gamma) + 2 r^gamma cos(gamma pi) + 1),

a positive integrand (no cancellation), integrated by the trapezoid rule in log r; the power
series sum_j (-x)^j / Gamma(gamma j + 1) for x <= 1.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass
class SOE:
    """sum_j weights_j exp(-rates_j t), with its measured relative error over [lo, hi]."""
    weights: np.ndarray
    rates: np.ndarray
    error: float
    lo: float
    hi: float

    def __len__(self):
        return len(self.rates)

    def __call__(self, t):
        t = np.asarray(t, float)
        return np.exp(-np.multiply.outer(t, self.rates)) @ self.weights


def _measure(weights, rates, beta, u, logu):
    """max over u of |sum_j w_j exp(-s_j u) u^beta - 1|."""
    approx = np.exp(-np.multiply.outer(u, rates)) @ weights
    return float(np.max(np.abs(approx * np.exp(beta * logu) - 1.0)))


def _gauss_reduce(weights, rates, scale, order):
    """Gauss rule with `order` = n points of the discrete measure sum_j w_j delta(s - s_j)
    (Lanczos on diag(s / scale) from sqrt(w), with full re-orthogonalization, then the Jacobi
    matrix, Golub & Welsch 1969): it keeps the moments sum_j w_j s_j^m, m < 2n, so for
    s u <= scale the sum changes by O(scale^(2n) / (2n)!)."""
    order = min(order, len(rates))
    x = rates / scale
    total = weights.sum()
    q = np.sqrt(weights / total)
    Q, a, b = [q], [], []
    for i in range(order):
        residual = x * Q[-1]
        a.append(Q[-1] @ residual)
        for old in Q:
            residual = residual - (old @ residual) * old
        if i < order - 1:
            b.append(np.linalg.norm(residual))
            if b[-1] < 1e-14:
                break
            Q.append(residual / b[-1])
    m = len(a)
    jacobi = np.diag(a) + np.diag(b[:m - 1], 1) + np.diag(b[:m - 1], -1)
    nodes, vectors = np.linalg.eigh(jacobi)
    return total * vectors[0] ** 2, scale * np.clip(nodes, 0.0, None)


def soe_power(beta: float, lo: float, hi: float, tol: float) -> SOE:
    """u^(-beta) ~ sum_j w_j exp(-s_j u) on [lo, hi], relative error <= tol (measured)."""
    if not (beta > 0 and 0 < lo < hi and 0 < tol < 1):
        raise ValueError(f"soe_power needs beta > 0, 0 < lo < hi, 0 < tol < 1; got "
                         f"{beta}, {lo}, {hi}, {tol}")
    u = np.geomspace(lo, hi, 4000)
    logu = np.log(u)
    x_c = -math.log(hi) - 2.0           # rates below e^(x_c) = 0.14 / hi: the slow group
    x_max = math.log((math.log(1.0 / tol) + 40.0) / lo)
    norm = 1.0 / math.gamma(beta)
    # The integrand is analytic for |Im x| < pi/2: the trapezoid error is ~ exp(-pi^2 / h).
    h = math.pi**2 / math.log(10.0 / tol)
    gauss = 3
    for _ in range(40):
        # Down to x_min, where the rest of the geometric tail adds < tol/10 at u = hi.
        tail = tol / 10 * math.gamma(beta) * (1 - math.exp(-beta * h)) / h
        x_min = (math.log(tail) - beta * math.log(hi)) / beta
        x = x_c + h * np.arange(math.floor((x_min - x_c) / h), math.ceil((x_max - x_c) / h))
        w = h * norm * np.exp(beta * x)
        s = np.exp(x)
        slow = x < x_c
        # Fast end: drop the terms that together add < tol/10 at every u.
        share = np.exp(np.log(w[~slow])[:, None] - np.multiply.outer(s[~slow], u)
                       + beta * logu[None, :])
        keep = np.cumsum(share[::-1], axis=0)[::-1].max(axis=1) > 0.1 * tol
        if slow.any():
            w_slow, s_slow = _gauss_reduce(w[slow], s[slow], math.exp(x_c), gauss)
        else:                            # a large beta: the tail ends above x_c
            w_slow, s_slow = np.zeros(0), np.zeros(0)
        weights = np.concatenate([w_slow, w[~slow][keep]])
        rates = np.concatenate([s_slow, s[~slow][keep]])
        error = _measure(weights, rates, beta, u, logu)
        if error <= tol:
            return SOE(weights, rates, error, lo, hi)
        # Which part misses? The slow group alone against its full sum, at u = hi.
        full = w[slow] @ np.exp(-s[slow] * hi)
        if slow.any() and gauss < 12 and \
                abs(w_slow @ np.exp(-s_slow * hi) - full) * hi**beta > 0.2 * tol:
            gauss += 1
        else:
            h *= 0.9
    raise RuntimeError(f"no sum of exponentials reaches {tol} for beta = {beta} on "
                       f"[{lo}, {hi}]")


def power_soe(alpha: float, beta: float, tau: float, T: float, tol: float) -> SOE:
    """alpha (1 + t/tau)^(-beta) on [0, T]: u = 1 + t/tau in [1, 1 + T/tau], so
    w_j exp(-s_j u) = (w_j e^(-s_j)) exp(-(s_j/tau) t)."""
    fit = soe_power(beta, 1.0, 1.0 + T / tau, tol)
    return SOE(alpha * fit.weights * np.exp(-fit.rates), fit.rates / tau, fit.error, 0.0, T)


class PowerTerms:
    """The power kernel's sum of exponentials with its rates frozen, for parameters that move:
    with v = t/tau, the fit of `fit` (power_soe at alpha_0, beta_0, tau_0 over [0, end])

        alpha (1 + v)^-beta ~ sum_j c_j exp(-S_j v),   S_j = rates_j tau_0,

    keeps the dimensionless rates S_j, and the coefficients for (alpha, beta) are the fit's
    own plus the least squares fit of the change of the kernel,

        c = alpha [c_0 + Q^+ (q ((1 + v)^-beta - (1 + v)^-beta_0))],   c_0 = weights / alpha_0,

    Q = diag(q) [exp(-S_j v_i)], q = (1 + v)^beta_0 (relative error), on a log grid of
    1 + v over [1, 1 + end/tau_0]. Q^+ is computed once, so the terms (c_j, tau / S_j) are
    the fit's at the reference, linear in alpha and in (1 + v)^-beta, smooth in beta and tau,
    with as many terms as the fit: what forward sensitivities differentiate
    (contactvisco.solver.sensitivity). The change's fit adds an error of the order of
    |beta - beta_0| times the fit's tolerance (`error` at beta_0 +- 0.05, measured).

    Parameters
    ----------
    fit : SOE
        power_soe(alpha_0, beta_0, tau_0, end, tol).
    alpha, beta, tau, end : float
        The reference parameters and the fitted span.
    """

    def __init__(self, fit: SOE, alpha: float, beta: float, tau: float, end: float):
        self.S = np.asarray(fit.rates, float) * tau
        self.c0 = np.asarray(fit.weights, float) / alpha
        self.beta0 = beta
        self.v = np.geomspace(1.0, 1.0 + end / tau, 2000) - 1.0
        self.q = (1.0 + self.v) ** beta
        E = np.exp(-np.outer(self.v, self.S))
        # a truncated pseudo-inverse: the rates are nearly dependent (condition about 1e15);
        # cut at 1e-8 the change is fitted to about the tolerance and the roundoff of
        # central differences of the change is not amplified beyond 1e-9 relative
        self.pinv = np.linalg.pinv(self.q[:, None] * E, rcond=1e-8)
        self.error = max(float(np.max(np.abs(self.q ** (b / beta) * (E @ self(1.0, b, 1.0)[0])
                                             - 1.0))) for b in (beta - 0.05, beta + 0.05))

    def __call__(self, alpha: float, beta: float, tau: float):
        """(coefficients c_j, relaxation times tau / S_j) of alpha (1 + t/tau)^-beta."""
        change = self.q * ((1.0 + self.v) ** -beta - (1.0 + self.v) ** -self.beta0)
        return alpha * (self.c0 + self.pinv @ change), tau / self.S


def fractional_soe(alpha: float, beta: float, lo: float, T: float, tol: float) -> SOE:
    """alpha t^(-beta) / Gamma(1 - beta) on [lo, T] (lo the smallest step)."""
    fit = soe_power(beta, lo, T, tol)
    return SOE(alpha / math.gamma(1.0 - beta) * fit.weights, fit.rates, fit.error, lo, T)


def ml_series(gamma: float, x) -> np.ndarray:
    """E_gamma(-x) = sum_j (-x)^j / Gamma(gamma j + 1), for 0 <= x <= 1 (no term above
    1/Gamma(gamma j + 1) <= 1.13: no cancellation; gamma = 1 also to x = 3)."""
    x = np.atleast_1d(np.asarray(x, float))
    terms = np.arange(int(40.0 / gamma) + 2)     # 1 / Gamma(gamma j + 1) < 1e-30 beyond
    coefficients = np.array([(-1.0) ** j / math.gamma(gamma * j + 1.0) for j in terms])
    return np.power.outer(x, terms) @ coefficients


def ml_integral(gamma: float, x) -> np.ndarray:
    """E_gamma(-x), 0 < gamma < 1, from the integral representation of the module docstring
    with t = x^(1/gamma), r = e^y: int K(r) r e^(-r t) dy by the trapezoid rule in y."""
    t = np.atleast_1d(np.asarray(x, float)) ** (1.0 / gamma)
    # The peak near r = 1 narrows like sin(gamma pi) as gamma -> 1; the r^gamma tail at 0
    # needs y down to log(1e-17) / gamma; e^(-r t) ends it for r t > 40.
    dy = min(0.05, 0.2 * math.sin(gamma * math.pi) / gamma)
    top = math.log(60.0 / max(float(t.min()), 1e-300))
    y = np.arange(min(-40.0, math.log(1e-17) / gamma), max(top, 1.0), dy)
    r = np.exp(y)
    c = math.cos(gamma * math.pi)
    K = math.sin(gamma * math.pi) / math.pi * r**gamma / (r**(2 * gamma) + 2 * c * r**gamma + 1)
    return dy * (np.exp(-np.multiply.outer(t, r)) @ K)


def mittag_leffler(gamma: float, x) -> np.ndarray:
    """E_gamma(-x) for x >= 0 and 0 < gamma <= 1: the series for x <= 1, the integral
    representation beyond; E_1(-x) = exp(-x)."""
    x = np.atleast_1d(np.asarray(x, float))
    if not 0 < gamma <= 1 or np.any(x < 0):
        raise ValueError(f"mittag_leffler needs 0 < gamma <= 1 and x >= 0; got {gamma}")
    if gamma == 1.0:
        return np.exp(-x)
    out = np.empty_like(x)
    small = x <= 1.0
    out[small] = ml_series(gamma, x[small])
    if np.any(~small):
        out[~small] = ml_integral(gamma, x[~small])
    return out


def history(mem: dict, time: dict, max_cuts: int, d: int, span: float | None = None,
            least: float = 1.0):
    """The history of a power or fractional kernel (the resolved memory and time tables):
    the sum of exponentials over [k / 2^max_cuts, T] (k the grid's smallest step: the smallest
    step a cut may take, so the fit covers every step of any grid) run by the Prony recursion, or the direct O(n) sum. Its `note` says which, with the number of
    exponentials and the measured error of the fit.

    Parameters
    ----------
    mem, time : dict
        The [memory] and [time] tables.
    max_cuts : int
        The most step cuts (the smallest step k / 2^max_cuts, k the grid's smallest).
    d : int
        The dimension of the strain.
    span : float, optional
        In reduced time (a temperature), the end xi(T) that the power kernel's fit must cover
        (T by default): alpha (1 + xi/tau)^-beta on [0, span], and the fractional kernel's
        alpha xi^-beta / Gamma(1 - beta) on [least k / 2^max_cuts, span]; kept as the
        attribute `span`.
    least : float, optional
        In reduced time, the smallest 1/a_T a step may see (1 by default): the shortest
        reduced step is then least k / 2^max_cuts.

    Returns
    -------
    History, FractionalHistory, DirectHistory or DirectFractionalHistory
        With `note` (and `fit` for a sum of exponentials).
    """
    from contactvisco.model.memory import (DirectFractionalHistory, DirectHistory,
        FractionalHistory, History)
    alpha, beta, part = float(mem["alpha"]), float(mem["beta"]), mem["part"]
    from contactvisco.model import time_grid
    T, rule = float(time["T"]), time["rule"]
    # the grid's smallest step: older steps of the product integration start there (or at
    # its halves, once cut), whatever the grid's kind
    k = float(time_grid.steps(time).min())
    if mem["kernel"] == "power":
        tau = float(mem["tau"])
        if mem["summation"] == "direct":
            out = DirectHistory(lambda t: alpha * (1.0 + t / tau) ** -beta, k, rule, part, d)
            out.note = ("memory: power kernel summed directly (exact kernel), O(n) work and "
                        "memory per step")
            return out
        end = T if span is None else float(span)
        fit = power_soe(alpha, beta, tau, end, float(mem["tolerance"]))
        out = History([(w, 1.0 / s, part) for w, s in zip(fit.weights, fit.rates)], k, rule, d)
        out.span = span
        span = f"[0, {end:g}]" + ("" if span is None else " in reduced time")
    else:
        if mem["summation"] == "direct":
            out = DirectFractionalHistory(alpha, beta, rule, part, d, k)
            out.note = ("memory: fractional kernel, product integration with the exact kernel, "
                        "O(n) work and memory per step")
            return out
        lo = k / 2 ** max_cuts * (1.0 if span is None else float(least))
        end = T if span is None else float(span)
        fit = fractional_soe(alpha, beta, lo, end, float(mem["tolerance"]))
        out = FractionalHistory(alpha, beta, fit, rule, part, d, k)
        out.span = span
        span = f"[{lo:.3g}, {end:g}]" + ("" if span is None else " in reduced time")
    out.fit = fit
    out.note = (f"memory: {mem['kernel']} kernel as a sum of {len(fit)} exponentials, "
                f"measured relative error {fit.error:.2e} on {span} (memory.tolerance "
                f"{float(mem['tolerance']):g}); O({len(fit)}) work and memory per step")
    return out
