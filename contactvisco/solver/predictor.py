"""Where Newton starts a step: the unknowns extrapolated in time from the accepted states.

Each step's first iterate is the linear extrapolation of the last two accepted states,

    w_pred = w_n + (t_{n+1} - t_n) / (t_n - t_{n-1}) (w_n - w_{n-1}),

for every unknown w (u and the multipliers lambda_nu, lambda_tau), with the exact step sizes
(a cut step's halves included). Only the start of Newton changes: the converged state is
fixed by the residual, and a step whose Newton fails from the prediction is solved again from
the last accepted state before any step is cut (contactvisco.solver.time_loop.advance), so a
prediction never changes the time grid. The first step of a run and of a restart starts from
the last accepted state, as there is no earlier pair to extrapolate from.
"""
from __future__ import annotations

import numpy as np


class Extrapolation:
    """The last two accepted states of a problem's unknowns and the linear extrapolation
    between them.

    Parameters
    ----------
    unknowns : list of dolfinx.fem.Function
        The unknowns of the Newton system (``Problem.unknowns``).
    """

    def __init__(self, unknowns):
        self.unknowns = unknowns
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
        """Set the unknowns to w_n + (t - t_n) / (t_n - t_{n-1}) (w_n - w_{n-1}).

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
            f.x.array[:] = w1 + ratio * (w1 - w0)
        return True


def create(scene: dict, unknowns) -> Extrapolation | None:
    """The predictor solver.predictor asks for ("extrapolate"), or None ("none": each step
    starts from the last accepted state)."""
    return Extrapolation(unknowns) if scene["solver"]["predictor"] == "extrapolate" else None
