"""The public names' docstrings are numpydoc: every public callable of contactvisco.__all__
(and every public function of the public module tradeoff) has a Parameters section naming each
of its parameters when it takes any, and a Returns (or Yields) section when it returns a
value. The Python reference of the documentation (docs/reference.md) is generated from them.

The sections are parsed with numpydoc.docscrape where numpydoc is installed (Debian's
python3-numpydoc, which `make docs` installs), else by a plain parser of the same layout."""
import ast
import inspect
import re
import textwrap
import types

import pytest

import contactvisco

try:
    from numpydoc.docscrape import NumpyDocString
except ImportError:                       # the PyPI route installs no numpydoc
    NumpyDocString = None


def _plain_sections(doc: str) -> dict[str, list[str]]:
    """Section title -> the names of its entries (lines at the section's base indentation,
    before ' : '), for a numpydoc layout: a title line underlined with dashes."""
    lines = textwrap.dedent(doc).splitlines()
    sections, title, body = {}, None, []
    for i, line in enumerate(lines):
        underline = i + 1 < len(lines) and re.fullmatch(r"\s*-{3,}\s*", lines[i + 1])
        if underline and line.strip():
            if title is not None:
                sections[title] = body
            title, body = line.strip(), []
        elif title is not None and not re.fullmatch(r"\s*-{3,}\s*", line):
            body.append(line)
    if title is not None:
        sections[title] = body
    names = {}
    for title, body in sections.items():
        indents = [len(b) - len(b.lstrip()) for b in body if b.strip()]
        base = min(indents, default=0)
        names[title] = [b.strip().split(" : ")[0] for b in body
                        if b.strip() and len(b) - len(b.lstrip()) == base]
    return names


def sections(doc: str) -> dict[str, list[str]]:
    """'Parameters', 'Returns', 'Yields', 'Raises' -> the names (or types) of their entries."""
    if NumpyDocString is not None:
        parsed = NumpyDocString(doc)
        out = {}
        for title in ("Parameters", "Returns", "Yields", "Raises"):
            out[title] = [p.name or p.type for p in parsed[title]]
        return out
    plain = _plain_sections(doc)
    return {title: plain.get(title, []) for title in ("Parameters", "Returns", "Yields",
                                                      "Raises")}


def documented_names(entries: list[str]) -> set[str]:
    """'E, nu' documents E and nu; '*paths' and '**kwargs' their bare names."""
    return {name.strip().lstrip("*") for entry in entries for name in entry.split(",")}


def parameters(obj) -> list[str] | None:
    """The names a caller passes (self excluded); a class: those of its constructor. None for
    a constructor inherited from a builtin (an exception's message), which has no signature:
    a Parameters section is wanted, its names are not checked."""
    try:
        signature = inspect.signature(obj)
    except (TypeError, ValueError):
        return None
    return [name for name in signature.parameters if name != "self"]


def returns_value(func) -> tuple[bool, bool]:
    """(returns a value, is a generator), from the function's own body (nested functions
    and lambdas left out)."""
    tree = ast.parse(textwrap.dedent(inspect.getsource(func)))
    top = tree.body[0]
    value = generator = False
    stack = list(top.body)
    while stack:
        node = stack.pop()
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda,
                             ast.ClassDef)):
            continue
        if isinstance(node, ast.Return) and node.value is not None and not (
                isinstance(node.value, ast.Constant) and node.value.value is None):
            value = True
        if isinstance(node, (ast.Yield, ast.YieldFrom)):
            generator = True
        stack.extend(ast.iter_child_nodes(node))
    return value, generator


def public_callables():
    found = {}
    for name in contactvisco.__all__:
        if name == "__version__":
            continue
        obj = getattr(contactvisco, name)
        if isinstance(obj, types.ModuleType):
            for inner, member in vars(obj).items():
                if (not inner.startswith("_") and callable(member)
                        and getattr(member, "__module__", None) == obj.__name__):
                    found[f"{name}.{inner}"] = member
        elif callable(obj):
            found[name] = obj
    return found


PUBLIC = public_callables()


def problems(obj) -> list[str]:
    doc = inspect.getdoc(obj) or ""
    if not doc.strip():
        return ["no docstring"]
    found = sections(doc)
    wrong = []
    wanted = parameters(obj)
    if wanted is None:
        if not found["Parameters"]:
            wrong.append("takes parameters but has no Parameters section")
        wanted = []
    if wanted and not found["Parameters"]:
        wrong.append(f"takes {wanted} but has no Parameters section")
    elif wanted:
        missing = [p for p in wanted if p not in documented_names(found["Parameters"])]
        if missing:
            wrong.append(f"Parameters does not name {missing}")
    if inspect.isfunction(obj):
        value, generator = returns_value(obj)
        if value and not found["Returns"]:
            wrong.append("returns a value but has no Returns section")
        if generator and not found["Yields"]:
            wrong.append("yields but has no Yields section")
    return wrong


def test_the_public_names_are_all_seen():
    """The names the reference documents: the interface of contactvisco.__all__ and the
    tradeoff module's functions."""
    for name in ("load_scene", "solve", "Result", "read_results", "builtin_scenes",
                 "pyvista_grid", "SceneError", "NewtonFailure", "hertz", "cattaneo_mindlin",
                 "cattaneo_traction", "quick", "show_images", "tradeoff.tradeoff",
                 "tradeoff.run", "tradeoff.TradeoffError"):
        assert name in PUBLIC, name


@pytest.mark.parametrize("name", sorted(PUBLIC))
def test_numpydoc_sections(name):
    wrong = problems(PUBLIC[name])
    assert not wrong, f"contactvisco.{name}: " + "; ".join(wrong)


def test_the_check_sees_a_missing_section():
    """Control: a function that takes a parameter the docstring does not name, and returns
    a value without a Returns section, is reported twice."""
    def scale(values, factor):
        """Scale values.

        Parameters
        ----------
        values : list of float
            The values.
        """
        return [v * factor for v in values]

    wrong = problems(scale)
    assert any("factor" in w for w in wrong) and any("Returns" in w for w in wrong), wrong


def test_the_plain_parser_reads_numpydoc():
    """The fallback parser agrees with the sections of a real docstring."""
    plain = _plain_sections(inspect.getdoc(contactvisco.load_scene))
    assert plain["Parameters"] == ["name_or_path", "preset", "sets", "**overrides"]
    assert plain["Returns"] == ["dict"]
    assert plain["Raises"] == ["SceneError"]
