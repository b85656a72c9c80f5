"""contactvisco: quasistatic frictional contact of viscoelastic bodies with long memory against
a foundation with normal compliance and a unilateral constraint (Ouafik 2024), in DOLFINx.

Modules: scene (parameters), material (A), memory (eq 19), contact (eqs 11-12, 20-21 in UFL),
geometry (meshes), problem (forms), solver (SNES), run (time loop), output, figures, cli.
PETSc-dependent modules are imported on use, so that the command line can hand its options to
PETSc first.
"""
__version__ = "0.1.0"

import importlib.util as _util
import logging as _logging

# A DOLFINx wheel that bundles its MPI and PETSc (PyPI's dolfinx-solver-*) loads their shared
# libraries when this module is imported, which must happen before dolfinx or petsc4py.
if _util.find_spec("dolfinx_solver") is not None:
    import dolfinx_solver  # noqa: F401

# A JIT compile of a form makes setuptools' distutils lower the root logger to INFO and log
# every compiler command line; keep those out of the user's console.
_logging.getLogger().addFilter(
    lambda record: record.levelno >= _logging.WARNING or "distutils" not in record.pathname)
