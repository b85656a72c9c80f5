"""The adaptive time grid (time.grid = "adaptive"): each step's size from the estimate of the
memory's local time error on the step before (contactvisco.model.time_error).

The first two steps are time.first (three strains make the first estimate); after each
accepted state of step size k with relative estimate e, the next step is

    k' = k min(GROW, max(SHRINK, SAFETY (tol/e)^(1/3)))   within [time.min_step, time.max_step],

shortened to land on the next time of time.landing_times and on T (stretched onto it when less than
time.min_step would be left). A step is not taken again when its estimate exceeds the
tolerance: the next one shrinks (at most by SHRINK). The cuts on a Newton failure stay those
of the time loop (halves, solver.max_cuts), each half an accepted state with its own
estimate. The estimate is a maximum over the points, reduced over the ranks, so every rank
steps on the same grid; a restart takes k and the estimate of the checkpoint's record and the
strain eps_{n-1} of the checkpoint, and so continues the same grid.
"""
from __future__ import annotations

import math

from mpi4py import MPI

from contactvisco.model import time_error, time_grid


class Controller:
    """The step sizes of an adaptive grid, one accepted state after another.

    Parameters
    ----------
    time : dict
        The checked [time] table (grid = "adaptive").
    problem : contactvisco.fem.problem.Problem
        The problem; its Prony history (or the histories of its bodies) keeps eps_{n-1}.
    comm : mpi4py.MPI.Comm
        The run's communicator.
    resumed : dict, optional
        The checkpoint's step record on a restart (its ``t``, ``k`` and ``error``).
    """

    def __init__(self, time: dict, problem, comm, resumed: dict | None = None):
        self.T, self.tolerance = float(time["T"]), float(time["tolerance"])
        self.least, self.largest = time_grid.step_bounds(time)
        self.first = float(time["first"])
        self.landing = time_grid.landing_times(time)
        self.comm = comm
        history = problem.memory.history
        self.histories = getattr(history, "histories", [history])
        for h in self.histories:
            h.keep_previous = True
        self.terms = [term for h in self.histories for term in h.terms]
        self.t, self.k, self.error = 0.0, None, None
        if resumed is not None:
            self.t, self.k, self.error = resumed["t"], resumed.get("k"), resumed.get("error")
            for h in self.histories:
                h.last_k = self.k

    def times(self):
        """The step times: t_0 = 0 (not after a restart), then each next time as the states
        are accepted (accepted() moves the controller on)."""
        if self.k is None and self.t == 0.0:
            yield 0.0
        while self.t < self.T:
            yield self.next_time()

    def next_time(self) -> float:
        """The time of the next step from the last accepted state."""
        if self.k is None or self.error is None:
            k = self.first if self.k is None else self.k
        else:
            k = time_error.next_step(self.k, self.error, self.tolerance, self.least,
                                     self.largest)
        k = min(max(k, self.least), self.largest)
        stop = next(t for t in self.landing if t > self.t)
        if self.t + k + self.least > stop:
            return stop
        return self.t + k

    def accepted(self, t: float, k: float | None) -> float | None:
        """Take an accepted state (collective): its time, its step k, and the relative
        estimate of the step's memory error (None until three strains are known).

        Parameters
        ----------
        t : float
            The state's time.
        k : float or None
            Its step (None at t_0).

        Returns
        -------
        float or None
            max |e| / (sum_i |alpha_i| min(tau_i, t) max |eps|) over the ranks
            (contactvisco.model.time_error).
        """
        local = [h.local_error for h in self.histories]
        known = all(e is not None for e in local)
        known = self.comm.allreduce(known, op=MPI.LAND)
        error = None
        if known and k is not None:
            numerator = self.comm.allreduce(max(e[0] for e in local), op=MPI.MAX)
            strain = self.comm.allreduce(max(e[1] for e in local), op=MPI.MAX)
            scale = sum(abs(a) * min(tau, t) for a, tau, _ in self.terms) * strain
            error = numerator / scale if scale > 0 else 0.0
            if not math.isfinite(error):
                error = None
        self.t, self.k, self.error = t, k, error
        return error
