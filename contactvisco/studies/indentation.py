"""Creep indentation against the correspondence principle (Lee and Radok 1960, for a contact
that does not shrink): a rigid sphere on an axisymmetric body (:class:`SphereLeeRadok`), and a
rigid cylinder (radius R) pressed by a constant force P per unit length into a viscoelastic
layer (plane strain), below.

The layer's law is the project's: sigma = A eps + int_0^t R(t - s) dev eps(s) ds with one
exponential term R = alpha exp(-t/tau) on the deviatoric part (dev eps = eps - tr(eps)/2 I in
2D). In Laplace variables the in-plane moduli become, with r(s) = alpha / (s + 1/tau),

    mu~ = mu + r/2,   lambda~ = lambda - r/2   (lambda~ + mu~ = lambda + mu),

and the plane-strain modulus of Hertz's law, E* = 4 mu (lambda + mu) / (lambda + 2 mu), becomes
E*~(s). Elastic Hertz for a cylinder, a^2 = 4 P R / (pi E*), gives under a force P H(t)

    a(t)^2 = (4 P R / pi) C(t),    C = L^-1[1 / (s E*~(s))] = A_0 + A_1 exp(-beta t),
    beta = 1/tau + alpha / (2 mu),
    A_0 = N(0) / (4 (lambda + mu) mu beta),  A_1 = -N(-beta) / (4 (lambda + mu) mu beta),
    N(s) = (lambda + 2 mu) (s + 1/tau) + alpha / 2,

C the creep compliance of the layer's E* (A_0 + A_1 = 1/E*, the elastic one). It holds while
a(t) does not decrease: alpha < 0 (a softening term) with 2 mu + alpha tau > 0 (a positive
long-time shear modulus), where C grows from 1/E* to A_0. The pressure is then not Hertz's
ellipse but the superposition of the ellipses of the widths passed,
p(x, t) = 1/(2R) int_0^t E*(t - s) d/ds sqrt(a(s)^2 - x^2)_+ ds with the relaxation modulus
E*(t) = L^-1[E*~(s) / s] = B_0 + B_1 exp(-gamma t), gamma = 1/tau + alpha / (2 (lambda + 2 mu));
its second moment, which the runs measure (int p x^2 = P a_m^2 / 4), is

    a_m(t)^2 = (pi / (4 R P)) [E*(t) a(0)^4 + int_0^t E*(t - s) d(a^4)/ds ds],

equal to a^2 for an ellipse (t = 0, and t -> infinity).
"""
from __future__ import annotations

import math

import numpy as np
from mpi4py import MPI

from contactvisco.model.material import lame_constants
from contactvisco.scene import loader as scene_module
from contactvisco.solver.time_loop import simulate

#: The trapezoid rule on samples (numpy.trapezoid from NumPy 2, numpy.trapz before).
trapezoid = getattr(np, "trapezoid", None) or np.trapz


class LeeRadok:
    """The closed forms of the module description for one layer and load.

    Parameters
    ----------
    E, nu : float
        Young's modulus and Poisson's ratio (plane strain).
    alpha, tau : float
        The deviatoric memory term R = alpha exp(-t/tau) (alpha < 0, 2 mu + alpha tau > 0).
    P, R : float
        The force per unit length and the cylinder's radius.
    """

    def __init__(self, E: float, nu: float, alpha: float, tau: float, P: float, R: float):
        lam, mu = lame_constants("plane_strain", E, nu)
        if not (alpha < 0 and 2 * mu + alpha * tau > 0):
            raise ValueError("Lee-Radok needs a growing contact: alpha < 0 and "
                             "2 mu + alpha tau > 0")
        b = 1.0 / tau
        self.beta = b + alpha / (2 * mu)
        N = lambda s: (lam + 2 * mu) * (s + b) + alpha / 2     # noqa: E731
        self.A0 = N(0.0) / (4 * (lam + mu) * mu * self.beta)
        self.A1 = -N(-self.beta) / (4 * (lam + mu) * mu * self.beta)
        self.gamma = b + alpha / (2 * (lam + 2 * mu))
        self.B0 = 4 * (lam + mu) * (mu * b + alpha / 2) / ((lam + 2 * mu) * self.gamma)
        self.B1 = -4 * (lam + mu) * (mu * (b - self.gamma) + alpha / 2) / (
            (lam + 2 * mu) * self.gamma)
        self.P, self.R, self.K = P, R, 4 * P * R / math.pi
        # the long-time moduli: r(0) = alpha tau in mu~ = mu + r/2, lambda~ = lambda - r/2
        lam_long, mu_long = lam - alpha * tau / 2, mu + alpha * tau / 2
        self.nu_long = lam_long / (2 * (lam_long + mu_long))
        self.E_long = 2 * mu_long * (1 + self.nu_long)

    def long_time(self) -> tuple[float, float]:
        """The elastic constants the layer tends to under a constant strain, from the
        long-time Lame constants lambda - alpha tau / 2 and mu + alpha tau / 2.

        Returns
        -------
        tuple of float
            (E_inf, nu_inf) with nu = lambda / (2 (lambda + mu)), E = 2 mu (1 + nu); an
            elastic layer of these constants has the creep compliance's limit,
            4 mu (lambda + mu) / (lambda + 2 mu) = 1 / A_0.
        """
        return self.E_long, self.nu_long

    def compliance(self, t):
        """C(t) = A_0 + A_1 exp(-beta t), the creep compliance of E*.

        Parameters
        ----------
        t : float or numpy.ndarray
            Times.

        Returns
        -------
        float or numpy.ndarray
            C(t).
        """
        return self.A0 + self.A1 * np.exp(-self.beta * np.asarray(t, float))

    def relaxation(self, t):
        """E*(t) = B_0 + B_1 exp(-gamma t), the relaxation modulus of E*.

        Parameters
        ----------
        t : float or numpy.ndarray
            Times.

        Returns
        -------
        float or numpy.ndarray
            E*(t).
        """
        return self.B0 + self.B1 * np.exp(-self.gamma * np.asarray(t, float))

    def width(self, t: float) -> float:
        """The contact half-width a(t) = sqrt(4 P R C(t) / pi).

        Parameters
        ----------
        t : float
            The time.

        Returns
        -------
        float
            a(t).
        """
        return math.sqrt(self.K * float(self.compliance(t)))

    def moment_width(self, t: float, points: int = 4001) -> float:
        """a_m(t), the width of the pressure's second moment (module description), the
        hereditary integral by the trapezoid rule on `points` points.

        Parameters
        ----------
        t : float
            The time.
        points : int, optional
            Quadrature points on [0, t].

        Returns
        -------
        float
            a_m(t) = 2 sqrt(int p x^2 / int p).
        """
        s = np.linspace(0.0, t, points)
        C = self.compliance(s)
        rate = 2 * self.K**2 * C * (-self.beta * self.A1 * np.exp(-self.beta * s))
        integral = float(trapezoid(self.relaxation(t - s) * rate, s)) if t > 0 else 0.0
        start = float(self.relaxation(t)) * (self.K * float(C[0])) ** 2
        return math.sqrt(math.pi / (4 * self.R * self.P) * (start + integral))


class SphereLeeRadok:
    """The closed forms of a rigid sphere (radius R) on a half-space of the project's law with
    one deviatoric memory term, R(t) = alpha exp(-t/tau) on dev eps = eps - tr(eps)/3 I
    (axisymmetric and 3D bodies), under Hertz's assumptions (Lee and Radok 1960, Ting 1966).

    In Laplace variables, with b = 1/tau, the shear modulus becomes G(s) = mu + alpha / (2 (s + b))
    = mu (s + beta_1) / (s + b) and the bulk modulus K stays; Hertz's contact modulus
    E* = 4 G (3K + G) / (3K + 4G) becomes

        E*(s) = E*_0 (s + beta_1)(s + beta_2) / ((s + b)(s + beta_3)),
        beta_1 = b + alpha / (2 mu),  beta_2 = b + alpha / (2 (3K + mu)),
        beta_3 = b + 2 alpha / (3K + 4 mu),  E*_0 = 4 mu (3K + mu) / (3K + 4 mu).

    Its relaxation function Er = L^-1[E*(s) / s] is, by partial fractions,
    Er(t) = E_inf + c_b exp(-b t) + c_3 exp(-beta_3 t) with E_inf = E*_0 beta_1 beta_2 / (b beta_3),
    c_b = E*_0 (beta_1 - b)(beta_2 - b) / (-b (beta_3 - b)),
    c_3 = E*_0 (beta_1 - beta_3)(beta_2 - beta_3) / (-beta_3 (b - beta_3)); its creep function
    C = L^-1[1 / (s E*(s))], from 1/E* = 1/(4G) + 3/(4 (3K + G)), is

        C(t) = 1/(4 mu) [b/beta_1 + (1 - b/beta_1) exp(-beta_1 t)]
               + 3/(4 (3K + mu)) [b/beta_2 + (1 - b/beta_2) exp(-beta_2 t)].

    Under a depth delta held from t = 0 the contact radius stays a = sqrt(R delta) and the force
    relaxes as P(t) = 4/3 Er(t) R^1/2 delta^3/2; under a force P held from t = 0 (a growing
    contact: alpha < 0) a(t)^3 = 3 R P C(t) / 4 and delta(t) = a(t)^2 / R. Both need
    mu + alpha tau / 2 > 0 (a positive long-time shear modulus).

    Parameters
    ----------
    E, nu : float
        The instantaneous Young's modulus and Poisson's ratio (3D constants).
    alpha, tau : float
        The deviatoric memory term.
    R : float
        The sphere's radius.
    """

    def __init__(self, E: float, nu: float, alpha: float, tau: float, R: float):
        lam, mu = lame_constants("3d", E, nu)
        K = lam + 2.0 * mu / 3.0
        if not mu + alpha * tau / 2.0 > 0:
            raise ValueError("the long-time shear modulus mu + alpha tau / 2 must be > 0")
        b = 1.0 / tau
        self.b, self.R, self.mu, self.M = b, R, mu, 3.0 * K + mu
        self.beta1 = b + alpha / (2.0 * mu)
        self.beta2 = b + alpha / (2.0 * self.M)
        self.beta3 = b + 2.0 * alpha / (3.0 * K + 4.0 * mu)
        self.E0 = 4.0 * mu * self.M / (3.0 * K + 4.0 * mu)
        b1, b2, b3 = self.beta1, self.beta2, self.beta3
        self.E_inf = self.E0 * b1 * b2 / (b * b3)
        self.c_b = self.E0 * (b1 - b) * (b2 - b) / (-b * (b3 - b))
        self.c_3 = self.E0 * (b1 - b3) * (b2 - b3) / (-b3 * (b - b3))

    def relaxation(self, t):
        """Er(t), the relaxation function of E* (Er(0) = E*_0).

        Parameters
        ----------
        t : float or numpy.ndarray
            Times >= 0.

        Returns
        -------
        numpy.ndarray
            Er(t).
        """
        t = np.asarray(t, float)
        return self.E_inf + self.c_b * np.exp(-self.b * t) + self.c_3 * np.exp(-self.beta3 * t)

    def compliance(self, t):
        """C(t) at the times t >= 0 (numbers or an array), the creep function of E*: the
        inverse of Er in the sense int_0^t C(t - s) dEr(s) = 1, C(0) = 1 / E*_0."""
        t = np.asarray(t, float)
        b = self.b
        return (1.0 / (4.0 * self.mu) * (b / self.beta1 + (1.0 - b / self.beta1)
                                         * np.exp(-self.beta1 * t))
                + 3.0 / (4.0 * self.M) * (b / self.beta2 + (1.0 - b / self.beta2)
                                          * np.exp(-self.beta2 * t)))

    def force(self, delta: float, t):
        """P(t) = 4/3 Er(t) R^1/2 delta^3/2 under the depth delta held from t = 0.

        Parameters
        ----------
        delta : float
            The depth.
        t : float or numpy.ndarray
            Times >= 0.

        Returns
        -------
        numpy.ndarray
            P(t), the total force.
        """
        return 4.0 / 3.0 * self.relaxation(t) * math.sqrt(self.R) * delta ** 1.5

    def radius(self, P: float, t):
        """a(t) = (3 R P C(t) / 4)^(1/3) under the force P held from t = 0 (alpha < 0).

        Parameters
        ----------
        P : float
            The total force.
        t : float or numpy.ndarray
            Times >= 0.

        Returns
        -------
        numpy.ndarray
            a(t); the depth is a(t)^2 / R.
        """
        return (0.75 * self.R * P * self.compliance(t)) ** (1.0 / 3.0)


def creep_indentation(h: float, steps: int, T: float = 3.0, E: float = 200.0,
                      nu: float = 0.3, alpha: float = -60.0, tau: float = 1.0,
                      P: float = 0.3, R: float = 1.0, comm=MPI.COMM_WORLD,
                      time: dict | None = None) -> dict:
    """A layer [0, 2] x [0, 1] (top held) under a cylinder pushed up by the constant force P
    (force control, from t = 0), with the deviatoric memory term alpha exp(-t/tau), trapezoid
    rule on `steps` uniform steps unless `time` says otherwise; the contact width at every
    step against Lee-Radok.

    Parameters
    ----------
    h : float
        The mesh size along the contact boundary.
    steps : int
        Time steps on [0, T] (uniform grid).
    T : float, optional
        The end time.
    E, nu, alpha, tau, P, R : float, optional
        The layer, its memory term, the force and the radius.
    comm : mpi4py.MPI.Comm, optional
        The communicator (collective).
    time : dict, optional
        Keys of the scene's `[time]` table that replace the uniform trapezoid grid (e.g.
        ``{"grid": "logarithmic", "first": 0.01, "per_decade": 5, "rule": "exponential"}``).

    Returns
    -------
    dict
        ``t``, ``a_m`` (measured: 2 sqrt(sum w p x^2 / sum w p)), ``a_m_exact``, ``a_exact``
        (sqrt(4 P R C / pi)), ``depth`` (the cylinder's displacement), ``force`` (recorded),
        ``error`` (the largest relative error of a_m over the steps), ``newton``.
    """
    raw = _layer_scene(h, E, nu, P, R)
    raw["memory"] = {"kernel": "prony",
                     "terms": [{"alpha": alpha, "tau": tau, "part": "deviatoric"}]}
    raw["time"] = {"T": T, "steps": steps, "rule": "trapezoid"}
    raw["time"].update(time or {})
    result = simulate(scene_module.resolve(raw), comm=comm, progress=False, keep_tables=True)
    exact = LeeRadok(E, nu, alpha, tau, P, R)
    out = {key: [] for key in ("t", "a_m", "a_m_exact", "a_exact", "depth", "force")}
    for step, table in zip(result.steps, result.tables):
        out["t"].append(step["t"])
        out["a_m"].append(_moment_width(table))
        out["a_m_exact"].append(exact.moment_width(step["t"]))
        out["a_exact"].append(exact.width(step["t"]))
        out["depth"].append(step["obstacle"]["displacement"][1])
        out["force"].append(step["obstacle"]["force"][1])
    out = {key: np.array(value) for key, value in out.items()}
    out["error"] = float(np.max(np.abs(out["a_m"] - out["a_m_exact"]) / out["a_m_exact"]))
    out["newton"] = [s["newton_iterations"] for s in result.steps]
    return out


def elastic_indentation(h: float, E: float = 200.0, nu: float = 0.3, P: float = 0.3,
                        R: float = 1.0, comm=MPI.COMM_WORLD) -> dict:
    """The layer and cylinder of creep_indentation without memory: one force-controlled step
    to the force P, on the same mesh. With the instantaneous constants (E, nu) it is the
    creeping layer at t = 0; with ``LeeRadok.long_time()`` the state it tends to.

    Parameters
    ----------
    h : float
        The mesh size along the contact boundary.
    E, nu, P, R : float, optional
        Young's modulus, Poisson's ratio (plane strain), the force and the radius.
    comm : mpi4py.MPI.Comm, optional
        The communicator (collective).

    Returns
    -------
    dict
        ``depth`` (the cylinder's displacement d_y), ``a_m`` (2 sqrt(sum w p x^2 / sum w p))
        and ``a_exact``, Hertz's sqrt(4 P R / (pi E*)), E* = E / (1 - nu^2).
    """
    raw = _layer_scene(h, E, nu, P, R)
    result = simulate(scene_module.resolve(raw), comm=comm, progress=False, keep_tables=True)
    return {"depth": result.steps[-1]["obstacle"]["displacement"][1],
            "a_m": _moment_width(result.tables[-1]),
            "a_exact": math.sqrt(4 * P * R * (1 - nu**2) / (math.pi * E))}


def _moment_width(table) -> float:
    """2 sqrt(sum w p x^2 / sum w p) about the cylinder's axis x = 1."""
    x = np.abs(table["x"][:, 0] - 1.0)
    force = table["reaction_nu"] * table["weight"]
    return 2 * math.sqrt(float(np.sum(force * x**2) / np.sum(force)))


def _layer_scene(h: float, E: float, nu: float, P: float, R: float) -> dict:
    """The layer [0, 2] x [0, 1] (top held) and the cylinder under the force P, elastic."""
    return {"name": "creep_indentation",
            "geometry": {"type": "gmsh", "script": "rectangle",
                         "parameters": {"length": 2.0, "height": 1.0, "h": 0.1,
                                        "h_bottom": h}},
            "material": {"model": "plane_strain", "E": E, "nu": nu},
            "dirichlet": [{"boundary": "top", "components": "all"}],
            "contact": {"boundary": "bottom", "g": 0.0, "mu": 0.0, "augmentation": E},
            "obstacle": {"shape": "cylinder", "centre": [1.0, -R], "radius": R,
                         "force_components": [1], "force": [P]},
            "time": {"T": 1.0, "steps": 1}, "output": {"probes": []}}
