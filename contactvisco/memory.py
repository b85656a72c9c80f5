"""The memory integral of eq (7), discretized by eq (19) and kept incrementally.

For a kernel R(t) = sum_i alpha_i exp(-t/tau_i) I (tau_i = inf for the constant kernel of the
paper) eq (19) reads, with d_i = exp(-k/tau_i),

    H_{n+1} = sum_i alpha_i ( k/2 d_i^{n+1} eps_0 + k sum_{j=1}^{n} d_i^{n+1-j} eps_j
                              + k/2 d_i eps_n ),

i.e. weight k/2 on eps_0 and 3k/2 on the newest strain (k at n = 0). Each term keeps

    B_i,n = k/2 d_i^{n+1} eps_0 + k sum_{j=1}^{n} d_i^{n+1-j} eps_j,
    B_i,0 = k/2 d_i eps_0,   B_i,n+1 = d_i B_i,n + k d_i eps_{n+1},

so that H_{n+1} = sum_i alpha_i (B_i,n + k/2 d_i eps_n): O(1) work and memory per step.
The arrays are the values of DG0 tensor Functions (exact for eps of P1 fields).

rule = "trapezoid" applies the trapezoid rule on the last sub-interval as well:
H_{n+1} = sum_i alpha_i B_i,n + k/2 R(0) eps_{n+1}; the last term is implicit and goes to the
left-hand side (:func:`implicit_coefficient`), the rest is what :meth:`History.advance` returns.
Scalar analogue m u' = -alpha u with b = alpha k / m: the paper's rule is forward Euler for the
first step, then the two-step Adams-Bashforth method (stable for b < 1); the trapezoid rule is
the Crank-Nicolson method (stable for every b).
"""
from __future__ import annotations

import math

import numpy as np


class History:
    """Incremental history stress H of eq (19) over arrays of strain values."""

    def __init__(self, terms: list[tuple[float, float]], k: float, rule: str = "paper"):
        self.alphas = np.array([a for a, _ in terms], dtype=float)
        self.decays = np.array([math.exp(-k / t) for _, t in terms], dtype=float)  # 1 if tau = inf
        self.k = k
        self.rule = rule
        self.sums: list[np.ndarray] | None = None   # B_i,n
        self.steps = 0                               # strains seen

    def advance(self, eps: np.ndarray) -> np.ndarray:
        """Take the converged strain eps_n of step n; return H_{n+1}, the history stress
        for the next step."""
        k = self.k
        if self.sums is None:
            self.sums = [0.5 * k * d * eps for d in self.decays]
        else:
            for s, d in zip(self.sums, self.decays):
                s *= d
                s += k * d * eps
        self.steps += 1
        out = np.zeros_like(eps)
        for a, d, s in zip(self.alphas, self.decays, self.sums):
            out += a * s
            if self.rule == "paper":
                out += (a * 0.5 * k * d) * eps
        return out


def implicit_coefficient(terms, k: float, rule: str) -> float:
    """The weight c of the implicit part c eps(u_{n+1}) of the history stress: k/2 R(0) for
    the trapezoid rule, 0 for the paper's rule."""
    return 0.5 * k * sum(a for a, _ in terms) if rule == "trapezoid" else 0.0


def direct_sum(terms: list[tuple[float, float]], k: float, strains: list[np.ndarray],
               rule: str = "paper"):
    """Eq (19) term by term: the history stress at t_n, n = len(strains), from eps_0..eps_{n-1}
    (for the trapezoid rule, its explicit part: without k/2 R(0) eps_n).

    O(n) work; used to check :class:`History`, and for kernels without a recursion.
    """
    n = len(strains)

    def R(t):
        return sum(a * (1.0 if math.isinf(tau) else math.exp(-t / tau)) for a, tau in terms)

    out = 0.5 * k * R(n * k) * strains[0]
    for j in range(1, n):
        out = out + k * R((n - j) * k) * strains[j]
    if rule == "trapezoid":
        return out
    return out + 0.5 * k * R(k) * strains[n - 1]
