"""Which accepted states of a run get their XDMF fields ([output] field_every, field_times).

Used by the time loop, which writes the fields, and by the scene check, which estimates the
size of what the run will write; it lives apart from both so that neither imports the other.
"""
from contactvisco.model import time_grid


class FieldSchedule:
    """Which accepted states get their XDMF fields ([output] field_every, field_times): those
    whose step number (the record's "step", counting accepted states: the halves of a cut step
    are two) is a multiple of `every`, those at the grid's step times nearest to `times` (as
    for figure_times), and the final state t_N."""

    def __init__(self, every: int, times, time: dict):
        self.every = every
        # the grid's times as the time loop steps to them: its states land on these floats
        grid = time_grid.times(time)
        self.times = {float(grid[n]) for n in time_grid.nearest(time, times)} | {
            float(grid[-1])}

    def due(self, step: int, t: float) -> bool:
        return step % self.every == 0 or t in self.times
