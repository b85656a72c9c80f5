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


def _module_imports(path: pathlib.Path) -> set[str]:
    """The contactvisco modules a file imports, lazy ones included; `from package import
    name` counts as the module package.name where that is a module."""
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("contactvisco"):
            for alias in node.names:
                sub = f"{node.module}.{alias.name}"
                found.add(sub if _module_path(sub) else node.module)
        elif isinstance(node, ast.Import):
            found.update(a.name for a in node.names if a.name.startswith("contactvisco"))
    return found


def _module_path(dotted: str) -> pathlib.Path | None:
    base = PACKAGE.parent.joinpath(*dotted.split("."))
    for path in (base.with_suffix(".py"), base / "__init__.py"):
        if path.exists():
            return path
    return None


def _reachable(graph: dict, start: str) -> set:
    seen, todo = set(), [start]
    while todo:
        for nxt in graph.get(todo.pop(), ()):
            if nxt not in seen:
                seen.add(nxt)
                todo.append(nxt)
    return seen


def _circles(graph: dict) -> set:
    """The import circles of `graph` (module -> imported modules): its strongly connected
    sets of more than one module, each a frozenset."""
    reach = {node: _reachable(graph, node) for node in graph}
    return {frozenset({node} | {other for other in reach[node] if node in reach.get(other, ())})
            for node in graph if any(node in reach.get(o, ()) for o in reach[node] if o != node)}


def _import_graph() -> dict:
    graph = {}
    for path in _modules():
        name = ".".join(path.relative_to(PACKAGE.parent).with_suffix("").parts)
        graph[name] = {m for m in _module_imports(path) if m != name and _module_path(m)
                       and not m.endswith("__init__") and m != "contactvisco"}
    return graph


#: Import circles that were there before the rule, each through a lazy import inside a
#: function; the rule keeps new ones out (and fails when one of these is gone, so that the
#: list shrinks with them).
KNOWN_CIRCLES = {
    frozenset({"contactvisco.fem.kinematics", "contactvisco.fem.problem"}),
    frozenset({"contactvisco.io.checkpoint", "contactvisco.io.output"}),
    frozenset({"contactvisco.solver.check", "contactvisco.solver.time_loop"}),
}


def test_no_import_circle_within_a_floor():
    """Modules of one floor may import each other, but not in a circle (lazy imports inside
    functions included): contactvisco.solver.newton and .interface_newton, for instance,
    share contactvisco.solver.newton_base instead of importing each other."""
    circles = _circles(_import_graph())
    new = sorted(sorted(c) for c in circles - KNOWN_CIRCLES)
    assert not new, f"import circles: {new}"
    assert KNOWN_CIRCLES <= circles, f"gone, drop from KNOWN_CIRCLES: {KNOWN_CIRCLES - circles}"


def test_the_circle_check_sees_a_circle():
    """Control: a circle of three modules is found, with the module that only leads into it
    left out; a chain has none."""
    assert _circles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == {
        frozenset("abc")}
    assert _circles({"a": {"b"}, "b": {"c"}, "c": set()}) == set()
