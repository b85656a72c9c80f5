"""Sphinx configuration of the contactvisco documentation (`make docs`).

The pages are Markdown (MyST). The Python reference is generated from the docstrings
(autodoc + numpydoc), which imports the package: build with the Python of an environment
that has DOLFINx (`.venv/bin/python -m sphinx ...`). The demos (jupytext percent-format
scripts in demos/) are executed as notebooks when the build starts and turned into MyST pages
in docs/demos/ with their outputs and figures (docs/demo_pages.py; the executed notebooks are
cached in build/docs-demos/).
"""
import pathlib
import re
import sys

DOCS = pathlib.Path(__file__).resolve().parent
ROOT = DOCS.parent
sys.path.insert(0, str(ROOT))          # the package of this tree, not an installed copy
sys.path.insert(0, str(DOCS))          # demo_pages

project = "contactvisco"
author = "contactvisco developers"
copyright = "2026, contactvisco developers"
release = version = "0.1.0"

extensions = ["myst_parser", "sphinx.ext.autodoc", "sphinx.ext.mathjax", "numpydoc"]
source_suffix = {".md": "markdown"}
root_doc = "index"
exclude_patterns = ["_build", "make_figures.py", "demos/*_files"]

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

def write_demo_pages(app):
    """docs/demos/<name>.md (with <name>.py and the executed <name>.ipynb to download) for
    every demos/<name>.py, executed as a notebook unless build/docs-demos/ has its outputs
    (docs/demo_pages.py)."""
    from sphinx.errors import ExtensionError
    from sphinx.util import logging
    import demo_pages
    try:
        demo_pages.write_pages(DOCS / "demos", log=logging.getLogger(__name__).info)
    except RuntimeError as error:
        raise ExtensionError(str(error)) from None


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
