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
trapezoid rule is the Crank-Nicolson method, stable for every b; its implicit stiffness
A + k/2 R(0) stays positive only for k < 2A/|R(0)|.

rule = "exponential" integrates each exponential term exactly against the strain taken linear
over each step (the recursive algorithm of Taylor, Pister & Goudreau, IJNME 2 (1970) 45;
Simo & Hughes, Computational Inelasticity (1998) ch. 10). With S_i,n = int_0^{t_n}
exp(-(t_n - s)/tau_i) e_i(s) ds and z = k/tau_i (:func:`exponential_weights`):

    S_i,n+1 = d_i S_i,n + w0_i e_n + w1_i e_{n+1},
    w0 = tau^2 (1 - d)/k - tau d = k phi2(z),   w1 = tau (1 - d) - w0 = k (phi1 - phi2)(z),

H_{n+1} = sum_i alpha_i S_i,n+1, whose w1 term is implicit. alpha w1 -> alpha k/2 (the
trapezoid) for k << tau and -> alpha tau = -G_i for k >> tau: the step's stiffness
A + sum_i alpha_i w1_i stays >= the long-term modulus for every k; second order, and exact
for a piecewise-linear strain. tau = inf gives w0 = w1 = k/2, the trapezoid rule.

A general kernel (a table of R(t)) has no recursion. :class:`DirectHistory` sums eq (19)
directly, at O(n) work and memory per step.

Power-law kernels (contactvisco/kernels.py) become sums of exponentials: the power kernel,
finite at 0, then runs as a Prony kernel in :class:`History`. The fractional kernel
alpha t^-beta / Gamma(1 - beta) is infinite at 0: :class:`FractionalHistory` integrates it
exactly against the piecewise-linear strain (product integration), the last step with the
exact kernel and older steps through the exponentials; :class:`DirectFractionalHistory` is
its O(n) reference with the exact kernel throughout.

With a temperature, :class:`ReducedTimeHistory` advances a Prony history in reduced time and
:class:`ReducedFractionalHistory` the fractional one (the last step's exact weights at the
reduced step dxi of each point).
"""
from __future__ import annotations

import math

import numpy as np

from contactvisco.model import time_error

PARTS = ("full", "deviatoric", "volumetric")

#: time.rule: eq (19) as printed, the trapezoid rule on the last sub-interval, and each
#: exponential integrated exactly against the strain taken linear over each step.
RULES = ("paper", "trapezoid", "exponential")

#: Below this z = k/tau, phi1 and phi2 are summed as their Taylor series (the closed forms
#: cancel: 1 - e^-z (1 + z) ~ z^2/2).
SERIES_BELOW = 0.1


def _phi_exact(z):
    """phi1 = (1 - e^-z)/z and phi2 = (1 - e^-z (1 + z))/z^2 for z >= 0 (arrays), to round-off:
    Taylor series phi1 = sum_n (-z)^n/(n+1)!, phi2 = sum_n (n+1) (-z)^n/(n+2)! (14 terms,
    truncation below 1e-20) under SERIES_BELOW, the closed forms (expm1) above."""
    z = np.asarray(z, float)
    small = z < SERIES_BELOW
    zs = np.where(small, 1.0, z)
    phi1 = -np.expm1(-zs) / zs
    phi2 = (-np.expm1(-zs) - zs * np.exp(-zs)) / zs**2
    if np.any(small):
        s1 = np.zeros_like(z)
        s2 = np.zeros_like(z)
        for n in range(13, -1, -1):                       # Horner in -z
            s1 = s1 * -z + 1.0 / math.factorial(n + 1)
            s2 = s2 * -z + (n + 1) / math.factorial(n + 2)
        phi1 = np.where(small, s1, phi1)
        phi2 = np.where(small, s2, phi2)
    return phi1, phi2


def exponential_weights(k, tau: float):
    """The weights of one step of the exponential rule for the term exp(-t/tau).

    For e linear on [t_n, t_n + k] (sigma = t_{n+1} - s),
    int_0^k exp(-sigma/tau) e(s) dsigma = w0 e_n + w1 e_{n+1} with, z = k/tau, d = exp(-z),

        w0 = tau^2 (1 - d)/k - tau d = k phi2(z),     w1 = tau (1 - d) - w0 = k (phi1 - phi2)(z),
        phi1 = (1 - e^-z)/z,   phi2 = (1 - e^-z (1 + z))/z^2,

    evaluated without cancellation for small z (series). w1 -> k/2 for z -> 0 and -> tau for
    z -> inf; tau = inf gives d = 1, w0 = w1 = k/2 (the trapezoid rule).

    Parameters
    ----------
    k : float or numpy.ndarray
        The step (or the reduced-time increments, one per point), >= 0.
    tau : float
        The relaxation time, > 0 (inf: the constant kernel).

    Returns
    -------
    tuple
        (d, w0, w1), numbers for a number k, else arrays shaped like k.
    """
    array = isinstance(k, np.ndarray)
    z = np.asarray(k, float) / tau
    phi1, phi2 = _phi_exact(z)
    d, w0, w1 = np.exp(-z), k * phi2, k * (phi1 - phi2)
    if array:
        return d, w0, w1
    return float(d), float(w0), float(w1)


def project(eps: np.ndarray, part: str, d: int) -> np.ndarray:
    """P eps for strain values stored as consecutive d x d blocks."""
    if part == "full":
        return eps
    blocks = eps.reshape(-1, d, d)
    volumetric = np.einsum("cii->c", blocks)[:, None, None] / d * np.eye(d)
    out = volumetric if part == "volumetric" else blocks - volumetric
    return out.reshape(eps.shape)


class History:
    """History stress of eq (19) for a Prony kernel [(alpha, tau, part)], incremental.

    Steps may differ in size (step cutting). With P_n the trapezoid sum over [t_0, t_n] at t_n
    (weights k_1/2, (k_j + k_{j+1})/2, k_n/2) and d = exp(-k/tau) for the next step k:

        P_{n+1} = d P_n + k/2 (d e_n + e_{n+1})                    (commit)
        H_{n+1} = sum_i alpha_i (d_i P_i,n + c k d_i e_i,n)        (explicit)

    with c = 1 for the paper's rule (left point on the last sub-interval) and c = 1/2 for the
    trapezoid rule, whose remaining k/2 R(0) eps_{n+1} is implicit. For uniform steps this is
    eq (19) term by term; each call is O(1) in the number of steps.

    rule = "exponential" keeps instead S_i,n, each term integrated exactly against the
    piecewise-linear strain (:func:`exponential_weights`):

        S_{n+1} = d S_n + w0 e_n + w1 e_{n+1}                      (commit)
        H_{n+1} = sum_i alpha_i (d_i S_i,n + w0_i e_i,n)           (explicit)

    and sum_i alpha_i w1_i P_i eps_{n+1} is implicit.
    """

    def __init__(self, terms, k: float = None, rule: str = "paper", d: int = 2):
        self.terms = [(float(a), float(tau), part) for a, tau, part in terms]
        self.k, self.rule, self.d = k, rule, d
        self.sums: list[np.ndarray] | None = None   # P_i,n
        self.last: dict | None = None               # parts of eps_n
        self.direct = False
        # An adaptive grid (solver.step_control) sets keep_previous: eps_{n-1} is then kept
        # (and checkpointed) and each commit estimates the step's local error (time_error).
        self.keep_previous = False
        self.previous: dict | None = None           # parts of eps_{n-1}
        self.last_k: float | None = None            # k_n, between eps_{n-1} and eps_n
        self.local_error: tuple | None = None       # (max |e_{n+1}|, max |eps_{n+1}|) here

    def commit(self, eps: np.ndarray, k: float | None):
        """Take the strain of a converged state, reached by a step of size k (None at t_0)."""
        parts = {part: project(eps, part, self.d).copy() for _, _, part in self.terms}
        if self.sums is None:
            self.sums = [np.zeros_like(eps) for _ in self.terms]
        else:
            for total, (_, tau, part) in zip(self.sums, self.terms):
                if self.rule == "exponential":
                    dec, w0, w1 = exponential_weights(k, tau)
                    total *= dec
                    total += w0 * self.last[part] + w1 * parts[part]
                    continue
                dec = _decay(k, tau)                  # 1 if tau = inf
                total *= dec
                total += (0.5 * k * dec) * self.last[part] + (0.5 * k) * parts[part]
        if self.keep_previous:
            self._estimate(parts, eps, k)
        self.last = parts

    def _estimate(self, parts: dict, eps: np.ndarray, k: float | None):
        """local_error of the step k to the strain `parts` (model.time_error), None until
        three strains are known; then eps_n becomes the previous strain."""
        self.local_error = None
        if self.previous is not None and k is not None and self.last_k is not None:
            error = np.zeros_like(eps)
            for a, tau, part in self.terms:
                curvature = time_error.second_difference(
                    self.previous[part], self.last[part], parts[part], self.last_k, k)
                error += (a * time_error.curvature_weight(k, tau)) * curvature
            self.local_error = (float(np.abs(error).max()) if error.size else 0.0,
                                float(np.abs(eps).max()) if eps.size else 0.0)
        self.previous = self.last
        self.last_k = k

    def explicit(self, k: float) -> np.ndarray:
        """The history stress (its explicit part for the trapezoid rule) of a step of size k
        from the committed state; nothing is changed, so a failed step can be retried."""
        c = 1.0 if self.rule == "paper" else 0.5
        out = np.zeros_like(self.sums[0])
        for (a, tau, part), total in zip(self.terms, self.sums):
            if self.rule == "exponential":
                dec, w0, _ = exponential_weights(k, tau)
                out += (a * dec) * total + (a * w0) * self.last[part]
                continue
            dec = _decay(k, tau)
            out += (a * dec) * total + (a * c * k * dec) * self.last[part]
        return out

    def advance(self, eps: np.ndarray) -> np.ndarray:
        """Uniform steps of size self.k: commit eps_n and return H_{n+1}."""
        self.commit(eps, None if self.sums is None else self.k)
        return self.explicit(self.k)

    def implicit(self, k: float) -> dict[str, float]:
        """Per part, the weight of P eps_{n+1} in H_{n+1}: k/2 R(0) (trapezoid rule),
        sum_i alpha_i w1_i (exponential rule; arrays for an array of increments k)."""
        if self.rule == "exponential":
            out: dict = {}
            for a, tau, part in self.terms:
                out[part] = out.get(part, 0.0) + a * exponential_weights(k, tau)[2]
            return out
        return {part: 0.5 * k * R0 for part, R0 in implicit_weights(self.terms,
                                                                     self.rule).items()}

    def state(self) -> dict:
        """Arrays that restore() takes back (checkpoints)."""
        out = {f"sum{i}": total for i, total in enumerate(self.sums or [])}
        out.update({f"last_{part}": e for part, e in (self.last or {}).items()})
        if self.keep_previous:
            out.update({f"prev_{part}": e for part, e in (self.previous or {}).items()})
        return out

    def restore(self, state: dict):
        count = sum(1 for key in state if key.startswith("sum"))
        self.sums = [state[f"sum{i}"].copy() for i in range(count)] or None
        self.last = {key[5:]: value.copy() for key, value in state.items()
                     if key.startswith("last_")} or None
        self.previous = {key[5:]: value.copy() for key, value in state.items()
                         if key.startswith("prev_")} or None


def _decay(k, tau: float):
    """exp(-k/tau) of a step k: a number, or an array of reduced-time increments per value."""
    return np.exp(-k / tau) if isinstance(k, np.ndarray) else math.exp(-k / tau)


class ReducedTimeHistory:
    """A Prony :class:`History` advanced in reduced time (time-temperature superposition):
    d xi = dt / a_T(theta) at each point, so a step of size k is, point by point, the reduced
    increment (trapezoid rule in t)

        dxi = k/2 (1/a_T(theta_n) + 1/a_T(theta_{n+1})),

    and the recursion of :class:`History` runs with exp(-dxi/tau_i) and the trapezoid weights
    dxi/2 per point instead of exp(-k/tau_i) and k/2: still O(1) work and memory per step.
    With eps = 0 before t = 0, sigma(t) = int phi(xi(t) - xi(s)) d eps(s) is eq (7) in xi:
    A eps(t) + int_0^xi(t) R(xi(t) - xi') eps(xi') dxi'. The implicit weight of the trapezoid
    rule, dxi/2 R(0), is then a field (one value per point).

    Parameters
    ----------
    history : History
        The isothermal recursion of the kernel (terms in reduced time).
    block : int
        Values per point of the strain arrays (d * d).
    """

    def __init__(self, history: History, block: int):
        self.history, self.block = history, block
        self.k, self.rule, self.d, self.direct = history.k, history.rule, history.d, False
        self.staged: np.ndarray | None = None      # 1/a_T at the staged time, per point
        self.committed: np.ndarray | None = None   # 1/a_T at the committed time
        self.temperature: np.ndarray | None = None  # theta at the staged time, per point
        self.reduced_time: np.ndarray | None = None  # xi at the committed time, per point

    def stage(self, inverse_shift: np.ndarray, temperature: np.ndarray | None = None):
        """Take 1/a_T(theta) (and theta) per point at the time the problem was moved to."""
        self.staged = np.asarray(inverse_shift, float).copy()
        self._version = getattr(self, "_version", 0) + 1     # a new step: new factors
        if temperature is not None:
            self.temperature = np.asarray(temperature, float).copy()

    def increment(self, k: float) -> np.ndarray:
        """The reduced-time increment per point of a step of size k from the committed time to
        the staged time (the time of the last :meth:`stage`)."""
        return 0.5 * k * (self.committed + self.staged)

    def _factors(self, k: float):
        """dxi (points, 1) and exp(-dxi/tau_i) per term (None for tau = inf) of the step of
        size k to the staged time, computed once for its explicit part and its commit."""
        key = (k, self._version)
        if getattr(self, "_cached", None) is None or self._cached[0] != key:
            dxi = self.increment(k)[:, None]
            if self.rule == "exponential":           # (d, w0, w1) per term and point
                decays = [exponential_weights(dxi, tau) for _, tau, _ in self.history.terms]
            else:
                decays = [None if math.isinf(tau) else np.exp(-dxi / tau)
                          for _, tau, _ in self.history.terms]
            self._cached = (key, dxi, decays)
        return self._cached[1], self._cached[2]

    def commit(self, eps: np.ndarray, k: float | None):
        """Take the strain of a converged state reached by a step of size k (None at t_0):
        P_{n+1} = d P_n + dxi/2 (d e_n + e_{n+1}) per point, d = exp(-dxi/tau)."""
        h, block = self.history, self.block
        if k is None:
            h.commit(eps, None)
            self.reduced_time = np.zeros_like(self.staged)
        elif self.rule == "exponential":
            self._commit_exponential(eps, k)
        else:
            dxi, decays = self._factors(k)
            half = 0.5 * dxi
            parts = {part: project(eps, part, h.d).reshape(-1, block)
                     for part in {part for _, _, part in h.terms}}
            # P <- d (P + dxi/2 e_n) + dxi/2 e_{n+1}: the products per part computed once
            old = {part: half * h.last[part].reshape(-1, block) for part in parts}
            new = {part: half * value for part, value in parts.items()}
            for total, (_, _, part), dec in zip(h.sums, h.terms, decays):
                total = total.reshape(-1, block)          # a view: updated in place
                total += old[part]
                if dec is not None:
                    total *= dec
                total += new[part]
            h.last = {part: value.reshape(-1).copy() for part, value in parts.items()}
            self.reduced_time = self.reduced_time + dxi[:, 0]
        self.committed = self.staged.copy()

    def _commit_exponential(self, eps: np.ndarray, k: float):
        """The exponential rule's commit in reduced time: S_{n+1} = d S_n + w0 e_n + w1 e_{n+1}
        per point, with the weights of :func:`exponential_weights` at dxi."""
        h, block = self.history, self.block
        dxi, weights = self._factors(k)
        parts = {part: project(eps, part, h.d).reshape(-1, block)
                 for part in {part for _, _, part in h.terms}}
        for total, (_, _, part), (dec, w0, w1) in zip(h.sums, h.terms, weights):
            total = total.reshape(-1, block)              # a view: updated in place
            total *= dec
            total += w0 * h.last[part].reshape(-1, block)
            total += w1 * parts[part]
        h.last = {part: value.reshape(-1).copy() for part, value in parts.items()}
        self.reduced_time = self.reduced_time + dxi[:, 0]

    def explicit(self, k: float) -> np.ndarray:
        """The history stress (explicit part) of a step of size k to the staged time:
        sum_i alpha_i (d_i P_i,n + c dxi d_i e_i,n), c = 1 (paper's rule) or 1/2;
        sum_i alpha_i (d_i S_i,n + w0_i e_i,n) for the exponential rule."""
        h, block = self.history, self.block
        dxi, decays = self._factors(k)
        if self.rule == "exponential":
            out = np.zeros((h.sums[0].size // block, block))
            for (a, _, part), total, (dec, w0, _) in zip(h.terms, h.sums, decays):
                out += a * (dec * total.reshape(-1, block)
                            + w0 * h.last[part].reshape(-1, block))
            return out.reshape(-1)
        c = 1.0 if h.rule == "paper" else 0.5
        out = np.zeros((h.sums[0].size // block, block))
        last = {part: (c * dxi) * h.last[part].reshape(-1, block)
                for part in {part for _, _, part in h.terms}}
        for (a, _, part), total, dec in zip(h.terms, h.sums, decays):
            # alpha d (P + c dxi e_n), with the product c dxi e_n per part computed once
            out += (a if dec is None else a * dec) * (total.reshape(-1, block) + last[part])
        return out.reshape(-1)

    def implicit(self, k: float) -> dict:
        """Per part, the weight dxi/2 R(0) per point (trapezoid rule), sum_i alpha_i w1_i(dxi)
        (exponential rule); a number 0 before a step is prepared."""
        if self.committed is None or self.staged is None:
            return self.history.implicit(0.0)
        return self.history.implicit(self.increment(k))

    def state(self) -> dict:
        out = self.history.state()
        if self.committed is not None:
            out["inverse_shift"] = np.repeat(self.committed, self.block)
            out["reduced_time"] = np.repeat(self.reduced_time, self.block)
        return out

    def restore(self, state: dict):
        state = dict(state)
        inverse = state.pop("inverse_shift", None)
        reduced = state.pop("reduced_time", None)
        self.history.restore(state)
        if inverse is not None:
            self.committed = np.asarray(inverse)[::self.block].copy()
            self.reduced_time = np.asarray(reduced)[::self.block].copy()


class StrainRecord:
    """The strain of every converged state and its time: what a direct sum (O(n) work and
    memory per step) keeps, and what its checkpoint holds."""

    def record(self, eps: np.ndarray, k: float | None):
        """Keep eps, reached by a step of size k (None at t_0)."""
        self.times.append(0.0 if not self.times else self.times[-1] + k)
        self.strains.append(eps.copy())

    def state(self) -> dict:
        out = {"times": np.array(self.times)}
        out.update({f"strain{j}": e for j, e in enumerate(self.strains)})
        return out

    def restore(self, state: dict):
        self.times = list(state["times"])
        self.strains = [state[f"strain{j}"].copy() for j in range(len(self.times))]


class DirectHistory(StrainRecord):
    """Eq (19) summed term by term for a general kernel R(t) eps = r(t) P eps, any step sizes;
    O(n) work and memory per step."""

    def __init__(self, r, k: float = None, rule: str = "paper", part: str = "full",
                 d: int = 2):
        self.r, self.k, self.rule, self.part, self.d = r, k, rule, part, d
        self.times: list[float] = []
        self.strains: list[np.ndarray] = []
        self.direct = True

    def implicit(self, k: float) -> dict[str, float]:
        return {self.part: 0.5 * k * self.r(0.0)} if self.rule == "trapezoid" else {}

    def commit(self, eps: np.ndarray, k: float | None):
        self.record(eps, k)

    def explicit(self, k: float) -> np.ndarray:
        out = direct_sum(lambda t, e: self.r(t) * e, self.times, self.strains,
                         self.times[-1] + k, self.rule)
        return out if self.part == "full" else project(out, self.part, self.d)

    def advance(self, eps: np.ndarray) -> np.ndarray:
        self.commit(eps, None if not self.times else self.k)
        return self.explicit(self.k)



def prony(terms, d: int):
    """R(t, eps) of a Prony kernel, for :func:`direct_sum`."""
    def R(t, eps):
        return sum(a * math.exp(-t / tau) * project(eps, part, d) for a, tau, part in terms)
    return R


def table_kernel(times, values):
    """r(t) interpolated linearly in a table, constant beyond its ends."""
    times, values = np.asarray(times, float), np.asarray(values, float)
    return lambda t: float(np.interp(t, times, values))


def implicit_weights(terms, rule: str) -> dict[str, float]:
    """Per part, R(0) of the implicit term k/2 R(0) P eps(u_{n+1}) of the trapezoid rule;
    nothing for the paper's rule."""
    if rule != "trapezoid":
        return {}
    out: dict[str, float] = {}
    for a, _, part in terms:
        out[part] = out.get(part, 0.0) + a
    return out


def direct_sum(R, times, strains: list[np.ndarray], t_next: float = None,
               rule: str = "paper"):
    """Eq (19) term by term at t_next from the strains at `times` (t_0 .. t_n), for any step
    sizes: the trapezoid rule on [t_0, t_n] plus, on [t_n, t_next], the left point (paper's
    rule) or the left half of the trapezoid (its implicit right end is left out). R(t, eps) applies
    the kernel at time t. O(n) work. A number k for `times` means uniform steps: times j k and
    t_next = (n + 1) k, which is eq (19) as printed."""
    if not isinstance(times, (list, tuple, np.ndarray)):
        k = times
        times = [j * k for j in range(len(strains))]
        t_next = len(strains) * k
    out = np.zeros_like(strains[0])
    for j in range(len(strains) - 1):
        half = 0.5 * (times[j + 1] - times[j])
        out = out + half * (R(t_next - times[j], strains[j])
                            + R(t_next - times[j + 1], strains[j + 1]))
    last = t_next - times[-1]          # the last sub-interval [t_n, t_next]
    weight = last if rule == "paper" else 0.5 * last
    return out + weight * R(last, strains[-1])


def _phi(z: np.ndarray):
    """phi1 = (1 - e^-z)/z and phi2 = (1 - e^-z (1 + z))/z^2, so that for a step of size k
    int_0^k e^(-s sigma) (1 - sigma/k) dsigma = k (phi1 - phi2) and
    int_0^k e^(-s sigma) sigma/k dsigma = k phi2 (z = s k; series below 1e-3)."""
    small = z < 1e-3
    zs = np.where(small, 1.0, z)
    decay = np.exp(-zs)
    phi1 = np.where(small, 1 - z / 2 + z**2 / 6 - z**3 / 24, -np.expm1(-zs) / zs)
    phi2 = np.where(small, 0.5 - z / 3 + z**2 / 8 - z**3 / 30,
                    (-np.expm1(-zs) - zs * decay) / zs**2)
    return phi1, phi2


class FractionalHistory:
    """H(t_{n+1}) = int_0^{t_{n+1}} r(t_{n+1} - s) P eps_h(s) ds for the weakly singular kernel
    r(t) = alpha t^(-beta) / Gamma(1 - beta), eps_h the piecewise-linear interpolant of the
    strains (product integration: the kernel is integrated exactly, R(0) never evaluated).

    Last step [t_n, t_{n+1}], exactly (sigma = t_{n+1} - s):
        trapezoid: alpha k^(1-beta) ((1-beta) P eps_n + P eps_{n+1}) / Gamma(3 - beta)
                   (eps_{n+1} implicit, see implicit()); rule = "exponential" is the same
                   product integration;
        paper:     alpha k^(1-beta) / Gamma(2 - beta) P eps_n (eps frozen at the left point,
                   explicit, as the paper's rule).
    Older steps, sigma >= k: r ~ sum_j w_j exp(-s_j sigma) (a fit with the stated relative
    accuracy on [k_min, T], :mod:`kernels`), each exponential integrated exactly against eps_h:
        U_j(t_{n+1}) = e^(-s_j k) U_j(t_n) + k phi2(s_j k) P eps_n
                       + k (phi1 - phi2)(s_j k) P eps_{n+1},
        H(t_{n+1}) = sum_j w_j e^(-s_j k) U_j(t_n) + (last step).
    O(len(fit)) work and memory per step, any step sizes >= k_min. The product trapezoid rule
    is second order for smooth strains; creep from rest has eps ~ t^(1-beta) near 0, which
    limits the observed order (tests). The paper's variant is first order.
    """

    def __init__(self, alpha: float, beta: float, fit, rule: str = "paper",
                 part: str = "full", d: int = 2, k: float = None):
        self.alpha, self.beta, self.fit = alpha, beta, fit
        self.rule, self.part, self.d, self.k = rule, part, d, k
        self.sums: np.ndarray | None = None       # U_j, one row per exponential
        self.last: np.ndarray | None = None       # P eps_n
        self.direct = False

    def _last_weights(self, k: float):
        """(weight of P eps_n, weight of P eps_{n+1}) over the last step."""
        b = self.beta
        scale = self.alpha * k ** (1.0 - b)
        if self.rule == "paper":
            return scale / math.gamma(2.0 - b), 0.0
        return scale * (1.0 - b) / math.gamma(3.0 - b), scale / math.gamma(3.0 - b)

    def commit(self, eps: np.ndarray, k: float | None):
        new = project(eps, self.part, self.d).copy()
        if self.sums is None:
            self.sums = np.zeros((len(self.fit.rates), eps.size))
        else:
            z = self.fit.rates * k
            phi1, phi2 = _phi(z)
            self.sums *= np.exp(-z)[:, None]
            self.sums += np.multiply.outer(k * phi2, self.last)
            self.sums += np.multiply.outer(k * (phi1 - phi2), new)
        self.last = new

    def explicit(self, k: float) -> np.ndarray:
        decay = self.fit.weights * np.exp(-self.fit.rates * k)
        return decay @ self.sums + self._last_weights(k)[0] * self.last

    def implicit(self, k: float) -> dict[str, float]:
        return {self.part: self._last_weights(k)[1]} if self.rule != "paper" else {}

    def advance(self, eps: np.ndarray) -> np.ndarray:
        self.commit(eps, None if self.sums is None else self.k)
        return self.explicit(self.k)

    def state(self) -> dict:
        out = {f"sum{i}": total
               for i, total in enumerate(self.sums if self.sums is not None else [])}
        if self.last is not None:
            out[f"last_{self.part}"] = self.last
        return out

    def restore(self, state: dict):
        count = sum(1 for key in state if key.startswith("sum"))
        if count:
            self.sums = np.array([state[f"sum{i}"] for i in range(count)])
            self.last = state[f"last_{self.part}"].copy()


class DirectFractionalHistory(StrainRecord, FractionalHistory):
    """The same product integration with the exact kernel on every older step: O(n) work and
    memory per step (the reference of the fitted one). Over [t_{m-1}, t_m], with
    a = t_{n+1} - t_m, b = t_{n+1} - t_{m-1}, h = b - a, I0 = int_a^b sigma^-beta,
    I1 = int_a^b sigma^(1-beta): weight (b I0 - I1)/h on eps_m and (I1 - a I0)/h on eps_{m-1},
    times alpha / Gamma(1 - beta)."""

    def __init__(self, alpha: float, beta: float, rule: str = "paper", part: str = "full",
                 d: int = 2, k: float = None):
        super().__init__(alpha, beta, None, rule, part, d, k)
        self.times: list[float] = []
        self.strains: list[np.ndarray] = []
        self.direct = True

    def commit(self, eps: np.ndarray, k: float | None):
        self.record(project(eps, self.part, self.d), k)
        self.last = self.strains[-1]

    def explicit(self, k: float) -> np.ndarray:
        b_ = self.beta
        out = self._last_weights(k)[0] * self.last
        if len(self.times) > 1:
            t = np.asarray(self.times)
            t_next = t[-1] + k
            a, b = t_next - t[1:], t_next - t[:-1]
            h = b - a
            I0 = (b ** (1 - b_) - a ** (1 - b_)) / (1 - b_)
            I1 = (b ** (2 - b_) - a ** (2 - b_)) / (2 - b_)
            weights = np.zeros(len(t))
            weights[1:] += (b * I0 - I1) / h
            weights[:-1] += (I1 - a * I0) / h
            weights *= self.alpha / math.gamma(1.0 - b_)
            out = out + weights @ np.asarray(self.strains)
        return out

    def restore(self, state: dict):
        StrainRecord.restore(self, state)
        self.last = self.strains[-1] if self.strains else None


class ReducedFractionalHistory(ReducedTimeHistory):
    """A :class:`FractionalHistory` advanced in reduced time (time-temperature superposition):
    the step of size k is, point by point, dxi = k/2 (1/a_T(theta_n) + 1/a_T(theta_{n+1})), and
    the product integration of :class:`FractionalHistory` runs in xi with the strain linear in
    xi over each step. Last step, exactly, per point (trapezoid and exponential rules):

        alpha dxi^(1-beta) ((1-beta) P eps_n + P eps_{n+1}) / Gamma(3 - beta),

    whose weight of P eps_{n+1} is the implicit field; the paper's rule keeps
    alpha dxi^(1-beta) / Gamma(2 - beta) P eps_n. Older steps through the exponentials of the
    fit (which must hold on [min dxi, xi(T)]), per point:

        U_j <- e^(-s_j dxi) U_j + dxi phi2(s_j dxi) P eps_n + dxi (phi1 - phi2)(s_j dxi) P eps_{n+1},
        H = sum_j w_j e^(-s_j dxi) U_j + (last step).

    O(len(fit)) work and memory per step and point. At a constant temperature it is the T_ref
    run of the time scaled by 1/a_T, to round-off.

    Parameters
    ----------
    history : FractionalHistory
        The isothermal product integration (its fit in reduced time).
    block : int
        Values per point of the strain arrays (d * d).
    """

    def _factors(self, k: float):
        """dxi (points,), and per exponential and point e^(-s_j dxi), dxi phi2 and
        dxi (phi1 - phi2) (arrays (fit, points)), computed once per staged step."""
        key = (k, self._version)
        if getattr(self, "_cached", None) is None or self._cached[0] != key:
            dxi = self.increment(k)
            z = np.multiply.outer(self.history.fit.rates, dxi)
            phi1, phi2 = _phi(z)
            self._cached = (key, dxi, (np.exp(-z), dxi * phi2, dxi * (phi1 - phi2)))
        return self._cached[1], self._cached[2]

    def commit(self, eps: np.ndarray, k: float | None):
        """Take the strain of a converged state reached by a step of size k (None at t_0):
        U_j <- e^(-s_j dxi) U_j + dxi phi2 P eps_n + dxi (phi1 - phi2) P eps_{n+1} per point."""
        h, block = self.history, self.block
        if k is None:
            h.commit(eps, None)
            self.reduced_time = np.zeros_like(self.staged)
        else:
            dxi, (decay, w0, w1) = self._factors(k)
            new = project(eps, h.part, h.d).copy()
            sums = h.sums.reshape(len(decay), -1, block)     # a view: updated in place
            sums *= decay[:, :, None]
            sums += w0[:, :, None] * h.last.reshape(1, -1, block)
            sums += w1[:, :, None] * new.reshape(1, -1, block)
            h.last = new
            self.reduced_time = self.reduced_time + dxi
        self.committed = self.staged.copy()

    def explicit(self, k: float) -> np.ndarray:
        """sum_j w_j e^(-s_j dxi) U_j + (weight of P eps_n over the last step) P eps_n, per
        point, for a step of size k to the staged time."""
        h, block = self.history, self.block
        dxi, (decay, _, _) = self._factors(k)
        sums = h.sums.reshape(len(decay), -1, block)
        out = np.einsum("jp,jpb->pb", h.fit.weights[:, None] * decay, sums)
        out += h._last_weights(dxi)[0][:, None] * h.last.reshape(-1, block)
        return out.reshape(-1)
