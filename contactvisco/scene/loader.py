"""Scenes: one TOML document that holds every parameter of a run.

:func:`load` reads a built-in scene by name or a TOML file by path, fills in :data:`DEFAULTS`,
applies ``--set key=value`` overrides (dotted keys, values in TOML syntax) or the Python API's
values, and returns a :class:`~contactvisco.scene.tables.Scene`: a nested dict of typed tables, each
of which checks its own keys and names where a refused value came from. Nothing else in the
package holds a parameter value of its own.
"""
from __future__ import annotations

import copy
import difflib
import math
import numbers
import pathlib
import sys
import tomllib

from contactvisco.model import time_grid
from contactvisco.scene.table import Provenance, finite, is_mesh_size
from contactvisco.scene.tables import TABLE_LISTS, TABLES, Contact, Scene
from contactvisco.scene import viscoelastic_table
from contactvisco.errors import SceneError

SCENE_DIR = pathlib.Path(__file__).parent.parent / "scenes"

#: Defaults filled into every scene; a scene file only states what differs. Each key is
#: declared once, with what it allows, in the tables of contactvisco/tables.py; docs/scenes.md
#: says what each means.
DEFAULTS: dict = Scene.defaults()

#: Speed-accuracy presets, relative to the scene's own discretization: mesh refines the mesh
#: (box cells times mesh; gmsh sizes h, h_* divided by mesh), steps multiplies time.steps.
#: Chosen from the measured trade-off (benchmarks/accuracy/tradeoff.py, README): on the built-in scenes
#: the space error dominates (the time error at the scenes' own k is 20-50 times smaller), so
#: no preset refines time; P2 is faster per error on the paper scene but its Newton diverges
#: on pure Signorini contact (Hertz), so every preset stays P1 with exact nodal conditions.
PRESETS = {
    "fast": {"mesh": 0.5, "steps": 1.0, "degree": 1, "rule": "trapezoid"},
    "balanced": {"mesh": 1.0, "steps": 1.0, "degree": 1, "rule": "trapezoid"},
    "accurate": {"mesh": 2.0, "steps": 1.0, "degree": 1, "rule": "trapezoid"},
}

#: Defaults of the [contact] table, used when a scene has one.
CONTACT_DEFAULTS = Contact.defaults()

#: Defaults of the [viscoelastic] table, used when a scene has one.
VISCOELASTIC_DEFAULTS = viscoelastic_table.Viscoelastic.defaults()

#: Keys of the tables in the lists [[dirichlet]] and [[traction]].
ITEM_KEYS = {name: tuple(table.KEYS) for name, table in TABLE_LISTS.items()}


def builtin_names() -> list[str]:
    return sorted(p.stem for p in SCENE_DIR.glob("*.toml"))


#: Tables whose keys are free: a gmsh script's parameters, PETSc options, a relaxation
#: function (instantaneous, tau with moduli or fractions, a file ...). Given whole (in a file,
#: by `--set 'viscoelastic.shear={...}'` or as a Python dict) such a table replaces the one it
#: overrides, as the file's table would; a declared table is merged key by key.
FREE_FORM = ("geometry.parameters", "solver.petsc_options", "viscoelastic.shear",
             "viscoelastic.bulk", "viscoelastic.young")


def _merge(base: dict, update: dict, where: str = "") -> dict:
    """`base` with the keys of `update` (each checked against `base`'s keys), recursively in
    declared tables; a free-form table of `update` (FREE_FORM, or any whose default is empty)
    replaces its counterpart whole."""
    if where.rstrip(".") in FREE_FORM:
        return copy.deepcopy(update)
    out = copy.deepcopy(base)
    for key, value in update.items():
        if key not in base:
            hint = difflib.get_close_matches(key, list(base), n=1)
            suggestion = f" (did you mean '{hint[0]}'?)" if hint else ""
            raise SceneError(f"unknown scene key '{where}{key}'{suggestion}; "
                             f"allowed here: {', '.join(sorted(base))}", key=f"{where}{key}")
        # An empty default table is free-form (geometry.parameters, solver.petsc_options).
        if isinstance(base[key], dict) and base[key] and isinstance(value, dict) \
                and f"{where}{key}" not in FREE_FORM:
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

    def __getnewargs__(self):          # copy and pickle rebuild it from (path, value)
        return self.assignment


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
    except RecursionError:
        raise SceneError(f"--set {key.strip()}: the value nests arrays or tables too deeply "
                         f"(at most {MAX_DEPTH} levels)", key=key.strip()) from None
    if isinstance(value, str) and value.lower() in ("inf", "+inf"):
        value = math.inf
    return key.strip().split("."), value


def _apply_set(scene: dict, path: list[str], value, source: str = "--set") -> None:
    """scene[path] = value, for an override from `source` (--set or load_scene)."""
    node = scene
    for i, key in enumerate(path):
        dotted = ".".join(path[:i + 1])
        if isinstance(node, list):
            if not (key.isdigit() and int(key) < len(node)):
                raise SceneError(f"{source} {dotted}: '{'.'.join(path[:i])}' is a list of "
                                 f"{len(node)} table(s); the index must be 0..{len(node) - 1}")
            key = int(key)
        elif not isinstance(node, dict):
            raise SceneError(f"{source} {dotted}: '{'.'.join(path[:i])}' is a value "
                             f"({node!r}), not a table with keys")
        if i == len(path) - 1:
            break
        if isinstance(node, dict) and key not in node and _item_table(path[:i + 1]):
            node[key] = {}                     # a [[body]] item's [material] or [memory]
        if isinstance(node, dict) and key not in node:
            raise SceneError(f"{source}: no scene key '{dotted}'")
        if node[key] is None and key == "contact":
            node[key] = dict(CONTACT_DEFAULTS)
        if node[key] is None and key == "viscoelastic" and i == 0:
            node[key] = dict(VISCOELASTIC_DEFAULTS)
        if node[key] is None and path[0] == "viscoelastic" and i == 1:
            node[key] = {}                     # a relaxation function, free-form

        node = node[key]
    last = key
    if isinstance(node, list):
        node[last] = value
        return
    free_form = tuple(path[:-1]) in (("geometry", "parameters"), ("solver", "petsc_options"),
                                     *(("viscoelastic", f) for f in ("shear", "bulk", "young")))
    allowed = ITEM_KEYS.get(path[0], ()) if len(path) == 3 else \
        tuple(_item_table(path[:-1]) or node)
    if last not in node and last not in allowed and not free_form:
        hint = difflib.get_close_matches(last, list(allowed), n=1)
        suggestion = f" (did you mean '{hint[0]}'?)" if hint else ""
        raise SceneError(f"{source}: unknown scene key '{'.'.join(path)}'{suggestion}")
    table = node.get(last) or {"contact": CONTACT_DEFAULTS, "viscoelastic":
                               VISCOELASTIC_DEFAULTS}.get(".".join(path))
    if isinstance(table, dict) and ".".join(path) in FREE_FORM and isinstance(value, dict):
        pass                                   # a free-form table given whole replaces it
    elif isinstance(table, dict) and table and not free_form:
        # A whole table: its keys are checked and the defaults kept.
        if not isinstance(value, dict):
            raise SceneError(f"{source} {'.'.join(path)}: '{'.'.join(path)}' is a table; set "
                             f"its keys ({'.'.join(path)}.{next(iter(table))}=...) or give "
                             f"a table {{...}}, got {value!r}")
        value = _merge(table, value, f"{'.'.join(path)}.")
    node[last] = value


def _item_table(path: list) -> dict | None:
    """The declared keys of a table inside an item of a list of tables (body.0.material:
    the keys of [material]), or None for any other path."""
    if len(path) == 3 and path[0] in TABLE_LISTS and path[1].isdigit():
        default = TABLE_LISTS[path[0]].KEYS.get(path[2])
        if default is not None and isinstance(default.default, dict) and path[2] in TABLES:
            return TABLES[path[2]].KEYS
    return None


def resolve(raw: dict, overrides: list[str] = (), provenance: Provenance | None = None) -> Scene:
    """Fill defaults into a raw scene dict, apply ``key=value`` overrides, and check the
    result table by table (errors name the value's origin from `provenance`)."""
    provenance = provenance or Provenance(overrides=overrides)
    check_plain(raw, provenance)               # before any check computes with a number
    optional = {"contact": CONTACT_DEFAULTS, "viscoelastic": VISCOELASTIC_DEFAULTS}
    scene = _merge(DEFAULTS, {k: v for k, v in raw.items() if k not in optional})
    for name, defaults in optional.items():
        if raw.get(name) is not None:
            if not isinstance(raw[name], dict):
                raise SceneError(f"{name} must be a table, got {raw[name]!r}", key=name)
            scene[name] = _merge(defaults, raw[name], f"{name}.")
    # An override is `key=value` text (--set) or an Override (the Python API's values).
    assignments = [getattr(text, "assignment", None) or parse_assignment(text)
                   for text in overrides]
    for path, value in assignments:
        check_plain({".".join(path): value}, provenance)
    _check_material_pairs(raw.get("material", {}), overrides, assignments)
    viscoelastic_table.check_alone(raw, assignments)
    for path, value in assignments:          # a preset from --set first, then the rest
        if path == ["preset"]:
            scene["preset"] = value
    if scene["preset"] is not None:
        apply_preset(scene, scene["preset"])
    for text, (path, value) in zip(overrides, assignments):
        if path != ["preset"]:
            _apply_set(scene, path, value, getattr(text, "source", "--set"))
    check_plain(scene, provenance)
    scene = Scene.build(scene, provenance)
    scene["material"].normalize()
    if scene["viscoelastic"] is not None:
        base = provenance.path.parent if provenance.path is not None else None
        scene["viscoelastic"].convert(scene, base)
    if scene["contact"] is not None:
        scene["contact"].normalize(scene["material"])
    scene.validate()
    scene.as_loaded = plain_copy(scene)
    return scene


def _check_material_pairs(raw_material, overrides, assignments) -> None:
    """Either (E, nu) or (lambda, mu), from the file and overrides together: a value of one pair
    next to the other pair would be dropped without a word."""
    if not isinstance(raw_material, dict):
        raise SceneError(f"material must be a table, got {raw_material!r}", key="material")
    given = {k: "the scene file" for k, v in raw_material.items() if v is not None}
    for text, (path, value) in zip(overrides, assignments):
        source = getattr(text, "source", "--set")
        if path[0] == "material" and len(path) == 2 and value is not None:
            given[path[1]] = f"{source} material.{path[1]}"
        elif path == ["material"] and isinstance(value, dict):
            given.update({k: f"{source} material" for k, v in value.items() if v is not None})
    young = [k for k in ("E", "nu") if k in given]
    lame = [k for k in ("lambda", "mu") if k in given]
    if young and lame:
        def named(keys):
            return ", ".join(f"material.{k} ({given[k]})" for k in keys)
        raise SceneError(f"material.{young[0]}: give either E and nu or lambda and mu, not "
                         f"both; got {named(young)} and {named(lame)}", key="material",
                         located=True)


def load(name_or_path: str, overrides: list[str] = ()) -> Scene:
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
    except RecursionError:
        raise SceneError(f"{path}: arrays or tables nested too deeply to be read (a scene "
                         f"nests a few levels, at most {MAX_DEPTH})") from None
    provenance = Provenance(path, text, overrides)
    try:
        return resolve(raw, overrides, provenance)
    except SceneError as err:
        # Errors of the merge (unknown keys, a value where a table belongs) name a key too.
        if err.located or err.key is None:
            raise
        raise SceneError(f"{err}{provenance.origin(err.key)}", key=err.key,
                         located=True) from None


#: Largest scene file read (a scene is a page of TOML; /dev/zero is not one).
MAX_SCENE_BYTES = 1_000_000


def _read_text(path: pathlib.Path) -> str:
    with open(path, "rb") as f:
        data = f.read(MAX_SCENE_BYTES + 1)
    if len(data) > MAX_SCENE_BYTES:
        raise SceneError(f"scene file {path} is larger than {MAX_SCENE_BYTES} bytes: not a "
                         "scene")
    return data.decode()


def apply_preset(scene: dict, name: str) -> None:
    """Scale the scene's discretization by the preset `name` (see PRESETS)."""
    if not isinstance(name, str) or name not in PRESETS:
        hint = difflib.get_close_matches(str(name), list(PRESETS), n=1)
        suggestion = f" (did you mean '{hint[0]}'?)" if hint else ""
        raise SceneError(f"unknown preset '{name}'{suggestion}; allowed: {', '.join(PRESETS)}",
                         key="preset")
    preset = PRESETS[name]
    geo = scene["geometry"]

    def integer(x):     # only valid values are scaled; the tables refuse the others as given
        return isinstance(x, int) and not isinstance(x, bool) and x >= 1

    if geo["type"] == "box":
        if isinstance(geo["cells"], list) and all(integer(n) for n in geo["cells"]):
            geo["cells"] = [max(1, round(n * preset["mesh"])) for n in geo["cells"]]
    elif isinstance(geo["parameters"], dict):
        geo["parameters"] = {k: (v / preset["mesh"] if is_mesh_size(k) and not
                                 isinstance(v, bool) and isinstance(v, (int, float)) else v)
                             for k, v in geo["parameters"].items()}
    # every kind of grid made preset["steps"] times as dense (time_grid.scaled)
    scene["time"].update(time_grid.scaled(scene["time"], preset["steps"]))
    if scene["time"].get("grid") != "adaptive":      # its estimate is the exponential rule's
        scene["time"]["rule"] = preset["rule"]
    scene["discretization"]["degree"] = preset["degree"]
    if preset["degree"] > 1:
        scene["discretization"]["contact_quadrature"] = "gauss"


# The scene where it is used: solve() and check() take a dict that Python code may have
# changed after load_scene; it is checked again here, with load_scene's messages.

#: Deepest nesting of arrays and tables in a scene (a scene nests three or four levels).
MAX_DEPTH = 32

#: Largest magnitude of a number in a scene: what a double holds.
MAX_NUMBER = sys.float_info.max


def plain_copy(value, depth: int = 0):
    """`value` as plain dicts, lists and scalars (tables, numpy scalars and arrays, tuples
    converted as the TOML reader would give them)."""
    if depth > MAX_DEPTH:
        raise SceneError(f"the scene nests arrays or tables more than {MAX_DEPTH} levels deep")
    if isinstance(value, bool) or value is None or isinstance(value, str):
        return value
    if isinstance(value, numbers.Integral):
        return int(value)
    if isinstance(value, numbers.Real):
        return float(value)
    if isinstance(value, dict):
        return {k: plain_copy(v, depth + 1) for k, v in value.items()}
    if isinstance(value, (list, tuple)) or hasattr(value, "tolist"):
        items = value.tolist() if hasattr(value, "tolist") else value
        if not isinstance(items, list):          # a numpy scalar's tolist() is a scalar
            return plain_copy(items, depth + 1)
        return [plain_copy(v, depth + 1) for v in items]
    return value


def check_plain(scene: dict, provenance: Provenance | None = None) -> None:
    """Every value of the scene is a float-sized number, a string, a boolean or a list or
    table of them nested at most MAX_DEPTH levels: an integer such as 10**400 (valid TOML) is
    refused naming its key, before any check computes with it."""
    stack = [("", scene, 0)]
    while stack:
        where, value, depth = stack.pop()
        if depth > MAX_DEPTH:
            key = ".".join(where.split("[")[0].split(".")[:3])
            raise SceneError(f"{key}: arrays or tables nested more than {MAX_DEPTH} levels "
                             "deep" + _origin(provenance, key), key=key, located=True)
        if isinstance(value, dict):
            stack.extend((f"{where}.{k}" if where else str(k), v, depth + 1)
                         for k, v in value.items())
        elif isinstance(value, (list, tuple)):
            stack.extend((f"{where}[{i}]", v, depth + 1) for i, v in enumerate(value))
        elif (isinstance(value, numbers.Integral) and not isinstance(value, bool)
              and abs(int(value)) > MAX_NUMBER):
            raise SceneError(f"{where} = {_short(value)} does not fit a floating-point number "
                             f"(at most {MAX_NUMBER:.3g} in magnitude; change the units)"
                             + _origin(provenance, where), key=where, located=True)


def _short(value) -> str:
    """A number of any size, shortened for a message (10**400 has 401 digits)."""
    text = str(value) if not isinstance(value, int) or abs(value) < 10 ** 30 else \
        f"{'-' if value < 0 else ''}{str(abs(value))[:6]}... ({len(str(abs(value)))} digits)"
    return text


def _origin(provenance, where: str) -> str:
    return provenance.origin(where) if provenance is not None else ""


class ChangedProvenance(Provenance):
    """The provenance of a loaded scene, for a scene changed in Python after load_scene: a
    changed value is said to be so, the others keep their file line or override."""

    def __init__(self, loaded: Provenance | None, changed: set):
        super().__init__(getattr(loaded, "path", None), getattr(loaded, "text", ""),
                         getattr(loaded, "overrides", ()))
        self.loaded, self.changed = loaded, changed

    def origin(self, key: str) -> str:
        dotted = key.replace("[", ".").replace("]", "")
        if any(dotted == c or dotted.startswith(c + ".") or c.startswith(dotted + ".")
               for c in self.changed):
            return " (changed in Python after load_scene)"
        return self.loaded.origin(key) if self.loaded is not None else " (given to solve)"


def _changes(old, new, where: str = "") -> set:
    """The dotted keys (list items as key.i) whose values differ between two plain scenes."""
    if isinstance(old, dict) and isinstance(new, dict):
        out = set()
        for key in set(old) | set(new):
            inner = f"{where}.{key}" if where else str(key)
            if key not in old or key not in new:
                out.add(inner)
            else:
                out |= _changes(old[key], new[key], inner)
        return out
    if isinstance(old, list) and isinstance(new, list) and len(old) == len(new):
        out = set()
        for i, (a, b) in enumerate(zip(old, new)):
            out |= _changes(a, b, f"{where}.{i}")
        return out
    same = type(old) is type(new) and (old == new or (old != old and new != new))
    return set() if same else {where}


def differences(old: dict, new: dict) -> set:
    """The dotted keys whose values differ between two plain scenes (list items as key.i).

    Parameters
    ----------
    old, new : dict
        Scenes as plain values (`plain_copy`).

    Returns
    -------
    set of str
        The keys k with old[k] != new[k] (NaN equal to NaN), those in one scene only
        included.
    """
    return _changes(old, new)


def check_given(scene: dict) -> Scene:
    """The scene `solve` or `check` was given, checked again as load_scene checks it: a scene
    changed in Python after load_scene (a misspelled choice, a NaN, a new key), or a plain
    dict, is refused with load_scene's messages; a value changed in Python is said to be so.

    Parameters
    ----------
    scene : dict
        A scene from load_scene, maybe changed since, or a dict of the same tables.

    Returns
    -------
    Scene
        The checked scene (a new object; the preset is not applied again, the material's
        E and nu follow lambda and mu when those are given).
    """
    if not isinstance(scene, dict):
        raise SceneError(f"a scene must be a dict from load_scene, got {type(scene).__name__}")
    loaded = getattr(scene, "provenance", None)
    plain = plain_copy(scene)
    before = getattr(scene, "as_loaded", None)
    changed = _changes(before, plain) if before is not None else set()
    provenance = ChangedProvenance(loaded, changed) if (changed or loaded is None) else loaded
    try:
        check_plain(plain, provenance)
        merged = _merge(DEFAULTS, {k: v for k, v in plain.items() if k != "contact"})
        if plain.get("contact") is not None:
            if not isinstance(plain["contact"], dict):
                raise SceneError(f"contact must be a table, got {plain['contact']!r}",
                                 key="contact")
            merged["contact"] = _merge(CONTACT_DEFAULTS, plain["contact"], "contact.")
        out = Scene.build(merged, provenance)
        _material_pairs_agree(out["material"], changed)
        out["material"].normalize()
        if out["contact"] is not None:
            out["contact"].normalize(out["material"])
        out.validate()
    except SceneError as err:
        if err.located or err.key is None:
            raise
        raise SceneError(f"{err}{provenance.origin(err.key)}", key=err.key,
                         located=True) from None
    out.as_loaded = plain_copy(out)
    return out


def _material_pairs_agree(material, changed: set) -> None:
    """A loaded scene holds E and nu computed from lambda and mu when those were given: E or
    nu changed in Python would be overwritten from lambda and mu without a word (lambda or mu
    changed alone: E and nu follow them)."""
    lam, mu = material["lambda"], material["mu"]
    if lam is None and mu is None:
        return
    if not changed & {"material.E", "material.nu"}:
        return                              # normalize() computes E and nu from them
    if not (finite(lam) and finite(mu) and mu > 0 and lam + mu > 0):
        return                              # normalize() refuses them with its message
    young = mu * (3 * lam + 2 * mu) / (lam + mu)
    nu = lam / (2 * (lam + mu))
    E_given, nu_given = material["E"], material["nu"]
    agree = (finite(E_given) and finite(nu_given)
             and math.isclose(E_given, young, rel_tol=1e-12)
             and math.isclose(nu_given, nu, rel_tol=1e-12, abs_tol=1e-15))
    material.need(agree, "E", f"material.E = {E_given!r} and material.nu = {nu_given!r} "
                              f"disagree with material.lambda = {lam!r} and material.mu = "
                              f"{mu!r} (which give E = {young:.6g}, nu = {nu:.6g}): give "
                              "either E and nu or lambda and mu (set the other pair to None)")
