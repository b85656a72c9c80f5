"""Scenes: one TOML document that holds every parameter of a run.

A scene is a plain nested dict. :func:`load` reads a built-in scene by name or a TOML file by
path, fills in :data:`DEFAULTS` and applies ``--set key=value`` overrides (dotted keys, values
in TOML syntax). Nothing else in the package holds a parameter value of its own.
"""
from __future__ import annotations

import copy
import difflib
import math
import pathlib
import tomllib

from .memory import PARTS

SCENE_DIR = pathlib.Path(__file__).parent / "scenes"

#: Defaults filled into every scene; a scene file only states what differs.
DEFAULTS: dict = {
    "name": "unnamed",
    "description": "",
    "preset": None,               # fast | balanced | accurate: see PRESETS
    "geometry": {
        "type": "box",            # box: structured mesh made in memory (2D triangles, 3D tets)
                                  # gmsh: a mesh script from meshes/ (or a .msh file)
        "script": None,           # gmsh: script name in meshes/ (meshes/<script>.py)
        "file": None,             # gmsh: a .msh file instead of a script
        "parameters": {},         # gmsh: keyword arguments of the script
        "lower": [0.0, 0.0],
        "upper": [1.0, 1.0],
        "cells": [32, 32],
        "diagonal": "right",      # 2D triangle diagonal: left, right, crossed, ...
        "rotation": 0.0,          # degrees about the z axis through the origin, applied after
                                  # the boundaries are named (tilted contact boundaries)
    },
    "material": {
        "model": "plane_strain",  # plane_stress | plane_strain | 3d
        "E": 1.0,                 # Young's modulus (or give lambda and mu instead of E, nu)
        "nu": 0.3,                # Poisson ratio
        "lambda": None,           # Lame constants (3D values; plane stress reduces them)
        "mu": None,
    },
    "memory": {
        "kernel": "none",         # none | constant | exponential | prony | table | power |
                                  #   fractional
        "alpha": 0.0,             # constant: R = alpha I; exponential: list, with tau;
                                  #   power, fractional: a number
        "tau": [],                # exponential: R = sum_i alpha_i exp(-t/tau_i) I;
                                  #   power: R = alpha (1 + t/tau)^(-beta) P, tau a number
        "beta": 0.5,              # power (> 0); fractional (0 < beta < 1):
                                  #   R = alpha t^(-beta) / Gamma(1 - beta) P
        "part": "full",           # power, fractional: P = full | deviatoric | volumetric
        "tolerance": 1e-6,        # power, fractional: relative error of the exponential sum
        "summation": "soe",       # power, fractional: soe (sum of exponentials, O(1) per
                                  #   step) | direct (exact kernel, O(n) per step)
        "terms": [],              # prony: [{alpha, tau (default inf), part = full |
                                  #   deviatoric | volumetric}]
        "times": [],              # table: R(t) = r(t) I, r linear between (times, values)
        "values": [],
    },
    "dirichlet": [],              # list of {boundary, components = "all" | [i, ...], value}
    "body_force": {"value": None},
    "traction": [],               # list of {boundary, value}
    "contact": None,              # {boundary, stiffness, g, mu, augmentation}
    "time": {
        "T": 1.0,
        "steps": 10,
        "rule": "paper",          # memory quadrature on the last sub-interval: paper (eq 19,
                                  # left point, explicit) | trapezoid (implicit, always stable)
        "allow_unstable": False,  # run the paper's rule where it amplifies errors (b >= 1)
    },
    "discretization": {
        "degree": 1,
        "contact_quadrature": "nodal",  # nodal (trapezoid: conditions hold node by node) | gauss
    },
    "solver": {
        "petsc_options": {},      # PETSc options; the command line overrides them
        "max_cuts": 4,            # a step whose Newton fails is halved, at most this many
                                  # times in a row (0: no step cutting)
        "linear_system": "auto",  # condensed (u only, multipliers eliminated node by node;
                                  # nodal contact quadrature) | coupled (u and multipliers);
                                  # auto: condensed where possible
        "linear_solver": "auto",  # direct (MUMPS LU) | iterative (GMRES + BoomerAMG); auto:
                                  # iterative from solver.AUTO_ITERATIVE unknowns on
    },
    "output": {
        "probes": [],
        "figure_times": [],       # times (besides T) at which the deformed mesh is drawn
        "xdmf": True,
        "fields": ["u", "sigma"],  # XDMF fields: u, sigma, history_stress, lambda_nu,
                                   # lambda_tau
        "figures": True,
        "snapshot_max_nodes": 200000,  # figure snapshots gather the whole mesh on rank 0:
                                       # skipped (with a note) above this many mesh nodes
        "checkpoint": True,        # save the state after every step (for --restart)
    },
    "units": {                     # labels on figure axes only (no conversion): e.g. "mm",
        "length": None,            # "N", "s"; none given: axes say "(model units)"
        "force": None,
        "time": None,
    },
}

#: Speed-accuracy presets, relative to the scene's own discretization: mesh refines the mesh
#: (box cells times mesh; gmsh sizes h, h_* divided by mesh), steps multiplies time.steps.
#: Chosen from the measured trade-off (benchmarks/tradeoff.py, README): on the built-in scenes
#: the space error dominates (the time error at the scenes' own k is 20-50 times smaller), so
#: no preset refines time; P2 is faster per error on the paper scene but its Newton diverges
#: on pure Signorini contact (Hertz), so every preset stays P1 with exact nodal conditions.
PRESETS = {
    "fast": {"mesh": 0.5, "steps": 1.0, "degree": 1, "rule": "trapezoid"},
    "balanced": {"mesh": 1.0, "steps": 1.0, "degree": 1, "rule": "trapezoid"},
    "accurate": {"mesh": 2.0, "steps": 1.0, "degree": 1, "rule": "trapezoid"},
}

#: Defaults of the [contact] table, used when a scene has one.
CONTACT_DEFAULTS = {
    "boundary": "bottom",
    "gap": 0.0,              # initial gap h(x) >= 0 (number or expression): the penetration
                             # into the layer is u_nu - h
    "stiffness": 0.0,        # compliance stiffness c_nu in p_nu(s) = c_nu max(0, s)
    "g": math.inf,           # layer thickness (bound on u_nu); inf: no unilateral bound
    "mu": 0.0,               # friction coefficient
    "friction": "compliance",  # friction bound: mu p_nu (compliance, the paper's) |
                             # mu (p_nu + R_nu) (coulomb: the total normal pressure)
    "slip": "total",         # slip measured by u_tau (total, the paper's) | by the step's
                             # u_tau - u_tau(t_{n-1}) (increment)
    "augmentation": None,    # augmentation parameter r; None: the stiffness, or E if that is 0
}


#: contact.friction: the friction ball's radius is mu p_nu(u_nu) or mu (p_nu(u_nu) + R_nu).
FRICTION_LAWS = ("compliance", "coulomb")
#: contact.slip: the friction law acts on u_tau or on u_tau - u_tau(t_{n-1}).
SLIP_MEASURES = ("total", "increment")

#: Keys of the tables in the lists [[dirichlet]] and [[traction]].
ITEM_KEYS = {"dirichlet": ("boundary", "components", "value"), "traction": ("boundary", "value")}


class SceneError(ValueError):
    """A scene value that is missing, misspelled or out of range."""

    #: True once the message says where the value came from (scene file line or --set).
    located = False


def _mesh_dir() -> pathlib.Path:
    """The gmsh scripts: installed inside the package, or meshes/ beside it in a source tree."""
    here = pathlib.Path(__file__).resolve().parent
    installed = here / "meshes"
    return installed if installed.is_dir() else here.parent / "meshes"


#: Folder of the built-in mesh scripts (geometry.script names one of them).
MESH_DIR = _mesh_dir()

#: Scene moduli (E, lambda, mu, stiffness, ...) and box sizes must lie in
#: [1/MODULUS_RANGE, MODULUS_RANGE]: products of moduli, lengths, displacements and their
#: squares then stay far inside double precision.
MODULUS_RANGE = 1e100

#: Most cells a gmsh script may be asked for, estimated as (largest length / smallest size)^d.
MAX_SCRIPT_CELLS = 1e7

#: Most boxes (each 2 triangles or 6 tetrahedra) of a box geometry.
MAX_BOX_CELLS = 1e8


def builtin_names() -> list[str]:
    return sorted(p.stem for p in SCENE_DIR.glob("*.toml"))


def _merge(base: dict, update: dict, where: str = "") -> dict:
    out = copy.deepcopy(base)
    for key, value in update.items():
        if key not in base:
            hint = difflib.get_close_matches(key, list(base), n=1)
            suggestion = f" (did you mean '{hint[0]}'?)" if hint else ""
            raise SceneError(f"unknown scene key '{where}{key}'{suggestion}; "
                             f"allowed here: {', '.join(sorted(base))}")
        # An empty default table is free-form (geometry.parameters, solver.petsc_options).
        if isinstance(base[key], dict) and base[key] and isinstance(value, dict):
            out[key] = _merge(base[key], value, f"{where}{key}.")
        else:
            out[key] = copy.deepcopy(value)
    return out


class Override(str):
    """A scene value given as a Python value: reads as `key=value` in messages, and carries
    (path, value) so that the value is used as given (not parsed as TOML)."""

    source = "load_scene"

    def __new__(cls, path: list[str], value):
        text = super().__new__(cls, f"{'.'.join(path)}={value!r}")
        text.assignment = (list(path), value)
        return text


def parse_assignment(text: str) -> tuple[list[str], object]:
    """Split ``a.b.c=value`` into (["a", "b", "c"], value); value in TOML syntax, bare words
    are strings."""
    if "=" not in text:
        raise SceneError(f"--set expects key=value, got '{text}'")
    key, raw = text.split("=", 1)
    try:
        value = tomllib.loads(f"v = {raw}")["v"]
    except tomllib.TOMLDecodeError:
        value = raw.strip()
    if isinstance(value, str) and value.lower() in ("inf", "+inf"):
        value = math.inf
    return key.strip().split("."), value


def _apply_set(scene: dict, path: list[str], value) -> None:
    node = scene
    for i, key in enumerate(path):
        dotted = ".".join(path[:i + 1])
        if isinstance(node, list):
            if not (key.isdigit() and int(key) < len(node)):
                raise SceneError(f"--set {dotted}: '{'.'.join(path[:i])}' is a list of "
                                 f"{len(node)} table(s); the index must be 0..{len(node) - 1}")
            key = int(key)
        elif not isinstance(node, dict):
            raise SceneError(f"--set {dotted}: '{'.'.join(path[:i])}' is a value "
                             f"({node!r}), not a table with keys")
        if i == len(path) - 1:
            break
        if isinstance(node, dict) and key not in node:
            raise SceneError(f"--set: no scene key '{dotted}'")
        if node[key] is None and key == "contact":
            node[key] = dict(CONTACT_DEFAULTS)
        node = node[key]
    last = key
    if isinstance(node, list):
        node[last] = value
        return
    free_form = tuple(path[:-1]) in (("geometry", "parameters"), ("solver", "petsc_options"))
    allowed = ITEM_KEYS.get(path[0], ()) if len(path) == 3 else list(node)
    if last not in node and last not in allowed and not free_form:
        hint = difflib.get_close_matches(last, list(allowed), n=1)
        suggestion = f" (did you mean '{hint[0]}'?)" if hint else ""
        raise SceneError(f"--set: unknown scene key '{'.'.join(path)}'{suggestion}")
    table = node.get(last) or (CONTACT_DEFAULTS if path == ["contact"] else None)
    if isinstance(table, dict) and table and not free_form:
        # A whole table: its keys are checked and the defaults kept.
        if not isinstance(value, dict):
            raise SceneError(f"--set {'.'.join(path)}: '{'.'.join(path)}' is a table; set "
                             f"its keys ({'.'.join(path)}.{next(iter(table))}=...) or give "
                             f"a table {{...}}, got {value!r}")
        value = _merge(table, value, f"{'.'.join(path)}.")
    node[last] = value


def resolve(raw: dict, overrides: list[str] = ()) -> dict:
    """Fill defaults into a raw scene dict and apply ``key=value`` overrides."""
    scene = _merge(DEFAULTS, {k: v for k, v in raw.items() if k != "contact"})
    if not isinstance(scene["material"], dict):
        raise SceneError(f"material must be a table, got {scene['material']!r}")
    if raw.get("contact") is not None:
        if not isinstance(raw["contact"], dict):
            raise SceneError(f"contact must be a table, got {raw['contact']!r}")
        scene["contact"] = _merge(CONTACT_DEFAULTS, raw["contact"], "contact.")
    # An override is `key=value` text (--set) or an Override (the Python API's values).
    assignments = [getattr(text, "assignment", None) or parse_assignment(text)
                   for text in overrides]
    _check_material_pairs(raw.get("material", {}), assignments)
    for path, value in assignments:          # a preset from --set first, then the rest
        if path == ["preset"]:
            scene["preset"] = value
    if scene["preset"] is not None:
        apply_preset(scene, scene["preset"])
    for path, value in assignments:
        if path != ["preset"]:
            _apply_set(scene, path, value)
    _lame_to_young(scene["material"])
    contact = scene["contact"]
    if contact is not None:
        if isinstance(contact["g"], str):
            try:
                contact["g"] = float(contact["g"])
            except ValueError:
                raise SceneError(f"contact.g must be a number >= 0 or inf, got "
                                 f"{contact['g']!r}") from None
        if contact["augmentation"] is None:
            contact["augmentation"] = contact["stiffness"] or scene["material"]["E"]
    check(scene)
    return scene


def _check_material_pairs(raw_material: dict, assignments) -> None:
    """Either (E, nu) or (lambda, mu), from the file and --set together: a value of one pair
    next to the other pair would be dropped without a word."""
    given = {k: "the scene file" for k, v in raw_material.items() if v is not None}
    for path, value in assignments:
        if path[0] == "material" and len(path) == 2 and value is not None:
            given[path[1]] = f"--set material.{path[1]}"
        elif path == ["material"] and isinstance(value, dict):
            given.update({k: "--set material" for k, v in value.items() if v is not None})
    young = [k for k in ("E", "nu") if k in given]
    lame = [k for k in ("lambda", "mu") if k in given]
    if young and lame:
        def named(keys):
            return ", ".join(f"material.{k} ({given[k]})" for k in keys)
        raise SceneError(f"material.{young[0]}: give either E and nu or lambda and mu, not "
                         f"both; got {named(young)} and {named(lame)}")


def load(name_or_path: str, overrides: list[str] = ()) -> dict:
    """A built-in scene by name, or a TOML scene file by path."""
    path = pathlib.Path(name_or_path)
    if not path.suffix and (SCENE_DIR / f"{name_or_path}.toml").exists():
        path = SCENE_DIR / f"{name_or_path}.toml"
    if not path.is_file():          # a device or a pipe could be read for ever
        raise SceneError(f"no scene '{name_or_path}': not a built-in scene "
                         f"({', '.join(builtin_names())}) and no such file")
    try:
        text = _read_text(path)
        raw = tomllib.loads(text)
    except (OSError, UnicodeDecodeError) as err:
        raise SceneError(f"cannot read scene file {path}: {err}") from None
    except tomllib.TOMLDecodeError as err:
        raise SceneError(f"{path}: {err}") from None
    try:
        return resolve(raw, overrides)
    except SceneError as err:
        raise located(err, path, text, overrides) from None


def located(err: SceneError, path, text: str, overrides) -> SceneError:
    """The error with the origin of the value it names appended (once)."""
    if err.located:
        return err
    out = SceneError(f"{err}{origin(str(err), pathlib.Path(path), text, overrides)}")
    out.located = True
    return out


def locate(err: SceneError, name_or_path: str, overrides=()) -> SceneError:
    """`located` for an error raised after loading (while building): the scene file is read
    again to find the line."""
    path = pathlib.Path(name_or_path)
    if not path.suffix and (SCENE_DIR / f"{name_or_path}.toml").exists():
        path = SCENE_DIR / f"{name_or_path}.toml"
    try:
        text = _read_text(path)
    except (OSError, UnicodeDecodeError, SceneError):
        text = ""
    return located(err, path, text, overrides)


#: Largest scene file read (a scene is a page of TOML; /dev/zero is not one).
MAX_SCENE_BYTES = 1_000_000


def _read_text(path: pathlib.Path) -> str:
    with open(path, "rb") as f:
        data = f.read(MAX_SCENE_BYTES + 1)
    if len(data) > MAX_SCENE_BYTES:
        raise SceneError(f"scene file {path} is larger than {MAX_SCENE_BYTES} bytes: not a "
                         "scene")
    return data.decode()


def origin(message: str, path, text: str, overrides) -> str:
    """Where the value a message names came from: a --set, or a line of the scene file."""
    key = message.split(" ", 1)[0].rstrip(":,")
    dotted = key.replace("[", ".").replace("]", "")
    if dotted.split(".")[0] not in DEFAULTS:
        return ""
    for text_set in reversed(list(overrides)):      # the last --set of a key wins
        set_key = text_set.split("=", 1)[0].strip()
        if dotted == set_key or dotted.startswith(set_key + "."):
            return f" (from {getattr(text_set, 'source', '--set')} {text_set})"
    found = _line_of(dotted, text)
    if found:
        number, line = found
        return f" ({path.name}, line {number}: {line.strip()})"
    last = [part for part in dotted.split(".") if not part.isdigit()][-1]
    for number, line in enumerate(text.splitlines(), start=1):
        if "=" in line and line.split("=", 1)[0].strip() == last:
            return f" ({path.name}, line {number}: {line.strip()})"
    section = f"[[{last}]]"
    for number, line in enumerate(text.splitlines(), start=1):
        if line.strip() == section:
            return f" ({path.name}, line {number}: {section})"
    return " (a default value)"


def _line_of(dotted: str, text: str):
    """(number, line) of the TOML line that sets the dotted key (or a table holding it), with
    the [table] and [[array]] headers followed; None if no line does."""
    prefix, counts, best = [], {}, None
    for number, line in enumerate(text.splitlines(), start=1):
        stripped = line.split("#", 1)[0].strip()
        if stripped.startswith("[[") and stripped.endswith("]]"):
            name = stripped[2:-2].strip()
            counts[name] = counts.get(name, -1) + 1
            prefix = [name, str(counts[name])]
            full = ".".join(prefix)
            if dotted == full or dotted.startswith(full + "."):
                best = best or (number, line)
            continue
        if stripped.startswith("[") and stripped.endswith("]"):
            prefix = stripped[1:-1].strip().split(".")
            continue
        if "=" in stripped:
            key = stripped.split("=", 1)[0].strip().strip('"')
            full = ".".join(prefix + [key])
            if dotted == full or dotted.startswith(full + "."):
                return number, line
    return best


def apply_preset(scene: dict, name: str) -> None:
    """Scale the scene's discretization by the preset `name` (see PRESETS)."""
    if not isinstance(name, str) or name not in PRESETS:
        hint = difflib.get_close_matches(str(name), list(PRESETS), n=1)
        raise SceneError(f"unknown preset '{name}'" + (f" (did you mean '{hint[0]}'?)" if hint
                                                       else "")
                         + f"; allowed: {', '.join(PRESETS)}")
    preset = PRESETS[name]
    geo = scene["geometry"]

    def integer(x):     # only valid values are scaled; check() refuses the others as given
        return isinstance(x, int) and not isinstance(x, bool) and x >= 1

    if geo["type"] == "box":
        if isinstance(geo["cells"], list) and all(integer(n) for n in geo["cells"]):
            geo["cells"] = [max(1, round(n * preset["mesh"])) for n in geo["cells"]]
    elif isinstance(geo["parameters"], dict):
        geo["parameters"] = {k: (v / preset["mesh"] if is_mesh_size(k) and not
                                 isinstance(v, bool) and isinstance(v, (int, float)) else v)
                             for k, v in geo["parameters"].items()}
    if integer(scene["time"]["steps"]):
        scene["time"]["steps"] = max(1, round(scene["time"]["steps"] * preset["steps"]))
    scene["time"]["rule"] = preset["rule"]
    scene["discretization"]["degree"] = preset["degree"]
    if preset["degree"] > 1:
        scene["discretization"]["contact_quadrature"] = "gauss"


def is_mesh_size(key: str) -> bool:
    """A gmsh script parameter that is a mesh size: h or h_<where> (not height)."""
    return key == "h" or key.startswith("h_")


def _lame_to_young(material: dict) -> None:
    lam, mu = material["lambda"], material["mu"]
    if lam is None and mu is None:
        return
    def number(v):
        return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
    if not (number(lam) and number(mu) and mu > 0 and lam + mu > 0):
        raise SceneError(f"material.lambda and material.mu must both be given with mu > 0 and "
                         f"lambda + mu > 0, got lambda = {lam}, mu = {mu}")
    material["E"] = mu * (3 * lam + 2 * mu) / (lam + mu)
    material["nu"] = lam / (2 * (lam + mu))


def dimension(scene: dict) -> int:
    return 3 if scene["material"]["model"] == "3d" else 2


def check(scene: dict) -> None:
    """Reject values the model cannot use, before anything is built."""
    def need(ok, message):
        if not ok:
            raise SceneError(message)

    def finite(x):
        return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)

    def integer(x):
        return isinstance(x, int) and not isinstance(x, bool)

    def modulus(x):
        return finite(x) and 1.0 / MODULUS_RANGE <= abs(x) <= MODULUS_RANGE

    for key, default in DEFAULTS.items():
        if isinstance(default, dict) and default:
            need(isinstance(scene[key], dict),
                 f"{key} must be a table ([{key}] in TOML), got {scene[key]!r}")
    for key in ("name", "description"):
        need(isinstance(scene[key], str), f"{key} must be a string, got {scene[key]!r}")
    # The name is the default output folder results/<name>: one plain folder name.
    need(0 < len(scene["name"]) <= 100 and "/" not in scene["name"]
         and "\\" not in scene["name"] and scene["name"] not in (".", "..")
         and scene["name"].isprintable(),
         f"name must be a plain folder name (1 to 100 printable characters, no '/' or '\\',"
         f" not '.' or '..'): it is the default output folder results/<name>; "
         f"got {scene['name']!r}")
    for table, key in (("output", "xdmf"), ("output", "figures"), ("output", "checkpoint"),
                       ("time", "allow_unstable")):
        need(isinstance(scene[table][key], bool),
             f"{table}.{key} must be true or false, got {scene[table][key]!r}")

    def number_list(value, where, length=None):
        need(isinstance(value, list) and all(finite(v) for v in value)
             and (length is None or len(value) == length),
             f"{where} must be a list of {length or 'any number of'} finite numbers, "
             f"got {value!r}")

    def table_list(key, required):
        items = scene[key]
        need(isinstance(items, list) and all(isinstance(i, dict) for i in items),
             f"{key} must be a list of tables ([[{key}]] in TOML), got {items!r}")
        for i, item in enumerate(items):
            missing = [r for r in required if r not in item]
            need(not missing, f"{key}[{i}] needs {', '.join(missing)}")
            unknown = sorted(set(item) - set(ITEM_KEYS[key]))
            need(not unknown, f"{key}[{i}].{unknown[0] if unknown else ''}: unknown key; a "
                              f"[[{key}]] table has {', '.join(ITEM_KEYS[key])}")

    geo, mat, mem, time = scene["geometry"], scene["material"], scene["memory"], scene["time"]
    d = dimension(scene)
    for key in ("lower", "upper", "cells"):
        need(isinstance(geo[key], list), f"geometry.{key} must be a list, got {geo[key]!r}")
    need(finite(geo["rotation"]), f"geometry.rotation must be a finite number of degrees, "
                                  f"got {geo['rotation']!r}")
    table_list("dirichlet", ["boundary"])
    table_list("traction", ["boundary", "value"])
    for i, item in enumerate(scene["dirichlet"]):
        comps = item.get("components", "all")
        need(comps == "all" or (isinstance(comps, list) and all(
            isinstance(c, int) and not isinstance(c, bool) and 0 <= c < d for c in comps)),
            f"dirichlet[{i}].components must be 'all' or a list of components 0..{d - 1} of "
            f"a {d}D displacement, got {comps!r}")
    for key in ("dirichlet", "traction"):
        for i, item in enumerate(scene[key]):
            need(isinstance(item["boundary"], str),
                 f"{key}[{i}].boundary must be a boundary name, got {item['boundary']!r}")
    for i, item in enumerate(scene["traction"]):
        need(isinstance(item["value"], list) and len(item["value"]) == d,
             f"traction[{i}].value must be a list of {d} components, got {item['value']!r}")
    body = scene["body_force"]["value"]
    need(body is None or (isinstance(body, list) and len(body) == d),
         f"body_force.value must be a list of {d} components, got {body!r}")
    probes = scene["output"]["probes"]
    need(isinstance(probes, list), f"output.probes must be a list of points, got {probes!r}")
    for i, point in enumerate(probes):
        number_list(point, f"output.probes[{i}]", d)
    number_list(scene["output"]["figure_times"], "output.figure_times")
    need(scene["contact"] is None or isinstance(scene["contact"], dict),
         f"contact must be a table, got {scene['contact']!r}")
    need(mat["model"] in ("plane_stress", "plane_strain", "3d"),
         f"material.model must be plane_stress, plane_strain or 3d, got '{mat['model']}'")
    need(geo["type"] in ("box", "gmsh"), f"geometry.type must be box or gmsh, got '{geo['type']}'")
    if geo["type"] == "box":
        need(len(geo["lower"]) == d and len(geo["upper"]) == d and len(geo["cells"]) == d,
             f"geometry.lower, upper and cells need {d} entries for material.model = "
             f"'{mat['model']}', got {geo['lower']}, {geo['upper']}, {geo['cells']}")
        need(all(isinstance(n, int) and not isinstance(n, bool) and n >= 1
                 for n in geo["cells"]),
             f"geometry.cells must be positive integers, got {geo['cells']}")
        need(math.prod(geo["cells"]) <= MAX_BOX_CELLS,
             f"geometry.cells = {geo['cells']} asks for {math.prod(geo['cells']):.3g} boxes "
             f"(at most {MAX_BOX_CELLS:.0g}: the mesh is made on one rank before it is "
             "distributed)")
        need(geo["diagonal"] in ("left", "right", "crossed", "left_right", "right_left"),
             f"geometry.diagonal must be left, right, crossed, left_right or right_left, "
             f"got '{geo['diagonal']}'")
        need(all(finite(a) and finite(b) and b > a for a, b in zip(geo["lower"], geo["upper"])),
             f"geometry.upper must exceed geometry.lower, got {geo['lower']}, {geo['upper']}")
        need(all(abs(a) <= MODULUS_RANGE and abs(b) <= MODULUS_RANGE
                 and b - a >= 1 / MODULUS_RANGE for a, b in zip(geo["lower"], geo["upper"])),
             f"geometry.lower and upper must lie within +-{MODULUS_RANGE:g} and be at least "
             f"{1 / MODULUS_RANGE:g} apart (change the units), got {geo['lower']}, "
             f"{geo['upper']}")
    else:
        need((geo["script"] is None) != (geo["file"] is None),
             "geometry.type = 'gmsh' needs exactly one of geometry.script or geometry.file")
        if geo["script"] is not None:
            _check_script(geo, d)
        else:
            need(isinstance(geo["file"], str) and geo["file"].endswith(".msh"),
                 f"geometry.file must be a gmsh .msh file, got {geo['file']!r} (a .geo file "
                 "is a gmsh script, which can run commands: mesh it into a .msh first)")
            need(not geo["parameters"], "geometry.parameters belong to a geometry.script; a "
                                        "geometry.file has none")
    need(finite(mat["E"]) and mat["E"] > 0, f"material.E must be > 0, got {mat['E']}")
    need(modulus(mat["E"]), f"material.E must lie in [{1 / MODULUS_RANGE:g}, "
                            f"{MODULUS_RANGE:g}] (change the units), got {mat['E']}")
    upper_nu = 1.0 if mat["model"] == "plane_stress" else 0.5
    need(finite(mat["nu"]) and -1.0 < mat["nu"] < upper_nu,
         f"material.nu must lie in (-1, {upper_nu}) for {mat['model']}, got {mat['nu']}")
    need(mem["kernel"] in ("none", "constant", "exponential", "prony", "table", "power",
                           "fractional"),
         f"memory.kernel must be none, constant, exponential, prony, table, power or "
         f"fractional, got '{mem['kernel']}'")
    if mem["kernel"] in ("power", "fractional"):
        _check_power(mem, need, finite)
    if mem["kernel"] == "constant":
        need(finite(mem["alpha"]), f"memory.alpha must be a number, got {mem['alpha']}")
    if mem["kernel"] == "exponential":
        alphas, taus = _as_list(mem["alpha"]), _as_list(mem["tau"])
        need(len(alphas) == len(taus) and len(taus) > 0,
             "memory.alpha and memory.tau must have the same (non-zero) length")
        need(all(finite(t) and t > 0 for t in taus), f"memory.tau must be > 0, got {taus}")
        need(all(finite(a) for a in alphas), f"memory.alpha must be numbers, got {alphas}")
    if mem["kernel"] == "prony":
        need(isinstance(mem["terms"], list) and len(mem["terms"]) > 0,
             "memory.kernel = 'prony' needs memory.terms = [{alpha, tau, part}, ...]")
        for i, term in enumerate(mem["terms"]):
            need(isinstance(term, dict) and set(term) <= {"alpha", "tau", "part"}
                 and "alpha" in term,
                 f"memory.terms[{i}] must be a table with alpha and optional tau, part; "
                 f"got {term}")
            need(finite(term["alpha"]), f"memory.terms[{i}].alpha must be a number")
            tau = term.get("tau", math.inf)
            need(isinstance(tau, (int, float)) and not isinstance(tau, bool) and tau > 0,
                 f"memory.terms[{i}].tau must be > 0 (inf: constant), got {tau}")
            need(term.get("part", "full") in PARTS,
                 f"memory.terms[{i}].part must be full, deviatoric or volumetric")
    if mem["kernel"] == "table":
        times, values = mem["times"], mem["values"]
        need(len(times) == len(values) and len(times) >= 1,
             "memory.times and memory.values must have the same (non-zero) length")
        need(all(finite(v) for v in list(times) + list(values)),
             "memory.times and memory.values must be finite numbers")
        need(all(b > a for a, b in zip(times, times[1:])),
             "memory.times must increase")
    need(finite(time["T"]) and time["T"] > 0, f"time.T must be > 0, got {time['T']}")
    need(integer(time["steps"]) and time["steps"] >= 1,
         f"time.steps must be an integer >= 1, got {time['steps']}")
    need(time["rule"] in ("paper", "trapezoid"),
         f"time.rule must be paper or trapezoid, got '{time['rule']}'")
    contact = scene["contact"]
    if contact is not None:
        for key in ("stiffness", "mu", "augmentation"):
            need(finite(contact[key]) and contact[key] >= 0,
                 f"contact.{key} must be a finite number >= 0, got {contact[key]}")
        need(contact["augmentation"] > 0, "contact.augmentation must be > 0")
        names = contact["boundary"]
        need(isinstance(names, str) or (isinstance(names, list) and names
                                        and all(isinstance(b, str) for b in names)),
             f"contact.boundary must be a boundary name or a list of names, got {names!r}")
        need(isinstance(contact["g"], (int, float)) and not isinstance(contact["g"], bool)
             and contact["g"] >= 0,
             f"contact.g must be >= 0 (inf: no bound), got {contact['g']}")
        for key in ("stiffness", "augmentation"):
            need(contact[key] == 0 or modulus(contact[key]),
                 f"contact.{key} must be 0 or lie in [{1 / MODULUS_RANGE:g}, "
                 f"{MODULUS_RANGE:g}] (change the units), got {contact[key]}")
        _check_expression(contact["gap"], "contact.gap", d)
        need(contact["stiffness"] > 0 or math.isfinite(contact["g"]),
             "contact.stiffness: a contact boundary needs a compliance stiffness > 0 or a finite "
             "bound g")
        need(contact["friction"] in FRICTION_LAWS,
             f"contact.friction must be one of {', '.join(FRICTION_LAWS)}, got "
             f"{contact['friction']!r}")
        need(contact["slip"] in SLIP_MEASURES,
             f"contact.slip must be one of {', '.join(SLIP_MEASURES)}, got {contact['slip']!r}")
        need(contact["mu"] == 0 or contact["friction"] == "coulomb"
             or (contact["stiffness"] > 0 and contact["g"] > 0),
             f"contact.mu = {contact['mu']} has no effect: the friction bound mu p_nu(u_nu) is "
             "zero without a compliance stiffness > 0 and a layer g > 0; set contact.mu = 0, "
             "or contact.friction = 'coulomb' for a bound mu times the total normal pressure")
    cuts = scene["solver"]["max_cuts"]
    need(isinstance(cuts, int) and not isinstance(cuts, bool) and 0 <= cuts <= 20,
         f"solver.max_cuts must be an integer from 0 to 20, got {cuts!r}")
    solver = scene["solver"]
    need(solver["linear_system"] in ("auto", "condensed", "coupled"),
         f"solver.linear_system must be auto, condensed or coupled, got "
         f"{solver['linear_system']!r}")
    need(solver["linear_solver"] in ("auto", "direct", "iterative"),
         f"solver.linear_solver must be auto, direct or iterative, got "
         f"{solver['linear_solver']!r}")
    if solver["linear_system"] == "condensed" and contact is not None:
        need(scene["discretization"]["contact_quadrature"] == "nodal",
             "solver.linear_system = 'condensed' needs discretization.contact_quadrature = "
             "'nodal' (the conditions must hold node by node); use 'coupled' or 'auto'")
    limit = scene["output"]["snapshot_max_nodes"]
    need((isinstance(limit, int) and not isinstance(limit, bool) and limit >= 0)
         or limit == math.inf,
         f"output.snapshot_max_nodes must be an integer >= 0 or inf, got {limit!r}")
    fields = scene["output"]["fields"]
    allowed = ("u", "sigma", "history_stress", "lambda_nu", "lambda_tau")
    need(isinstance(fields, list) and all(f in allowed for f in fields),
         f"output.fields must be a list of {', '.join(allowed)}, got {fields!r}")
    need(scene["discretization"]["contact_quadrature"] in ("nodal", "gauss"),
         "discretization.contact_quadrature must be nodal or gauss")
    need(integer(scene["discretization"]["degree"]) and scene["discretization"]["degree"]
         in (1, 2), f"discretization.degree must be 1 or 2, got "
                    f"{scene['discretization']['degree']!r}")
    units = scene["units"]
    need(isinstance(units, dict), f"units must be a table (length, force, time), got {units!r}")
    for key, label in units.items():
        need(label is None or isinstance(label, str),
             f"units.{key} must be a text label such as \"mm\", got {label!r}")
    options = scene["solver"]["petsc_options"]
    need(isinstance(options, dict), f"solver.petsc_options must be a table, got {options!r}")
    for key, value in options.items():
        need(key.replace("_", "").isalnum() and not key.startswith("_"),
             f"solver.petsc_options: '{key}' is not a PETSc option name (letters, digits "
             "and _, without the leading '-')")
        need(isinstance(value, (str, int, float, bool)),
             f"solver.petsc_options.{key} must be a string, number or boolean, got {value!r}")
    for i, item in enumerate(scene["dirichlet"]):
        value = item.get("value", 0.0)
        for j, v in enumerate(value if isinstance(value, list) else [value]):
            _check_expression(v, f"dirichlet[{i}].value" + (f"[{j}]" if isinstance(value, list)
                                                             else ""), d)
    for i, item in enumerate(scene["traction"]):
        for j, v in enumerate(item["value"]):
            _check_expression(v, f"traction[{i}].value[{j}]", d)
    for j, v in enumerate(body or []):
        _check_expression(v, f"body_force.value[{j}]", d)
    b = stability_number(scene)
    need(time["rule"] != "paper" or not amplifies(b, time["steps"]) or time["allow_unstable"],
         f"time.steps = {time['steps']}: the paper's time rule is unstable here (b = "
         f"k R(0) (1 + nu) / E = {b:.3g} >= 1, the solution grows without bound); use "
         f"time.steps > {steps_for_stability(time['steps'], b)}, time.rule = 'trapezoid', "
         "or set time.allow_unstable = true to run it anyway")


def amplifies(b: float, steps: int) -> bool:
    """Whether the paper's rule amplifies errors: its scalar analogue (see stability_number) is
    u_1 = (1 - b) u_0 (one forward Euler step), then u_{n+1} = (1 - 3b/2) u_n + b/2 u_{n-1}
    with a root of modulus > 1 once b > 1. A single step amplifies only from b = 2 on."""
    return b >= 1.0 and (steps >= 2 or b >= 2.0)


def steps_for_stability(steps: int, b: float) -> str:
    return f"{math.ceil(steps * b)}" if b < 1e15 else "(far more steps)"


def _check_expression(value, where: str, d: int) -> None:
    """A number, or an expression text that passes the whitelist (only its constant parts are
    computed, to catch overflow and domain errors)."""
    if isinstance(value, str):
        from .expressions import parse
        parse(value, where, d)
    elif isinstance(value, bool) or not isinstance(value, (int, float)) \
            or not math.isfinite(value):
        raise SceneError(f"{where} must be a finite number or an expression string, "
                         f"got {value!r}")


#: Script parameters that are lengths but not extents of the body (a refinement distance).
NOT_EXTENTS = ("refine",)


def is_mesh_size(key: str) -> bool:
    """Mesh-size parameters of the scripts are h and h_<where> (h_bottom, h_contact, ...)."""
    return key == "h" or key.startswith("h_")


def _script_signature(name: str) -> dict:
    """Keyword parameters of build() in meshes/<name>.py with their default values, read from
    the script's syntax tree (nothing is run)."""
    import ast
    tree = ast.parse((MESH_DIR / f"{name}.py").read_text())
    for node in tree.body:
        if isinstance(node, ast.FunctionDef) and node.name == "build":
            names = [a.arg for a in node.args.args][1:]          # after gmsh
            defaults = [ast.literal_eval(v) for v in node.args.defaults]
            return dict(zip(names[len(names) - len(defaults):], defaults))
    return {}


def _check_script(geo: dict, d: int) -> None:
    """geometry.script names a built-in script of meshes/ (never a path), and its parameters
    are the script's, positive and finite, and not so fine that the mesh cannot be made."""
    def need(ok, message):
        if not ok:
            raise SceneError(message)
    scripts = sorted(p.stem for p in MESH_DIR.glob("*.py") if p.stem != "refinement")
    name = geo["script"]
    need(isinstance(name, str) and name in scripts,
         f"geometry.script must be the name of a built-in mesh script ({', '.join(scripts)}), "
         f"not a path; got {name!r}")
    signature = _script_signature(name)
    parameters = geo["parameters"]
    need(isinstance(parameters, dict), f"geometry.parameters must be a table, got "
                                       f"{parameters!r}")
    unknown = sorted(set(parameters) - set(signature))
    need(not unknown, f"geometry.parameters.{unknown[0] if unknown else ''}: meshes/{name}.py "
                      f"has no parameter {', '.join(unknown)}; it has "
                      f"{', '.join(signature)}")
    values = dict(signature, **parameters)
    for key, value in parameters.items():
        need(isinstance(value, (int, float)) and not isinstance(value, bool)
             and math.isfinite(value) and value > 0,
             f"geometry.parameters.{key} must be a finite number > 0 (a length or a mesh "
             f"size), got {value!r}")
    sizes = {k: v for k, v in values.items() if is_mesh_size(k) and v is not None}
    lengths = [v for k, v in values.items() if not is_mesh_size(k) and v is not None
               and k not in NOT_EXTENTS]
    if sizes and lengths:
        finest = min(sizes, key=sizes.get)
        cells = (max(lengths) / sizes[finest]) ** d
        need(cells <= MAX_SCRIPT_CELLS,
             f"geometry.parameters.{finest}: mesh size {sizes[finest]:g} for a body up to "
             f"{max(lengths):g} long would make about {cells:.2g} cells (at most "
             f"{MAX_SCRIPT_CELLS:.0g})")


def _check_power(mem: dict, need, finite):
    """The keys of the power and fractional kernels."""
    kind = mem["kernel"]
    need(finite(mem["alpha"]), f"memory.alpha must be a number for memory.kernel = '{kind}', "
                               f"got {mem['alpha']!r}")
    beta = mem["beta"]
    if kind == "power":
        need(finite(beta) and 0 < beta <= 20,
             f"memory.beta must be a number in (0, 20] for the power kernel, got {beta!r}")
        need(finite(mem["tau"]) and mem["tau"] > 0,
             f"memory.tau must be a number > 0 (the time scale of R = alpha (1 + t/tau)^-beta) "
             f"for the power kernel, got {mem['tau']!r}")
    else:
        need(finite(beta) and 0.01 <= beta <= 0.99,
             f"memory.beta must lie in [0.01, 0.99] for the fractional kernel (t^-beta must "
             f"be integrable at 0), got {beta!r}")
    tol = mem["tolerance"]
    need(finite(tol) and 1e-12 <= tol <= 1e-2,
         f"memory.tolerance must be a number in [1e-12, 1e-2] (relative error of the sum of "
         f"exponentials), got {tol!r}")
    need(mem["part"] in PARTS, f"memory.part must be full, deviatoric or volumetric, got "
                               f"{mem['part']!r}")
    need(mem["summation"] in ("soe", "direct"),
         f"memory.summation must be soe or direct, got {mem['summation']!r}")


def _as_list(x):
    return list(x) if isinstance(x, (list, tuple)) else [x]


def memory_terms(scene: dict) -> list[tuple[float, float, str]]:
    """A Prony kernel as terms [(alpha_i, tau_i, part_i)], tau = inf for the constant kernel;
    empty without memory and for a table kernel (see :func:`memory_table`)."""
    mem = scene["memory"]
    if mem["kernel"] == "constant":
        alpha = float(mem["alpha"])
        return [(alpha, math.inf, "full")] if alpha != 0.0 else []
    if mem["kernel"] == "exponential":
        return [(float(a), float(t), "full")
                for a, t in zip(_as_list(mem["alpha"]), _as_list(mem["tau"])) if a != 0]
    if mem["kernel"] == "prony":
        return [(float(t["alpha"]), float(t.get("tau", math.inf)), t.get("part", "full"))
                for t in mem["terms"] if t["alpha"] != 0]
    return []


def memory_table(scene: dict):
    """(times, values) of a table kernel, else None."""
    mem = scene["memory"]
    if mem["kernel"] == "table" and any(v != 0 for v in mem["values"]):
        return list(map(float, mem["times"])), list(map(float, mem["values"]))
    return None


def memory_power(scene: dict) -> dict | None:
    """The memory table of a power or fractional kernel with alpha != 0, else None."""
    mem = scene["memory"]
    if mem["kernel"] in ("power", "fractional") and mem["alpha"] != 0:
        return mem
    return None


def memory_R0(scene: dict) -> dict[str, float]:
    """R(0) per part: the instantaneous stiffness the memory adds (for the fractional kernel,
    infinite, the mean (1/k) int_0^k R of a step k instead)."""
    power = memory_power(scene)
    if power is not None:
        alpha = float(power["alpha"])
        if power["kernel"] == "fractional":
            k = scene["time"]["T"] / scene["time"]["steps"]
            alpha *= k ** -power["beta"] / math.gamma(2.0 - power["beta"])
        return {power["part"]: alpha}
    table = memory_table(scene)
    if table is not None:
        return {"full": table[1][0]}
    out: dict[str, float] = {}
    for a, _, part in memory_terms(scene):
        out[part] = out.get(part, 0.0) + a
    return out


def stability_number(scene: dict) -> float:
    """b = k |R(0)| / (2 mu): the paper's rule is stable for b < 1 (NOTES: the scalar analogue
    u_{n+1} = (1 - 3b/2) u_n + b/2 u_{n-1}); 2 mu = E / (1 + nu) is the deviatoric modulus."""
    R0 = sum(abs(a) for a in memory_R0(scene).values())
    if R0 == 0.0:
        return 0.0
    k = scene["time"]["T"] / scene["time"]["steps"]
    mat = scene["material"]
    return k * R0 * (1.0 + mat["nu"]) / mat["E"]
