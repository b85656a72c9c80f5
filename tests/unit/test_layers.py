"""The package's layers: every import inside contactvisco goes down the floors of
docs/architecture.md, so no import cycle is possible and each layer can be read alone."""
import ast
import pathlib

import pytest

from helpers import ROOT

PACKAGE = ROOT / "contactvisco"

#: Floors from the ground up; solver and post stand side by side and do not import each other.
FLOOR = {"errors": 0, "model": 1, "scene": 2, "fem": 3, "io": 4, "solver": 5, "post": 5,
         "studies": 6, "api": 7, "cli": 8, "__main__": 9}


def _layer(dotted: str) -> str | None:
    parts = dotted.split(".")
    return parts[1] if len(parts) > 1 and parts[0] == "contactvisco" else None


def _imports(path: pathlib.Path):
    """(line, imported contactvisco module) for every import in a file, lazy ones included."""
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and node.level:
            yield node.lineno, "relative import"
        elif isinstance(node, ast.ImportFrom) and (node.module or "").startswith("contactvisco"):
            if node.module == "contactvisco":
                for alias in node.names:
                    yield node.lineno, f"contactvisco.{alias.name}"
            else:
                yield node.lineno, node.module
        elif isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.startswith("contactvisco"):
                    yield node.lineno, alias.name


def _modules():
    return sorted(p for p in PACKAGE.rglob("*.py") if p.name != "__init__.py")


def test_every_module_has_a_floor():
    for path in _modules():
        name = ".".join(path.relative_to(PACKAGE.parent).with_suffix("").parts)
        assert _layer(name) in FLOOR, f"{name} is in no layer of {sorted(FLOOR)}"


@pytest.mark.parametrize("path", _modules(), ids=lambda p: str(p.relative_to(PACKAGE)))
def test_imports_go_down(path):
    name = ".".join(path.relative_to(PACKAGE.parent).with_suffix("").parts)
    mine = _layer(name)
    wrong = []
    for line, target in _imports(path):
        if target == "relative import":
            wrong.append(f"line {line}: a relative import (write contactvisco.<layer>...)")
            continue
        theirs = _layer(target)
        if theirs is None or theirs == "__version__" or theirs == mine:
            continue
        if FLOOR[theirs] >= FLOOR[mine]:
            wrong.append(f"line {line}: {target} (floor {FLOOR[theirs]} >= {FLOOR[mine]})")
    assert not wrong, f"{name} imports upward or sideways:\n" + "\n".join(wrong)


def test_the_check_sees_an_upward_import(tmp_path):
    """Control: the parser reports a lazy upward import inside a function."""
    bad = tmp_path / "bad.py"
    bad.write_text("def f():\n    from contactvisco.post import figures\n")
    assert list(_imports(bad)) == [(2, "contactvisco.post")]
