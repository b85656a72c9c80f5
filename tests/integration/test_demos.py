"""Every demo in demos/ runs as a notebook (jupytext -> nbclient, a kernel from this
environment) without error, at the small sizes CONTACTVISCO_QUICK selects, and the paper demo
prints the paper's zone counts."""
import os
import shutil

import pytest
from mpi4py import MPI

from helpers import ROOT

DEMOS = sorted((ROOT / "demos").glob("*.py"))

pytestmark = pytest.mark.skipif(MPI.COMM_WORLD.size > 1,
                                reason="starts a Jupyter kernel; run on one rank")


#: Over 10 s each (the 3D block; the paper scene at its full size; the obstacle demos).
SLOW = ("block3d", "paper", "creep_indentation", "cattaneo_mindlin", "two_bodies",
        "sphere_creep")


@pytest.mark.parametrize("demo", [pytest.param(d, marks=pytest.mark.slow) if d.stem in SLOW
                                  else d for d in DEMOS], ids=[d.stem for d in DEMOS])
def test_demo_runs_as_notebook(demo, tmp_path, monkeypatch):
    monkeypatch.setitem(os.environ, "CONTACTVISCO_QUICK", "1")   # the kernel inherits it
    shutil.copytree(ROOT / "demos" / "data", tmp_path / "data")   # the files beside the demos
    jupytext = pytest.importorskip("jupytext")
    nbclient = pytest.importorskip("nbclient")
    notebook = jupytext.read(demo)
    client = nbclient.NotebookClient(notebook, timeout=600, kernel_name="python3",
                                     resources={"metadata": {"path": str(tmp_path)}})
    client.execute()
    text = "".join(out.get("text", "") for cell in notebook.cells if cell.cell_type == "code"
                   for out in cell.get("outputs", []))
    if demo.stem == "paper":
        assert "{'separated': 1, 'compliance': 13, 'bound': 19}" in text
    if demo.stem == "two_bodies":       # the patch test: mortar exact, node to segment not
        assert "mortar: interface pressure / p from 1.0000 to 1.0000" in text
        assert "node_to_segment: interface pressure / p from 0.9" in text


@pytest.mark.parametrize("layout", ["demos", "root"])
def test_a_demo_finds_its_data_wherever_the_notebook_runs(layout, tmp_path):
    """viscoelastic.py's cells up to its reading of the Prony table, as a notebook started
    in the demos' folder or in the repository's root (a notebook has no __file__)."""
    jupytext = pytest.importorskip("jupytext")
    nbclient = pytest.importorskip("nbclient")
    data = tmp_path / "data" if layout == "demos" else tmp_path / "demos" / "data"
    shutil.copytree(ROOT / "demos" / "data", data)
    notebook = jupytext.read(ROOT / "demos" / "viscoelastic.py")
    last = next(i for i, cell in enumerate(notebook.cells)
                if "prony_csv.read_text()" in cell.source)
    notebook.cells = notebook.cells[:last + 1]
    client = nbclient.NotebookClient(notebook, timeout=300, kernel_name="python3",
                                     resources={"metadata": {"path": str(tmp_path)}})
    client.execute()
    text = "".join(out.get("text", "") for cell in notebook.cells if cell.cell_type == "code"
                   for out in cell.get("outputs", []))
    assert (data / "sbs_ac13_prony.csv").read_text().splitlines()[1] in text


@pytest.mark.processes
def test_the_own_mesh_demo_leaves_no_traceback_at_exit(tmp_path):
    """demos/own_mesh.py run as a script (pyvista plotter included) exits 0 with nothing
    "ignored" on stderr: a plotter left to the interpreter's teardown prints pyvista's
    __del__ tracebacks there."""
    import subprocess
    import sys
    env = {**os.environ, "CONTACTVISCO_QUICK": "1"}
    done = subprocess.run([sys.executable, str(ROOT / "demos" / "own_mesh.py")], cwd=tmp_path,
                          env=env, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-2000:]
    assert "largest |u|" in done.stdout
    assert "Exception ignored" not in done.stderr and "Traceback" not in done.stderr, \
        done.stderr[-2000:]
