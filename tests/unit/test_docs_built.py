"""The built documentation (build/docs, `make docs`) reads offline: no page loads anything from
the network, the MathJax a page loads is in the build, every formula is inside the elements
MathJax renders (no raw \\( \\), \\[ \\] or $ $ left in the text), and no Markdown table is left
as `| ... |` text. Skipped when the documentation is not built; `make docs` runs it."""
import re

import pytest

from helpers import ROOT

BUILD = ROOT / "build" / "docs"
PAGES = sorted(BUILD.rglob("*.html")) if (BUILD / "index.html").exists() else []

pytestmark = pytest.mark.skipif(not PAGES, reason="the documentation is not built (make docs)")

#: What is not text a reader sees as prose: code, scripts, styles, and the math elements.
_HIDDEN = re.compile(r"<(pre|code|script|style|textarea)\b.*?</\1>"
                     r"|<(span|div) class=\"math\b[^\"]*\">.*?</\2>", re.S)
_TAG = re.compile(r"<[^>]+>")
_REMOTE = re.compile(r"""<(?:script|link|img|iframe)\b[^>]*\b(?:src|href)=["']"""
                     r"""((?:https?:)?//[^"']+)["']""")


def prose(html: str) -> str:
    """The text of a page outside code, scripts and math elements, tags removed."""
    return _TAG.sub(" ", _HIDDEN.sub(" ", html))


def relative(page) -> str:
    return str(page.relative_to(BUILD))


def test_no_page_loads_from_the_network():
    """No script, style sheet, image or frame from a URL (a CDN's MathJax among them)."""
    remote = {relative(page): _REMOTE.findall(page.read_text()) for page in PAGES}
    assert not {page: urls for page, urls in remote.items() if urls}


def test_the_mathjax_of_every_page_with_math_is_in_the_build():
    """A page with math elements loads a MathJax script that is a file of the build, and the
    configuration it names is there too."""
    with_math = 0
    for page in PAGES:
        html = page.read_text()
        if 'class="math' not in html:
            continue
        with_math += 1
        scripts = re.findall(r"<script[^>]*src=\"([^\"]*MathJax[^\"]*)\"", html, re.I)
        assert scripts, f"{relative(page)} has math and loads no MathJax"
        for src in scripts:
            path, _, query = src.partition("?")
            assert (page.parent / path).is_file(), f"{relative(page)}: {path} not in the build"
            config = re.search(r"config=([\w-]+)", query)
            if config:
                assert (page.parent / path).parent.joinpath(
                    "config", f"{config.group(1)}.js").is_file(), src
        # MathJax 2 skips an element of an ignored class (MyST marks every section so)
        # unless the element's class is one it processes.
        if "tex2jax_ignore" in html:
            config = re.search(r'"processClass": "([^"]*)"', html)
            assert config and "math" in config.group(1).split("|"), relative(page)
    assert with_math >= 5          # model.md, the demos and more have math


def test_no_formula_is_left_raw_in_the_text():
    """Outside the math elements no \\( \\), \\[ \\] or $...$ with a TeX command: those would
    show as typed."""
    raw = re.compile(r"\\\(|\\\)|\\\[|\\\]|\$\$|\$[^$\s][^$]*\\[a-zA-Z]+[^$]*\$")
    found = {}
    for page in PAGES:
        hits = raw.findall(prose(page.read_text()))
        if hits:
            found[relative(page)] = hits[:3]
    assert not found


def test_every_markdown_table_is_rendered():
    """No line of prose that looks like a Markdown table row (`| a | b |`): a table that a
    blank line or a missing header broke is left as such text."""
    row = re.compile(r"^\s*\|.*\|\s*$", re.M)
    found = {}
    for page in PAGES:
        text = "\n".join(line for line in prose(page.read_text()).splitlines())
        hits = [m.strip()[:80] for m in row.findall(text) if m.count("|") >= 3]
        if hits:
            found[relative(page)] = hits[:3]
    assert not found


def test_the_checks_see_what_they_check():
    """The helpers find what they look for: a CDN script, raw math, a table row in prose."""
    html = ('<p>a \\(x\\) b</p><span class="math notranslate">\\(y\\)</span>'
            '<script src="https://cdn.example.org/mathjax.js"></script>\n<p>| a | b |</p>')
    assert _REMOTE.findall(html) == ["https://cdn.example.org/mathjax.js"]
    text = prose(html)
    assert "\\(x\\)" in text and "\\(y\\)" not in text and "| a | b |" in text


def test_every_demo_page_shows_its_executed_outputs_and_offers_both_downloads():
    """Each demos/<name>.py has a page that links a download of <name>.py and of <name>.ipynb
    (both in the build, the notebook with the outputs of every code cell that prints or
    draws, and no error), shows printed output, and shows as many images as the notebook
    holds; a demo that draws shows them from the build."""
    import json
    demos = sorted((ROOT / "demos").glob("*.py"))
    assert demos
    pictures = 0
    for demo in demos:
        page = BUILD / "demos" / f"{demo.stem}.html"
        assert page.is_file(), f"no page for demos/{demo.name}"
        html = page.read_text()
        links = dict((suffix, re.search(rf'href="([^"]*/{demo.stem}\.{suffix})"', html))
                     for suffix in ("py", "ipynb"))
        assert all(links.values()), f"{relative(page)}: downloads {links}"
        script = page.parent / links["py"].group(1)
        assert script.read_text() == demo.read_text(), f"{script} is not demos/{demo.name}"
        notebook = json.loads((page.parent / links["ipynb"].group(1)).read_text())
        outputs = [o for c in notebook["cells"] if c["cell_type"] == "code"
                   for o in c.get("outputs", [])]
        assert outputs and not [o for o in outputs if o["output_type"] == "error"], demo.stem
        images = sum("image/png" in o.get("data", {}) for o in outputs)
        shown = re.findall(rf'<img alt="output \d+ of {demo.stem}\.py" src="([^"]+)"', html)
        assert len(shown) == images, f"{relative(page)}: {len(shown)} images of {images}"
        assert all((page.parent / src).is_file() for src in shown)
        pictures += images
        # printed text: a literal block after the code (highlight-none), not only code
        assert 'class="highlight-none' in html, f"{relative(page)} shows no printed output"
    assert pictures >= len(demos)         # the demos draw: at least one figure each on average
