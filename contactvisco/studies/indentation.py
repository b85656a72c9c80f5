"""Creep indentation: a rigid cylinder (radius R) pressed by a constant force P per unit
length into a viscoelastic layer (plane strain), against the correspondence principle
(Lee and Radok 1960, for a contact width that does not decrease).

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


def creep_indentation(h: float, steps: int, T: float = 3.0, E: float = 200.0,
                      nu: float = 0.3, alpha: float = -60.0, tau: float = 1.0,
                      P: float = 0.3, R: float = 1.0, comm=MPI.COMM_WORLD) -> dict:
    """A layer [0, 2] x [0, 1] (top held) under a cylinder pushed up by the constant force P
    (force control, from t = 0), with the deviatoric memory term alpha exp(-t/tau), trapezoid
    rule; the contact width at every step against Lee-Radok.

    Parameters
    ----------
    h : float
        The mesh size along the contact boundary.
    steps : int
        Time steps on [0, T].
    T : float, optional
        The end time.
    E, nu, alpha, tau, P, R : float, optional
        The layer, its memory term, the force and the radius.
    comm : mpi4py.MPI.Comm, optional
        The communicator (collective).

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
