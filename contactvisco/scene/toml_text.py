"""A scene as TOML text that `contactvisco run` reads back to the same scene.

:func:`scene_text` writes either what a scene sets (the values that differ from the defaults
of its tables) or every value. TOML has no null: a key whose value is None (an unset optional
key such as ``geometry.script``) is left out, which is what reading it back gives. The preset
is not written: its scaling is already in the values.
"""
from __future__ import annotations

import json
import math
import re

from contactvisco.scene.tables import TABLE_LISTS, TABLES, Scene

_BARE_KEY = re.compile(r"^[A-Za-z0-9_-]+$")

#: Keys written even at their default value: they say what the scene is.
_ALWAYS = {"geometry": ("type",), "material": ("model",), "memory": ("kernel",),
           "contact": ("boundary",)}


#: Keys a [viscoelastic] table derives (material.E, nu, ...; the whole [memory] table).
_DERIVED = {"material": ("E", "nu", "lambda", "mu"), "memory": tuple(TABLES["memory"].KEYS)}


def _key(name: str) -> str:
    return name if _BARE_KEY.match(name) else json.dumps(name)


def value_text(value) -> str:
    """One TOML value: strings in JSON-compatible basic-string syntax, inf and nan as TOML
    writes them, lists and dicts inline."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if math.isnan(value):
            return "nan"
        if math.isinf(value):
            return "inf" if value > 0 else "-inf"
        return repr(value)
    if isinstance(value, str):
        return json.dumps(value, ensure_ascii=False)
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(value_text(v) for v in value if v is not None) + "]"
    if isinstance(value, dict):
        items = [f"{_key(str(k))} = {value_text(v)}" for k, v in value.items() if v is not None]
        return "{ " + ", ".join(items) + " }" if items else "{}"
    raise TypeError(f"no TOML form for {type(value).__name__}")


def _lines(values: dict) -> list[str]:
    return [f"{_key(name)} = {value_text(v)}" for name, v in values.items() if v is not None]


def document_text(document: dict) -> str:
    """A dict as TOML: its plain values first, then one ``[table]`` per dict and one
    ``[[table]]`` per list of dicts; deeper dicts inline; None values left out.

    Parameters
    ----------
    document : dict
        Values of TOML types, or None.

    Returns
    -------
    str
        The TOML text.
    """
    def is_tables(value):
        return isinstance(value, list) and value and all(isinstance(v, dict) for v in value)
    plain = {k: v for k, v in document.items() if not isinstance(v, dict) and not is_tables(v)}
    lines = _lines(plain)
    for name, value in document.items():
        if isinstance(value, dict):
            lines += ["", f"[{_key(name)}]", *_lines(value)]
        elif is_tables(value):
            for entry in value:
                lines += ["", f"[[{_key(name)}]]", *_lines(entry)]
    return "\n".join(lines).lstrip("\n") + "\n"


def _changed(values: dict, defaults: dict, always) -> dict:
    return {name: v for name, v in values.items()
            if name in always or name not in defaults or v != defaults[name]}


def scene_text(scene: Scene, every_value: bool = False) -> str:
    """The TOML text of a resolved scene.

    Parameters
    ----------
    scene : Scene
        A scene from ``load_scene`` (defaults filled in, checked).
    every_value : bool
        True writes every key, defaults included; False (default) only what differs from the
        defaults of the scene's tables.

    Returns
    -------
    str
        TOML text; ``contactvisco run`` on it gives the same scene.
    """
    document = {"name": scene["name"], "description": scene.get("description")}
    for name in scene:
        if name in document or name == "preset" or scene[name] is None:
            continue
        if name in TABLE_LISTS:          # items hold what was given; defaults apply on use
            defaults = TABLE_LISTS[name].defaults() if every_value else {}
            document[name] = [{**defaults, **item} for item in scene[name]]
            continue
        values = dict(scene[name])
        if scene.get("viscoelastic") is not None and name in _DERIVED \
                and not scene["viscoelastic"].thermal_only():
            # derived from [viscoelastic] when read back: written once, there
            values = {k: v for k, v in values.items() if k not in _DERIVED[name]}
        if name in TABLES and not every_value:
            values = _changed(values, TABLES[name].defaults(), _ALWAYS.get(name, ()))
        if values:
            document[name] = values
    return document_text(document)
