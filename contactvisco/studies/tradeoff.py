"""The speed-accuracy trade of one scene: a ladder of discretizations, each run's error
estimated against the finest, its wall time, the Pareto front and the cheapest settings that
reach a target (`contactvisco tradeoff SCENE --target TOL`).

The ladder. Mesh levels j = 0..L-1 scale the scene's own mesh by m_j = c 2^j (box: cells
times m_j; gmsh: every mesh size parameter, h or h_*, divided by m_j, as the presets do). At every level the
time steps are N/2, N and 2N (N the scene's time.steps; only N when N = 1), and below the top
level degree 2 is tried at N steps (kept where its Newton converges). The reference is the
finest run: top level, 2N steps, degree 1.

The error estimate of a run q (`estimated_error`) is an upper estimate of ``|q - q*|``, q*
the exact value: by the triangle inequality ``|q - q*| <= |q - q_ref| + |q_ref - q*|``, and
the reference's own error ``|q_ref - q*|`` comes from Richardson extrapolation::

    |q_ref - q*| ~ d_h / (2^p_h - 1) + d_k / (2^p_k - 1),

d_h the difference between the two top mesh levels (2N steps), d_k between N and 2N steps on
the top level, and the observed orders p = log2(d_coarser / d_finer) from three levels (clamped
to [0.5, 3]; taken as 1 when only two levels ran).

Error measures (relative; differences of fields at all times the two runs share, at the
reference's contact nodes, linear interpolation of the other run along the boundary)::

    contact_displacement  (u_nu, u_tau) at the contact nodes, discrete L2 along the boundary,
                          divided by the largest L2 norm of the reference over time
    contact_pressure      the normal traction -sigma_nu at the contact nodes, the same norm
    probe                 u at the scene's output.probes: the largest difference of a
                          component, divided by the largest |u_i| of the reference

Wall time: the whole run (mesh, set-up with form compilation, time steps), the largest over
ranks.
"""
from __future__ import annotations

import json
import math
import pathlib
import time as clock
import tomllib

import numpy as np
from mpi4py import MPI

from contactvisco.errors import SceneError
from contactvisco.io import files
from contactvisco.model import time_grid
from contactvisco.model.material import dimension
from contactvisco.scene import loader as scene_module
from contactvisco.scene.toml_text import document_text

MEASURES = {
    "contact_displacement": "(u_nu, u_tau) at the contact nodes, relative discrete L2 norm "
                            "along the contact boundary",
    "contact_pressure": "normal traction -sigma_nu at the contact nodes, relative discrete L2 "
                        "norm along the contact boundary",
    "probe": "displacement at output.probes, largest component difference relative to the "
             "largest |u_i|",
}

ESTIMATE = ("difference to the finest run of the ladder (the reference) plus the reference's "
            "own error by Richardson extrapolation in mesh size and time step")


class TradeoffError(ValueError):
    """A scene or option the ladder cannot use: a mesh that cannot be refined, an unknown
    measure, a target or a level count out of range, runs that share no time level.

    Parameters
    ----------
    message : str
        What cannot be used and what to give instead.
    """


# --- the ladder -------------------------------------------------------------------------


def settings_lines(scene: dict, mesh: float, steps: int, degree: int,
                   density: float = 1.0) -> list[str]:
    """The absolute ``--set`` lines of one rung of the ladder.

    Parameters
    ----------
    scene : dict
        The resolved scene (from ``load_scene``).
    mesh : float
        The factor on the scene's own mesh: box cells are multiplied by it, gmsh mesh sizes
        (``h``, ``h_*``) divided by it.
    steps : int
        The number of time steps.
    degree : int
        The Lagrange degree of the displacement; degree 2 also selects the Gauss contact
        quadrature (the nodal conditions are P1's).
    density : float, optional
        A grid other than uniform: the factor on its density (time_grid.scaled), whose keys
        replace ``time.steps``.

    Returns
    -------
    list of str
        ``"key=value"`` lines, e.g. ``["geometry.cells=[16,16]", "time.steps=10",
        "discretization.degree=1"]``.
    """
    geo = scene["geometry"]
    lines = []
    if geo["type"] == "box":
        cells = [max(1, round(n * mesh)) for n in geo["cells"]]
        lines.append("geometry.cells=[" + ",".join(str(n) for n in cells) + "]")
    else:
        for key, value in geo["parameters"].items():
            if scene_module.is_mesh_size(key):
                lines.append(f"geometry.parameters.{key}={value / mesh:.6g}")
    if scene["time"]["grid"] == "uniform":
        lines.append(f"time.steps={steps}")
    else:
        lines += [f"time.{key}={_toml_value(value)}"
                  for key, value in time_grid.scaled(scene["time"], density).items()]
    lines.append(f"discretization.degree={degree}")
    if degree > 1:                       # nodal contact conditions are P1's
        lines.append("discretization.contact_quadrature=gauss")
    return lines


def rungs(scene: dict, levels: int, coarsest: float, degrees=(1, 2)) -> list[dict]:
    """The ladder in the order it is climbed: level by level, cheapest first.

    Parameters
    ----------
    scene : dict
        The resolved scene.
    levels : int
        The number of mesh levels; level j scales the mesh by ``coarsest * 2**j``.
    coarsest : float
        The mesh factor of the coarsest level.
    degrees : tuple of int, optional
        The Lagrange degrees to try; a degree above the scene's is tried at N steps on every
        level but the top one.

    Returns
    -------
    list of dict
        One rung per run: ``level``, ``mesh``, ``steps``, ``degree`` and ``set`` (its
        ``--set`` lines).

    Raises
    ------
    TradeoffError
        When the scene's mesh cannot be refined (a .msh file, or a gmsh script without mesh
        size parameters), or its time grid is not uniform.
    """
    if scene["geometry"]["type"] != "box" and not any(
            scene_module.is_mesh_size(key) for key in scene["geometry"]["parameters"]):
        raise TradeoffError("geometry: the mesh cannot be refined (a .msh file, or a gmsh "
                            "script without mesh size parameters h or h_*); give a box or a gmsh "
                            "script with them")
    time = scene["time"]
    if time["grid"] in ("times", "adaptive"):
        raise TradeoffError(f"time.grid = '{time['grid']}': the ladder's time knob is the "
                            "density of a uniform, logarithmic or piecewise grid (given times "
                            "are data; an adaptive grid's steps are not known before the run: "
                            "vary time.tolerance)")
    N = int(time_grid.count(time))
    # the grid half, once and twice as dense (time_grid.scaled): N/2, N, 2N uniform steps
    densities = [0.5, 1.0, 2.0] if N > 1 else [1.0]
    base_degree = scene["discretization"]["degree"]
    out = []
    for j in range(levels):
        mesh = coarsest * 2 ** j
        for density in densities:
            steps = int(time_grid.count({**time, **time_grid.scaled(time, density)}))
            out.append({"level": j, "mesh": mesh, "steps": steps, "degree": base_degree,
                        "density": density})
        for degree in degrees:
            if degree > base_degree and j < levels - 1:
                out.append({"level": j, "mesh": mesh, "steps": N, "degree": degree,
                            "density": 1.0})
    for rung in out:
        rung["set"] = settings_lines(scene, rung["mesh"], rung["steps"], rung["degree"],
                                     rung["density"])
    return out


def work(rung: dict, d: int) -> float:
    """Relative cost model of a rung: unknowns times steps, ``(mesh * degree)**d * N``.

    Parameters
    ----------
    rung : dict
        A rung of ``rungs``.
    d : int
        The space dimension.

    Returns
    -------
    float
        The rung's work in units of one step on the unit mesh.
    """
    return (rung["mesh"] * rung["degree"]) ** d * rung["steps"]


# --- one run and its samples ------------------------------------------------------------


def run(source: str, overrides: list[str], comm=MPI.COMM_WORLD) -> dict:
    """Solve a scene once and sample what the error measures compare.

    Parameters
    ----------
    source : str
        A built-in scene name or the path of a scene file.
    overrides : list of str
        ``"key=value"`` lines, as ``--set``.
    comm : mpi4py.MPI.Comm, optional
        The communicator to solve on (collective).

    Returns
    -------
    dict
        ``samples`` (per time: the probes' displacements and, with contact, the contact
        nodes' ``x``, ``u_nu``, ``u_tau`` and ``pressure``), ``wall_s`` (the whole run, largest
        over ranks), ``steps_s``, ``unknowns`` and ``newton_mean``. When Newton fails even
        after cutting the step: ``{"failed": message, "wall_s": ...}`` instead.
    """
    from contactvisco.solver.time_loop import simulate
    from contactvisco.solver.newton import NewtonFailure
    scene = scene_module.load(source, list(overrides))
    tick = clock.perf_counter()
    try:
        result = simulate(scene, comm=comm, progress=False, keep_tables=True)
    except NewtonFailure as err:
        return {"failed": str(err).split(";")[0],
                "wall_s": comm.allreduce(clock.perf_counter() - tick, op=MPI.MAX)}
    wall = comm.allreduce(clock.perf_counter() - tick, op=MPI.MAX)
    samples = {}
    for record, table in zip(result.steps, result.tables):
        entry = {"probes": [p["u"] for p in record["probes"]]}
        if table is not None:
            entry.update(x=table["x"], u_nu=table["u_nu"], u_tau=table["u_tau"],
                         pressure=table["reaction_nu"])
        samples[_time_key(record["t"], scene["time"]["T"])] = entry
    return {"samples": samples, "wall_s": wall,
            "steps_s": comm.allreduce(sum(s["wall_s"] for s in result.steps), op=MPI.MAX),
            "unknowns": int(sum(result.problem.count_unknowns().values())),
            "newton_mean": float(np.mean([s["newton_iterations"] for s in result.steps]))}


def _toml_value(value) -> str:
    """A number, or a list of inline tables (time.segments), as a TOML value of --set."""
    if isinstance(value, list):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{" + ", ".join(f"{k} = {_toml_value(v)}" for k, v in value.items()) + "}"
    if isinstance(value, str):
        return f'"{value}"'
    return repr(value)


def _time_key(t: float, T: float) -> int:
    """Times matched between runs to 1e-9 T."""
    return int(round(t / (1e-9 * T)))


def _boundary_weights(s: np.ndarray) -> np.ndarray:
    """Trapezoid weights of sorted points s along a curve."""
    if len(s) < 2:
        return np.ones_like(s)
    w = np.zeros_like(s)
    w[1:] += 0.5 * np.diff(s)
    w[:-1] += 0.5 * np.diff(s)
    return w


def _onto(x_from: np.ndarray, values: np.ndarray, x_to: np.ndarray) -> np.ndarray:
    """Values at the contact nodes x_from, linearly interpolated to the points x_to: along the
    coordinate of largest spread in 2D, on a Delaunay triangulation of the face's two spanning
    coordinates in 3D (nearest node outside it)."""
    span = np.ptp(x_to, axis=0)
    if x_to.shape[1] == 2:
        a = int(np.argmax(span))
        order = np.argsort(x_from[:, a])
        return np.interp(x_to[:, a], x_from[order, a], values[order])
    from matplotlib.tri import LinearTriInterpolator, Triangulation
    a, b = sorted(np.argsort(span, kind="stable")[-2:])
    tri = Triangulation(x_from[:, a], x_from[:, b])
    out = np.ma.filled(LinearTriInterpolator(tri, values)(x_to[:, a], x_to[:, b]), np.nan)
    missing = np.isnan(out)
    if missing.any():
        distance = ((x_to[missing, None, :] - x_from[None, :, :]) ** 2).sum(-1)
        out[missing] = values[np.argmin(distance, axis=1)]
    return out


def difference(run_a: dict, reference: dict, measure: str) -> float:
    """The relative difference of an error measure between two runs, over the times both have
    (the measures are defined in the module's description).

    Parameters
    ----------
    run_a : dict
        A run, as ``run`` returns it.
    reference : dict
        The run compared against; its contact nodes carry the comparison.
    measure : str
        ``"contact_pressure"``, ``"contact_displacement"`` or ``"probe"``.

    Returns
    -------
    float
        The largest difference over the shared times divided by the reference's largest norm.

    Raises
    ------
    TradeoffError
        When the runs share no time level, or the reference's measured field is zero at every
        time.
    """
    common = sorted(set(run_a["samples"]) & set(reference["samples"]))
    if not common:
        raise TradeoffError("the two runs share no time level")
    top, scale = 0.0, 0.0
    for key in common:
        other, ref = run_a["samples"][key], reference["samples"][key]
        if measure == "probe":
            ua, ur = np.array(other["probes"], float), np.array(ref["probes"], float)
            top = max(top, float(np.max(np.abs(ua - ur))))
            scale = max(scale, float(np.max(np.abs(ur))))
            continue
        fields = ("u_nu", "u_tau") if measure == "contact_displacement" else ("pressure",)
        x = ref["x"]
        if x.shape[1] == 2:
            s = x[:, int(np.argmax(np.ptp(x, axis=0)))]
            w = _boundary_weights(s) if np.all(np.diff(s) >= 0) else np.ones(len(s))
        else:
            w = np.ones(len(x))
        diff2 = sum(np.sum(w * (_onto(other["x"], other[f], x) - ref[f]) ** 2) for f in fields)
        norm2 = sum(np.sum(w * ref[f] ** 2) for f in fields)
        top = max(top, math.sqrt(diff2))
        scale = max(scale, math.sqrt(norm2))
    if scale == 0.0:
        raise TradeoffError(f"the reference's {measure.replace('_', ' ')} is zero at every "
                            "time: choose another --measure")
    return top / scale


def _order(coarse: float, fine: float) -> float:
    """Observed order from the differences of three levels, clamped to [0.5, 3]."""
    if not (coarse > 0 and fine > 0):
        return 3.0 if fine == 0 else 0.5
    return float(min(3.0, max(0.5, math.log2(coarse / fine))))


# --- the trade ----------------------------------------------------------------------------


def tradeoff(source: str, target: float, overrides=(), measure: str = "contact_pressure",
             levels: int = 4, coarsest: float = 0.25, degrees=(1, 2), budget: float = math.inf,
             out=None, comm=MPI.COMM_WORLD, say=print) -> dict:
    """Climb the ladder of discretizations of a scene, estimate each run's error and recommend
    the cheapest run whose estimated error is at most `target` (``contactvisco tradeoff``).

    Parameters
    ----------
    source : str
        A built-in scene name or the path of a scene file.
    target : float
        The relative error to reach (> 0).
    overrides : sequence of str, optional
        ``"key=value"`` lines applied to the scene first, as ``--set``.
    measure : str, optional
        The error measure: ``"contact_pressure"`` (default), ``"contact_displacement"`` or
        ``"probe"``.
    levels : int, optional
        The number of mesh levels (>= 2).
    coarsest : float, optional
        The mesh factor of the coarsest level (the others double it).
    degrees : tuple of int, optional
        The Lagrange degrees tried.
    budget : float, optional
        Seconds: the climb stops before a run whose predicted time exceeds what is left.
    out : path-like, optional
        A folder for ``tradeoff.json``, ``tradeoff.png`` and ``recommended.toml`` (written by
        rank 0); None writes nothing.
    comm : mpi4py.MPI.Comm, optional
        The communicator of the runs (collective).
    say : callable, optional
        Prints the progress lines (rank 0 only).

    Returns
    -------
    dict
        ``scene``, ``measure``, ``target``, ``reference`` (its settings, own error and the
        observed orders), ``ladder`` (one row per run with ``set``, ``wall_s``,
        ``difference``, ``estimated_error``, ``pareto``), ``recommended`` (``set``,
        ``estimated_error``, ``wall_s``; None with ``not_reached`` saying why), ``stopped``
        (why the budget ended the climb, or None) and ``total_s``.

    Raises
    ------
    TradeoffError
        For an unknown measure, a target <= 0, fewer than 2 levels, a scene without contact
        (or without probes) for the measure, or a mesh that cannot be refined.
    """
    if measure not in MEASURES:
        raise TradeoffError(f"unknown measure '{measure}'; allowed: {', '.join(MEASURES)}")
    if not target > 0:
        raise TradeoffError(f"--target must be > 0 (a relative error), got {target}")
    check_options(target, levels, coarsest, degrees, budget)
    overrides = list(overrides)
    scene = scene_module.load(source, overrides)
    if measure != "probe" and scene["contact"] is None:
        raise TradeoffError(f"scene '{scene['name']}' has no contact: use --measure probe")
    if measure == "probe" and not scene["output"]["probes"]:
        raise TradeoffError(f"scene '{scene['name']}' has no output.probes for --measure probe")
    d = dimension(scene)
    ladder = rungs(scene, levels, coarsest, degrees)
    _check_ends(source, overrides, ladder)
    say = say if comm.rank == 0 else (lambda *a, **k: None)
    started = clock.perf_counter()
    stopped = None
    done = []
    for rung in ladder:
        spent = comm.allreduce(clock.perf_counter() - started, op=MPI.MAX)
        predicted = _predict(rung, done, d)
        if predicted is not None and spent + predicted > budget:
            stopped = (f"stopped before mesh level {rung['level'] + 1} of {levels} (mesh "
                       f"x{rung['mesh']:g}, "
                       f"{rung['steps']} steps, P{rung['degree']}): predicted "
                       f"{predicted:.1f} s, {max(0.0, budget - spent):.1f} s of the "
                       f"{budget:g} s budget left")
            say(f"tradeoff: {stopped}")
            break
        measured = run(source, overrides + rung["set"], comm)
        rung.update(measured)
        rung["predicted_s"] = predicted
        done.append(rung)
        say(f"tradeoff: mesh x{rung['mesh']:g}, {rung['steps']:4d} steps, P{rung['degree']}: "
            + (f"Newton failed ({rung['failed']})" if "failed" in rung else
               f"{rung['unknowns']} unknowns, {rung['wall_s']:.2f} s"))
    try:
        result = _estimate(done, target, measure, scene, source, overrides)
    except TradeoffError as err:
        raise TradeoffError(f"{err}" + (f"; {stopped}" if stopped else "")) from None
    result.update(budget_s=budget if math.isfinite(budget) else None, stopped=stopped,
                  total_s=comm.allreduce(clock.perf_counter() - started, op=MPI.MAX))
    if out is not None and comm.rank == 0:
        write(result, pathlib.Path(out), source, overrides)
    comm.barrier()
    return result


#: Most mesh levels of a ladder: each doubles the cells per direction (4^levels in 2D).
MAX_LEVELS = 8


def check_options(target: float, levels, coarsest: float, degrees, budget: float) -> None:
    """The ladder's options at their edges: a relative error target in (0, 1), an integer
    number of levels from 2 to MAX_LEVELS, a finite coarsest mesh factor > 0, distinct
    degrees 1 or 2, a budget of seconds > 0 (inf: none).

    Parameters
    ----------
    target, levels, coarsest, degrees, budget
        As for `tradeoff`.

    Raises
    ------
    TradeoffError
        Naming the option, the value and what is allowed.
    """
    def number(x) -> bool:
        return isinstance(x, (int, float)) and not isinstance(x, bool)

    if not (number(target) and 0 < target < 1):
        raise TradeoffError(f"--target must be a relative error between 0 and 1 (e.g. 0.01), "
                            f"got {target}")
    if not (isinstance(levels, int) and not isinstance(levels, bool)
            and 2 <= levels <= MAX_LEVELS):
        raise TradeoffError(f"--levels must be an integer from 2 to {MAX_LEVELS} (each level "
                            f"doubles the cells in every direction), got {levels}")
    if not (number(coarsest) and math.isfinite(coarsest) and coarsest > 0):
        raise TradeoffError(f"--coarsest must be a finite mesh factor > 0 (0.25: a quarter of "
                            f"the scene's cells per direction), got {coarsest}")
    degrees = tuple(degrees)
    if not degrees or any(d not in (1, 2) for d in degrees) or len(set(degrees)) < len(degrees):
        raise TradeoffError(f"--degrees must list 1 and/or 2, each once, got "
                            f"{','.join(map(str, degrees)) or 'nothing'}")
    if not (number(budget) and budget > 0):
        raise TradeoffError(f"--budget must be a number of seconds > 0 (inf: no bound), got "
                            f"{budget}")


def _check_ends(source: str, overrides: list, ladder: list) -> None:
    """The coarsest and the finest rung are scenes that load (a mesh of at least a cell, not
    beyond the scene limits), before any run: a refused rung must not end the climb halfway."""
    for rung in (ladder[0], max(ladder, key=lambda r: (r["mesh"], r["steps"], r["degree"]))):
        try:
            scene_module.load(source, overrides + rung["set"])
        except SceneError as err:
            raise TradeoffError(f"mesh x{rung['mesh']:g}, {rung['steps']} steps, "
                                f"P{rung['degree']} of the ladder cannot run: {err}; change "
                                "--coarsest or --levels") from None
    meshes = {}
    for rung in ladder:
        lines = tuple(line for line in rung["set"] if line.startswith("geometry."))
        meshes.setdefault(rung["level"], lines)
    for level in range(1, len(meshes)):
        if meshes[level] == meshes[level - 1]:
            raise TradeoffError(f"--coarsest: mesh levels {level} and {level + 1} of the "
                                f"ladder are the same mesh ({', '.join(meshes[level])}): the "
                                "coarsest level is below one cell; raise --coarsest")


def _predict(rung: dict, done: list, d: int) -> float | None:
    """The next run's time: the time per unit of work() of the costliest run so far, times
    1.5 for the superlinear cost of larger solves; None before the first run."""
    ok = [r for r in done if "failed" not in r]
    if not ok:
        return None
    big = max(ok, key=lambda r: work(r, d))
    return 1.5 * big["wall_s"] * work(rung, d) / work(big, d)


def _estimate(done: list, target: float, measure: str, scene: dict, source: str,
              overrides: list) -> dict:
    """Differences to the reference, Richardson for the reference's own error, the Pareto
    front and the recommendation."""
    ok = [r for r in done if "failed" not in r]
    base_degree = scene["discretization"]["degree"]
    reference, self_error, summary = _reference_error(
        [r for r in ok if r["degree"] == base_degree], measure)
    ladder = _ladder_rows(done, reference, self_error, measure)
    result = {"scene": scene["name"], "source": str(source), "overrides": overrides,
              "measure": measure, "measure_description": MEASURES[measure],
              "target": target, "error_estimate": ESTIMATE,
              "reference": summary, "ladder": ladder}
    result.update(_recommend([r for r in ladder if "failed" not in r], target, overrides))
    return result


def _reference_error(base_runs: list, measure: str) -> tuple[dict, float, dict]:
    """The reference (top level, most steps, the scene's degree) among `base_runs` and its
    own error by Richardson extrapolation, d_h / (2^p_h - 1) + d_k / (2^p_k - 1): d_h the
    difference of the two top mesh levels at the reference's steps, d_k of the two largest
    step counts on the top level, p the observed orders (1 from two levels). Returns the
    reference, its error and the summary stored under "reference"."""
    if len({r["level"] for r in base_runs}) < 2:
        raise TradeoffError("fewer than two mesh levels ran (raise --budget or lower "
                            "--coarsest): no error estimate")
    top = max(r["level"] for r in base_runs)
    n_max = max(r["steps"] for r in base_runs if r["level"] == top)
    reference = next(r for r in base_runs if r["level"] == top and r["steps"] == n_max)
    # Space: the mesh levels at the reference's steps.
    mesh_column = sorted((r for r in base_runs if r["steps"] == n_max),
                         key=lambda r: r["level"])
    d_h = [difference(a, b, measure) for a, b in zip(mesh_column[:-1], mesh_column[1:])]
    p_h = _order(d_h[-2], d_h[-1]) if len(d_h) >= 2 else 1.0
    # Time: the step counts on the top level.
    time_row = sorted((r for r in base_runs if r["level"] == top), key=lambda r: r["steps"])
    d_k = [difference(a, b, measure) for a, b in zip(time_row[:-1], time_row[1:])]
    p_k = _order(d_k[-2], d_k[-1]) if len(d_k) >= 2 else 1.0
    self_error = d_h[-1] / (2 ** p_h - 1) + (d_k[-1] / (2 ** p_k - 1) if d_k else 0.0)
    summary = {"set": reference["set"], "self_error": self_error,
               "order_space": p_h, "order_time": p_k if d_k else None,
               "difference_space": d_h[-1], "difference_time": d_k[-1] if d_k else None}
    return reference, self_error, summary


def _ladder_rows(done: list, reference: dict, self_error: float, measure: str) -> list:
    """A row per run: its settings and times, and (if it ran) its difference to the
    reference, its estimated error (difference + the reference's own error) and whether it
    is on the Pareto front of (estimated error, wall time)."""
    ladder = []
    for r in done:
        row = {key: r[key] for key in ("level", "mesh", "steps", "degree", "set", "wall_s")}
        row["predicted_s"] = r.get("predicted_s")
        if "failed" in r:
            row.update(failed=r["failed"], pareto=False)
        else:
            diff = 0.0 if r is reference else difference(r, reference, measure)
            row.update(unknowns=r["unknowns"], steps_s=r["steps_s"],
                       newton_mean=r["newton_mean"], difference=diff,
                       estimated_error=diff + self_error, reference=r is reference)
        ladder.append(row)
    good = [r for r in ladder if "failed" not in r]
    for r in good:
        r["pareto"] = not any(o is not r and o["estimated_error"] <= r["estimated_error"]
                              and o["wall_s"] <= r["wall_s"] and
                              (o["estimated_error"] < r["estimated_error"]
                               or o["wall_s"] < r["wall_s"]) for o in good)
    return ladder


def _recommend(good: list, target: float, overrides: list) -> dict:
    """{"recommended": the fastest run of `good` whose estimated error is <= target}, or
    {"recommended": None, "not_reached": why}."""
    reaching = [r for r in good if r["estimated_error"] <= target]
    if reaching:
        best = min(reaching, key=lambda r: r["wall_s"])
        return {"recommended": {"set": overrides + best["set"],
                                "estimated_error": best["estimated_error"],
                                "wall_s": best["wall_s"], "mesh": best["mesh"],
                                "steps": best["steps"], "degree": best["degree"]}}
    smallest = min(good, key=lambda r: r["estimated_error"])
    return {"recommended": None,
            "not_reached": (f"no run reached {target:g}: the smallest estimated error is "
                            f"{smallest['estimated_error']:.3g} (mesh "
                            f"x{smallest['mesh']:g}); add levels (--levels) or budget")}


# --- files --------------------------------------------------------------------------------


def write(result: dict, folder: pathlib.Path, source: str, overrides: list) -> None:
    """Write a trade-off result into a folder: ``tradeoff.json``, ``tradeoff.png`` and, with a
    recommendation, ``recommended.toml``.

    Parameters
    ----------
    result : dict
        What ``tradeoff`` returns; ``recommended["scene_file"]`` is set to the file written.
    folder : pathlib.Path
        The folder (made if missing).
    source : str
        The scene name or file the ladder ran.
    overrides : list of str
        The ``--set`` lines the ladder ran with.
    """
    folder.mkdir(parents=True, exist_ok=True)
    if result["recommended"] is not None:
        path = folder / "recommended.toml"
        files.replace(path, recommended_toml(source, result["recommended"]["set"], result))
        result["recommended"]["scene_file"] = path.name
    files.replace(folder / "tradeoff.json", json.dumps(result, indent=1))
    figure(result, folder / "tradeoff.png")


def recommended_toml(source: str, lines: list[str], result: dict) -> str:
    """The scene file of `source` with `--set` lines applied to its own (unresolved) tables,
    so that it loads to the same scene as `source` with those lines; the preset key is
    dropped (the lines give absolute values).

    Parameters
    ----------
    source : str
        A built-in scene name or the path of a scene file.
    lines : list of str
        ``"key=value"`` lines.
    result : dict
        The trade-off result, quoted in the file's heading comment.

    Returns
    -------
    str
        The TOML text.
    """
    path = pathlib.Path(source)
    if not path.suffix and (scene_module.SCENE_DIR / f"{source}.toml").exists():
        path = scene_module.SCENE_DIR / f"{source}.toml"
    raw = tomllib.loads(path.read_text())
    preset = raw.pop("preset", None)
    if preset is not None:       # the preset's other settings (rule) written out
        full = scene_module.load(str(path))
        raw.setdefault("time", {})["rule"] = full["time"]["rule"]
    for text in lines:
        keys, value = scene_module.parse_assignment(text)
        if keys == ["preset"]:
            continue
        node = raw
        for key in keys[:-1]:
            node = node.setdefault(key, {})
        node[keys[-1]] = value
    rec = result["recommended"]
    head = (f"# {result['scene']}: the cheapest run of the ladder with estimated "
            f"{result['measure'].replace('_', ' ')} error {rec['estimated_error']:.3g} <= "
            f"{result['target']:g}\n# (contactvisco tradeoff; wall time {rec['wall_s']:.2f} s)\n"
            f"# estimate: {ESTIMATE}\n")
    return head + document_text(raw)


def figure(result: dict, path: pathlib.Path, dpi: int = 300):
    """The trade-off figure of a result, saved to a file (one journal column wide).

    Parameters
    ----------
    result : dict
        What ``tradeoff`` returns.
    path : pathlib.Path
        The image file; its suffix gives the format.
    dpi : int, optional
        Resolution of raster formats.

    Returns
    -------
    pathlib.Path
        `path`.
    """
    import matplotlib
    from matplotlib.figure import Figure

    from contactvisco.post.figures import STYLE
    with matplotlib.rc_context(STYLE):
        fig = Figure()
        draw(result, fig)
        files.replace_with(path, lambda f: fig.savefig(
            f, format=pathlib.Path(path).suffix[1:] or "png", dpi=dpi))
    return path


def draw(result: dict, fig):
    """Draw estimated error against wall time, log-log: circles P1, squares P2, time steps by
    colour, the Pareto front (filled markers, line), the target and the recommendation.

    Parameters
    ----------
    result : dict
        What ``tradeoff`` returns.
    fig : matplotlib.figure.Figure
        An empty figure to draw on (sized and laid out here).

    Returns
    -------
    matplotlib.figure.Figure
        `fig`.
    """
    import matplotlib
    from contactvisco.post.figures import COLUMN, STYLE, size_constrained
    with matplotlib.rc_context(STYLE):
        size_constrained(fig, COLUMN, 2.9)
        ax = fig.subplots()
        rows = [r for r in result["ladder"] if "failed" not in r]
        step_counts = sorted({r["steps"] for r in rows})
        for r in rows:
            colour = f"C{step_counts.index(r['steps'])}"
            ax.loglog(r["wall_s"], r["estimated_error"], "o" if r["degree"] == 1 else "s",
                      color=colour, mfc=colour if r["pareto"] else "none", ms=4, mew=0.8)
        for i, n in enumerate(step_counts):
            ax.plot([], [], "o", color=f"C{i}", label=f"{n} steps")
        if any(r["degree"] > 1 for r in rows):
            ax.plot([], [], "s", color="0.3", mfc="none", label="P2 (circles: P1)")
        front = sorted((r for r in rows if r["pareto"]), key=lambda r: r["wall_s"])
        ax.plot([r["wall_s"] for r in front], [r["estimated_error"] for r in front], "k-",
                lw=0.7, label="Pareto front (filled)")
        ax.axhline(result["target"], color="C3", ls="--", lw=0.8, label="target")
        rec = result["recommended"]
        if rec is not None:
            ax.plot(rec["wall_s"], rec["estimated_error"], "*", color="C3", ms=9,
                    label="recommended")
        from matplotlib.ticker import FuncFormatter, LogLocator, NullFormatter
        for axis in (ax.xaxis, ax.yaxis):    # 0.2, 0.5, 1, 2 ...: readable within a decade
            axis.set_major_locator(LogLocator(subs=(1.0, 2.0, 5.0)))
            axis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
            axis.set_minor_formatter(NullFormatter())
        ax.set_xlabel("wall time [s]")
        ax.set_ylabel(f"estimated relative error\n({result['measure'].replace('_', ' ')})")
        ax.set_title(f"{result['scene']}: error vs the finest run + Richardson")
        ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.25), ncol=2, frameon=False)
    return fig


def verify(source: str, overrides: list, recommended_set: list, measure: str,
           reference_set: list, comm=MPI.COMM_WORLD) -> dict:
    """The recommended run's error measured against a reference finer than the ladder.

    Parameters
    ----------
    source : str
        A built-in scene name or the path of a scene file.
    overrides : list of str
        The ``--set`` lines the ladder ran with (the reference runs with them too).
    recommended_set : list of str
        The recommended run's ``--set`` lines (absolute values).
    measure : str
        The error measure.
    reference_set : list of str
        The reference's ``--set`` lines (``finer_reference``).
    comm : mpi4py.MPI.Comm, optional
        The communicator of the runs.

    Returns
    -------
    dict
        ``error`` (the measured relative difference), ``wall_s``, ``reference_wall_s`` and
        ``reference_unknowns``.

    Raises
    ------
    TradeoffError
        When either run's Newton fails.
    """
    rec = run(source, list(recommended_set), comm)
    ref = run(source, list(overrides) + list(reference_set), comm)
    if "failed" in rec or "failed" in ref:
        raise TradeoffError(f"verification run failed: {rec.get('failed') or ref['failed']}")
    return {"error": difference(rec, ref, measure), "wall_s": rec["wall_s"],
            "reference_wall_s": ref["wall_s"], "reference_unknowns": ref["unknowns"]}


def finer_reference(source: str, overrides: list, levels: int, coarsest: float) -> list[str]:
    """The ``--set`` lines of a run one mesh level above the ladder's top and with twice its
    largest step count.

    Parameters
    ----------
    source : str
        A built-in scene name or the path of a scene file.
    overrides : list of str
        ``--set`` lines applied to the scene first.
    levels : int
        The ladder's number of mesh levels.
    coarsest : float
        The ladder's coarsest mesh factor.

    Returns
    -------
    list of str
        ``"key=value"`` lines.
    """
    scene = scene_module.load(source, list(overrides))
    N = scene["time"]["steps"]
    return settings_lines(scene, coarsest * 2 ** levels, 4 * N if N > 1 else N,
                          scene["discretization"]["degree"])


def summary_lines(result: dict) -> list[str]:
    """What ``contactvisco tradeoff`` prints at the end: the measure, the estimate, the
    budget stop and the recommendation as ``--set`` lines.

    Parameters
    ----------
    result : dict
        What ``tradeoff`` returns.

    Returns
    -------
    list of str
        The lines.
    """
    lines = [f"error measure: {result['measure']} ({result['measure_description']})",
             f"error estimate: {ESTIMATE}; reference's own error "
             f"{result['reference']['self_error']:.3g} (observed orders: space "
             f"{result['reference']['order_space']:.2f}"
             + (f", time {result['reference']['order_time']:.2f}"
                if result['reference']['order_time'] is not None else "") + ")"]
    if result.get("stopped"):
        lines.append(f"budget: {result['stopped']}")
    rec = result["recommended"]
    if rec is None:
        lines.append(result["not_reached"])
    else:
        lines.append(f"recommended (estimated error {rec['estimated_error']:.3g} <= "
                     f"{result['target']:g}, {rec['wall_s']:.2f} s):")
        lines += [f"  --set {line}" for line in rec["set"]]
    return lines

