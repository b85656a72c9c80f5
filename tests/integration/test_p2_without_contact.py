"""P2 bodies without contact through the ordinary solver set-up (the connected parts of the
mesh are labelled on P2's nodes, not on P1's vertices)."""
import numpy as np
import pytest
from mpi4py import MPI

from contactvisco.fem import parts
from contactvisco.scene import loader
from contactvisco.solver.time_loop import simulate
from contactvisco.studies.verification import uniaxial_exact

pytestmark = pytest.mark.mpi


def _uniaxial(model):
    """u_y at the top of the unit block in uniaxial strain (rollers, the axis in axisymmetry)
    under the pressure 10, the exponential kernel of verification.UNIAXIAL_KERNELS, P2."""
    rollers = [] if model == "axisymmetric" else [{"boundary": "left", "components": [0]}]
    raw = {"name": "uniaxial_p2",
           "geometry": {"lower": [0.0, 0.0], "upper": [1.0, 1.0], "cells": [2, 2]},
           "material": {"model": model, "E": 100.0, "nu": 0.3},
           "memory": {"kernel": "exponential", "alpha": [300.0], "tau": [0.2]},
           "dirichlet": [{"boundary": "bottom", "components": [1]},
                         {"boundary": "right", "components": [0]}] + rollers,
           "traction": [{"boundary": "top", "value": [0.0, -10.0]}],
           "time": {"T": 1.0, "steps": 40, "rule": "trapezoid"},
           "discretization": {"degree": 2},
           "output": {"probes": [[0.5, 1.0]]}}
    result = simulate(loader.resolve(raw), comm=MPI.COMM_WORLD, progress=False)
    return np.array([s["probes"][0]["u"][1] for s in result.steps]), result.problem


@pytest.mark.parametrize("model", ["plane_strain", "axisymmetric"])
def test_p2_creep_without_contact(model):
    """A P2 block with memory and no contact runs (it failed setting up the solver) and creeps
    as the closed form e(T) (within the trapezoid rule's 4e-4 relative at 40 steps; space is
    exact for uniaxial strain, also in axisymmetry, where u_r = 0 throughout); its P2 nodes
    form one connected part."""
    u, problem = _uniaxial(model)
    exact = uniaxial_exact("exponential", 1.0)
    assert abs(u[-1] - exact) < 1e-3 * abs(exact), (u[-1], exact)
    assert abs(u[0] + 10.0 / (100 * 0.3 / (1.3 * 0.4) + 100 / 1.3)) < 1e-10   # -q / M
    labels, count = parts.part_labels(problem.V)
    index_map = problem.V.dofmap.index_map
    assert count == 1 and labels.size == index_map.size_local + index_map.num_ghosts
