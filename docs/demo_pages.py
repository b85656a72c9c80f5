"""The demo pages of the documentation, made when the build starts (docs/conf.py): every
demos/<name>.py (a jupytext percent-format script) is executed as a notebook (jupytext ->
nbclient, a kernel of the Python that builds the docs), and docs/demos/<name>.md shows its
text, its code and what each cell printed and drew; docs/demos/<name>.py and <name>.ipynb (the
executed notebook) are offered for download.

Executed notebooks are kept in build/docs-demos/, keyed by the SHA-256 of the demo, its data,
the package's sources and the Python version: a build re-executes a demo only when one of them
changed. The demos run two at a time (two kernels), each in its own folder
build/docs-demos/run/<name>/ with a copy of demos/data, so what they write stays in build/.

    python docs/demo_pages.py execute DEMO.py OUT.ipynb FOLDER   (one demo; used by the build)
"""
from __future__ import annotations

import base64
import concurrent.futures
import hashlib
import json
import os
import pathlib
import shutil
import subprocess
import sys
import time

DOCS = pathlib.Path(__file__).resolve().parent
ROOT = DOCS.parent
DEMOS = ROOT / "demos"
CACHE = ROOT / "build" / "docs-demos"
#: Two kernels at once: the two cores of the machines the build is timed on.
WORKERS = int(os.environ.get("CONTACTVISCO_DOCS_WORKERS", "2"))
#: A demo that runs longer fails the build (the longest takes about 50 s on a loaded 2-core
#: machine).
TIMEOUT = 900


def source_key(script: pathlib.Path) -> str:
    """The SHA-256 of what a demo's outputs depend on: the demo, demos/data, the package's
    Python sources, scenes and mesh scripts, and the Python version."""
    digest = hashlib.sha256(sys.version.encode())
    inputs = [script, *sorted((DEMOS / "data").rglob("*")),
              *sorted((ROOT / "contactvisco").rglob("*.py")),
              *sorted((ROOT / "contactvisco").rglob("*.toml")),
              *sorted((ROOT / "meshes").glob("*.py"))]
    for path in inputs:
        if path.is_file():
            digest.update(str(path.relative_to(ROOT)).encode())
            digest.update(path.read_bytes())
    return digest.hexdigest()


def execute(script: pathlib.Path, target: pathlib.Path, folder: pathlib.Path) -> None:
    """Execute demo `script` as a notebook in `folder` (a copy of demos/data beside it) and
    write the executed notebook to `target`, with the wall time in its metadata."""
    import jupytext
    import nbclient
    import nbformat
    if folder.exists():
        shutil.rmtree(folder)
    folder.mkdir(parents=True)
    shutil.copytree(DEMOS / "data", folder / "data")
    notebook = jupytext.read(script)
    start = time.perf_counter()
    nbclient.NotebookClient(notebook, timeout=TIMEOUT, kernel_name="python3",
                            resources={"metadata": {"path": str(folder)}}).execute()
    notebook.metadata["contactvisco"] = {"seconds": round(time.perf_counter() - start, 1)}
    notebook.metadata.pop("jupytext", None)
    notebook.metadata["kernelspec"] = {"name": "python3", "display_name": "Python 3",
                                       "language": "python"}
    tmp = target.with_suffix(".tmp")
    nbformat.write(notebook, tmp)
    tmp.replace(target)


def executed(scripts, log=print) -> dict:
    """{name: path of its executed notebook} for the demos `scripts`, executing those whose
    key has no notebook in the cache, WORKERS at a time, each in its own process (its kernel's
    shutdown messages stay out of the build's log unless it fails)."""
    CACHE.mkdir(parents=True, exist_ok=True)
    paths = {s.stem: CACHE / f"{s.stem}-{source_key(s)[:20]}.ipynb" for s in scripts}
    todo = [s for s in scripts if not paths[s.stem].is_file()]

    def run(script):
        start = time.perf_counter()
        done = subprocess.run([sys.executable, __file__, "execute", str(script),
                               str(paths[script.stem]), str(CACHE / "run" / script.stem)],
                              capture_output=True, text=True)
        if done.returncode != 0:
            raise RuntimeError(f"demos/{script.name} failed when executed as a notebook:\n"
                               + done.stderr[-4000:])
        log(f"demo {script.stem}: executed in {time.perf_counter() - start:.0f} s")

    if todo:
        log(f"executing {len(todo)} demo(s) as notebooks, {WORKERS} at a time "
            f"(cached in {CACHE.relative_to(ROOT)})")
        with concurrent.futures.ThreadPoolExecutor(WORKERS) as pool:
            for future in [pool.submit(run, s) for s in todo]:
                future.result()
    for name, path in paths.items():      # older notebooks of the same demo
        for old in CACHE.glob(f"{name}-*.ipynb"):
            if old != path:
                old.unlink()
    return paths


def _fence(text: str, language: str = "") -> str:
    """A fenced block longer than any backtick run inside `text`."""
    ticks = "`" * max(3, max((len(run) for run in text.split("\n") if set(run) == {"`"}),
                             default=0) + 1)
    return f"{ticks}{language}\n{text.rstrip()}\n{ticks}"


def render(notebook: dict, name: str, folder: pathlib.Path) -> str:
    """The MyST page of an executed notebook: markdown cells as they are, code cells as
    Python blocks, each followed by its printed text (one block per stream) and its images
    (written to folder/<name>_files/, shown at the width the demo asked for). A cell that
    raised fails the build."""
    images = folder / f"{name}_files"
    if images.exists():
        shutil.rmtree(images)
    seconds = notebook.get("metadata", {}).get("contactvisco", {}).get("seconds")
    header = ("{download}`Download the script (.py) <" + name + ".py>` · "
              "{download}`Download the notebook (.ipynb) <" + name + ".ipynb>`\n\n"
              f"*This page was made by executing `demos/{name}.py` as a notebook when the "
              f"documentation was built" + (f" ({seconds:.0f} s)" if seconds else "")
              + "; the text and the figures below are what its cells printed and drew.*")
    out, count = [], 0
    for cell in notebook["cells"]:
        source = "".join(cell["source"]) if isinstance(cell["source"], list) else cell["source"]
        if cell["cell_type"] == "markdown":
            if not out:          # the downloads under the title
                title, _, rest = source.partition("\n")
                out.extend([title, header] if title.startswith("# ") else [header])
                source = rest if title.startswith("# ") else source
            if source.strip():
                out.append(source)
            continue
        if cell["cell_type"] != "code" or not source.strip():
            continue
        if not out:
            out.append(header)
        out.append(_fence(source, "python"))
        streams = {}
        for output in cell.get("outputs", []):
            kind = output["output_type"]
            if kind == "error":
                raise RuntimeError(f"demos/{name}.py: a cell raised {output['ename']}: "
                                   f"{output['evalue']}")
            if kind == "stream":
                text = output["text"] if isinstance(output["text"], str) \
                    else "".join(output["text"])
                streams[output["name"]] = streams.get(output["name"], "") + text
                continue
            _flush(streams, out)
            data = output.get("data", {})
            if "image/png" in data:
                count += 1
                images.mkdir(parents=True, exist_ok=True)
                path = images / f"{name}_output_{count}.png"
                path.write_bytes(base64.b64decode(data["image/png"]))
                width = output.get("metadata", {}).get("image/png", {}).get("width")
                out.append(f"```{{image}} {name}_files/{path.name}\n:alt: output {count} of "
                           f"{name}.py\n" + (f":width: {int(width)}px\n" if width else "")
                           + "```")
            elif "text/plain" in data:
                text = data["text/plain"]
                out.append(_fence(text if isinstance(text, str) else "".join(text), "none"))
        _flush(streams, out)
    return "\n\n".join(out) + "\n"


def _flush(streams: dict, out: list):
    for text in streams.values():
        if text.strip():
            out.append(_fence(text, "none"))
    streams.clear()


def write_pages(target: pathlib.Path, log=print) -> None:
    """docs/demos/<name>.md, <name>.py and <name>.ipynb for every demo (files rewritten only
    when their content changes, so that Sphinx reads an unchanged page from its cache)."""
    scripts = sorted(DEMOS.glob("*.py"))
    notebooks = executed(scripts, log)
    target.mkdir(exist_ok=True)
    for script in scripts:
        name = script.stem
        notebook_bytes = notebooks[name].read_bytes()
        page = render(json.loads(notebook_bytes), name, target)
        for path, content in ((target / f"{name}.md", page.encode()),
                              (target / f"{name}.py", script.read_bytes()),
                              (target / f"{name}.ipynb", notebook_bytes)):
            if not path.exists() or path.read_bytes() != content:
                path.write_bytes(content)


if __name__ == "__main__":
    if len(sys.argv) != 5 or sys.argv[1] != "execute":
        sys.exit(__doc__)
    execute(pathlib.Path(sys.argv[2]), pathlib.Path(sys.argv[3]), pathlib.Path(sys.argv[4]))
