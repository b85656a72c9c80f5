"""contactvisco: quasistatic frictional contact of viscoelastic bodies with long memory against
a foundation with normal compliance and a unilateral constraint (Ouafik 2024), in DOLFINx.

The public interface (docs/api.md): load_scene, solve, check, scene_toml, Result, read_results,
builtin_scenes, pyvista_grid, SceneError, NewtonFailure, the module tradeoff; for the demos also
hertz, cattaneo_mindlin, cattaneo_traction, cattaneo_obstacle_scene, cattaneo_mindlin_figure,
creep_indentation, elastic_indentation, LeeRadok, SphereLeeRadok, creep_compliance, quick,
show_images, show_figure.

Layers, each importing only those below it (docs/architecture.md):

- errors: the errors a user meets;
- model: the constitutive pieces (A, the memory kernel and eq (19), the contact law of
  eqs 11-12 and 20-21 in UFL, the stability of the time rule);
- scene: a scene's parameters, read and checked;
- fem: the discrete problem on a mesh (geometry, forms, the DOLFINx differences);
- io: output, checkpoints, the output folder's lock, MPI agreement;
- solver: Newton (SNES), the condensed linear system, the time loop; post: figures, rendering;
- studies: the speed-accuracy trade, verification, Coulomb closed forms;
- api and cli on top.
PETSc-dependent modules are imported on use, so that the command line can hand its options to
PETSc first.
"""
__version__ = "0.1.0"

import importlib.util as _util
import logging as _logging

# A DOLFINx wheel that bundles its MPI and PETSc (PyPI's dolfinx-solver-*) loads their shared
# libraries when this module is imported, which must happen before dolfinx or petsc4py. A
# signal during that native start-up is held back until it is complete (an interrupt in the
# middle of it can crash the process on its way out).
# The command line's start-up ends at once on SIGINT/SIGTERM (contactvisco.io.parallel).
from contactvisco.io import parallel as _parallel

_parallel.command_line_start_up()
if _util.find_spec("dolfinx_solver") is not None:
    with _parallel.signals_deferred():
        import dolfinx_solver  # noqa: F401

# VTK's compiled modules (pyvista) open their shared objects with their own symbols first, so
# that a library loaded before them (Debian's DOLFINx 0.5) cannot abort a rendering
# (contactvisco/post/render.py); this imports nothing but the standard library.
from contactvisco.post import vtk_guard as _vtk_guard

_vtk_guard.install()

# A JIT compile of a form makes setuptools' distutils lower the root logger to INFO and log
# every compiler command line; keep those out of the user's console.
_logging.getLogger().addFilter(
    lambda record: record.levelno >= _logging.WARNING or "distutils" not in record.pathname)

#: Public name -> the module that defines it; imported on first use (PEP 562), so that
#: `import contactvisco` loads neither DOLFINx nor PETSc.
_PUBLIC = {
    "load_scene": "api", "solve": "api", "read_results": "api", "builtin_scenes": "api",
    "pyvista_grid": "api", "check": "api", "scene_toml": "api", "fit": "api",
    "Result": "solver.time_loop", "SceneError": "errors", "NewtonFailure": "solver.newton",
    "SlidingLimit": "solver.newton",
    "hertz": "studies.verification", "cattaneo_mindlin": "studies.coulomb",
    "cattaneo_traction": "studies.coulomb", "cattaneo_obstacle_scene": "studies.coulomb",
    "creep_indentation": "studies.indentation", "elastic_indentation": "studies.indentation",
    "LeeRadok": "studies.indentation", "SphereLeeRadok": "studies.indentation",
    "quick": "post.notebook", "show_images": "post.notebook", "show_figure": "post.notebook",
    "cattaneo_mindlin_figure": "post.figures", "relaxation_figure": "post.figures",
    "creep_compliance": "studies.relaxation",
}
#: Public modules, by the name they are reached under: the speed-accuracy trade of a scene
#: (contactvisco tradeoff).
_MODULES = {"tradeoff": "studies.tradeoff"}
__all__ = ["__version__", *_PUBLIC, *_MODULES]


def __getattr__(name):
    if name in _MODULES:
        import importlib
        return importlib.import_module(f".{_MODULES[name]}", __name__)
    if name in _PUBLIC:
        import importlib
        value = getattr(importlib.import_module(f".{_PUBLIC[name]}", __name__), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'contactvisco' has no attribute '{name}'")


def __dir__():
    return sorted(set(globals()) | set(__all__))
