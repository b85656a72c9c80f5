"""Sphinx configuration of the contactvisco documentation (`make docs`).

The pages are Markdown (MyST). The Python reference is generated from the docstrings
(autodoc + numpydoc), which imports the package: build with the Python of an environment
that has DOLFINx (`.venv/bin/python -m sphinx ...`). The demos (jupytext percent-format
scripts in demos/) are turned into MyST pages in docs/demos/ when the build starts; they are
not run: each page shows the committed figures of docs/figures/ that its demo draws.
"""
import pathlib
import re
import sys

DOCS = pathlib.Path(__file__).resolve().parent
ROOT = DOCS.parent
sys.path.insert(0, str(ROOT))          # the package of this tree, not an installed copy

project = "contactvisco"
author = "contactvisco developers"
copyright = "2026, contactvisco developers"
release = version = "0.1.0"

extensions = ["myst_parser", "sphinx.ext.autodoc", "sphinx.ext.mathjax", "numpydoc"]
source_suffix = {".md": "markdown"}
root_doc = "index"
exclude_patterns = ["_build", "make_figures.py"]

# MyST: $...$ and $$...$$ math (the demos use both, $$ also inside a paragraph), anchors for
# headings down to ### so that links to #a-section are checked by the build.
myst_enable_extensions = ["dollarmath", "amsmath", "colon_fence", "deflist"]
myst_dmath_double_inline = True
myst_heading_anchors = 3

# The reference: numpydoc sections, signatures without the annotations (the types are in
# the Parameters and Returns sections, in words; the annotations name classes of DOLFINx
# and of the package's inner layers, which have no page to link to).
autodoc_typehints = "none"
autodoc_member_order = "bysource"
numpydoc_show_class_members = False
numpydoc_xref_param_type = False

# MathJax from the build itself (the pages are read offline): MathJax 2 as Debian packages it
# (libjs-mathjax, /usr/share/javascript/mathjax), the parts the TeX input and the CommonHTML
# output need copied into _static/mathjax when the build ends (about 3 MB). Elsewhere, point
# CONTACTVISCO_MATHJAX at a MathJax 2 folder.
MATHJAX_CONFIG = "TeX-AMS_CHTML"
MATHJAX_PARTS = ("MathJax.js", f"config/{MATHJAX_CONFIG}.js", "jax/input/TeX", "jax/element",
                 "jax/output/CommonHTML", "fonts/HTML-CSS/TeX/woff", "extensions")
mathjax_path = f"mathjax/MathJax.js?config={MATHJAX_CONFIG}"
# Setting it selects the MathJax 2 configuration block; the TeX delimiters Sphinx writes
# (\( \) and \[ \]) are MathJax 2's defaults. MyST marks each page's sections
# tex2jax_ignore (so that a $ in the text is left alone): only the math elements are typeset.
mathjax2_config = {"showMathMenu": False, "messageStyle": "none",
                   "tex2jax": {"ignoreClass": "tex2jax_ignore|mathjax_ignore",
                               "processClass": "math|tex2jax_process|mathjax_process"}}

html_theme = "sphinx_rtd_theme"
html_title = "contactvisco"
html_static_path = []
html_show_sourcelink = False

# --- the demos as pages -----------------------------------------------------------------

#: The committed figures of docs/figures/ each demo draws (the same runs, by make figures).
DEMO_FIGURES = {
    "paper": [("paper_deformed_mesh", "Deformed mesh at t = 0.1 and t = 1 (the paper's Fig. 2)"),
              ("paper_contact_reactions", "Reactions of the contact nodes at T = 1, zones "
                                          "shaded (Fig. 3)"),
              ("paper_contact_displacements", "Displacements of the contact nodes at T = 1, "
                                              "zones shaded, bound g drawn (Fig. 4)"),
              ("paper_probes", "Displacement at the probes against time"),
              ("paper_stress", "Von Mises stress on the deformed body at T = 1")],
    "hertz": [("hertz_stress", "Von Mises stress on the quarter cylinder, the contact zone "
                               "zoomed in a second panel"),
              ("hertz_contact_reactions", "Contact pressure against Hertz's profile")],
    "block3d": [("block3d_stress", "Von Mises stress on the deformed block and on its contact "
                                   "face seen from below"),
                ("block3d_contact_status", "Contact nodes at T in the plane of the face, "
                                           "coloured by state")],
    "coulomb": [("coulomb_cattaneo_mindlin", "Tangential traction of the pulled cylinder at "
                                             "a/h = 22 against Cattaneo-Mindlin, nu = 0.49 "
                                             "and 0.3")],
    "tradeoff": [("tradeoff", "Estimated error of the contact pressure against wall time on "
                              "the paper scene: the ladder, its Pareto front, the 5 % target "
                              "and the recommended run")],
}

_CELL = re.compile(r"^# %%(.*)$")


def percent_to_myst(text: str, name: str) -> str:
    """A jupytext percent-format script as a MyST page: markdown cells as text (their
    leading '# ' removed), code cells as Python blocks; the jupytext header is dropped."""
    lines = text.splitlines()
    if lines and lines[0].startswith("# ---"):
        end = next(i for i in range(1, len(lines)) if lines[i].startswith("# ---"))
        lines = lines[end + 1:]
    cells, kind, body = [], None, []
    for line in lines:
        match = _CELL.match(line)
        if match:
            if kind is not None:
                cells.append((kind, body))
            kind, body = ("markdown" if "[markdown]" in match.group(1) else "code"), []
        elif kind is not None:
            body.append(line)
    if kind is not None:
        cells.append((kind, body))
    out = []
    for kind, body in cells:
        while body and not body[-1].strip():
            body.pop()
        while body and not body[0].strip():
            body.pop(0)
        if not body:
            continue
        if kind == "markdown":
            out.append("\n".join(re.sub(r"^# ?", "", line) if line.startswith("#") else line
                                 for line in body))
        else:
            out.append("```python\n" + "\n".join(body) + "\n```")
    out.append(f"*The script: `demos/{name}.py`; run it with `.venv/bin/python demos/{name}.py`"
               f" or open it as a notebook ([the demos](../demos.md)).*")
    figures = DEMO_FIGURES.get(name)
    if figures:
        out.append("## Its figures\n\nAs committed in `docs/figures/` (drawn by "
                   "`make figures`, checked by `tests/integration/test_figures.py`):")
        out.extend(f"![{caption}](../figures/{stem}.png)" for stem, caption in figures)
    return "\n\n".join(out) + "\n"


def write_demo_pages(app):
    """docs/demos/<name>.md for every demos/<name>.py; a page is rewritten only when its
    text changes, so that an unchanged demo is not read again."""
    target = DOCS / "demos"
    target.mkdir(exist_ok=True)
    for script in sorted((ROOT / "demos").glob("*.py")):
        page = target / f"{script.stem}.md"
        text = percent_to_myst(script.read_text(), script.stem)
        if not page.exists() or page.read_text() != text:
            page.write_text(text)


def mathjax_source() -> pathlib.Path:
    """The MathJax 2 folder to copy: CONTACTVISCO_MATHJAX, else Debian's libjs-mathjax."""
    import os
    for folder in (os.environ.get("CONTACTVISCO_MATHJAX"), "/usr/share/javascript/mathjax"):
        if folder and (pathlib.Path(folder) / "MathJax.js").is_file():
            return pathlib.Path(folder)
    from sphinx.errors import ConfigError
    raise ConfigError("MathJax 2 not found: install Debian's libjs-mathjax (apt-get install -y "
                      "libjs-mathjax) or set CONTACTVISCO_MATHJAX to a MathJax 2 folder")


def check_mathjax(app):
    if app.builder.format == "html":
        mathjax_source()


def copy_mathjax(app, exception):
    """The MathJax parts into the build's _static/mathjax (unchanged files are skipped)."""
    import shutil
    if exception is not None or app.builder.format != "html":
        return
    source, target = mathjax_source(), pathlib.Path(app.outdir) / "_static" / "mathjax"
    for part in MATHJAX_PARTS:
        if (source / part).is_dir():
            shutil.copytree(source / part, target / part, dirs_exist_ok=True)
        else:
            (target / part).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(source / part, target / part)


def setup(app):
    app.connect("builder-inited", write_demo_pages)
    app.connect("builder-inited", check_mathjax)
    app.connect("build-finished", copy_mathjax)
