"""Where Newton starts a step: the unknowns extrapolated in time from the accepted states.

Each step's first iterate is the linear extrapolation of the last two accepted states,

    w_pred = w_n + rho (w_n - w_{n-1}),    rho = (t_{n+1} - t_n) / (t_n - t_{n-1}),

for every unknown w (u and the multipliers lambda_nu, lambda_tau), with the exact step sizes
(a cut step's halves included), except the bound's reaction R_nu = -lambda_nu inside the zone
at the bound (a node whose reaction is positive in both states, as are those of its
neighbours on Gamma_C at t_n: contactvisco.fem.bound_zone): its square is extrapolated,

    R_pred^2 = R_n^2 + rho (R_n^2 - R_{n-1}^2),

lambda_pred = -R_pred where that is >= 0, and lambda_pred = +sqrt(-R_pred^2) > 0 (the free
side of R_nu = (r (u_nu - g) - lambda_nu)_+ at u_nu near g) where it is not: the node is
predicted to leave the bound within the step.

Why the square: near the edge of a zone in contact the reaction of an elastic body grows like
the square root of the distance to the edge (the pressure of Hertz's and Signorini's
problems; Johnson, Contact Mechanics, 1985, ch. 4 and 5), so where the edge moves at a steady
speed, R_nu^2 at a node ahead of it is affine in time, while R_nu falls to 0 with an infinite
slope, which a linear extrapolation of R_nu reaches only a step late: each node it misses
costs a Newton iteration, one node per iteration (docs/scaling.md). Away from the edge R_nu is
smooth and both extrapolations are of the same (first) order. At the outermost bound nodes
the discrete reaction (an integral of the pressure over the node's facets) goes to 0
smoothly instead, and the square would release them too early: there R_nu is extrapolated
linearly.

Only the start of Newton changes: the converged state is fixed by the residual, and a step
whose Newton fails from the prediction is solved again from the last accepted state before
any step is cut (contactvisco.solver.time_loop.advance), so a prediction never changes the
time grid. The first step of a run and of a restart starts from the last accepted state, as
there is no earlier pair to extrapolate from.
"""
from __future__ import annotations

import numpy as np
from mpi4py import MPI

#: A node is at the bound where its reaction R_nu exceeds this fraction of the largest one
#: (of all ranks) at t_n: a free node's multiplier is 0 only to round-off.
TINY = 1e-10


def extrapolate_reaction(older, newer, ratio, inside):
    """lambda_nu's prediction from its two last states (module description): at the nodes
    `inside` the zone at the bound, R_pred^2 = R_n^2 + ratio (R_n^2 - R_{n-1}^2) with
    R = -lambda_nu, and lambda_pred = -sqrt(R_pred^2), or +sqrt(-R_pred^2) where
    R_pred^2 < 0; elsewhere the linear extrapolation.

    Parameters
    ----------
    older, newer : numpy.ndarray
        lambda_nu at t_{n-1} and t_n.
    ratio : float
        rho = (t_{n+1} - t_n) / (t_n - t_{n-1}).
    inside : numpy.ndarray of bool
        The nodes inside the zone at the bound (R > 0 at both times and at t_n at every
        neighbour on Gamma_C).

    Returns
    -------
    numpy.ndarray
        lambda_nu's first iterate at t_{n+1}.
    """
    linear = newer + ratio * (newer - older)
    square = newer ** 2 + ratio * (newer ** 2 - older ** 2)       # R_pred^2
    return np.where(inside, -np.sign(square) * np.sqrt(np.abs(square)), linear)


class Extrapolation:
    """The last two accepted states of a problem's unknowns and the extrapolation between
    them.

    Parameters
    ----------
    unknowns : list of dolfinx.fem.Function
        The unknowns of the Newton system (``Problem.unknowns``).
    reaction : dolfinx.fem.Function, optional
        The one of them that is the bound's multiplier lambda_nu (R_nu = -lambda_nu), whose
        reaction is extrapolated in its square inside the zone at the bound; None: every
        unknown linearly.
    zone : contactvisco.fem.bound_zone.BoundZone, optional
        The test of which nodes lie inside that zone (needed with `reaction`).
    """

    def __init__(self, unknowns, reaction=None, zone=None):
        self.unknowns = unknowns
        self.reaction = reaction if zone is not None else None
        self.zone = zone
        self.states: list[tuple[float, list[np.ndarray]]] = []   # (t, values), newest last

    def record(self, t: float):
        """Keep the accepted state at time t (the unknowns' current values).

        Parameters
        ----------
        t : float
            The time of the accepted state.
        """
        self.states = self.states[-1:] + [(t, [f.x.array.copy() for f in self.unknowns])]

    def apply(self, t: float) -> bool:
        """Set the unknowns to their prediction at t: w_n + rho (w_n - w_{n-1}), lambda_nu
        by extrapolate_reaction.

        Parameters
        ----------
        t : float
            The time the step goes to.

        Returns
        -------
        bool
            Whether a prediction was made (False before two states are known).
        """
        if len(self.states) < 2:
            return False
        (t0, older), (t1, newer) = self.states
        ratio = (t - t1) / (t1 - t0)
        for f, w0, w1 in zip(self.unknowns, older, newer):
            if f is self.reaction:            # collective: every rank has lambda_nu
                comm = f.function_space.mesh.comm
                tiny = TINY * comm.allreduce(float(np.max(-w1, initial=0.0)), op=MPI.MAX)
                inside = (w0 < -tiny) & self.zone.interior(w1 < -tiny)
                f.x.array[:] = extrapolate_reaction(w0, w1, ratio, inside)
            else:
                f.x.array[:] = w1 + ratio * (w1 - w0)
        return True


def create(scene: dict, problem) -> Extrapolation | None:
    """The predictor solver.predictor asks for: "extrapolate" (the bound's reaction in its
    square inside the zone at the bound, every other unknown linearly), "linear" (every
    unknown linearly) or None for "none" (each step starts from the last accepted state).
    Collective.

    Parameters
    ----------
    scene : dict
        The scene (its solver.predictor).
    problem : contactvisco.fem.problem.Problem
        Its unknowns, and lambda_nu among its multipliers where the bound g is finite, with the
        contact part's BoundZone.
    """
    choice = scene["solver"]["predictor"]
    if choice == "none":
        return None
    reaction = problem.multipliers.get("lambda_nu") if choice == "extrapolate" else None
    zone = problem.contact.bound_zone if reaction is not None else None
    return Extrapolation(problem.unknowns, reaction, zone)
