"""The header line of a run names the linear solver the steps use: with the direct solver's
stale factorizations, steps whose Jacobian is close to the factorized one are solved by FGMRES
on the last factors and print Krylov iterations, and the header says so."""
import pytest
from mpi4py import MPI

from contactvisco import load_scene, solve


@pytest.mark.skipif(MPI.COMM_WORLD.size > 1, reason="reads what rank 0 prints")
def test_the_header_names_fgmres_when_steps_print_krylov_iterations(capsys):
    scene = load_scene("paper", geometry={"cells": [8, 8]}, time={"steps": 4},
                       output={"figures": False})
    solve(scene, progress=True)
    lines = capsys.readouterr().out.splitlines()
    header = next(line for line in lines if line.startswith("contactvisco: scene"))
    steps = [line for line in lines if line.startswith("step")]
    assert any("Krylov" in line for line in steps), steps
    assert "preonly/lu, fgmres/lu on the last factors" in header, header
