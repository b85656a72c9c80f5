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


#: Circles inside a floor not broken yet, as sets of modules; an entry goes when its circle does
#: (test_known_circles_still_exist fails then, so that the entry is removed with it).
KNOWN_CIRCLES = [
    {"contactvisco.solver.newton", "contactvisco.solver.interface_newton"},
]


def _module_name(path: pathlib.Path) -> str:
    parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _module_graph(root: pathlib.Path = PACKAGE) -> dict:
    """{module: the modules under `root` it imports}, lazy imports included; `from a.b import c`
    counts as an import of a.b.c when c is a module, else of a.b. Outside the package (the
    control below) a module is named by its file's stem."""
    def name(path):
        return _module_name(path) if root == PACKAGE else path.stem

    paths = sorted(root.rglob("*.py"))
    known = {name(p) for p in paths}
    graph = {}
    for path in paths:
        targets = set()
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom) and node.module:
                for alias in node.names:
                    full = f"{node.module}.{alias.name}"
                    targets.add(full if full in known else node.module)
            elif isinstance(node, ast.Import):
                targets.update(alias.name for alias in node.names)
        graph[name(path)] = sorted(t for t in targets if t in known and t != name(path))
    return graph


def _circles(graph: dict) -> list[set]:
    """The strongly connected components of more than one module (each holds a circle)."""
    from scipy.sparse import csr_matrix
    from scipy.sparse.csgraph import connected_components
    names = sorted(graph)
    index = {name: i for i, name in enumerate(names)}
    rows = [index[a] for a in names for _ in graph[a]]
    cols = [index[b] for a in names for b in graph[a]]
    adjacency = csr_matrix(([1] * len(rows), (rows, cols)), shape=(len(names), len(names)))
    count, label = connected_components(adjacency, directed=True, connection="strong")
    groups = [{names[i] for i in range(len(names)) if label[i] == c} for c in range(count)]
    return [g for g in groups if len(g) > 1]


def test_no_circle_inside_a_floor():
    """Modules of one floor may import each other, but never in a circle (a circle makes the
    import order matter and hides which module owns what)."""
    circles = [c for c in _circles(_module_graph()) if c not in KNOWN_CIRCLES]
    assert not circles, "modules that import each other in a circle:\n" + "\n".join(
        " <-> ".join(sorted(c)) for c in circles)


def test_known_circles_still_exist():
    """An entry of KNOWN_CIRCLES whose circle is broken must go, so the list only shrinks."""
    circles = _circles(_module_graph())
    gone = [sorted(c) for c in KNOWN_CIRCLES if c not in circles]
    assert not gone, f"these circles are broken; remove them from KNOWN_CIRCLES: {gone}"


def test_the_check_sees_a_circle(tmp_path):
    """Control: a lazy import that closes a circle of three modules is found, a chain is not."""
    (tmp_path / "a.py").write_text("import b\n")
    (tmp_path / "b.py").write_text("def f():\n    from c import g\n")
    (tmp_path / "c.py").write_text("x = 1\n")
    assert _circles(_module_graph(tmp_path)) == []
    (tmp_path / "c.py").write_text("def g():\n    import a\n")
    assert _circles(_module_graph(tmp_path)) == [{"a", "b", "c"}]
