"""Identification of material parameters from indentation curves, with the contact solver in
the loop (docs/identification.md).

A fit description (TOML) names experiments, each a scene and a CSV file of measured samples
(t_j, F_j, d_j), and the parameters theta to identify, each a scene key. The measured force
drives each run as the obstacle's force F(t), piecewise linear through the samples, on the
time grid of the sample times (time.grid = "times"); the fit minimizes the weighted least
squares of the depth (of the force for an experiment under control = "depth", which the
measured depth drives as the obstacle's displacement),

    r_ej(theta) = w_e (d_e(t_j; theta) - d_ej),     cost = 1/2 sum_e sum_j r_ej^2,

with w_e = 1/sigma_e for a noise level sigma_e (or sqrt(weight_e)), by
``scipy.optimize.least_squares`` (trust-region reflective, bounds) over the parameters in
their scale, x_i = theta_i (linear) or ln theta_i (log). Each experiment's problem is built
once (contactvisco.solver.sensitivity.ForwardModel) and run again at every evaluation. The
Jacobian J = dr/dx is taken by forward sensitivities through the time loop (fit.jacobian =
"auto" where they cover every parameter, or "sensitivities"), or by finite differences of
forward runs (scipy's "2-point" or "3-point" rule with the relative step fit.step:
h_i = step * max(1, |x_i|), one-sided near a bound).

At the optimum, with m residuals and n parameters, the residual variance
s^2 = 2 cost / (m - n) scales the covariance of x,

    C_x = s^2 (J^T J)^-1 = s^2 V diag(1/S_k^2) V^T     (J = U S V^T),

and the standard error of theta_i is sqrt(C_x,ii) (linear) or theta_i sqrt(C_x,ii) (log, the
delta method). A singular value S_k < RCOND S_max is a direction the data does not determine:
every parameter with a component |V_ik| > NULL_SHARE in it gets an infinite standard error
and is reported as not identifiable, as is one whose standard error exceeds its value.
"""
from __future__ import annotations

import csv
import json
import math
import pathlib
import time
import tomllib

import numpy as np

from contactvisco.errors import SceneError
from contactvisco.scene import expressions
from contactvisco.scene import loader as scene_module
from contactvisco.scene import prony_file
from contactvisco.scene import toml_text

#: The keys of a fit description, by table.
FIT_KEYS = {"jacobian": "auto", "difference": "central", "step": 1e-3, "max_evaluations": 200,
            "tolerance": 1e-8, "regularization": 0.0, "reduction": False,
            "reduction_threshold": 1e-4, "communicators": "auto"}
#: fit.jacobian: forward sensitivities through the time loop (contactvisco.solver.sensitivity),
#: finite differences of forward runs, or the sensitivities where they cover every parameter.
JACOBIANS = ("auto", "sensitivities", "finite-differences")
#: Relative step of the central differences of the scene's conversion of a parameter (its
#: Constants and Prony terms; no solve): h = SCENE_STEP max(|theta|, 1e-300).
SCENE_STEP = 1e-5
EXPERIMENT_KEYS = ("scene", "data", "set", "noise", "weight", "control")
#: experiment.control: what the data drives. "force": the measured force drives the
#: obstacle's force-controlled component, the depth is fitted (creep); "depth": the measured
#: depth drives that component as a displacement, the force is fitted (relaxation).
CONTROLS = ("force", "depth")
PARAMETER_KEYS = ("key", "initial", "bounds", "scale", "prior")
#: fit.communicators: how the ranks share the experiments. "shared": every rank runs every
#: experiment; "split": the fit's communicator is split into min(P, n) groups, experiment i
#: run by group i mod k; "auto": split when P >= 2 and n >= 2.
COMMUNICATORS = ("auto", "shared", "split")
#: fit.difference: the finite-difference rule of the Jacobian and scipy's name of it.
DIFFERENCES = {"central": "3-point", "forward": "2-point"}
SCALES = ("linear", "log")
#: parameter.initial: the start from a Lee-Radok fit of the same curves (studies.lee_radok).
CLOSED_FORM = "closed-form"
#: Relative size below which a singular value of J is a direction the data does not fix.
RCOND = 1e-6
#: A parameter's share of such a direction that makes it not identifiable.
NULL_SHARE = 1e-2
#: A correlation above which two parameters are reported as not separable.
HIGH_CORRELATION = 0.99
#: The confidence level of the parameters' intervals and of the moduli's band.
LEVEL = 0.95
#: The scene keys fit.regularization and fit.reduction act on: the Prony moduli (absolute or
#: as fractions).
REGULARIZED = ("moduli", "fractions")


def _fail(key: str, message: str):
    raise SceneError(f"{key}: {message}", key=key)


def _number(value, key: str, what: str = "a finite number") -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        _fail(key, f"must be {what}, got {value!r}")
    return float(value)


def _known(table: dict, allowed, where: str) -> None:
    for name in table:
        if name not in allowed:
            _fail(f"{where}{name}", f"unknown key; allowed here: {', '.join(allowed)}")


def read_fit(path) -> dict:
    """Read and check a fit description (docs/identification.md).

    Parameters
    ----------
    path : path-like
        The TOML file; scene files and data files it names are relative to its folder and
        must stay inside it.

    Returns
    -------
    dict
        ``fit`` (the [fit] table with defaults), ``experiments`` (each with its base scene
        overrides ``set``, the data arrays ``t``, ``force`` (or None), ``depth``, the weight
        ``w`` and its scene name), ``parameters`` (each with ``key``, ``path``, ``initial``,
        ``bounds``, ``scale``).

    Raises
    ------
    SceneError
        Naming the key (``experiment[0].data``, ``parameter[1].bounds``, ...), what is wrong
        and what is allowed.
    """
    path = pathlib.Path(path)
    try:
        raw = tomllib.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as err:
        raise SceneError(f"fit description {path}: cannot be read ({err})") from None
    _known(raw, ("fit", "experiment", "parameter"), "")
    base = path.resolve().parent
    fit = dict(FIT_KEYS)
    given = raw.get("fit", {})
    if not isinstance(given, dict):
        _fail("fit", "must be a table")
    _known(given, tuple(FIT_KEYS), "fit.")
    fit.update(given)
    if fit["jacobian"] not in JACOBIANS:
        _fail("fit.jacobian", f"must be one of {', '.join(JACOBIANS)}, got {fit['jacobian']!r}")
    if fit["communicators"] not in COMMUNICATORS:
        _fail("fit.communicators", f"must be one of {', '.join(COMMUNICATORS)}, got "
              f"{fit['communicators']!r}")
    if fit["difference"] not in DIFFERENCES:
        _fail("fit.difference", f"must be one of {', '.join(DIFFERENCES)}, got "
              f"{fit['difference']!r}")
    if _number(fit["regularization"], "fit.regularization", "a number >= 0") < 0:
        _fail("fit.regularization", f"must be >= 0, got {fit['regularization']!r}")
    for name in ("step", "tolerance"):
        if _number(fit[name], f"fit.{name}") <= 0 or fit[name] >= 1:
            _fail(f"fit.{name}", f"must be in (0, 1), got {fit[name]!r}")
    if isinstance(fit["max_evaluations"], bool) or not isinstance(fit["max_evaluations"], int) \
            or fit["max_evaluations"] < 1:
        _fail("fit.max_evaluations", f"must be an integer >= 1, got {fit['max_evaluations']!r}")
    experiments = [_experiment(item, f"experiment[{i}].", base)
                   for i, item in enumerate(_items(raw, "experiment"))]
    parameters = [_parameter(item, f"parameter[{i}].")
                  for i, item in enumerate(_items(raw, "parameter"))]
    for i, (item, p) in enumerate(zip(_items(raw, "parameter"), parameters)):
        if "prior" in item and not (p["regularized"] and fit["regularization"] > 0):
            _fail(f"parameter[{i}].prior", "acts through fit.regularization > 0 on a Prony "
                  "modulus (a key viscoelastic.<function>.moduli.<i> or .fractions.<i>)")
    if fit["regularization"] > 0 and not any(p["regularized"] for p in parameters):
        _fail("fit.regularization", "acts on the Prony moduli (keys viscoelastic.<function>."
              "moduli.<i> or .fractions.<i>); no parameter is one")
    _check_reduction(fit, parameters)
    keys = [p["key"] for p in parameters]
    for i, key in enumerate(keys):
        if key in keys[:i]:
            _fail(f"parameter[{i}].key", f"{key!r} is identified twice")
    x0 = [p["initial"] for p in parameters]
    for i, experiment in enumerate(experiments):
        _component(experiment, i)
        # Every key is a number of the scene (a misspelled key fails with the scene's own
        # message), and the scene runs with the initial values.
        scene = _scene(experiment, [], [])
        for j, p in enumerate(parameters):
            try:
                value = _at(scene, p["path"])
            except (KeyError, IndexError, ValueError, TypeError):
                _fail(f"parameter[{j}].key", f"{p['key']!r}: unknown scene key in the scene "
                      f"of experiment[{i}]")
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                _fail(f"parameter[{j}].key", f"{p['key']!r} is not a number of the scene of "
                      f"experiment[{i}] (it holds {value!r})")
            if fit["reduction"] and p["regularized"] and not isinstance(
                    _at(scene, p["path"][:-2]).get("tau"), list):
                _fail("fit.reduction", f"drops terms of a Prony grid given inline: "
                      f"{'.'.join(p['path'][:-2])} of experiment[{i}] has no list tau (a file "
                      "gives its terms); write its tau and moduli (or fractions) in the scene")
        _scene(experiment, parameters, x0)
    return {"fit": fit, "experiments": experiments, "parameters": parameters}


def _check_reduction(fit: dict, parameters: list) -> None:
    """fit.reduction: a bool; with it the Prony moduli are bounded below by 0 in linear scale,
    the relaxation times stay fixed and no Tikhonov rows pull the moduli (the bound is where a
    term is dropped)."""
    if not isinstance(fit["reduction"], bool):
        _fail("fit.reduction", f"must be true or false, got {fit['reduction']!r}")
    rho = _number(fit["reduction_threshold"], "fit.reduction_threshold", "a number in (0, 1)")
    if not 0 < rho < 1:
        _fail("fit.reduction_threshold", f"must be in (0, 1), got {fit['reduction_threshold']!r}")
    if not fit["reduction"]:
        return
    if fit["regularization"] > 0:
        _fail("fit.reduction", "drops the Prony terms whose moduli reach the bound 0; "
              f"fit.regularization = {fit['regularization']!r} pulls them to their prior "
              "instead: use one of the two (fit.regularization = 0 with fit.reduction)")
    if not any(p["regularized"] for p in parameters):
        _fail("fit.reduction", "drops Prony terms: it needs a parameter "
              "viscoelastic.<function>.moduli.<i> or .fractions.<i>; no parameter is one")
    for k, p in enumerate(parameters):
        parts = p["path"]
        if len(parts) >= 3 and parts[0] == "viscoelastic" and parts[-2] == "tau":
            _fail("fit.reduction", f"works on a fixed grid of relaxation times; "
                  f"parameter[{k}].key = {p['key']!r} frees one (fix the times, or set "
                  "fit.reduction = false)")
        if not p["regularized"]:
            continue
        if p["scale"] != "linear":
            _fail(f"parameter[{k}].scale", f"{p['key']!r}: with fit.reduction a Prony modulus "
                  "is fitted in linear scale (its bound 0 is outside the log scale), got "
                  f"{p['scale']!r}")
        if p["bounds"][0] != 0:
            _fail(f"parameter[{k}].bounds", f"{p['key']!r}: with fit.reduction the lower "
                  f"bound of a Prony modulus is 0 (non-negativity), got {list(p['bounds'])!r}")
        if p["initial"] <= 0:
            _fail(f"parameter[{k}].initial", f"{p['key']!r}: must be > 0 (a modulus of 0 "
                  f"leaves its term out of the scene), got {p['initial']!r}")


def _measured(experiment: dict) -> np.ndarray:
    """The fitted data of an experiment: its depth, or its force under control = "depth"."""
    return experiment["force"] if experiment["control"] == "depth" else experiment["depth"]


def _component(experiment: dict, i: int) -> None:
    """The experiment's controlled axis c (the first of obstacle.force_components of its
    scene) and the space dimension, into `experiment`."""
    scene = scene_module.load(experiment["scene"], experiment["set"])
    obstacle = scene.get("obstacle") or {}
    if not obstacle.get("force_components"):
        _fail(f"experiment[{i}].scene", "the scene's obstacle must name its axis under force "
              "control (obstacle.force_components): the measured force (or depth, with "
              "control = 'depth') drives the run along it")
    experiment["component"] = int(obstacle["force_components"][0])
    experiment["dim"] = 3 if scene["material"]["model"] == "3d" or any(
        isinstance(obstacle.get(k), list) and len(obstacle[k]) == 3
        for k in ("centre", "point", "normal")) else 2


def _items(raw: dict, name: str) -> list:
    items = raw.get(name)
    if not isinstance(items, list) or not items or not all(isinstance(v, dict) for v in items):
        _fail(name, f"the fit description needs at least one [[{name}]] table")
    return items


def _experiment(item: dict, where: str, base: pathlib.Path) -> dict:
    """One [[experiment]]: its scene, its data and its weight."""
    _known(item, EXPERIMENT_KEYS, where)
    scene = item.get("scene")
    if not isinstance(scene, str) or not scene:
        _fail(f"{where}scene", f"must be a built-in scene name or a scene file, got {scene!r}")
    if scene not in scene_module.builtin_names():
        scene = str(prony_file.inside_path(scene, base, f"{where}scene"))
    sets = item.get("set", [])
    if not isinstance(sets, list) or not all(isinstance(s, str) and "=" in s for s in sets):
        _fail(f"{where}set", f"must be a list of 'key=value' texts, got {sets!r}")
    if "noise" in item and "weight" in item:
        _fail(f"{where}noise", "give either noise (the depth's standard deviation) or weight")
    if "noise" in item:
        noise = _number(item["noise"], f"{where}noise", "a number > 0")
        if noise <= 0:
            _fail(f"{where}noise", f"must be > 0, got {noise!r}")
        w = 1.0 / noise
    else:
        weight = _number(item.get("weight", 1.0), f"{where}weight", "a number > 0")
        if weight <= 0:
            _fail(f"{where}weight", f"must be > 0, got {weight!r}")
        w = math.sqrt(weight)
    control = item.get("control", "force")
    if control not in CONTROLS:
        _fail(f"{where}control", f"must be one of {', '.join(CONTROLS)}, got {control!r}")
    data = prony_file.inside_path(item.get("data"), base, f"{where}data")
    t, force, depth = read_data(data, f"{where}data")
    if control == "depth" and force is None:
        _fail(f"{where}data", f"{data}: control = 'depth' fits the force: the data needs a "
              "'force' column")
    return {"scene": scene, "set": list(sets), "t": t, "force": force, "depth": depth, "w": w,
            "data": str(data), "control": control}


def read_data(path: pathlib.Path, key: str):
    """The samples of an indentation curve: a CSV file with a header row naming the columns
    ``t``, ``depth`` and optionally ``force``, then one row of finite numbers per sample, the
    times >= 0 and strictly increasing.

    Parameters
    ----------
    path : pathlib.Path
        The file.
    key : str
        The dotted key naming it, for errors.

    Returns
    -------
    tuple
        t, force (None without a force column) and depth, numpy arrays.
    """
    # Read as a Prony file is: at most its byte limit, UTF-8, blank rows skipped.
    rows = prony_file._rows(path, lambda message: _fail(key, f"{path}: {message}"),
                            "an indentation curve")
    if not rows:
        _fail(key, f"{path} is empty: a header row (t, force, depth), then one row per sample")
    header = [cell.strip() for cell in rows[0][1]]
    for name in ("t", "depth"):
        if name not in header:
            _fail(key, f"{path}: the header row {header!r} has no column '{name}' (columns: "
                  "t, depth, and force to drive the run)")
    values = []
    for number, row in rows[1:]:
        if len(row) != len(header):
            _fail(key, f"{path}, row {number}: {len(row)} cells, the header has {len(header)}")
        try:
            cells = [float(cell) for cell in row]
        except ValueError:
            _fail(key, f"{path}, row {number}: not numbers: {row!r}")
        if not all(math.isfinite(c) for c in cells):
            _fail(key, f"{path}, row {number}: a value is not finite: {row!r}")
        values.append(cells)
    if len(values) < 2:
        _fail(key, f"{path}: at least two samples are needed, got {len(values)}")
    table = np.array(values)
    t = table[:, header.index("t")]
    bad = np.flatnonzero(np.diff(t) <= 0)
    if t[0] < 0 or bad.size:
        row = rows[1 + (int(bad[0]) + 1 if bad.size else 0)][0]
        _fail(key, f"{path}, row {row}: the times must be >= 0 and increase")
    force = table[:, header.index("force")] if "force" in header else None
    return t, force, table[:, header.index("depth")]


def _parameter(item: dict, where: str) -> dict:
    """One [[parameter]]: a scene key with its start, bounds and scale."""
    _known(item, PARAMETER_KEYS, where)
    key = item.get("key")
    if not isinstance(key, str) or not key or any(not part for part in key.split(".")):
        _fail(f"{where}key", f"must be a dotted scene key (e.g. 'contact.mu', "
              f"'viscoelastic.shear.fractions.0'), got {key!r}")
    scale = item.get("scale", "linear")
    if scale not in SCALES:
        _fail(f"{where}scale", f"must be one of {', '.join(SCALES)}, got {scale!r}")
    bounds = item.get("bounds")
    if not isinstance(bounds, list) or len(bounds) != 2:
        _fail(f"{where}bounds", f"must be [lower, upper], got {bounds!r}")
    lower, upper = (_number(b, f"{where}bounds") for b in bounds)
    if not lower < upper:
        _fail(f"{where}bounds", f"lower {lower!r} must be below upper {upper!r}")
    if scale == "log" and lower <= 0:
        _fail(f"{where}bounds", f"with scale = 'log' the bounds must be > 0, got {bounds!r}")
    closed = item.get("initial") == CLOSED_FORM
    if closed:      # checked at the bounds' middle; the closed-form fit starts there too
        initial = (math.sqrt(lower * upper) if scale == "log" else 0.5 * (lower + upper))
    else:
        initial = _number(item.get("initial"), f"{where}initial",
                          f"a finite number or '{CLOSED_FORM}'")
    if not lower <= initial <= upper:
        _fail(f"{where}initial", f"{initial!r} is outside the bounds {bounds!r}")
    prior = _number(item.get("prior", initial), f"{where}prior")
    if not lower <= prior <= upper:
        _fail(f"{where}prior", f"{prior!r} is outside the bounds {bounds!r}")
    return {"key": key, "path": key.split("."), "initial": initial, "bounds": (lower, upper),
            "scale": scale, "closed_form": closed, "prior": prior,
            "regularized": len(key.split(".")) >= 3 and key.split(".")[0] == "viscoelastic"
            and key.split(".")[-2] in REGULARIZED}


def _at(scene: dict, path: list):
    node = scene
    for part in path:
        node = node[int(part)] if isinstance(node, list) else node[part]
    return node


def force_expression(t: np.ndarray, force: np.ndarray, name: str = "force") -> float | str:
    """The measured force as an expression in t, piecewise linear through the samples:

        F(t) = F_0 + sum_i s_i min(max(t - t_i, 0), t_{i+1} - t_i),
        s_i = (F_{i+1} - F_i) / (t_{i+1} - t_i),

    constant before t_0 and after the last sample; samples on a line with their neighbours
    (to 1e-12 of the largest |F|) add no term, so a held force is one number.

    Parameters
    ----------
    t, force : numpy.ndarray
        The sample times (increasing) and forces.

    Returns
    -------
    float or str
        The constant force, or the expression.

    Raises
    ------
    SceneError
        When the expression is longer than a scene expression may be (too many kinks).
    """
    tol = 1e-12 * max(np.max(np.abs(force)), 1e-300)
    kinks = [0]
    for i in range(1, len(t) - 1):
        a = kinks[-1]
        line = force[a] + (force[i + 1] - force[a]) * (t[i] - t[a]) / (t[i + 1] - t[a])
        if abs(force[i] - line) > tol:
            kinks.append(i)
    kinks.append(len(t) - 1)
    if np.all(np.abs(force - force[0]) <= tol):
        return float(force[0])
    terms = [repr(float(force[0]))]
    for a, b in zip(kinks, kinks[1:]):
        slope = (force[b] - force[a]) / (t[b] - t[a])
        terms.append(f"{float(slope)!r} * min(max(t - {float(t[a])!r}, 0), "
                     f"{float(t[b] - t[a])!r})")
    text = " + ".join(terms)
    if len(text) > expressions.MAX_LENGTH:
        _fail(name, f"the measured {name} has {len(kinks) - 2} kinks; as a piecewise-linear "
              f"function of t it would take {len(text)} characters, more than a scene "
              f"expression's {expressions.MAX_LENGTH}: smooth or resample the {name} column")
    return text


def _scene(experiment: dict, parameters: list, values) -> dict:
    """The experiment's scene with the parameters' values, the data's times as its time grid
    and the measured force as the obstacle's force."""
    t = experiment["t"]
    sets = list(experiment["set"])
    sets += [scene_module.Override(["time", "grid"], "times"),
             scene_module.Override(["time", "T"], float(t[-1])),
             scene_module.Override(["time", "times"], [float(v) for v in t if v > 0]),
             scene_module.Override(["output", "figures"], False)]
    if experiment.get("control", "force") == "depth":
        # the measured depth as the obstacle's displacement along its axis: u_c = -d(t)
        displacement = [0.0] * experiment["dim"]
        displacement[experiment["component"]] = force_expression(t, -experiment["depth"],
                                                                 "depth")
        sets += [scene_module.Override(["obstacle", "force_components"], []),
                 scene_module.Override(["obstacle", "force"], []),
                 scene_module.Override(["obstacle", "displacement"], displacement)]
    elif experiment["force"] is not None:
        sets.append(scene_module.Override(
            ["obstacle", "force"], [force_expression(t, experiment["force"])]))
    sets += [scene_module.Override(p["path"], float(v)) for p, v in zip(parameters, values)]
    return scene_module.load(experiment["scene"], sets)


def forward(experiment: dict, parameters: list, values, comm=None) -> np.ndarray:
    """The simulated depth at the data's sample times: the obstacle's displacement along its
    first force-controlled component, with the sign that makes pressing in positive
    (d = -u_obstacle . e_c).

    Parameters
    ----------
    experiment : dict
        One of ``read_fit(...)["experiments"]``.
    parameters : list of dict
        ``read_fit(...)["parameters"]``.
    values : sequence of float
        The parameters' values (not their scale).
    comm : mpi4py.MPI.Comm, optional
        The communicator of the run (default COMM_WORLD).

    Returns
    -------
    numpy.ndarray
        d(t_j), one per sample.
    """
    from mpi4py import MPI

    from contactvisco.solver.time_loop import simulate
    scene = _scene(experiment, parameters, values)
    result = simulate(scene, comm=comm or MPI.COMM_WORLD, progress=False)
    c = experiment["component"]
    times = np.array([step["t"] for step in result.steps])
    if experiment.get("control", "force") == "depth":      # the force is observed
        depth = np.array([step["obstacle"]["force"][c] for step in result.steps])
    else:
        depth = -np.array([step["obstacle"]["displacement"][c] for step in result.steps])
    # The grid is the sample times; a cut step adds records between them, never at them.
    return depth[_sample_index(times, experiment)]


def _sample_index(times: np.ndarray, experiment: dict) -> np.ndarray:
    """The grid's states at the data's sample times (the grid is the sample times)."""
    tol = 1e-9 * experiment["t"][-1]
    where = np.minimum(np.searchsorted(times, experiment["t"] - tol), len(times) - 1)
    missed = np.flatnonzero(np.abs(times[where] - experiment["t"]) > tol)
    if missed.size:
        raise SceneError(f"{experiment['data']}: the run has no step at the sample time "
                         f"t = {experiment['t'][missed[0]]!r}", key="time.times")
    return where


def _tangents(experiment: dict, parameters: list, values) -> list:
    """Per parameter, the experiment's scene at theta_i +- h_i and 2 h_i (SCENE_STEP): the
    central differences of the scene's conversion that the sensitivities take."""
    out = []
    for i, v in enumerate(values):
        h = SCENE_STEP * max(abs(v), 1e-300)
        shifted = []
        for sign in (1.0, -1.0):
            moved = np.array(values, float)
            moved[i] = v + sign * h
            shifted.append(_scene(experiment, parameters, moved))
        out.append((shifted[0], shifted[1], 2 * h))
    return out


def groups_of(mode: str, ranks: int, experiments: int) -> int:
    """How many groups of ranks run the experiments (fit.communicators): "shared" one (every
    rank on every experiment), "split" min(P, n), "auto" min(P, n) when P >= 2 and n >= 2.

    Parameters
    ----------
    mode : str
        fit.communicators.
    ranks, experiments : int
        P, the size of the fit's communicator, and n.
    """
    if mode == "shared":
        return 1
    return max(1, min(ranks, experiments))


class _Groups:
    """The fit's communicator split into groups (comm.Split), experiment i run by group
    i mod k on its sub-communicator; every rank gathers the residual and Jacobian blocks of
    all experiments, so the optimizer runs the same on every rank."""

    def __init__(self, comm, count: int, n: int):
        self.comm, self.count = comm, count
        self.color = comm.rank * count // comm.size
        self.sub = comm.Split(self.color, comm.rank) if count > 1 else comm
        self.owned = [i % count == self.color for i in range(n)]

    def free(self):
        if self.sub is not self.comm:
            self.sub.Free()
            self.sub = None

    def gather(self, blocks: dict, failure) -> dict:
        """Every experiment's block on every rank (allgather over the fit's communicator; a
        group's first rank gives its blocks), or the first failure, by experiment, raised on
        every rank: the ranks of the failing run raise their own exception, the others one of
        the same class and message."""
        if self.count == 1:
            if failure is not None:
                raise failure[1]
            return blocks
        summary = None if failure is None else (failure[0], _describe(failure[1]))
        gathered = self.comm.allgather((blocks if self.sub.rank == 0 else {}, summary))
        failures = sorted((f for _, f in gathered if f is not None), key=lambda f: f[0])
        if failures:
            if failure is not None and failure[0] == failures[0][0]:
                raise failure[1]
            raise _rebuilt(failures[0][1])
        out = {}
        for part, _ in gathered:
            out.update(part)
        return out


def _describe(err: BaseException) -> dict:
    """What rebuilds an exception on another rank: its class (NewtonFailure, SceneError, or
    another as RuntimeError), message with its notes, and the fields of its class."""
    from contactvisco.solver.newton import NewtonFailure
    text = "\n".join([str(err), *getattr(err, "__notes__", [])])
    if isinstance(err, NewtonFailure):
        return {"kind": "newton", "message": text, "reason": err.reason,
                "residuals": list(getattr(err, "residuals", []))}
    if isinstance(err, SceneError):
        return {"kind": "scene", "message": text, "key": getattr(err, "key", None)}
    return {"kind": "other", "message": f"{type(err).__name__}: {text}"}


def _rebuilt(described: dict) -> BaseException:
    from contactvisco.solver.newton import NewtonFailure
    if described["kind"] == "newton":
        return NewtonFailure(described["message"], described["reason"], described["residuals"])
    if described["kind"] == "scene":
        return SceneError(described["message"], key=described["key"])
    return RuntimeError(described["message"])


def _models(experiments, parameters, mode: str, groups: _Groups):
    """The forward models of the experiments this rank's group runs
    (contactvisco.solver.sensitivity.ForwardModel, each built once at the initial values, on
    the group's communicator; None elsewhere), whether the Jacobian is taken by
    sensitivities, and why not when fit.jacobian = "auto" falls back to finite differences
    (None if it does not). The reasons and a failing build are shared by every rank."""
    from contactvisco.solver import sensitivity
    reasons = [(-1, r) for r in (sensitivity.unsupported_key(p["key"]) for p in parameters)
               if r]
    whole = bool(reasons)            # a key the built problem cannot follow: whole runs
    models, failure = [], None
    for i, e in enumerate(experiments):
        if whole or failure is not None or not groups.owned[i]:
            models.append(None)      # whole runs, or another group's experiment
            continue
        try:
            model = sensitivity.ForwardModel(
                _scene(e, parameters, [p["initial"] for p in parameters]),
                groups.sub, component=e["component"])
        except Exception as err:
            failure = (i, err)
            models.append(None)
            continue
        if model.memory_reason:
            reasons.append((i, model.memory_reason))
            model.destroy()
            models.append(None)
            continue
        models.append(model)
        if mode != "finite-differences":
            try:
                model.sensitivity = sensitivity.StepSensitivity(model.problem, model.newton)
            except SceneError as err:
                reasons.append((i, str(err)))
    if groups.count > 1:             # the same decision on every rank
        shared = groups.comm.allgather(reasons)
        reasons = sorted({r for part in shared for r in part})
    reasons = [r for _, r in sorted(reasons)]
    try:
        groups.gather({}, failure)
    except BaseException:
        _destroy(models)
        raise
    if mode == "sensitivities" and reasons:
        _destroy(models)
        _fail("fit.jacobian", f"forward sensitivities do not cover this fit: {reasons[0]}")
    return models, mode != "finite-differences" and not reasons, (
        reasons[0] if reasons and mode == "auto" else None)


def _destroy(models: list) -> None:
    for model in models:
        if model is not None:
            model.destroy()


def _closed_form_start(experiments: list, parameters: list) -> tuple:
    """The Lee-Radok fit of the creep curves (studies.lee_radok: a sphere on a half-space, no
    friction) over the parameters whose initial is "closed-form", the others held at their
    start, by the same least squares and bounds; its estimates become their starts.

    Returns
    -------
    tuple
        (key -> closed-form estimate, the closed form's depth per experiment at them); empty
        and None when no parameter asks for it.
    """
    from scipy.optimize import least_squares

    from contactvisco.studies import lee_radok
    chosen = [i for i, p in enumerate(parameters) if p.get("closed_form")]
    if not chosen:
        return {}, None
    # The closed form is one of creep: relaxation experiments are left out of its fit.
    creep = [i for i, e in enumerate(experiments) if e["control"] == "force"]
    if not creep:
        _fail(f"parameter[{chosen[0]}].initial", f"'{CLOSED_FORM}' needs at least one creep "
              "experiment (control = 'force'); all are under control = 'depth'")
    for i in creep:
        e = experiments[i]
        scene = _scene(e, parameters, [p["initial"] for p in parameters])
        obstacle = scene["obstacle"]
        if (e["force"] is None or obstacle["shape"] != "sphere"
                or scene["material"]["model"] not in ("axisymmetric", "3d")):
            _fail(f"parameter[{chosen[0]}].initial", f"'{CLOSED_FORM}' needs creep "
                  "experiments of a sphere (control = 'force' with a force column, "
                  "obstacle.shape = 'sphere', an axisymmetric or 3D body); experiment"
                  f"[{i}] is not one")
    used = [experiments[i] for i in creep]
    values = np.array([p["initial"] for p in parameters], float)

    def residual(x):
        values[chosen] = _to_values([parameters[i] for i in chosen], x)
        return np.concatenate([
            e["w"] * (lee_radok.creep_depth(_scene(e, parameters, values), e["t"], e["force"],
                                            e_radius) - e["depth"])
            for e, e_radius in zip(used, radii)])

    radii = [_scene(e, parameters, values)["obstacle"]["radius"] for e in used]
    picked = [parameters[i] for i in chosen]
    result = least_squares(
        residual, _to_x(picked, [p["initial"] for p in picked]),
        bounds=(_to_x(picked, [p["bounds"][0] for p in picked]),
                _to_x(picked, [p["bounds"][1] for p in picked])),
        method="trf", x_scale="jac", ftol=1e-12, xtol=1e-12, gtol=1e-12)
    out = {}
    depths = residual(result.x)     # at the estimates (values[chosen] set to them)
    curves, offset = [None] * len(experiments), 0
    for i, e in zip(creep, used):
        k = len(e["t"])
        curves[i] = e["depth"] + depths[offset:offset + k] / e["w"]
        offset += k
    for p, v in zip(picked, _to_values(picked, result.x)):
        p["initial"] = float(v)
        out[p["key"]] = float(v)
    return out, curves


def _to_x(parameters, values):
    return np.array([math.log(v) if p["scale"] == "log" else v
                     for p, v in zip(parameters, values)])


def _to_values(parameters, x):
    return np.array([math.exp(v) if p["scale"] == "log" else v for p, v in zip(parameters, x)])


def statistics(jacobian: np.ndarray, residual: np.ndarray, parameters: list,
               values: np.ndarray) -> dict:
    """Standard errors, correlations and identifiability at the optimum (module description).

    Parameters
    ----------
    jacobian : numpy.ndarray
        J = dr/dx, (m, n), x the parameters in their scale.
    residual : numpy.ndarray
        r at the optimum, (m,).
    parameters : list of dict
        The parameters (their scale).
    values : numpy.ndarray
        theta at the optimum.

    Returns
    -------
    dict
        ``s2`` (residual variance), ``singular_values``, ``rank``, ``standard_error`` (of
        theta; inf where not determined), ``correlation`` (nan rows where not determined),
        ``identifiable`` (bool per parameter), ``covariance`` (C_x, of x in the parameters'
        scale, over the kept singular directions) and ``warnings`` (text).
    """
    m, n = jacobian.shape
    s2 = float(residual @ residual / (m - n)) if m > n else math.nan
    _, S, Vt = np.linalg.svd(jacobian, full_matrices=False)
    kept = S > RCOND * S[0] if S.size and S[0] > 0 else np.zeros(n, bool)
    V = Vt.T
    cov = (V[:, kept] / S[kept] ** 2) @ V[:, kept].T * s2
    undetermined = np.any(np.abs(V[:, ~kept]) > NULL_SHARE, axis=1)
    se_x = np.sqrt(np.maximum(np.diag(cov), 0.0))
    se_x[undetermined] = math.inf
    se = np.array([v * e if p["scale"] == "log" else e
                   for p, v, e in zip(parameters, values, se_x)])
    with np.errstate(invalid="ignore", divide="ignore"):
        corr = cov / np.outer(se_x, se_x)
    corr[undetermined, :] = math.nan
    corr[:, undetermined] = math.nan
    np.fill_diagonal(corr, 1.0)
    warnings, identifiable = [], []
    for i, p in enumerate(parameters):
        ok = True
        if undetermined[i]:
            ok = False
            warnings.append(f"{p['key']}: not identifiable: the data does not determine it "
                            f"(J has a singular value below {RCOND:g} of the largest along it)")
        elif se[i] > abs(values[i]):
            ok = False
            warnings.append(f"{p['key']}: not identifiable: its standard error {se[i]:.3g} "
                            f"exceeds its value {values[i]:.6g}")
        identifiable.append(ok)
        for j in range(i):
            if abs(corr[i, j]) > HIGH_CORRELATION:
                warnings.append(f"{p['key']} and {parameters[j]['key']}: correlated "
                                f"({corr[i, j]:+.4f}): the data hardly separates them")
    return {"s2": s2, "singular_values": S.tolist(), "rank": int(kept.sum()),
            "standard_error": se.tolist(), "correlation": corr.tolist(),
            "identifiable": identifiable, "covariance": cov.tolist(), "warnings": warnings}


def fit(description, comm=None, progress: bool = False) -> dict:
    """Identify the parameters of a fit description by weighted least squares over all its
    experiments (module description), with fit.reduction = true repeated on the reduced
    Prony grid until no term is dropped (:func:`reduce_terms`).

    Parameters
    ----------
    description : path-like or dict
        A fit TOML file, or what ``read_fit`` returned.
    comm : mpi4py.MPI.Comm, optional
        The communicator of the forward runs.
    progress : bool
        Print a line per dropped term and per round (first rank only).

    Returns
    -------
    dict
        What :func:`_fit_round` returns for the last round, with ``reduction`` (``enabled``,
        ``threshold``, ``rounds``, ``dropped``: per dropped term its key in the description,
        function, tau, estimate, the sum it is compared with, the cost's gradient and why)
        and ``fitted_scene`` (per experiment the scene and the ``key=value`` texts that make
        the fitted scene: the kept terms only).
    """
    import copy

    spec = description if isinstance(description, dict) else read_fit(description)
    spec = copy.deepcopy(spec) if spec["fit"].get("reduction") else spec
    settings = spec["fit"]
    origin = [p["key"] for p in spec["parameters"]]    # each parameter's key as given
    report = _fit_round(spec, comm)
    first = report
    dropped, rounds = [], 1
    while settings.get("reduction"):
        drops = reduce_terms(spec, report, float(settings["reduction_threshold"]))
        if not drops:
            break
        for d in drops:
            d["key"], d["round"] = origin[d.pop("index")], rounds
            dropped.append(d)
            _say(progress, f"fit: round {rounds}: dropped {d['key']} (tau = {d['tau']:.6g}): "
                 f"{d['why']}")
        gone = {origin.index(d["key"]) for d in drops}
        origin = [k for i, k in enumerate(origin) if i not in gone]
        rounds += 1
        _say(progress, f"fit: round {rounds} with {len(spec['parameters'])} parameters")
        previous = report
        report = _fit_round(spec, comm)
        report["evaluations"] += previous["evaluations"]     # all rounds' runs and time
        report["wall_s"] += previous["wall_s"]
    closed = {p["key"]: p["closed_form"] for p in first["parameters"]}
    for p, key in zip(report["parameters"], origin):
        p["closed_form"] = closed.get(key)
        p["description_key"] = key
    if report is not first:          # the closed-form start is the first round's
        for c, c0 in zip(report["curves"], first["curves"]):
            c["closed_form"] = c0.get("closed_form")
    report["reduction"] = {"enabled": bool(settings.get("reduction")),
                           "threshold": float(settings["reduction_threshold"]),
                           "rounds": rounds, "dropped": dropped}
    report["fitted_scene"] = [
        {"scene": e["scene"], "set": [str(v) for v in e["set"]] + [
            f"{p['key']}={float(v['estimate'])!r}"
            for p, v in zip(spec["parameters"], report["parameters"])]}
        for e in spec["experiments"]]
    return report


def _say(progress: bool, line: str) -> None:
    from contactvisco.io import parallel
    if progress and parallel.first_rank():
        print(line, flush=True)


def reduce_terms(spec: dict, report: dict, threshold: float) -> list:
    """Drop from `spec` (in place) the Prony terms whose fitted modulus sits at its bound 0:
    a parameter viscoelastic.<function>.<moduli|fractions>.<i> with estimate

        theta_i <= threshold * sum_j theta_j,

    the sum over the entries of that list in the first experiment's scene at the estimates
    (fitted and fixed terms). The term's tau and modulus leave the lists of every
    experiment's scene (overrides appended to its ``set``), the other parameters of the list
    are renumbered and start again from their estimates.

    Returns
    -------
    list of dict
        Per dropped term: ``index`` (its parameter's position), ``function``, ``tau``,
        ``estimate``, ``sum``, ``gradient`` (the cost's, (J^T r)_i: >= 0 when the bound is
        active) and ``why``.
    """
    parameters, experiments = spec["parameters"], spec["experiments"]
    values = np.array([p["estimate"] for p in report["parameters"]], float)
    jac = np.asarray(report["jacobian_matrix"])
    gradient = jac.T @ np.asarray(report["residual"]) if jac.size else np.zeros(values.size)
    scene = _scene(experiments[0], parameters, values)
    drops = []
    for i, p in enumerate(parameters):
        if not p["regularized"]:
            continue
        listed = [float(v) for v in _at(scene, p["path"][:-1])]
        total = sum(abs(v) for v in listed)
        if values[i] <= threshold * total:
            tau = float(_at(scene, p["path"][:-2] + ["tau"])[int(p["path"][-1])])
            drops.append({"index": i, "function": p["path"][1], "tau": tau,
                          "estimate": float(values[i]), "sum": total,
                          "gradient": float(gradient[i]),
                          "why": f"{p['path'][-2][:-1]} {values[i]:.3g} <= {threshold:g} of "
                                 f"the sum {total:.6g} of {'.'.join(p['path'][:-1])} (at the "
                                 f"bound 0; the cost's gradient {gradient[i]:+.3g})"})
    if not drops:
        return drops
    gone = {d["index"] for d in drops}
    lists = {}                       # (function path, kind) -> dropped list indices
    for i in sorted(gone):
        path = parameters[i]["path"]
        lists.setdefault((tuple(path[:-2]), path[-2]), set()).add(int(path[-1]))
    for e in experiments:
        at = _scene(e, parameters, values)
        for (function, kind), out in lists.items():
            taus = list(_at(at, list(function) + ["tau"]))
            entries = list(_at(at, list(function) + [kind]))
            keep = [j for j in range(len(taus)) if j not in out]
            e["set"] = list(e["set"]) + [
                scene_module.Override(list(function) + ["tau"], [float(taus[j]) for j in keep]),
                scene_module.Override(list(function) + [kind],
                                      [float(entries[j]) for j in keep])]
    kept = []
    for i, p in enumerate(parameters):
        if i in gone:
            continue
        path = p["path"]
        out = lists.get((tuple(path[:-2]), path[-2])) if p["regularized"] else None
        if out:
            j = int(path[-1])
            path = path[:-1] + [str(j - sum(1 for o in out if o < j))]
            p["path"], p["key"] = path, ".".join(path)
        lower, upper = p["bounds"]
        p["initial"] = float(min(max(values[i], lower), upper))
        p["closed_form"] = False
        kept.append(p)
    parameters[:] = kept
    return drops


def _fit_round(spec: dict, comm=None) -> dict:
    """One least-squares fit of the parameters of a checked fit description over all its
    experiments (module description).

    Parameters
    ----------
    spec : dict
        What ``read_fit`` returned (a closed-form start replaces its parameters' initial).
    comm : mpi4py.MPI.Comm, optional
        The communicator of the forward runs.

    Returns
    -------
    dict
        ``parameters`` (per parameter: key, estimate, initial, standard_error, identifiable,
        scale, bounds), ``correlation``, ``singular_values``, ``rank``, ``cost``
        (1/2 sum r^2), ``s2``, ``residual_rms`` (of the unweighted depth), ``evaluations``
        (forward runs of all experiments, differences included), ``residual_evaluations``
        (the optimizer's, at most fit.max_evaluations), ``jacobian_evaluations``,
        ``wall_s``, ``status`` and ``message`` of the optimizer, ``success``, ``warnings``,
        ``jacobian`` (how J was taken), ``curves`` (per experiment: t, the fitted
        ``quantity``, depth or force, measured, fitted and ``closed_form``), per parameter
        its 95 % ``interval``; ``covariance`` (C_x), ``confidence`` (level, m - n, the
        Student quantile q), ``regularization`` (weight w, Tikhonov rows
        sqrt(w) (x_i - x0_i) on the Prony moduli appended to r) and ``moduli`` (see
        :func:`moduli`).
    """
    from scipy.optimize import least_squares

    parameters, experiments = spec["parameters"], spec["experiments"]
    settings = spec["fit"]
    runs = [0]
    closed, closed_curves = _closed_form_start(experiments, parameters)
    # Tikhonov rows sqrt(w) (x_i - x0_i) on the Prony moduli (module description)
    weight = float(settings.get("regularization", 0.0))
    regularized = [i for i, p in enumerate(parameters) if p["regularized"]] if weight > 0 \
        else []
    prior = _to_x(parameters, [p["prior"] for p in parameters])[regularized]
    prior_rows = np.zeros((len(regularized), len(parameters)))
    prior_rows[np.arange(len(regularized)), regularized] = math.sqrt(weight)
    from mpi4py import MPI
    comm = comm or MPI.COMM_WORLD
    count = groups_of(settings.get("communicators", "auto"), comm.size, len(experiments))
    groups = _Groups(comm, count, len(experiments))
    try:
        models, sensitivities, reason = _models(experiments, parameters,
                                                settings["jacobian"], groups)
    except BaseException:
        groups.free()
        raise
    cached = {}

    def evaluate(x, with_jacobian):
        values = _to_values(parameters, x)
        runs[0] += 1
        blocks, failure = {}, None
        # dtheta/dx: 1 in linear scale, theta in log scale
        scale = np.array([v if p["scale"] == "log" else 1.0 for p, v in zip(parameters, values)])
        for i, (e, model) in enumerate(zip(experiments, models)):
            if not groups.owned[i]:
                continue             # another group's experiment
            try:
                if model is None:     # whole runs (a key the built problem cannot follow)
                    blocks[i] = (e["w"] * (forward(e, parameters, values, groups.sub)
                                           - _measured(e)), None)
                    continue
                tangents = _tangents(e, parameters, values) if with_jacobian else ()
                result = model.run(_scene(e, parameters, values), tangents)
                where = _sample_index(result["t"], e)
                name = "force" if e["control"] == "depth" else "depth"
                blocks[i] = (e["w"] * (result[name][where] - _measured(e)),
                             e["w"] * result[f"d_{name}"][where] * scale
                             if with_jacobian else None)
            except Exception as err:
                # The run's own message names the step; this names the parameters.
                err.add_note(f"in the forward run of experiment[{i}] at " + ", ".join(
                    f"{p['key']} = {v!r}" for p, v in zip(parameters, values)))
                failure = (i, err)
                break
        blocks = groups.gather(blocks, failure)
        out = [blocks[i][0] for i in range(len(experiments))]
        out.append(math.sqrt(weight) * (np.asarray(x)[regularized] - prior))
        if with_jacobian:
            rows = [blocks[i][1] for i in range(len(experiments))] + [prior_rows]
            cached["x"], cached["J"] = np.array(x, copy=True), np.concatenate(rows)
        return np.concatenate(out)

    def residual(x):
        return evaluate(x, sensitivities)

    def jacobian(x):
        if "x" not in cached or not np.array_equal(cached["x"], x):
            evaluate(x, True)
        return cached["J"]

    lower = _to_x(parameters, [p["bounds"][0] for p in parameters])
    upper = _to_x(parameters, [p["bounds"][1] for p in parameters])
    start = time.perf_counter()
    tol = settings["tolerance"]
    try:
        result = least_squares(residual, _to_x(parameters, [p["initial"] for p in parameters]),
                               jac=jacobian if sensitivities
                               else DIFFERENCES[settings["difference"]],
                               bounds=(lower, upper), method="trf", diff_step=settings["step"],
                               x_scale="jac", ftol=tol, xtol=tol, gtol=tol,
                               max_nfev=settings["max_evaluations"])
    finally:
        _destroy(models)
        models.clear()
        cached.clear()
        groups.free()
    wall = time.perf_counter() - start
    values = _to_values(parameters, result.x)
    stats = statistics(result.jac, result.fun, parameters, values)
    curves, offset = [], 0
    for e in experiments:
        k = len(e["t"])
        fitted = _measured(e) + result.fun[offset:offset + k] / e["w"]
        curves.append({"data": e["data"], "t": e["t"].tolist(),
                       "force": None if e["force"] is None else e["force"].tolist(),
                       "quantity": "force" if e["control"] == "depth" else "depth",
                       "measured": _measured(e).tolist(), "fitted": fitted.tolist()})
        offset += k
    for c, closed_depth in zip(curves, closed_curves or [None] * len(curves)):
        c["closed_form"] = None if closed_depth is None else closed_depth.tolist()
    misfit = np.concatenate([np.array(c["fitted"]) - c["measured"] for c in curves])
    from scipy.stats import t as student
    dof = len(result.fun) - len(parameters)
    quantile = float(student.ppf(0.5 + LEVEL / 2, dof)) if dof > 0 else math.inf
    x_se = [se / v if p["scale"] == "log" else se
            for p, v, se in zip(parameters, values, stats["standard_error"])]
    intervals = [[math.exp(x - quantile * e), math.exp(x + quantile * e)]
                 if p["scale"] == "log" else [x - quantile * e, x + quantile * e]
                 for p, x, e in zip(parameters, result.x, x_se)]
    return {
        "parameters": [{"key": p["key"], "estimate": float(v), "initial": p["initial"],
                        "closed_form": closed.get(p["key"]),
                        "standard_error": se, "interval": interval, "identifiable": ok,
                        "scale": p["scale"], "bounds": list(p["bounds"]),
                        "prior": p["prior"] if i in regularized else None}
                       for i, (p, v, se, ok, interval) in enumerate(zip(
                           parameters, values, stats["standard_error"], stats["identifiable"],
                           intervals))],
        "covariance": stats["covariance"],
        "confidence": {"level": LEVEL, "dof": dof, "quantile": quantile},
        "regularization": {"weight": weight, "rows": len(regularized)},
        "moduli": moduli(experiments[0], parameters, values),
        "correlation": stats["correlation"], "singular_values": stats["singular_values"],
        "rank": stats["rank"], "cost": float(result.cost), "s2": stats["s2"],
        "residual_rms": float(np.sqrt(np.mean(misfit ** 2))), "evaluations": runs[0],
        "residual_evaluations": int(result.nfev),
        "jacobian_evaluations": int(result.njev or 0), "wall_s": wall,
        "status": int(result.status), "message": str(result.message),
        "success": bool(result.success), "warnings": stats["warnings"],
        "communicators": {"mode": settings.get("communicators", "auto"), "groups": count,
                          "ranks": comm.size},
        "jacobian": ({"rule": "sensitivities", "scene_step": SCENE_STEP} if sensitivities
                     else {"rule": settings["difference"], "step": settings["step"],
                           **({"why": reason} if reason else {})}),
        "curves": curves,
        # J and r at the optimum, for the reduction's gradient J^T r (not written out)
        "jacobian_matrix": np.asarray(result.jac), "residual": np.asarray(result.fun),
    }


def moduli(experiment: dict, parameters: list, values) -> dict | None:
    """The relaxation functions of the fitted material (its [viscoelastic] table, at T_ref:
    G(t) of the shear series, K(t) of the bulk one, E(t) where the scene gives Young's) on a
    log grid of t, with their Jacobian in the optimizer's variables x, for the confidence
    band var phi(t) = g(t)^T C_x g(t), g = dphi(t)/dx (linear propagation).

    dphi/dx by central differences of the scene's conversion (no solve; phi is linear in the
    moduli, smooth in the times): h = SCENE_STEP max(1, |x_k|), forward differences where
    x_k - h is below the parameter's lower bound.

    Returns
    -------
    dict or None
        ``t`` and per function name (``shear``, ``bulk``, ``young``) its ``value`` and
        ``jacobian`` (len(t) x n); None for a scene without relaxation functions.
    """
    from contactvisco.model import viscoelastic as ve

    def functions(x):
        scene = _scene(experiment, parameters, _to_values(parameters, x))
        return dict(getattr(scene.get("viscoelastic"), "functions", None) or {})

    x = _to_x(parameters, values)
    base = functions(x)
    if not base:
        return None
    taus = [tau for phi in base.values() for tau in phi.taus] or [1.0]
    t = np.geomspace(min(taus) / 1e2, max(taus) * 1e2, 200)
    out = {"t": t.tolist()}
    jacobians = {name: np.zeros((t.size, x.size)) for name in base}
    lower = _to_x(parameters, [p["bounds"][0] for p in parameters])
    for k in range(x.size):
        h = SCENE_STEP * max(1.0, abs(x[k]))
        step = np.zeros(x.size)
        step[k] = h
        # one-sided at a bound (a modulus near 0 under fit.reduction): phi is linear in it
        central = x[k] - h >= lower[k]
        plus, minus = functions(x + step), functions(x - step) if central else base
        for name in base:
            jacobians[name][:, k] = (ve.relaxation(plus[name], t)
                                     - ve.relaxation(minus[name], t)) / ((2.0 if central
                                                                          else 1.0) * h)
    for name, phi in base.items():
        out[name] = {"value": ve.relaxation(phi, t).tolist(),
                     "jacobian": jacobians[name].tolist()}
    return out


def write(report: dict, out) -> None:
    """Write a fit's report into folder `out`: ``fit.json`` (the report without the
    curves), ``curves.csv`` (experiment, t, force, measured, fitted and closed-form depth,
    the quantity fitted) and the figures drawn from these two files
    (contactvisco.post.fit_figures: ``fit.png``, ``fit_moduli.png``,
    ``fit_correlation.png``), and per experiment i the fitted scene ``fitted_<i>.toml``: the
    experiment's scene with its ``set`` and the fitted values (the kept Prony terms only
    under fit.reduction), as ``contactvisco run`` reads it. Its load is the scene's own, not
    the measured history that drove the fit.

    Parameters
    ----------
    report : dict
        What :func:`fit` returned.
    out : path-like
        The folder (created).
    """
    from contactvisco.post import fit_figures

    out = pathlib.Path(out)
    out.mkdir(parents=True, exist_ok=True)
    summary = {k: v for k, v in report.items()
               if k not in ("curves", "jacobian_matrix", "residual")}
    # Strict JSON: an undetermined standard error (inf) or correlation (nan) is null.
    (out / "fit.json").write_text(json.dumps(_finite(summary), indent=2) + "\n")
    with open(out / "curves.csv", "w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(["experiment", "t", "force", "measured_depth", "fitted_depth",
                         "closed_form_depth", "quantity"])
        for i, c in enumerate(report["curves"]):
            force = c["force"] or [""] * len(c["t"])
            closed = c.get("closed_form") or [""] * len(c["t"])
            for row in zip(c["t"], force, c["measured"], c["fitted"], closed):
                writer.writerow([i, *[repr(v) if v != "" else "" for v in row],
                                 c.get("quantity", "depth")])
    for i, entry in enumerate(report.get("fitted_scene", [])):
        scene = scene_module.load(entry["scene"], entry["set"])
        (out / f"fitted_{i}.toml").write_text(toml_text.scene_text(scene))
    fit_figures.draw(out)


def _finite(value):
    """The report with every non-finite number as None."""
    if isinstance(value, dict):
        return {k: _finite(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_finite(v) for v in value]
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value
