"""Prescribed contact laws (contact.p_nu, contact.p_tau): a column on a power-law foundation
against its closed form and the bound at the predicted load, Newton's quadratic convergence,
the linear law written as expressions against stiffness/mu, the condensed system against
the coupled one, 1 and 2 ranks, and the checks of the laws when a scene is loaded."""
import numpy as np
import pytest
from mpi4py import MPI

from contactvisco.errors import SceneError
from contactvisco.scene import loader as scene_module
from contactvisco.solver.time_loop import simulate
from contactvisco.studies import laws

#: The paper scene, short, with a power-law compliance and a saturating friction bound.
PAPER = ["geometry.cells=[16, 16]", "time.T=0.4", "time.steps=4"]
NONLINEAR = ["contact.stiffness=0", "contact.p_nu='2000 * s**1.5'", "contact.mu=0",
             "contact.p_tau='0.3 * min(p_nu, 1.5)'"]


def _paper(sets, comm=MPI.COMM_WORLD):
    scene = scene_module.load("paper", PAPER + sets)
    scene["output"]["probes"] = []
    return simulate(scene, comm=comm, progress=False, keep_tables=True)


def test_column_on_a_power_law_foundation():
    """s(t) = s_1 t and q = c s^1.5 up to the bound, reached at t* = g/s_1 under q* = c g^m;
    after it s = g and the bound carries q - c g^m (closed form to the Newton tolerance)."""
    result = laws.compliant_column(p_tau="0.3 * min(p_nu, 1.5)")
    exact = result["exact"]
    assert result["spread"] < 1e-12          # the same penetration at every contact node
    assert result["error_s"] < 1e-8 and result["error_q"] < 1e-8, result
    t, R = result["t"], result["R_nu"]
    before, after = t < exact["t_bound"] - 1e-9, t > exact["t_bound"] + 1e-9
    assert np.all(result["s"][before] < 0.01 - 1e-6) and np.max(np.abs(R[before])) < 1e-10
    at = np.argmin(np.abs(t - exact["t_bound"]))
    assert abs(result["q"][at] - exact["q_bound"]) < 1e-8 * exact["q_bound"]
    assert abs(R[at]) < 1e-8 and np.all(R[after] > 0.1)
    # p_tau's bound at the nodes: 0.3 min(c s^m, 1.5) (no tangential load: sigma_tau = 0).
    for table, s in zip(result["tables"], exact["s"]):
        assert np.allclose(table["radius"], 0.3 * min(2000 * s**1.5, 1.5), atol=1e-9)
        assert np.max(np.abs(table["reaction_tau"])) < 1e-10


def test_newton_is_quadratic_near_the_solution():
    """Every step of the column whose history has three residuals above round-off shows
    log(r_{k+1}/r_0) / log(r_k/r_0) near 2 (measured 2.09 to 2.47). Each step starts from
    the last accepted state: the extrapolated start is the solution before the bound."""
    result = laws.compliant_column(predictor="none")
    orders = [laws.quadratic_orders(h) for h in result["residuals"]]
    measured = [o[-1] for o in orders if o]
    assert len(measured) >= 5, result["residuals"]
    assert min(measured) > 1.8, measured


def test_linear_law_as_expressions_gives_the_same_answer():
    """p_nu = '100 * s', p_tau = '0.2 * p_nu' is the paper's stiffness = 100, mu = 0.2: the
    same Newton counts, zones and contact values to round-off."""
    short = _paper([])
    written = _paper(["contact.stiffness=0", "contact.p_nu='100 * s'", "contact.mu=0",
                      "contact.p_tau='0.2 * p_nu'"])
    assert [s["newton_iterations"] for s in short.steps] == \
        [s["newton_iterations"] for s in written.steps]
    for a, b in zip(short.tables, written.tables):
        assert np.array_equal(a["status"], b["status"])
        for key in ("u_nu", "u_tau", "lambda_nu", "p_nu", "reaction_nu", "reaction_tau",
                    "radius"):
            scale = max(1e-12, np.max(np.abs(a[key])))
            assert np.max(np.abs(a[key] - b[key])) <= 1e-12 * scale, key


@pytest.mark.mpi
def test_condensed_equals_coupled_with_prescribed_laws():
    """A power-law p_nu and a saturating p_tau: the node-wise elimination gives the coupled
    answer (contact values to round-off) on the paper scene and the column, with the same
    Newton counts after t_0. At t_0 Newton starts at u = 0, where every contact node sits
    at the kink s = 0 of the law (p_nu'(0) = 0, p_nu'' unbounded for m = 1.5): on which side
    an early iterate lands depends on round-off (measured 7 and 8 iterations on DOLFINx
    0.11, 9 and 7 on 2 ranks; the same converged state)."""
    coupled = _paper(NONLINEAR + ["solver.linear_system='coupled'"])
    condensed = _paper(NONLINEAR + ["solver.linear_system='condensed'"])
    assert condensed.linear_system == "condensed"
    counts = [[s["newton_iterations"] for s in r.steps] for r in (coupled, condensed)]
    assert counts[0][1:] == counts[1][1:], counts
    saturated = 0
    for a, b in zip(coupled.tables, condensed.tables):
        assert np.array_equal(a["status"], b["status"])
        for key in ("u_nu", "u_tau", "lambda_nu", "reaction_nu", "reaction_tau", "radius"):
            scale = max(1e-12, np.max(np.abs(a[key])))
            assert np.max(np.abs(a[key] - b[key])) <= 1e-10 * scale, key
        saturated += int(np.sum(np.isclose(a["radius"], 0.45)))
    assert saturated > 0                       # the friction bound's saturation is reached
    column = laws.compliant_column(linear_system="condensed")
    assert column["error_s"] < 1e-8 and column["error_q"] < 1e-8


@pytest.mark.mpi
def test_ranks_agree_with_prescribed_laws():
    """The distributed run gives the 1-rank answer with a power-law p_nu and a saturating
    p_tau."""
    world = _paper(NONLINEAR, MPI.COMM_WORLD)
    single = _paper(NONLINEAR, MPI.COMM_SELF)
    for a, b in zip(world.tables, single.tables):
        for key in ("x", "u_nu", "u_tau", "reaction_nu", "reaction_tau", "radius"):
            scale = max(1.0, np.max(np.abs(b[key])))
            assert np.max(np.abs(a[key] - b[key])) < 1e-10 * scale, key
        assert np.array_equal(a["status"], b["status"])


@pytest.mark.parametrize("sets, message", [
    (["contact.p_nu='2e3 * s**0.5'"], "contact.p_nu = .* has an infinite slope at s = 0"),
    (["contact.p_nu='2e3 * s + 1'"], r"gives 1 at s = 0 .* must vanish for s <= 0"),
    (["contact.p_nu='-s'"], "is negative"),
    (["contact.p_nu='conditional(s < 0.02, 100 * s, 1)'"], "must be non-decreasing"),
    (["contact.p_nu='0 * s'"], "no compliance"),
    (["contact.p_nu='exp(1e5 * s)'"], "overflows"),
    (["contact.p_nu='p_nu * s'"], "the name 'p_nu' is not allowed"),
    (["contact.p_nu=2.0"], "must be an expression string in s"),
    (["contact.stiffness=100", "contact.p_nu='100 * s'"], "give one"),
    (["contact.mu=0.2", "contact.p_tau='0.2 * p_nu'"], "give one"),
    (["contact.mu=0", "contact.p_tau='0.2 * p_nu'", "contact.friction_law='coulomb'"],
     "with 'coulomb' the bound is mu times the total pressure"),
    (["contact.mu=0", "contact.p_tau='0.2 * s**0.5'"], "contact.p_tau = .* infinite slope"),
    (["contact.mu=0", "contact.p_tau='0.2 * p_nu - 1'"], "must vanish"),
])
def test_law_checks(sets, message):
    """Each refused law names its key and says why."""
    base = [] if any("stiffness" in s for s in sets) or not any("p_nu" in s.split("=")[0]
                                                                 for s in sets) \
        else ["contact.stiffness=0"]
    with pytest.raises(SceneError, match=message) as err:
        scene_module.load("paper", base + sets)
    assert err.value.key in ("contact.p_nu", "contact.p_tau")


def test_regularized_square_root_is_accepted():
    """The documented regularization of c s^0.5, c s / sqrt(s + delta), passes the checks."""
    scene = scene_module.load("paper", ["contact.stiffness=0",
                                        "contact.p_nu='100 * s / sqrt(s + 1e-4)'"])
    assert scene["contact"]["p_nu"] == "100 * s / sqrt(s + 1e-4)"


# ---- a nonlinear elasticity operator (material.law) ----

LINEAR_AS_ENERGY = ["material.law='energy'",
                    "material.energy='0.5 * lmbda * tr_eps**2 + mu_lame * eps2'"]


@pytest.mark.parametrize("sets", [LINEAR_AS_ENERGY,
                                  ["material.law='hencky'", "material.hencky_exponent=0"]])
def test_linear_law_as_an_energy_gives_the_same_answer(sets):
    """The linear A written as W (an expression, or Hencky's law with m = 0) and as E/nu:
    the paper scene's Newton counts, zones and contact values to round-off (measured 0 and
    2e-14 relative)."""
    linear = _paper([])
    energy = _paper(sets)
    assert [s["newton_iterations"] for s in energy.steps] == \
        [s["newton_iterations"] for s in linear.steps]
    for a, b in zip(linear.tables, energy.tables):
        assert np.array_equal(a["status"], b["status"])
        for key in ("u_nu", "u_tau", "lambda_nu", "reaction_nu", "reaction_tau"):
            scale = max(1e-12, np.max(np.abs(a[key])))
            assert np.max(np.abs(a[key] - b[key])) <= 1e-12 * scale, key
    assert all(abs(s["tangent_min"] - 1.0) < 1e-12 for s in energy.steps)


@pytest.mark.convergence
@pytest.mark.parametrize("alpha", [50.0, 0.0])
def test_manufactured_solution_of_a_hencky_material(alpha):
    """Hencky's power law (m = 1, e_0 = 0.1: the secant shear modulus grows up to ~10 times
    over the square), with and without memory: P1 orders ~2 in L2 and ~1 in H1 on 8, 16, 32
    (measured 1.89, 1.97 and 1.00, 1.00 with memory; 1.87, 1.96 and 1.01, 1.00 without; the
    same on DOLFINx 0.5 and 0.11)."""
    from contactvisco.studies.verification import manufactured, orders
    runs = [manufactured(n, 1, alpha=alpha, material={"law": "hencky", "hencky_exponent": 1.0,
                                                      "hencky_strain": 0.1})
            for n in (8, 16, 32)]
    h = [r["h"] for r in runs]
    l2, h1 = orders([r["L2"] for r in runs], h), orders([r["H1"] for r in runs], h)
    assert l2[-1] > 1.85 and h1[-1] > 0.95 and h1[-1] < 1.1, (l2, h1)


def _sheared_square(sets, gamma=0.02):
    """A built unit square (8 x 8 squares) whose u is the P1 interpolant of (gamma y^2, 0):
    in the cells between y_0 and y_0 + h, eps_xy = gamma (y_0 + h/2), largest in the top
    row (y_0 + h/2 = 15/16)."""
    from contactvisco.fem import geometry as geometry_module
    from contactvisco.fem.problem import build
    raw = {"name": "square", "geometry": {"lower": [0.0, 0.0], "upper": [1.0, 1.0],
                                          "cells": [8, 8]},
           "material": {"model": "plane_strain", "E": 100.0, "nu": 0.3},
           "dirichlet": [{"boundary": "bottom", "components": "all", "value": 0.0}]}
    scene = scene_module.resolve(raw, sets)
    problem = build(scene, geometry_module.build(scene, MPI.COMM_WORLD))
    problem.u.interpolate(lambda x: np.vstack([gamma * x[1] ** 2, 0.0 * x[0]]))
    return problem


def test_tangent_of_a_softening_hencky_law():
    """m = -0.4, e_0 = 0.01 under shear: the smallest eigenvalue of the tangent over 2 mu is
    (1 + x)^(m - 1) (1 + (2m + 1) x), x = |dev eps|^2 / e_0^2, largest strain at y = 1 (P1:
    the top row, where the P1 strain is that of y = 15/16)."""
    problem = _sheared_square(["material.law='hencky'", "material.hencky_exponent=-0.4",
                               "material.hencky_strain=0.01"])
    check = problem.tangent.smallest(MPI.COMM_WORLD)
    assert check["x"][1] > 1 - 1 / 8
    x = 2 * (0.02 * 15 / 16) ** 2 / 0.01**2
    assert abs(check["ratio"] - (1 + x) ** (-1.4) * (1 + 0.2 * x)) < 1e-10


def test_a_non_convex_energy_is_reported_where_it_fails(capsys):
    """W = K/2 tr^2 + mu (q - q^2 / (2a)), q = |dev eps|^2: convex at zero strain (accepted
    when loaded), its tangent along dev eps is 2 mu (1 - 3q/a) < 0 for q > a/3; the check
    gives that value at the top row and the run's warning names the point and the time."""
    from contactvisco.solver import report
    energy = ("0.5 * (lmbda + mu_lame) * tr_eps**2 + mu_lame * (dev_eps2 - dev_eps2**2 "
              "/ (2 * 1e-3))")
    problem = _sheared_square(["material.law='energy'", f"material.energy='{energy}'"])
    check = problem.tangent.smallest(MPI.COMM_WORLD)
    assert check["x"][1] > 1 - 1 / 8
    assert abs(check["ratio"] - (1 - 3 * 2 * (0.02 * 15 / 16) ** 2 / 1e-3)) < 1e-10
    record = {"t": 0.5}
    assert report.tangent_warning(record, problem, MPI.COMM_WORLD, None, False)
    assert record["tangent_min"] == check["ratio"] < 0
    if MPI.COMM_WORLD.rank == 0:
        err = capsys.readouterr().err
        assert "not positive definite at x = (" in err and "t = 0.5" in err


@pytest.mark.parametrize("sets, key, message", [
    (["material.law='energy'"], "material.energy", "needs material.energy"),
    (["material.energy='mu_lame * eps2'"], "material.energy", "set material.law = 'energy'"),
    (["material.law='energy'", "material.energy='mu_lame * eps2 + 3 * tr_eps'"],
     "material.energy", "stress at zero strain"),
    (["material.law='energy'", "material.energy='mu_lame * eps2 - lmbda * tr_eps**2'"],
     "material.energy", "not positive definite at zero strain"),
    (["material.law='energy'", "material.energy='mu_lame * eps2 + s'"], "material.energy",
     "the name 's' is not allowed"),
    (["material.law='hencky'", "material.hencky_exponent=-0.6"], "material.hencky_exponent",
     "must be > -1/2"),
    (["material.law='neo_hooke'"], "material.law", "material.law must be"),
])
def test_material_law_checks(sets, key, message):
    with pytest.raises(SceneError, match=message) as err:
        scene_module.load("paper", sets)
    assert err.value.key == key


# ---- the condensed system's line search (solver.line_search) ----

#: The paper's in-plane moduli K = lambda* + mu = 71.43, mu = 38.46 with a shear stress that
#: saturates at 2 mu c (c = 0.15).
SATURATING = ["material.law='energy'",
              "material.energy='0.5 * (lmbda + mu_lame) * tr_eps**2 + 2 * mu_lame * 0.15**2 "
              "* (sqrt(1 + dev_eps2 / 0.15**2) - 1)'"]


def _full_paper(sets, comm=MPI.COMM_WORLD):
    scene = scene_module.load("paper", sets)
    scene["output"]["probes"] = []
    return simulate(scene, comm=comm, progress=False, keep_tables=True)


@pytest.mark.mpi
def test_saturating_energy_converges_in_the_uniform_steps():
    """The saturating law on the paper scene: the full generalized Newton step diverges on
    the first loaded step and the step is cut (measured 6 cut steps); the default condensed
    system, which backtracks on the coupled residual, takes the 10 uniform steps with every
    residual at convergence <= 1e-10, and its contact values are those of the coupled system
    with PETSc's backtracking line search (measured 1.9e-10, the Newton tolerance)."""
    full_step = _full_paper(SATURATING + ["solver.line_search='none'"])
    assert any(s["cuts"] for s in full_step.steps)
    result = _full_paper(SATURATING)
    assert [s["t"] for s in result.steps] == pytest.approx([0.1 * i for i in range(11)])
    assert not any(s["cuts"] for s in result.steps)
    assert max(s["residual"] for s in result.steps) <= 1e-10
    coupled = _full_paper(SATURATING + ["solver.linear_system='coupled'",
                                        "solver.petsc_options={snes_linesearch_type='bt'}"])
    for a, b in zip(result.tables, coupled.tables):
        assert np.array_equal(a["status"], b["status"])
        for key in ("u_nu", "u_tau", "lambda_nu", "reaction_nu", "reaction_tau"):
            scale = max(1.0, np.max(np.abs(b[key])))
            assert np.max(np.abs(a[key] - b[key])) <= 1e-8 * scale, key


@pytest.mark.parametrize("sets", [[], ["material.law='hencky'"]])
def test_line_search_keeps_the_answer(sets):
    """The line search on the short paper scene: with the linear law every full Newton step
    is accepted and the Newton counts are those of the full-step method; with the Hencky law
    it shortens steps at t = 0 (measured 13 -> 11 iterations) and no step takes more. The
    contact values agree to the Newton tolerance (measured 0 and 1e-13 relative)."""
    plain = _paper(sets + ["solver.line_search='none'"])
    searched = _paper(sets + ["solver.line_search='nonmonotone'"])
    counts = [s["newton_iterations"] for s in plain.steps]
    searched_counts = [s["newton_iterations"] for s in searched.steps]
    if not sets:
        assert searched_counts == counts
    assert all(a <= b for a, b in zip(searched_counts, counts)), (searched_counts, counts)
    for a, b in zip(plain.tables, searched.tables):
        assert np.array_equal(a["status"], b["status"])
        for key in ("u_nu", "u_tau", "lambda_nu", "reaction_nu", "reaction_tau"):
            scale = max(1e-12, np.max(np.abs(a[key])))
            assert np.max(np.abs(a[key] - b[key])) <= 1e-10 * scale, key
