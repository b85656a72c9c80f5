"""The memory integral of eq (7), discretized by eq (19) and kept incrementally.

Prony kernels. R(t) eps = sum_i alpha_i exp(-t/tau_i) P_i eps, where P_i is the identity
("full"), the deviatoric part dev eps = eps - tr(eps)/d I, or the volumetric part tr(eps)/d I
(d the dimension of the strain). tau_i = inf gives the paper's constant kernel. Eq (19) is then,
with d_i = exp(-k/tau_i),

    H_{n+1} = sum_i alpha_i ( k/2 d_i^{n+1} e_0 + k sum_{j=1}^{n} d_i^{n+1-j} e_j
                              + k/2 d_i e_n ),            e_j = P_i eps_j,

so the weight is k/2 on eps_0 and 3k/2 on the newest strain (k when n = 0). Each term keeps

    B_i,n = k/2 d_i^{n+1} e_0 + k sum_{j=1}^{n} d_i^{n+1-j} e_j,
    B_i,0 = k/2 d_i e_0,   B_i,n+1 = d_i B_i,n + k d_i e_{n+1},

and then H_{n+1} = sum_i alpha_i (B_i,n + k/2 d_i e_n). That is O(1) work and memory per step.
The arrays are the values of DG tensor Functions; for P1 fields, DG0 holds eps exactly.

rule = "trapezoid" uses the trapezoid rule on the last sub-interval too:
H_{n+1} = sum_i alpha_i B_i,n + k/2 R(0) eps_{n+1}. The last term is implicit and goes to the
left-hand side (see :func:`implicit_weights`); :meth:`History.advance` returns the rest.
For the scalar analogue m u' = -alpha u with b = alpha k / m, the paper's rule is forward Euler
for the first step and then the two-step Adams-Bashforth method, stable for b < 1. The
trapezoid rule is the Crank-Nicolson method, stable for every b.

A general kernel (a table of R(t)) has no recursion. :class:`DirectHistory` sums eq (19)
directly, at O(n) work and memory per step.
"""
from __future__ import annotations

import math

import numpy as np

PARTS = ("full", "deviatoric", "volumetric")


def project(eps: np.ndarray, part: str, d: int) -> np.ndarray:
    """P eps for strain values stored as consecutive d x d blocks."""
    if part == "full":
        return eps
    blocks = eps.reshape(-1, d, d)
    volumetric = np.einsum("cii->c", blocks)[:, None, None] / d * np.eye(d)
    out = volumetric if part == "volumetric" else blocks - volumetric
    return out.reshape(eps.shape)


class History:
    """Incremental history stress of eq (19) for a Prony kernel [(alpha, tau, part)]."""

    def __init__(self, terms, k: float, rule: str = "paper", d: int = 2):
        self.terms = [(float(a), float(tau), part) for a, tau, part in terms]
        self.decays = [math.exp(-k / tau) for _, tau, _ in self.terms]   # 1 if tau = inf
        self.k, self.rule, self.d = k, rule, d
        self.sums: list[np.ndarray] | None = None   # B_i,n
        self.direct = False

    def advance(self, eps: np.ndarray) -> np.ndarray:
        """Take the converged strain eps_n of step n; return H_{n+1} (its explicit part for
        the trapezoid rule), the history stress of the next step."""
        k = self.k
        parts = {part: project(eps, part, self.d) for _, _, part in self.terms}
        if self.sums is None:
            self.sums = [0.5 * k * dec * parts[part]
                         for (_, _, part), dec in zip(self.terms, self.decays)]
        else:
            for s, (_, _, part), dec in zip(self.sums, self.terms, self.decays):
                s *= dec
                s += (k * dec) * parts[part]
        out = np.zeros_like(eps)
        for (a, _, part), dec, s in zip(self.terms, self.decays, self.sums):
            out += a * s
            if self.rule == "paper":
                out += (a * 0.5 * k * dec) * parts[part]
        return out


class DirectHistory:
    """Eq (19) summed term by term for a general kernel R(t) eps = r(t) eps."""

    def __init__(self, r, k: float, rule: str = "paper"):
        self.r, self.k, self.rule = r, k, rule
        self.strains: list[np.ndarray] = []
        self.direct = True

    def advance(self, eps: np.ndarray) -> np.ndarray:
        self.strains.append(eps.copy())
        return direct_sum(lambda t, e: self.r(t) * e, self.k, self.strains, self.rule)


def prony(terms, d: int):
    """R(t, eps) of a Prony kernel, for :func:`direct_sum`."""
    def R(t, eps):
        return sum(a * math.exp(-t / tau) * project(eps, part, d) for a, tau, part in terms)
    return R


def table_kernel(times, values):
    """r(t) interpolated linearly in a table, constant beyond its ends."""
    times, values = np.asarray(times, float), np.asarray(values, float)
    return lambda t: float(np.interp(t, times, values))


def implicit_weights(terms, k: float, rule: str) -> dict[str, float]:
    """Per part, the weight c of the implicit term c P eps(u_{n+1}) of the history stress:
    k/2 R(0) for the trapezoid rule, nothing for the paper's rule."""
    if rule != "trapezoid":
        return {}
    out: dict[str, float] = {}
    for a, _, part in terms:
        out[part] = out.get(part, 0.0) + 0.5 * k * a
    return out


def direct_sum(R, k: float, strains: list[np.ndarray], rule: str = "paper"):
    """Eq (19) term by term: the history stress at t_n, n = len(strains), from eps_0..eps_{n-1}.
    For the trapezoid rule it is the explicit part, without k/2 R(0) eps_n. R(t, eps) applies
    the kernel at time t. O(n) work."""
    n = len(strains)
    out = 0.5 * k * R(n * k, strains[0])
    for j in range(1, n):
        out = out + k * R((n - j) * k, strains[j])
    if rule == "trapezoid":
        return out
    return out + 0.5 * k * R(k, strains[n - 1])
