"""What every scene table is made of: a declared key (:class:`Key`: its default, its test, the
words for what it allows), the :class:`Table` that checks its keys and names where a refused
value came from (:class:`Provenance`: a line of the scene file, an override, or the defaults),
and the value tests the declarations share."""
from __future__ import annotations

import copy
import math
import pathlib
import sys

from contactvisco.errors import SceneError
from contactvisco.scene.limits import MODULUS_RANGE


# Value tests, shared by the declarations below.
def finite(x) -> bool:
    if isinstance(x, int) and not isinstance(x, bool) and abs(x) > sys.float_info.max:
        return False                 # math.isfinite would raise OverflowError
    return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)


def integer(x) -> bool:
    return isinstance(x, int) and not isinstance(x, bool)


def modulus(x) -> bool:
    return finite(x) and 1.0 / MODULUS_RANGE <= abs(x) <= MODULUS_RANGE


def one_of(*choices):
    return lambda x: isinstance(x, str) and x in choices


def boolean(x) -> bool:
    return isinstance(x, bool)


def number_list(x) -> bool:
    return isinstance(x, list) and all(finite(v) for v in x)


def repeated(items) -> tuple | None:
    """(first index, second index, entry) of the first entry of `items` that equals an
    earlier one, or None when all differ."""
    seen = {}
    for j, item in enumerate(items):
        key = _hashable(item)
        if key in seen:
            return seen[key], j, item
        seen[key] = j
    return None


def _hashable(value):
    """A key equal for equal values (1 and 1.0 alike, as == has them)."""
    if isinstance(value, dict):
        return ("table", tuple(sorted((str(k), _hashable(v)) for k, v in value.items())))
    if isinstance(value, (list, tuple)):
        return ("list", tuple(_hashable(v) for v in value))
    return value


def is_mesh_size(key: str) -> bool:
    """A gmsh script parameter that is a mesh size: h or h_<where> (not height)."""
    return key == "h" or key.startswith("h_")


def choices(*names) -> str:
    return ", ".join(names[:-1]) + f" or {names[-1]}"


class Key:
    """One scene key: its default, a test of its values (None: checked by the table's rules),
    the words saying what the test allows, and for a list whose entries must differ, the words
    (what an entry is, what to do instead of repeating one: Table.no_repeats); empty: repeats
    are the rules' business."""

    __slots__ = ("default", "test", "allowed", "distinct")

    def __init__(self, default, test=None, allowed: str = "", distinct: tuple = ()):
        self.default, self.test, self.allowed = default, test, allowed
        self.distinct = distinct


def choice(default: str, *names: str) -> Key:
    return Key(default, one_of(*names), choices(*names))


class Provenance:
    """Where the values of a scene came from: the scene file (its name and text) and the
    overrides in the order they were applied (``key=value`` texts or Override objects)."""

    def __init__(self, path=None, text: str = "", overrides=()):
        self.path = pathlib.Path(path) if path is not None else None
        self.text = text
        self.overrides = list(overrides)

    def origin(self, key: str) -> str:
        """" (from --set k=v)", " (file.toml, line N: ...)", " (a default value)" or "" for
        the dotted key (list items as [i] or .i)."""
        dotted = key.replace("[", ".").replace("]", "")
        for given in reversed(self.overrides):       # the last override of a key wins
            set_key = given.split("=", 1)[0].strip()
            if dotted == set_key or dotted.startswith(set_key + "."):
                return f" (from {getattr(given, 'source', '--set')} {_cut(given)})"
        if self.path is None:
            return ""
        found = _line_of(dotted, self.text)
        if found:
            number, line = found
            return f" ({self.path.name}, line {number}: {_cut(line.strip())})"
        return " (a default value)"


def _cut(text: str, most: int = 100) -> str:
    """A text shortened for a message (a scene line may be a megabyte long)."""
    return text if len(text) <= most else f"{text[:most]}... ({len(text)} characters)"


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
            name = stripped.split("=", 1)[0].strip().strip('"')
            full = ".".join(prefix + [name])
            if dotted == full or dotted.startswith(full + "."):
                return number, line
    return best


class Table(dict):
    """A scene table: its values by key, checked against the declarations KEYS and the rules
    of :meth:`rules`; errors name the key and its origin."""

    KEYS: dict[str, Key] = {}

    #: Keys that mean something only in some scenes: name -> (test(table, scene), the words
    #: for what gives the key a meaning, or a callable(table) giving them). A key set to another value than its default where
    #: its test fails is refused, naming the key and what would give it a meaning: one rule
    #: for every such key, in every route (a scene file, --set, the Python interface).
    MEANINGFUL_WHEN: dict = {}

    def __init__(self, values=(), path: str = "", provenance: Provenance | None = None):
        super().__init__(values)
        self.path = path
        self.provenance = provenance

    @classmethod
    def defaults(cls) -> dict:
        return {name: copy.deepcopy(key.default) for name, key in cls.KEYS.items()}

    def key(self, name: str) -> str:
        return f"{self.path}.{name}" if self.path else name

    def origin(self, name: str) -> str:
        return self.provenance.origin(self.key(name)) if self.provenance else ""

    def fail(self, name: str, message: str):
        raise SceneError(f"{message}{self.origin(name)}", key=self.key(name), located=True)

    def need(self, ok: bool, name: str, message: str) -> None:
        if not ok:
            self.fail(name, message)

    def no_repeats(self, name: str, items, what: str, instead: str) -> None:
        """A list-valued key lists each entry once: a repeated entry would act twice, or one
        would override the other, without a word."""
        found = repeated(items) if isinstance(items, list) else None
        if found:
            i, j, item = found
            self.fail(name, f"{self.key(name)} lists {what} {item!r} twice (entries {i} and "
                            f"{j}); {instead}")

    def validate(self, scene: dict) -> None:
        """Each declared test, then the table's rules."""
        for name, key in self.KEYS.items():
            if key.test is not None and name in self and not key.test(self[name]):
                self.fail(name, f"{self.key(name)} must be {key.allowed}, got {self[name]!r}")
            if key.distinct and name in self:
                self.no_repeats(name, self[name], *key.distinct)
        for name, (test, meaning) in self.MEANINGFUL_WHEN.items():
            if self.get(name, self.KEYS[name].default) != self.KEYS[name].default \
                    and not test(self, scene):
                meaning = meaning if isinstance(meaning, str) else meaning(self)
                self.fail(name, f"{self.key(name)} = {self[name]!r} has no meaning in this "
                                f"scene: it takes effect only {meaning}; drop it, or give it "
                                "that meaning")
        self.rules(scene)

    def rules(self, scene: dict) -> None:
        """Rules that involve several keys, or the rest of the scene."""

    def expression(self, name: str, value, d: int, where: str | None = None) -> None:
        """A number, or an expression text that passes the whitelist (only its constant parts
        are computed, to catch overflow and domain errors)."""
        where = where or self.key(name)
        if isinstance(value, str):
            from contactvisco.scene.expressions import parse
            try:
                parse(value, where, d)
            except SceneError as err:
                self.fail(name, str(err))
        elif not finite(value):
            self.fail(name, f"{where} must be a finite number or an expression string, "
                            f"got {value!r}")
