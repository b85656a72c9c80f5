"""Relaxation moduli as engineers give them (generalized Maxwell, Prony series) and their exact
conversion to the (A, R) of eq (7), with the closed forms the figures and the verification use.

A Prony series is phi(t) = phi_inf + sum_i phi_i exp(-t/tau_i); phi(0) = phi_inf + sum_i phi_i is
the instantaneous modulus. For a strain that is zero before t = 0,
sigma(t) = int_0-^t phi(t - s) d eps(s) = phi(0) eps(t) + int_0^t phi'(t - s) eps(s) ds
(integration by parts), which is eq (7) with A = phi(0) and R(t) = phi'(t)
= -sum_i (phi_i / tau_i) exp(-t/tau_i): a Prony kernel of today's machinery, alpha_i =
-phi_i / tau_i, with the part (deviatoric, volumetric) and the factor of the dimension below.

Isotropic material, shear G(t) and bulk K(t), 3D: sigma = 2 G dev3 eps + 3 K vol3 eps with
vol_d eps = tr(eps)/d I, dev_d = eps - vol_d (the parts of model/memory.py). In 2D the parts are
taken with d = 2:

    3D             2 G(t) dev3 + 3 K(t) vol3
    plane strain   2 G(t) dev2 + (2 K(t) + 2/3 G(t)) vol2    (eps_33 = 0: 2G dev3 + K tr I)
    plane stress   2 G(t) dev2 + 2 K2(t) vol2,  K2 = 9 K G / (3 K + 4 G)  (sigma_33 = 0)

In plane stress K2 is a ratio of the Carson transforms of K and G: its relaxation times are
the zeros of 3 K~(s) + 4 G~(s), not those of K and G, unless both relax with the same
normalized function g(t) (g_i = k_i, same tau_i), when K2(t) = K2(0) g(t) exactly. Only that
proportional case is converted (:func:`proportional`); the other is refused by the scene.

Elastic constants and the Prony moduli do not depend on temperature: a temperature acts on the
relaxation times only (time-temperature superposition, :func:`log10_shift`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: Relative difference below which two relaxation times are the same time.
SAME_TIME = 1e-9

#: Universal gas constant, J/(mol K): the Arrhenius shift takes an activation energy in J/mol.
GAS_CONSTANT = 8.314462618


@dataclass(frozen=True)
class PronySeries:
    """phi(t) = long_term + sum_i moduli_i exp(-t / taus_i) (absolute moduli)."""
    long_term: float
    moduli: tuple
    taus: tuple

    @property
    def instantaneous(self) -> float:
        """phi(0) = phi_inf + sum_i phi_i."""
        return self.long_term + sum(self.moduli)

    def fractions(self) -> tuple:
        """The normalized g_i = phi_i / phi(0)."""
        return tuple(m / self.instantaneous for m in self.moduli)

    def scaled(self, factor: float) -> "PronySeries":
        """factor phi(t)."""
        return PronySeries(factor * self.long_term, tuple(factor * m for m in self.moduli),
                           self.taus)


def series(instantaneous=None, long_term=None, taus=(), moduli=None, fractions=None):
    """The Prony series of one relaxation function, from the instantaneous or the long-term
    modulus and absolute moduli phi_i or normalized fractions g_i = phi_i / phi(0).

    Parameters
    ----------
    instantaneous : float, optional
        phi(0); exactly one of instantaneous and long_term.
    long_term : float, optional
        phi_inf.
    taus : sequence of float
        The relaxation times tau_i.
    moduli : sequence of float, optional
        Absolute phi_i; or
    fractions : sequence of float, optional
        Normalized g_i with phi_i = g_i phi(0) and phi_inf = phi(0) (1 - sum g_i).

    Returns
    -------
    PronySeries
        phi(t) = phi_inf + sum_i phi_i exp(-t / tau_i). Nothing is checked here (the scene
        checks signs, sums and duplicates).
    """
    taus = tuple(float(t) for t in taus)
    if fractions is not None:
        g = tuple(float(x) for x in fractions)
        rest = 1.0 - sum(g)
        phi0 = float(instantaneous) if instantaneous is not None else float(long_term) / rest
        return PronySeries(phi0 * rest, tuple(phi0 * x for x in g), taus)
    phi = tuple(float(x) for x in (moduli or ()))
    inf = float(long_term) if long_term is not None else float(instantaneous) - sum(phi)
    return PronySeries(inf, phi, taus)


def proportional(a: PronySeries, b: PronySeries) -> bool:
    """Whether a(t)/a(0) = b(t)/b(0) for all t (same times and fractions, to SAME_TIME), or one
    of them has no terms and the other none either.

    Parameters
    ----------
    a, b : PronySeries
        Two relaxation functions.

    Returns
    -------
    bool
        True when they relax with the same normalized function g(t).
    """
    if len(a.taus) != len(b.taus):
        return False
    pa = sorted(zip(a.taus, a.fractions()))
    pb = sorted(zip(b.taus, b.fractions()))
    return all(abs(ta - tb) <= SAME_TIME * ta and abs(ga - gb) <= SAME_TIME
               for (ta, ga), (tb, gb) in zip(pa, pb))


def young_series(young: PronySeries, nu: float) -> tuple[PronySeries, PronySeries]:
    """Shear and bulk of E(t) with a constant Poisson ratio nu.

    Parameters
    ----------
    young : PronySeries
        E(t).
    nu : float
        The Poisson ratio, constant in time.

    Returns
    -------
    tuple of PronySeries
        G(t) = E(t) / (2 (1 + nu)) and K(t) = E(t) / (3 (1 - 2 nu)).
    """
    return young.scaled(1.0 / (2.0 * (1.0 + nu))), young.scaled(1.0 / (3.0 * (1.0 - 2.0 * nu)))


def young_poisson(G: float, K: float) -> tuple[float, float]:
    """(E, nu) of a shear modulus G and a bulk modulus K.

    Parameters
    ----------
    G, K : float
        Shear and bulk moduli (> 0).

    Returns
    -------
    tuple of float
        E = 9 K G / (3 K + G), nu = (3 K - 2 G) / (2 (3 K + G)).
    """
    return 9.0 * K * G / (3.0 * K + G), (3.0 * K - 2.0 * G) / (2.0 * (3.0 * K + G))


def paper_form(model: str, shear: PronySeries, bulk: PronySeries):
    """The (A, R) of eq (7) for shear G(t) and bulk K(t) relaxation: A as (E, nu) = the
    instantaneous G(0), K(0), R as Prony terms alpha_i = -c phi_i / tau_i per part, with the
    dimension factors c of the module description (terms of the same time and part summed).

    Parameters
    ----------
    model : str
        ``plane_strain``, ``plane_stress`` (shear and bulk must be :func:`proportional`) or
        ``3d``.
    shear, bulk : PronySeries
        G(t) and K(t).

    Returns
    -------
    tuple
        (E, nu, terms) with terms [(alpha_i, tau_i, part_i)] for memory.kernel = "prony":
        sigma = A(E, nu) eps + int_0^t sum_i alpha_i exp(-(t - s)/tau_i) P_i eps(s) ds.
    """
    G0, K0 = shear.instantaneous, bulk.instantaneous
    E, nu = young_poisson(G0, K0)
    out: dict[tuple[float, str], float] = {}

    def add(phi, tau, part, factor):
        key = next((k for k in out if k[1] == part and abs(k[0] - tau) <= SAME_TIME * tau),
                   (tau, part))
        out[key] = out.get(key, 0.0) - factor * phi / tau

    if model == "plane_stress":
        if not proportional(shear, bulk):
            raise ValueError("plane stress needs proportional shear and bulk relaxation")
        K2 = 9.0 * K0 * G0 / (3.0 * K0 + 4.0 * G0)
        for g, tau in zip(shear.fractions(), shear.taus):
            add(g * G0, tau, "deviatoric", 2.0)
            add(g * K2, tau, "volumetric", 2.0)
    else:
        three = model in ("3d", "axisymmetric")     # a 3 x 3 strain (material.strain_dimension)
        for phi, tau in zip(shear.moduli, shear.taus):
            add(phi, tau, "deviatoric", 2.0)
            if not three:
                add(phi, tau, "volumetric", 2.0 / 3.0)
        for phi, tau in zip(bulk.moduli, bulk.taus):
            add(phi, tau, "volumetric", 3.0 if three else 2.0)
    terms = [(alpha, tau, part) for (tau, part), alpha in out.items() if alpha != 0.0]
    return E, nu, terms


def relaxation(phi: PronySeries, t) -> np.ndarray:
    """phi(t) = phi_inf + sum_i phi_i exp(-t / tau_i).

    Parameters
    ----------
    phi : PronySeries
        The relaxation function.
    t : float or array
        Times >= 0.

    Returns
    -------
    numpy.ndarray
        phi at t.
    """
    t = np.asarray(t, float)
    return phi.long_term + 0.0 * t + sum(m * np.exp(-t / tau)
                                         for m, tau in zip(phi.moduli, phi.taus))


def storage_loss(phi: PronySeries, omega) -> tuple[np.ndarray, np.ndarray]:
    """The storage and loss moduli of a Prony series (sigma = eps0 (E' sin wt + E'' cos wt) in
    the steady state of eps = eps0 sin wt).

    Parameters
    ----------
    phi : PronySeries
        The relaxation function.
    omega : float or array
        Angular frequencies > 0.

    Returns
    -------
    tuple of numpy.ndarray
        E'(w) = phi_inf + sum_i phi_i w^2 tau_i^2 / (1 + w^2 tau_i^2) and
        E''(w) = sum_i phi_i w tau_i / (1 + w^2 tau_i^2).
    """
    w = np.asarray(omega, float)
    storage = phi.long_term + 0.0 * w
    loss = 0.0 * w
    for m, tau in zip(phi.moduli, phi.taus):
        wt = w * tau
        storage = storage + m * wt**2 / (1.0 + wt**2)
        loss = loss + m * wt / (1.0 + wt**2)
    return storage, loss


def response(phi: PronySeries, history: str, t, rate: float = 1.0, omega: float = 1.0):
    """sigma(t) = int_0-^t phi(t - s) d eps(s) of a unit strain history in closed form.

    Parameters
    ----------
    phi : PronySeries
        The relaxation function.
    history : str
        ``step`` (eps = 1 for t >= 0), ``ramp`` (eps = rate t) or ``sine``
        (eps = sin(omega t)).
    t : float or array
        Times >= 0.
    rate, omega : float, optional
        The ramp's rate and the sine's angular frequency.

    Returns
    -------
    numpy.ndarray
        step: phi(t); ramp: rate (phi_inf t + sum_i phi_i tau_i (1 - exp(-t/tau_i)));
        sine: E' sin wt + E'' cos wt - sum_i phi_i w tau_i / (1 + w^2 tau_i^2) exp(-t/tau_i).
    """
    t = np.asarray(t, float)
    if history == "step":
        return relaxation(phi, t)
    if history == "ramp":
        return rate * (phi.long_term * t + sum(m * tau * -np.expm1(-t / tau)
                                               for m, tau in zip(phi.moduli, phi.taus)))
    if history == "sine":
        storage, loss = storage_loss(phi, omega)
        out = storage * np.sin(omega * t) + loss * np.cos(omega * t)
        for m, tau in zip(phi.moduli, phi.taus):
            out = out - m * omega * tau / (1.0 + (omega * tau) ** 2) * np.exp(-t / tau)
        return out
    raise ValueError(f"unknown strain history {history!r}")


def log10_shift(shift: dict, theta):
    """log10 a_T(theta) of a thermorheologically simple material.

    Parameters
    ----------
    shift : dict
        ``{"shift": "wlf", "T_ref", "C1", "C2"}``: log10 a_T = -C1 (T - T_ref) /
        (C2 + T - T_ref) (Williams, Landel and Ferry 1955); ``{"shift": "arrhenius", "T_ref",
        "activation_energy"}`` (J/mol, temperatures in kelvin): log10 a_T =
        Ea / (R ln 10) (1/T - 1/T_ref); ``{"shift": "table", "shift_temperatures",
        "shift_log10_aT"}``: log10 a_T interpolated piecewise linearly in T between the
        points of the table (:func:`shift_points`), monotone between two points and exact at
        them, or with ``"shift_interpolation": "monotone_cubic"`` by the monotone Hermite
        cubic of :func:`monotone_cubic`; ``{"shift": "none"}``: 0 (a [viscoelastic] table).
    theta : float or array
        Temperatures.

    Returns
    -------
    numpy.ndarray
        log10 a_T; a_T > 1 below T_ref (slower), < 1 above.
    """
    theta = np.asarray(theta, float)
    kind = shift.get("shift", "none")
    if kind == "none":
        return 0.0 * theta
    if kind == "table":
        temps, logs = shift_points(shift)
        if shift.get("shift_interpolation", "linear") == "monotone_cubic":
            return monotone_cubic(temps, logs, theta)
        return np.interp(theta, temps, logs)
    d = theta - float(shift["T_ref"])
    if kind == "wlf":
        return -float(shift["C1"]) * d / (float(shift["C2"]) + d)
    if kind == "arrhenius":
        return (float(shift["activation_energy"]) / (GAS_CONSTANT * math.log(10.0))
                * (1.0 / theta - 1.0 / float(shift["T_ref"])))
    raise ValueError(f"unknown shift type {kind!r}")


def monotone_slopes(x, y, limited: bool = True) -> np.ndarray:
    """The node slopes of the monotone piecewise-cubic Hermite interpolant (Fritsch and
    Carlson, SIAM J. Numer. Anal. 17 (1980) 238-246).

    Parameters
    ----------
    x : array_like
        Increasing nodes x_0 < ... < x_n (n >= 1).
    y : array_like
        The values y_k.
    limited : bool, optional
        False: the three-point slopes as they are (the unlimited cubic, which may overshoot).

    Returns
    -------
    numpy.ndarray
        m_k. With h_k = x_{k+1} - x_k and the secants D_k = (y_{k+1} - y_k) / h_k: inside,
        m_k = (h_k D_{k-1} + h_{k-1} D_k) / (h_{k-1} + h_k), the slope of the parabola through
        three nodes (second order); at the ends the one-sided parabola,
        m_0 = ((2 h_0 + h_1) D_0 - h_0 D_1) / (h_0 + h_1) (and its mirror at x_n); two nodes:
        m = D_0. Limited: m_k = 0 where D_{k-1} D_k <= 0 (a local extremum of the data) or
        where m_k has the sign opposite to the adjacent secant; on every interval with
        D_k = 0 both slopes 0; and where a_k = m_k / D_k, b_k = m_{k+1} / D_k have
        a_k^2 + b_k^2 > 9, both scaled by 3 / sqrt(a_k^2 + b_k^2) (the circle inside
        Fritsch and Carlson's region of monotonicity), so that the cubic is monotone on
        every interval where the data are.
    """
    x, y = np.asarray(x, float), np.asarray(y, float)
    h = np.diff(x)
    D = np.diff(y) / h
    if len(D) == 1:
        return np.array([D[0], D[0]])
    m = np.empty(len(x))
    m[1:-1] = (h[1:] * D[:-1] + h[:-1] * D[1:]) / (h[:-1] + h[1:])
    m[0] = ((2 * h[0] + h[1]) * D[0] - h[0] * D[1]) / (h[0] + h[1])
    m[-1] = ((2 * h[-1] + h[-2]) * D[-1] - h[-1] * D[-2]) / (h[-1] + h[-2])
    if not limited:
        return m
    m[1:-1][D[:-1] * D[1:] <= 0] = 0.0
    if m[0] * D[0] <= 0:
        m[0] = 0.0
    if m[-1] * D[-1] <= 0:
        m[-1] = 0.0
    flat = D == 0
    m[:-1][flat] = 0.0
    m[1:][flat] = 0.0
    safe = np.where(flat, 1.0, D)
    a, b = m[:-1] / safe, m[1:] / safe
    r2 = np.where(flat, 0.0, a * a + b * b)
    for k in np.flatnonzero(r2 > 9.0):          # in order: a shared node keeps the smaller
        scale = 3.0 / math.sqrt((m[k] / D[k]) ** 2 + (m[k + 1] / D[k]) ** 2)
        if scale < 1.0:
            m[k] *= scale
            m[k + 1] *= scale
    return m


def monotone_cubic(x, y, xq, limited: bool = True) -> np.ndarray:
    """The piecewise-cubic Hermite interpolant of (x_k, y_k) with the slopes of
    :func:`monotone_slopes`, at the points xq (inside [x_0, x_n]; beyond, the end cubic).

    Parameters
    ----------
    x, y : array_like
        Increasing nodes and their values.
    xq : float or array_like
        Where to evaluate.
    limited : bool, optional
        As for :func:`monotone_slopes`.

    Returns
    -------
    numpy.ndarray
        On [x_k, x_{k+1}], with s = (xq - x_k) / h_k:
        p = (2s^3 - 3s^2 + 1) y_k + (s^3 - 2s^2 + s) h_k m_k + (-2s^3 + 3s^2) y_{k+1}
        + (s^3 - s^2) h_k m_{k+1}; exact at the nodes, and linear data are reproduced.
    """
    x, y = np.asarray(x, float), np.asarray(y, float)
    xq = np.asarray(xq, float)
    m = monotone_slopes(x, y, limited)
    k = np.clip(np.searchsorted(x, xq, side="right") - 1, 0, len(x) - 2)
    h = x[k + 1] - x[k]
    s = (xq - x[k]) / h
    s2, s3 = s * s, s * s * s
    return ((2 * s3 - 3 * s2 + 1) * y[k] + (s3 - 2 * s2 + s) * h * m[k]
            + (3 * s2 - 2 * s3) * y[k + 1] + (s3 - s2) * h * m[k + 1])


def shift_points(shift) -> tuple[np.ndarray, np.ndarray]:
    """The points (theta_j, log10 a_T(theta_j)) of a tabulated shift function.

    Parameters
    ----------
    shift : dict
        ``{"shift": "table", ...}``: the points of a file read by the scene (the attribute
        ``shift_points`` of a [viscoelastic] table), else the keys ``shift_temperatures`` and
        ``shift_log10_aT``.

    Returns
    -------
    tuple of numpy.ndarray
        (theta_j increasing, log10 a_T(theta_j)); between two points
        log10 a_T = ((theta_{j+1} - T) L_j + (T - theta_j) L_{j+1}) / (theta_{j+1} - theta_j).
    """
    points = getattr(shift, "shift_points", None)
    if points is None:
        points = (shift["shift_temperatures"], shift["shift_log10_aT"])
    return np.asarray(points[0], float), np.asarray(points[1], float)


#: Largest |log10 a_T| taken: beyond, 1/a_T is 0 or overflows in double precision.
MAX_LOG10_SHIFT = 300.0


def shift_error(shift: dict, theta) -> str | None:
    """Why the shift function cannot be taken at the temperatures theta, or None.

    Parameters
    ----------
    shift : dict
        As for :func:`log10_shift`.
    theta : float or array
        Temperatures.

    Returns
    -------
    str or None
        WLF with C2 + T - T_ref <= 0 (outside its range), Arrhenius with T <= 0 (kelvin), a
        table's temperature outside [theta_0, theta_last] (not extrapolated), or
        |log10 a_T| > MAX_LOG10_SHIFT; None when every temperature is fine.
    """
    theta = np.atleast_1d(np.asarray(theta, float))
    kind = shift.get("shift", "none")
    if theta.size == 0 or kind == "none":
        return None
    if not np.all(np.isfinite(theta)):
        return "viscoelastic.temperature is not a finite number"
    if kind == "wlf":
        den = float(shift["C2"]) + theta - float(shift["T_ref"])
        if np.any(den <= 0):
            i = int(np.argmin(den))
            return (f"viscoelastic.temperature = {theta[i]:.6g}: C2 + T - T_ref = {den[i]:.6g} "
                    f"<= 0, outside the range of the WLF shift (T must exceed T_ref - C2 = "
                    f"{float(shift['T_ref']) - float(shift['C2']):.6g})")
    if kind == "table":
        temps, _ = shift_points(shift)
        outside = (theta < temps[0]) | (theta > temps[-1])
        if np.any(outside):
            i = int(np.flatnonzero(outside)[0])
            return (f"viscoelastic.temperature = {theta[i]:.6g} is outside the shift table "
                    f"[{temps[0]:.6g}, {temps[-1]:.6g}] (viscoelastic.shift = 'table' is not "
                    "extrapolated: extend the table)")
    if kind == "arrhenius" and np.any(theta <= 0):
        return (f"viscoelastic.temperature = {theta.min():.6g}: the Arrhenius shift takes "
                "absolute temperatures (kelvin), > 0")
    log10_aT = log10_shift(shift, theta)
    if np.any(np.abs(log10_aT) > MAX_LOG10_SHIFT):
        i = int(np.argmax(np.abs(log10_aT)))
        return (f"viscoelastic.temperature = {theta[i]:.6g}: log10 a_T = {log10_aT[i]:.6g} is "
                f"beyond +-{MAX_LOG10_SHIFT:g} (the relaxation times would be 0 or infinite)")
    return None


def first_error_point(shift: dict, theta) -> int | None:
    """The index of the first temperature at which the shift function cannot be taken.

    Parameters
    ----------
    shift : dict
        As for :func:`log10_shift`.
    theta : array
        Temperatures.

    Returns
    -------
    int or None
        The smallest i with :func:`shift_error` (shift, theta[i]) not None; None if none.
    """
    theta = np.atleast_1d(np.asarray(theta, float))
    for i, value in enumerate(theta):
        if shift_error(shift, value) is not None:
            return i
    return None


def inverse_shift(shift: dict, theta) -> tuple[np.ndarray, str | None]:
    """1/a_T(theta), the rate of reduced time d xi / dt, and why it cannot be taken.

    Parameters
    ----------
    shift : dict
        As for :func:`log10_shift` (a [viscoelastic] table).
    theta : array
        Temperatures.

    Returns
    -------
    tuple
        (1/a_T = 10^(-log10 a_T) per temperature, :func:`shift_error` or None); where there is
        an error the values are not to be used.
    """
    theta = np.asarray(theta, float)
    if shift.get("shift", "none") == "wlf" and theta.size and np.all(np.isfinite(theta)):
        den = float(shift["C2"]) + theta - float(shift["T_ref"])
        if np.all(den > 0):              # the common case: one pass, no second evaluation
            log10_aT = -float(shift["C1"]) * (theta - float(shift["T_ref"])) / den
            if np.all(np.abs(log10_aT) <= MAX_LOG10_SHIFT):
                return 10.0 ** -log10_aT, None
    error = shift_error(shift, theta)
    if error is not None:
        return np.ones_like(theta), error
    return 10.0 ** -log10_shift(shift, theta), None


def shifted(phi: PronySeries, log10_aT: float) -> PronySeries:
    """The series at a temperature whose shift is a_T: phi(t / a_T), times tau_i a_T.

    Parameters
    ----------
    phi : PronySeries
        The relaxation function at T_ref.
    log10_aT : float
        log10 a_T at the temperature.

    Returns
    -------
    PronySeries
        The same moduli with the relaxation times a_T tau_i (the master curve shifted).
    """
    a = 10.0 ** float(log10_aT)
    return PronySeries(phi.long_term, phi.moduli, tuple(a * tau for tau in phi.taus))
