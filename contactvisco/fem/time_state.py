"""What a time step stages before its solve and commits after it: the time of the scene's
expressions with the data that follow it, the history of eq (19), the slip's origin and the
obstacle's motion."""
from __future__ import annotations

from dataclasses import dataclass

from dolfinx import fem

from contactvisco.fem.memory_part import MemoryPart
from contactvisco.fem.stress import BodyMemory


@dataclass
class TimeState:
    """What a time step stages before its solve and commits after it (like an ODE
    integrator's stage and update): the time t of the scene's expressions with the data that
    follow it (loads, Dirichlet values, the gap), the history stress H of eq (19) with the
    implicit weights of the step, prepared from the committed strains, and the origin of the
    step's slip (slip = "increment").

    stage(t) takes the problem from the committed time to t, a step of size k = t - committed
    (the first state, t_0, has no step and nothing to prepare); a step that failed is staged
    again with another t. commit() takes the converged state into the history and makes the
    staged time the committed one. A restart sets `committed` to the checkpoint's time."""
    t: fem.Constant                            # the time of the expressions (Context.t)
    updates: list                              # callables that follow t (interpolations)
    u: fem.Function
    memory: MemoryPart | None
    u_previous: fem.Function | None            # the slip's origin (slip = "increment")
    committed: float | None = None             # the last committed time (None: none yet)
    staged: float | None = None
    obstacle: object | None = None             # fem.obstacle.ObstaclePart (None: none)

    def stage(self, t: float):
        """Move to time t and prepare the step from the committed state."""
        self.move_to(t)
        if self.committed is not None:
            self.prepare(t - self.committed)
        self.staged = t

    def commit(self):
        """Take the converged state at the staged time into the history."""
        self.record(None if self.committed is None else self.staged - self.committed)
        self.committed = self.staged
        if self.obstacle is not None:
            self.obstacle.commit()

    def move_to(self, t: float):
        """Move time-dependent data (loads, Dirichlet values, gap) to time t."""
        self.t.value = t
        for update in self.updates:
            update()

    def prepare(self, k: float):
        """Set the history stress H of a step of size k from the committed state, and the
        implicit weight k/2 R(0) of the trapezoid rule (0 at t_0, where nothing is prepared).
        A failed step can be prepared again with a smaller k.

        With slip = "increment" the current u, the converged state of t_{n-1}, becomes the
        origin of the step's slip; it stays so until the next step is prepared, so that the
        step's output still sees it."""
        if self.u_previous is not None:
            self.u_previous.x.array[:] = self.u.x.array
        if self.obstacle is not None:
            self.obstacle.prepare(self.committed)
        if self.memory is None:
            return
        for memory in getattr(self.memory, "parts", (self.memory,)):
            weights = memory.history.implicit(k)
            for constant, part in memory.implicit_terms:
                if isinstance(constant, fem.Function):  # a weight per point (reduced time)
                    constant.x.array[:] = weights[part]
                else:
                    constant.value = weights[part]
            memory.H.x.array[:] = memory.history.explicit(k)
        if isinstance(self.memory, BodyMemory):
            self.memory.combine()

    def record(self, k: float | None):
        """Take eps of the current, converged u (reached by a step of size k; None at t_0)
        into the history."""
        if self.memory is None:
            return
        for memory in getattr(self.memory, "parts", (self.memory,)):
            memory.eps_function.interpolate(memory.eps_expression)
            memory.history.commit(memory.eps_function.x.array, k)
