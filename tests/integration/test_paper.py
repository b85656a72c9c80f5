"""The paper's 2D test (section 4): discrete contact conditions at every step, Newton
convergence, the zone counts reported in the paper, and the equilibrium residual."""
import numpy as np
import pytest
from dolfinx import fem
from helpers import assert_contact_conditions

from contactvisco.fem import compat

pytestmark = pytest.mark.mpi

TOL = 1e-10   # Newton stops at |F| < 1e-10: conditions hold to that order


def test_newton_converges_every_step(paper_run):
    scene, result = paper_run
    assert len(result.steps) == scene["time"]["steps"] + 1
    for step in result.steps:
        assert step["newton_iterations"] <= 10, step
        assert step["residual"] < 1e-10, step


def test_contact_conditions_every_step(paper_run):
    """Normal compliance, bound, complementarity and Coulomb friction at every contact node and
    every step; the roller corner x = 1 carries its tangential reaction in u_x = 0."""
    scene, result = paper_run
    checked = 0
    for table in result.tables:
        roller = table["x"][:, 0] > 1.0 - 1e-12
        checked += assert_contact_conditions(table, scene["contact"]["g"], TOL, roller)
    assert checked > 100    # many sliding nodes were checked, not none


def test_zone_counts_match_the_paper(paper_run):
    """Ouafik (2024), sec. 4: at T = 1, 13 nodes in normal compliance (zone AB, sliding) and 19
    at the bound (zone BC, sliding); the clamped node x = 0 carries no contact force."""
    _, result = paper_run
    final = result.tables[-1]
    counts = result.steps[-1]["status_counts"]
    assert counts == {"separated": 1, "compliance": 13, "bound": 19}
    # the zones are contiguous: compliance on [A, B), bound on [B, C]
    status = final["status"]
    assert list(status) == [0] + [1] * 13 + [2] * 19
    # and every loaded node slides
    assert np.all(np.abs(final["u_tau"][1:-1]) > 1e-6)


def test_memory_stiffens_the_body(paper_run):
    """The paper's Fig. 2: under constant loads the memory term makes the body recover its
    shape; the deflection at (0.5, 1) decreases at every step and by t = 1 is below 60 % of
    its value at t = 0.1."""
    _, result = paper_run
    uy = [[p["u"][1] for p in step["probes"] if p["x"] == [0.5, 1.0]][0]
          for step in result.steps]
    assert all(b > a for a, b in zip(uy, uy[1:]))
    assert uy[-1] < 0.0
    assert abs(uy[-1]) < 0.6 * abs(uy[1])


def test_residual_of_converged_state(paper_run):
    """An independent assembly of F at the converged final state is below the Newton
    tolerance (the SNES norm is not merely its own bookkeeping)."""
    _, result = paper_run
    problem = result.problem
    F = [fem.form(f) for f in problem.F]
    J = [[None if a is None else fem.form(a) for a in row] for row in problem.J]
    b = compat.block_vector(F)
    with b.localForm() as local:
        local.set(0.0)
    compat.assemble_block_residual(b, F, J, problem.bcs, None, scale=-1.0)
    # with x0 = None the Dirichlet rows hold -(g - 0) = 0 for homogeneous conditions
    assert b.norm() < 1e-9
