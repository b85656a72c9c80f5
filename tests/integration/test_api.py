"""The public interface: Python overrides are the --set overrides, a caller's DOLFINx mesh
gives the built-in scene's answer on the same mesh (1 and 2 ranks), a mesh that does not fit
the scene is a clear SceneError, and the demos use nothing but the public names."""
import ast
import pathlib
import subprocess
import sys

import numpy as np
import pytest
from dolfinx import mesh as dmesh
from mpi4py import MPI

import contactvisco
from contactvisco import SceneError, load_scene, solve
from contactvisco.scene import loader as scene_module
from helpers import ROOT

COMM = MPI.COMM_WORLD
DEMOS = sorted((ROOT / "demos").glob("*.py"))
CELLS = 8


def unit_square(n, sides=("left", "right", "bottom", "top")):
    """The unit square made and tagged as a notebook would: tag i + 1 on side i."""
    planes = {"left": (0, 0.0), "right": (0, 1.0), "bottom": (1, 0.0), "top": (1, 1.0)}
    domain = dmesh.create_unit_square(COMM, n, n, dmesh.CellType.triangle,
                                      diagonal=dmesh.DiagonalType.right)
    fdim = domain.topology.dim - 1
    facets, values = [], []
    for tag, name in enumerate(sides, start=1):
        axis, position = planes[name]
        found = dmesh.locate_entities_boundary(
            domain, fdim, lambda x, a=axis, p=position: np.isclose(x[a], p))
        facets.append(found)
        values.append(np.full(found.size, tag, dtype=np.int32))
    facets, values = np.concatenate(facets), np.concatenate(values)
    order = np.argsort(facets)
    tags = dmesh.meshtags(domain, fdim, facets[order], values[order])
    return domain, tags, {name: tag for tag, name in enumerate(sides, start=1)}


def test_python_overrides_are_the_set_overrides():
    given = load_scene("paper", contact={"mu": 0.4}, time={"steps": 20},
                       memory={"alpha": np.float64(50.0)}, geometry={"cells": (8, 8)})
    texts = scene_module.load("paper", ["contact.mu=0.4", "time.steps=20", "memory.alpha=50.0",
                                        "geometry.cells=[8, 8]"])
    assert given == texts
    assert given["contact"]["mu"] == 0.4 and given["contact"]["g"] == 0.05   # others kept


@pytest.mark.parametrize("overrides, words", [
    ({"contact": {"muu": 0.4}}, ["contact.muu", "did you mean 'mu'"]),
    ({"time": {"steps": 0}}, ["time.steps must be an integer >= 1", "load_scene time.steps=0"]),
    ({"contact": {"mu": -1.0}}, ["contact.mu", ">= 0", "load_scene contact.mu=-1.0"]),
    ({"material": {"lambda": 3.0}}, ["give either E and nu or lambda and mu"]),
])
def test_bad_overrides_are_scene_errors_naming_the_key(overrides, words):
    with pytest.raises(SceneError) as caught:
        load_scene("paper", **overrides)
    for word in words:
        assert word in str(caught.value)


@pytest.mark.mpi
def test_own_mesh_gives_the_builtin_answer():
    """The paper's scene (mu = 0.4) on a mesh built and tagged by the caller, against the
    scene's own box of the same cells: every contact value at every step agrees to 1e-10."""
    overrides = dict(contact={"mu": 0.4}, time={"steps": 3},
                     geometry={"cells": [CELLS, CELLS]}, output={"probes": [[0.5, 1.0]]})
    builtin = solve(load_scene("paper", **overrides))
    seen = []
    # The tags in another order than the box's: the names carry the meaning, not the values.
    domain, tags, boundaries = unit_square(CELLS, ("top", "bottom", "right", "left"))
    own = solve(load_scene("paper", **overrides), mesh=domain, facet_tags=tags,
                boundaries=boundaries, on_step=seen.append)
    assert seen == own.steps and len(own.steps) == 4
    assert [s["status_counts"] for s in own.steps] == [s["status_counts"] for s in builtin.steps]
    assert own.final["status_counts"] == builtin.final["status_counts"]
    # Contact at the end, with nodes at the bound and in compliance: a real comparison.
    assert own.final["status_counts"]["bound"] > 0 and own.final["status_counts"]["compliance"] > 0
    for a, b in zip(own.contact, builtin.contact):
        assert a.keys() == b.keys()
        for key in a:
            if a[key].dtype.kind == "U":          # the names of the state codes
                assert np.array_equal(a[key], b[key]), key
                continue
            scale = max(1.0, float(np.abs(b[key]).max()))
            assert np.allclose(a[key], b[key], rtol=0.0, atol=1e-10 * scale), key
    probe_a, probe_b = own.steps[-1]["probes"][0]["u"], builtin.steps[-1]["probes"][0]["u"]
    assert np.allclose(probe_a, probe_b, rtol=0.0, atol=1e-12) and abs(probe_a[1]) > 1e-3
    assert own.u.function_space.mesh is domain


def test_a_mesh_that_does_not_fit_the_scene_is_a_scene_error():
    scene = load_scene("paper", geometry={"cells": [2, 2]})
    domain, tags, boundaries = unit_square(2)
    missing = {k: v for k, v in boundaries.items() if k != "bottom"}
    with pytest.raises(SceneError, match=r"contact.boundary: no boundary named 'bottom'"):
        solve(scene, mesh=domain, facet_tags=tags, boundaries=missing)
    with pytest.raises(SceneError, match=r"boundaries\['top'\] = 9 tags no facet"):
        solve(scene, mesh=domain, facet_tags=tags, boundaries={**boundaries, "top": 9})
    with pytest.raises(SceneError, match="needs a 3D mesh"):
        solve(load_scene("block3d"), mesh=domain, facet_tags=tags, boundaries=boundaries)
    with pytest.raises(SceneError, match="all three"):
        solve(scene, mesh=domain)
    cell_tags = dmesh.meshtags(domain, 2, np.arange(1, dtype=np.int32),
                               np.ones(1, dtype=np.int32))
    with pytest.raises(SceneError, match="must tag facets"):
        solve(scene, mesh=domain, facet_tags=cell_tags, boundaries=boundaries)


def public_uses(path: pathlib.Path) -> list[str]:
    """Every name a demo takes from contactvisco: `from contactvisco[.x] import y`,
    `import contactvisco.x`, and `contactvisco.y` attribute uses."""
    tree = ast.parse(path.read_text())
    used = []
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("contactvisco"):
            prefix = "" if node.module == "contactvisco" else f"{node.module}:"
            used += [prefix + alias.name for alias in node.names]
        elif isinstance(node, ast.Import):
            used += [f"import {a.name}" for a in node.names
                     if a.name.startswith("contactvisco.")]
        elif isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) \
                and node.value.id == "contactvisco":
            used.append(node.attr)
    return used


@pytest.mark.parametrize("demo", DEMOS, ids=[d.stem for d in DEMOS])
def test_demos_use_only_the_public_names(demo):
    used = public_uses(demo)
    assert used, f"{demo.name} does not use contactvisco"
    private = [name for name in used if name not in contactvisco.__all__]
    assert not private, f"{demo.name} uses names outside contactvisco.__all__: {private}"
    for name in used:
        assert getattr(contactvisco, name) is not None


@pytest.mark.skipif(COMM.size > 1, reason="starts a Python process; run on one rank")
def test_import_loads_neither_petsc_nor_dolfinx():
    """The command line hands its options to PETSc before PETSc is imported."""
    code = ("import sys, contactvisco; contactvisco.load_scene('paper', time={'steps': 3}); "
            "print(sorted(m for m in ('petsc4py', 'dolfinx') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True, timeout=120).stdout
    assert out.strip() == "[]"
