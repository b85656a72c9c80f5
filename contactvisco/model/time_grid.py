"""The time grid of a run: the step times 0 = t_0 < t_1 < ... < t_N = T of [time].

Four kinds (time.grid):

- ``uniform``: t_n = n k, k = T/N (N = time.steps).
- ``logarithmic``: geometric steps k_j = k_1 g^(j-1) from t = 0, with k_1 = time.first and the
  growth g = time.growth, or g = 10^(1/m) for m = time.per_decade steps per decade. Their sum
  s_j = k_1 (g^j - 1)/(g - 1) reaches T after

      N = ceil(log(1 + (T/k_1)(g - 1)) / log g)

  steps; all steps are then scaled by one factor T/s_N in (1/g, 1], so that t_N = T. Once
  t >> k_1/(g - 1), t_j grows by the factor g per step: m steps per decade of time.
- ``piecewise``: segments [t_{i-1}, end_i], each uniform (its own steps) or logarithmic from
  its start (its own first step and growth); each segment's end is a step time (the kink of a
  ramp-and-hold load). The last end is T.
- ``times``: the given times (a list, or a column of a CSV file read by the scene), T added
  when the list ends before it.
- ``adaptive``: the steps are chosen as the run goes (contactvisco.solver.step_control) from
  an estimate of the memory's local time error against time.tolerance, between time.min_step
  and time.max_step, from time.first. Known in advance are only the times it lands on (0,
  time.landing_times, T: :func:`times`) and the bounds of its steps (:func:`steps` gives
  [min_step, max_step], which every check that needs the grid's steps takes).

Every step is at least :data:`LEAST_STEP` T (the time loop matches times to 1e-12 T) and
the grid has at most the scene's bound of steps; :func:`count` gives N before any array is
built.
"""
from __future__ import annotations

import math

import numpy as np

#: time.grid: the kinds of time grid.
GRIDS = ("uniform", "logarithmic", "piecewise", "times", "adaptive")

#: Kinds of a segment of a piecewise grid.
SEGMENT_GRIDS = ("uniform", "logarithmic")

#: Smallest step, relative to T: the loop matches times to 1e-12 T.
LEAST_STEP = 1e-10

#: Most steps of a grid (the memory of eq 19 is summed over all earlier steps).
MAX_STEPS = 1_000_000


def growth_of(spec: dict) -> float:
    """The growth factor g of a logarithmic grid or segment.

    Parameters
    ----------
    spec : dict
        ``growth`` (g > 1) or ``per_decade`` (m > 0: g = 10^(1/m)); one of them not None.

    Returns
    -------
    float
        g.
    """
    if spec.get("growth") is not None:
        return float(spec["growth"])
    return 10.0 ** (1.0 / float(spec["per_decade"]))


def geometric_count(span: float, first: float, growth: float) -> float:
    """N = ceil(log(1 + (span/first)(g - 1)) / log g) (module description) as a float: inf
    when it overflows, so that a bound refuses it before anything is built.

    Parameters
    ----------
    span : float
        The length of the interval, > 0.
    first : float
        The first step k_1, > 0.
    growth : float
        g > 1.

    Returns
    -------
    float
        The number of steps, >= 1 (an integer value, or inf).
    """
    with np.errstate(over="ignore"):
        x = np.log1p(np.float64(span) / first * (growth - 1.0)) / math.log(growth)
    if not np.isfinite(x):
        return math.inf
    # an exact fit (span a sum of whole steps) must not gain a step from round-off
    return float(max(1, math.ceil(float(x) * (1.0 - 1e-12))))


def geometric(start: float, end: float, first: float, growth: float) -> np.ndarray:
    """The step times after `start` of geometric steps k_1 g^(j-1) scaled to end at `end`.

    Parameters
    ----------
    start, end : float
        The interval, end > start.
    first : float
        The first step k_1 before scaling.
    growth : float
        g > 1.

    Returns
    -------
    numpy.ndarray
        t_1 .. t_N (start excluded), the last exactly `end`.
    """
    span = end - start
    n = int(geometric_count(span, first, growth))
    sums = first * np.expm1(np.arange(1, n + 1) * math.log(growth)) / (growth - 1.0)
    out = start + sums * (span / sums[-1])
    out[-1] = end
    return out


def uniform(start: float, end: float, steps: int) -> np.ndarray:
    """t_1 .. t_N of N uniform steps after `start`: start + n (end - start)/N (n (T/N) for
    start = 0, as the time loop has always stepped)."""
    k = (end - start) / steps
    out = start + np.arange(1, steps + 1) * k
    return out


def _segment_count(start: float, segment: dict, T: float) -> float:
    if segment.get("grid", "uniform") == "uniform":
        return float(segment["steps"])
    return geometric_count(float(segment["end"]) - start, float(segment["first"]),
                           growth_of(segment))


def count(time: dict) -> float:
    """The number of steps N of a [time] table, computed without building the grid (a float:
    inf when it would overflow).

    Parameters
    ----------
    time : dict
        The [time] table (its keys checked one by one).

    Returns
    -------
    float
        N.
    """
    kind, T = time.get("grid", "uniform"), float(time["T"])
    if kind == "uniform":
        return float(time["steps"])
    if kind == "adaptive":            # the fewest it can take: the landing times
        return float(len(landing_times(time)))
    if kind == "logarithmic":
        return geometric_count(T, float(time["first"]), growth_of(time))
    if kind == "piecewise":
        total, start = 0.0, 0.0
        for segment in time["segments"]:
            total += _segment_count(start, segment, T)
            start = float(segment["end"])
        return total
    return float(len(explicit_times(time)))


def explicit_times(time: dict) -> list:
    """The times of a ``times`` grid after 0: time.times, or the file's column (the
    attribute ``file_times`` the scene sets when it reads time.times_file), a leading 0
    dropped, T appended when the list ends before it."""
    given = time.get("times")
    if given is None:
        given = getattr(time, "file_times", None)
        if given is None:
            raise ValueError("time.grid = 'times' with time.times_file: the file is read when "
                             "the scene is loaded (load_scene)")
    out = [float(t) for t in given]
    if out and out[0] == 0.0:
        out = out[1:]
    T = float(time["T"])
    if not out or out[-1] < T:
        out.append(T)
    return out


def times(time: dict) -> np.ndarray:
    """The step times t_0 = 0 < t_1 < ... < t_N of a checked [time] table (module
    description); kept on a table as the attribute ``grid`` with the values it follows.

    Parameters
    ----------
    time : dict
        The checked [time] table (or a dict of its keys).

    Returns
    -------
    numpy.ndarray
        t_0 .. t_N (read only), N + 1 values, t_N = T (uniform: n (T/N) for every n).
    """
    signature = _signature(time)
    kept = getattr(time, "grid", None)
    if kept is not None and kept[0] == signature:
        return kept[1]
    kind, T = time.get("grid", "uniform"), float(time["T"])
    if kind == "uniform":
        after = uniform(0.0, T, int(time["steps"]))
    elif kind == "logarithmic":
        after = geometric(0.0, T, float(time["first"]), growth_of(time))
    elif kind == "piecewise":
        parts, start = [], 0.0
        for segment in time["segments"]:
            end = float(segment["end"])
            if segment.get("grid", "uniform") == "uniform":
                parts.append(uniform(start, end, int(segment["steps"])))
            else:
                parts.append(geometric(start, end, float(segment["first"]),
                                       growth_of(segment)))
            start = end
        after = np.concatenate(parts)
    elif kind == "adaptive":
        after = np.array(landing_times(time))
    else:
        after = np.array(explicit_times(time))
    out = np.concatenate([[0.0], after])
    out.flags.writeable = False
    try:
        time.grid = (signature, out)      # a table keeps it; a plain dict cannot
    except AttributeError:
        pass
    return out


def _signature(time: dict) -> str:
    """The values the grid follows (a table changed in place builds its grid again)."""
    return repr((sorted((str(k), repr(v)) for k, v in time.items()),
                 id(getattr(time, "file_times", None))))


def largest_step(time: dict) -> float | None:
    """The largest step of a [time] table's grid, or None when the table does not make a
    grid of at most MAX_STEPS steps (a table checked before [time] asks; [time]'s own rules
    then say what is wrong).

    Parameters
    ----------
    time : dict
        The [time] table, maybe not checked yet.

    Returns
    -------
    float or None
        max k_n.
    """
    try:
        if not count(time) <= MAX_STEPS:
            return None
        return float(steps(time).max())
    except (TypeError, ValueError, KeyError, ZeroDivisionError, OverflowError):
        return None


def steps(time: dict) -> np.ndarray:
    """The step sizes k_n = t_n - t_{n-1}, n = 1..N.

    Parameters
    ----------
    time : dict
        The [time] table whose grid is stepped.

    Returns
    -------
    numpy.ndarray
        k_1 .. k_N; a uniform grid's are T/N each, as k has always been computed (not the
        differences of its times, which differ from T/N by round-off).
    """
    if time.get("grid", "uniform") == "uniform":
        return np.full(int(time["steps"]), float(time["T"]) / time["steps"])
    if time.get("grid") == "adaptive":
        return np.array(step_bounds(time))
    return np.diff(times(time))


def summary(time: dict) -> tuple[int, float, float]:
    """(N, smallest step, largest step) of a [time] table's grid.

    Parameters
    ----------
    time : dict
        The [time] table.

    Returns
    -------
    tuple of (int, float, float)
        The number of steps and the extreme step sizes.
    """
    k = steps(time)
    if time.get("grid") == "adaptive":            # the fewest steps, and the bounds
        return int(count(time)), float(k[0]), float(k[1])
    return len(k), float(k.min()), float(k.max())


def nearest(time: dict, wanted) -> list[int]:
    """The indices n of the grid times t_n nearest to each wanted time: round(t/k) clipped to
    0..N on a uniform grid (as the output schedules have always chosen), the nearest time
    (the earlier one of two equally near) on the others.

    Parameters
    ----------
    time : dict
        The [time] table.
    wanted : iterable of float
        Times.

    Returns
    -------
    list of int
        One index per wanted time.
    """
    if time.get("grid", "uniform") == "uniform":
        steps = int(time["steps"])
        k = float(time["T"]) / steps
        return [min(steps, max(0, round(t / k))) for t in wanted]
    grid = times(time)
    return [int(np.argmin(np.abs(grid - t))) for t in wanted]


def adaptive(time: dict) -> bool:
    """Whether the [time] table's steps are chosen as the run goes (time.grid = "adaptive")."""
    return time.get("grid") == "adaptive"


#: Default smallest step of an adaptive grid, relative to its first step.
MIN_STEP_OF_FIRST = 0.01


def step_bounds(time: dict) -> tuple[float, float]:
    """(k_min, k_max) of an adaptive grid: time.min_step (default first/100) and time.max_step
    (default T); the checks that need a grid's steps in advance take these two.

    Parameters
    ----------
    time : dict
        The [time] table, grid = "adaptive".

    Returns
    -------
    tuple of float
        The smallest and the largest step the controller may choose.
    """
    first = float(time["first"])
    least = time.get("min_step")
    largest = time.get("max_step")
    least = MIN_STEP_OF_FIRST * first if least is None else float(least)
    return least, float(time["T"]) if largest is None else float(largest)


def landing_times(time: dict) -> list:
    """The times after 0 an adaptive grid steps onto exactly: time.landing_times below T,
    then T."""
    T = float(time["T"])
    return [float(t) for t in (time.get("landing_times") or []) if 0.0 < float(t) < T] + [T]


def scaled(time: dict, factor: float) -> dict:
    """The [time] keys that make a grid `factor` times as dense (presets, the trade-off's
    ladder): uniform steps N f; a logarithmic grid's (or segment's) first step k_1 / f and
    per_decade m f (growth g^(1/f)); an adaptive grid's first step k_1 / f and tolerance
    tol / f^3 (its local error is of order 3, so its steps scale as tol^(-1/3)); given times
    are data and stay.

    Parameters
    ----------
    time : dict
        The [time] table (values not yet checked are left as they are).
    factor : float
        f > 0.

    Returns
    -------
    dict
        The changed keys and their values (empty when nothing scales).
    """
    def number(x):
        return isinstance(x, (int, float)) and not isinstance(x, bool) and x > 0

    def geometric(spec):
        out = {}
        if number(spec.get("first")):
            out["first"] = spec["first"] / factor
        if number(spec.get("per_decade")):
            out["per_decade"] = spec["per_decade"] * factor
        elif number(spec.get("growth")) and spec["growth"] > 1:
            out["growth"] = spec["growth"] ** (1.0 / factor)
        return out

    def steps(spec):
        n = spec.get("steps")
        ok = isinstance(n, int) and not isinstance(n, bool) and n >= 1
        return {"steps": max(1, round(n * factor))} if ok else {}

    kind = time.get("grid", "uniform")
    if factor == 1:                       # the scene as it is, its values' types kept
        return {}
    if kind == "uniform":
        return steps(time)
    if kind == "logarithmic":
        return geometric(time)
    if kind == "adaptive":
        out = {"first": time["first"] / factor} if number(time.get("first")) else {}
        if number(time.get("tolerance")):
            out["tolerance"] = time["tolerance"] / factor ** 3
        return out
    if kind == "piecewise" and isinstance(time.get("segments"), list):
        segments = [dict(s, **(steps(s) if s.get("grid", "uniform") == "uniform"
                               else geometric(s))) if isinstance(s, dict) else s
                    for s in time["segments"]]
        return {"segments": segments}
    return {}
