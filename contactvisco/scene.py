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

SCENE_DIR = pathlib.Path(__file__).parent / "scenes"

#: Defaults filled into every scene; a scene file only states what differs.
DEFAULTS: dict = {
    "name": "unnamed",
    "description": "",
    "geometry": {
        "type": "box",            # built-in structured box mesh (2D: triangles, 3D: tetrahedra)
        "lower": [0.0, 0.0],
        "upper": [1.0, 1.0],
        "cells": [32, 32],
        "diagonal": "right",      # 2D triangle diagonal: left, right, crossed, ...
        "rotation": 0.0,          # degrees about the z axis through the origin, applied after
                                  # the boundaries are named (tilted contact boundaries)
    },
    "material": {
        "model": "plane_strain",  # plane_stress | plane_strain | 3d
        "E": 1.0,
        "nu": 0.3,
    },
    "memory": {
        "kernel": "none",         # none | constant | exponential
        "alpha": 0.0,             # kernel amplitude(s): R(t) = sum_i alpha_i exp(-t/tau_i) I
        "tau": [],                # relaxation times (exponential kernel only)
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
    },
    "discretization": {
        "degree": 1,
        "contact_quadrature": "nodal",  # nodal (trapezoid: conditions hold node by node) | gauss
    },
    "solver": {
        "petsc_options": {},      # PETSc options; the command line overrides them
    },
    "output": {
        "probes": [],
        "figure_times": [],       # times (besides T) at which the deformed mesh is drawn
        "xdmf": True,
        "figures": True,
    },
}

#: Defaults of the [contact] table, used when a scene has one.
CONTACT_DEFAULTS = {
    "boundary": "bottom",
    "stiffness": 0.0,        # compliance stiffness c_nu in p_nu(s) = c_nu max(0, s)
    "g": math.inf,           # layer thickness (bound on u_nu); inf: no unilateral bound
    "mu": 0.0,               # friction coefficient, p_tau = mu p_nu
    "augmentation": None,    # augmentation parameter r; None: the stiffness, or E if that is 0
}


class SceneError(ValueError):
    """A scene value that is missing, misspelled or out of range."""


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
        if isinstance(base[key], dict) and isinstance(value, dict):
            out[key] = _merge(base[key], value, f"{where}{key}.")
        else:
            out[key] = copy.deepcopy(value)
    return out


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
    for i, key in enumerate(path[:-1]):
        if isinstance(node, list):
            key = int(key)
        elif key not in node:
            raise SceneError(f"--set: no scene key '{'.'.join(path[:i + 1])}'")
        if node[key] is None and key == "contact":
            node[key] = dict(CONTACT_DEFAULTS)
        node = node[key]
    last = path[-1]
    if isinstance(node, list):
        node[int(last)] = value
        return
    if last not in node:
        hint = difflib.get_close_matches(last, list(node), n=1)
        suggestion = f" (did you mean '{hint[0]}'?)" if hint else ""
        raise SceneError(f"--set: unknown scene key '{'.'.join(path)}'{suggestion}")
    node[last] = value


def resolve(raw: dict, overrides: list[str] = ()) -> dict:
    """Fill defaults into a raw scene dict and apply ``key=value`` overrides."""
    scene = _merge(DEFAULTS, {k: v for k, v in raw.items() if k != "contact"})
    if raw.get("contact") is not None:
        scene["contact"] = _merge(CONTACT_DEFAULTS, raw["contact"], "contact.")
    for text in overrides:
        _apply_set(scene, *parse_assignment(text))
    contact = scene["contact"]
    if contact is not None:
        if isinstance(contact["g"], str):
            contact["g"] = float(contact["g"])
        if contact["augmentation"] is None:
            contact["augmentation"] = contact["stiffness"] or scene["material"]["E"]
    check(scene)
    return scene


def load(name_or_path: str, overrides: list[str] = ()) -> dict:
    """A built-in scene by name, or a TOML scene file by path."""
    path = pathlib.Path(name_or_path)
    if not path.suffix and (SCENE_DIR / f"{name_or_path}.toml").exists():
        path = SCENE_DIR / f"{name_or_path}.toml"
    if not path.exists():
        raise SceneError(f"no scene '{name_or_path}': not a built-in scene "
                         f"({', '.join(builtin_names())}) and no such file")
    try:
        raw = tomllib.loads(path.read_text())
    except tomllib.TOMLDecodeError as err:
        raise SceneError(f"{path}: {err}") from None
    return resolve(raw, overrides)


def dimension(scene: dict) -> int:
    return len(scene["geometry"]["lower"])


def check(scene: dict) -> None:
    """Reject values the model cannot use, before anything is built."""
    def need(ok, message):
        if not ok:
            raise SceneError(message)

    def finite(x):
        return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)

    geo, mat, mem, time = scene["geometry"], scene["material"], scene["memory"], scene["time"]
    d = dimension(scene)
    need(d in (2, 3), f"geometry.lower must have 2 or 3 coordinates, got {geo['lower']}")
    need(len(geo["upper"]) == d and len(geo["cells"]) == d,
         "geometry.lower, geometry.upper and geometry.cells must have the same length")
    need(all(isinstance(n, int) and n >= 1 for n in geo["cells"]),
         f"geometry.cells must be positive integers, got {geo['cells']}")
    need(mat["model"] in ("plane_stress", "plane_strain", "3d"),
         f"material.model must be plane_stress, plane_strain or 3d, got '{mat['model']}'")
    need((mat["model"] == "3d") == (d == 3),
         f"material.model '{mat['model']}' does not fit a {d}D geometry")
    need(finite(mat["E"]) and mat["E"] > 0, f"material.E must be > 0, got {mat['E']}")
    upper_nu = 1.0 if mat["model"] == "plane_stress" else 0.5
    need(finite(mat["nu"]) and -1.0 < mat["nu"] < upper_nu,
         f"material.nu must lie in (-1, {upper_nu}) for {mat['model']}, got {mat['nu']}")
    need(mem["kernel"] in ("none", "constant", "exponential"),
         f"memory.kernel must be none, constant or exponential, got '{mem['kernel']}'")
    if mem["kernel"] == "exponential":
        alphas, taus = _as_list(mem["alpha"]), _as_list(mem["tau"])
        need(len(alphas) == len(taus) and len(taus) > 0,
             "memory.alpha and memory.tau must have the same (non-zero) length")
        need(all(finite(t) and t > 0 for t in taus), f"memory.tau must be > 0, got {taus}")
    need(finite(time["T"]) and time["T"] > 0, f"time.T must be > 0, got {time['T']}")
    need(isinstance(time["steps"], int) and time["steps"] >= 1,
         f"time.steps must be an integer >= 1, got {time['steps']}")
    need(time["rule"] in ("paper", "trapezoid"),
         f"time.rule must be paper or trapezoid, got '{time['rule']}'")
    contact = scene["contact"]
    if contact is not None:
        for key in ("stiffness", "mu", "augmentation"):
            need(finite(contact[key]) and contact[key] >= 0,
                 f"contact.{key} must be a finite number >= 0, got {contact[key]}")
        need(contact["augmentation"] > 0, "contact.augmentation must be > 0")
        need(isinstance(contact["g"], (int, float)) and contact["g"] >= 0,
             f"contact.g must be >= 0 (inf: no bound), got {contact['g']}")
        need(contact["stiffness"] > 0 or math.isfinite(contact["g"]),
             "a contact boundary needs a compliance stiffness > 0 or a finite bound g")
        need(contact["mu"] == 0 or (contact["stiffness"] > 0 and contact["g"] > 0),
             f"contact.mu = {contact['mu']} has no effect: the friction bound mu p_nu(u_nu) is "
             "zero without a compliance stiffness > 0 and a layer g > 0; set contact.mu = 0")
    need(scene["discretization"]["contact_quadrature"] in ("nodal", "gauss"),
         "discretization.contact_quadrature must be nodal or gauss")
    need(scene["discretization"]["degree"] in (1, 2), "discretization.degree must be 1 or 2")


def _as_list(x):
    return list(x) if isinstance(x, (list, tuple)) else [x]


def memory_terms(scene: dict) -> list[tuple[float, float]]:
    """The kernel as Prony terms [(alpha_i, tau_i)], tau = inf for the constant kernel;
    empty when the scene has no memory."""
    mem = scene["memory"]
    if mem["kernel"] == "none":
        return []
    if mem["kernel"] == "constant":
        alpha = float(mem["alpha"])
        return [(alpha, math.inf)] if alpha != 0.0 else []
    return [(float(a), float(t)) for a, t in zip(_as_list(mem["alpha"]), _as_list(mem["tau"]))
            if float(a) != 0.0]


def stability_number(scene: dict) -> float:
    """b = k R(0) / (2 mu): the paper's rule is stable for b < 1 (NOTES: the scalar analogue
    u_{n+1} = (1 - 3b/2) u_n + b/2 u_{n-1}); 2 mu = E / (1 + nu) is the deviatoric modulus."""
    terms = memory_terms(scene)
    if not terms:
        return 0.0
    k = scene["time"]["T"] / scene["time"]["steps"]
    mat = scene["material"]
    return k * sum(a for a, _ in terms) * (1.0 + mat["nu"]) / mat["E"]
