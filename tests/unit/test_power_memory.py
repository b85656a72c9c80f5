"""Power-law memory: the sums of exponentials, the Mittag-Leffler function, the product
integration of the fractional kernel, uniaxial creep against its closed form with the observed
time orders, the fitted history against the direct sum on the paper scene, restart, bad input."""
import math

import numpy as np
import pytest
from mpi4py import MPI

from contactvisco.errors import SceneError
from contactvisco.io import checkpoint
from contactvisco.fem import geometry, problem as problem_module
from contactvisco.model import kernels
from contactvisco.scene import loader as scene_module
from contactvisco.model.memory import DirectFractionalHistory, FractionalHistory
from contactvisco.solver.time_loop import simulate
from contactvisco.solver.newton import BlockSNES
from contactvisco.studies.verification import orders, uniaxial, uniaxial_exact

COMM = MPI.COMM_WORLD


def test_mittag_leffler_known_values():
    """E_1(-z) = exp(-z), E_1/2(-z) = exp(z^2) erfc(z); the series and the integral
    representation agree where both apply."""
    z = np.linspace(0.0, 3.0, 13)
    assert np.max(np.abs(kernels.ml_series(1.0, z) / np.exp(-z) - 1.0)) < 1e-13
    z = np.array([0.05, 0.3, 0.7, 1.0, 2.0, 5.0, 12.0])
    exact = np.array([math.exp(v * v) * math.erfc(v) for v in z])
    assert np.max(np.abs(kernels.mittag_leffler(0.5, z) / exact - 1)) < 1e-12
    assert np.max(np.abs(kernels.ml_integral(0.5, z) / exact - 1)) < 1e-12
    z = np.linspace(0.2, 1.0, 9)
    for gamma in (0.05, 0.3, 0.8, 0.95):
        assert np.max(np.abs(kernels.ml_series(gamma, z) - kernels.ml_integral(gamma, z))) \
            < 1e-11


@pytest.mark.parametrize("beta", [0.01, 0.1, 0.5, 0.9, 2.0, 20.0])
@pytest.mark.parametrize("tol", [1e-4, 1e-8])
def test_sum_of_exponentials_accuracy(beta, tol):
    """The fit reaches its tolerance at points it was not measured on, and the number of terms
    grows by a constant per decade of hi/lo (like log(T/k))."""
    counts = []
    for decades in (2, 4, 6, 8):
        fit = kernels.soe_power(beta, 1.0, 10.0**decades, tol)
        u = np.exp(np.random.default_rng(decades).uniform(0.0, decades * math.log(10), 3000))
        error = np.max(np.abs(fit(u) * u**beta - 1.0))
        assert fit.error <= tol and error <= tol
        counts.append(len(fit))
    growth = np.diff(counts)
    assert np.all(growth > 0) and growth.max() - growth.min() <= 3, counts


def test_product_integration_is_exact_for_linear_strain():
    """For eps = a + b t the fractional history (exact and fitted) equals
    alpha (a t^(1-beta)/Gamma(2-beta) + b t^(2-beta)/Gamma(3-beta)), on uneven steps."""
    alpha, beta, a, b = 3.0, 0.4, np.array([1.0, -2.0]), np.array([0.5, 4.0])
    steps = np.random.default_rng(3).uniform(0.005, 0.05, 60)
    fit = kernels.fractional_soe(alpha, beta, steps.min(), steps.sum() + 0.05, 1e-10)
    for history in (DirectFractionalHistory(alpha, beta, "trapezoid"),
                    FractionalHistory(alpha, beta, fit, "trapezoid")):
        history.commit(a, None)
        t = 0.0
        for k in steps:
            t += k
            history.commit(a + b * t, k)
        k = 0.04
        t += k
        H = history.explicit(k) + history.implicit(k)["full"] * (a + b * t)
        exact = alpha * (a * t ** (1 - beta) / math.gamma(2 - beta)
                         + b * t ** (2 - beta) / math.gamma(3 - beta))
        assert np.max(np.abs(H - exact)) <= 1e-9 * np.max(np.abs(exact))


@pytest.mark.parametrize("rule", ["paper", "trapezoid"])
def test_fitted_fractional_history_against_direct(rule):
    """Random strains, uneven steps: fitted and direct histories differ by less than the fit's
    relative error times int r |eps|."""
    alpha, beta, tol = 2.0, 0.5, 1e-8
    rng = np.random.default_rng(5)
    steps = rng.uniform(0.01, 0.05, 200)
    fit = kernels.fractional_soe(alpha, beta, 0.01, steps.sum() + 0.05, tol)
    fitted = FractionalHistory(alpha, beta, fit, rule)
    direct = DirectFractionalHistory(alpha, beta, rule)
    eps = rng.standard_normal(6)
    fitted.commit(eps, None)
    direct.commit(eps, None)
    t = 0.0
    for k in steps:
        t += k
        bound = tol * alpha * (t + 0.05) ** (1 - beta) / math.gamma(2 - beta) * 3.0
        assert np.max(np.abs(fitted.explicit(0.05) - direct.explicit(0.05))) <= bound
        eps = rng.standard_normal(6)
        fitted.commit(eps, k)
        direct.commit(eps, k)


@pytest.mark.convergence
@pytest.mark.parametrize("kernel", ["fractional", "power"])
@pytest.mark.parametrize("rule", ["paper", "trapezoid"])
def test_uniaxial_creep_closed_form_and_order(kernel, rule):
    """Creep of the uniaxial block under constant pressure against the closed form (fractional:
    Mittag-Leffler; power: partial fractions of its 1e-12 fit) at T = 1; observed orders for
    k = 1/10 .. 1/80. The fractional creep behaves like t^(1-beta) at 0, which limits product
    integration to order 2 - beta for both rules; the power kernel is smooth: order 2 for the
    trapezoid rule."""
    exact = uniaxial_exact(kernel, 1.0)
    counts = [10, 20, 40, 80]
    # The 2-cell block gains nothing from a second rank: each rank solves it alone.
    errors = [abs(uniaxial(kernel, rule, 1.0, n, memory={"tolerance": 1e-10},
                           comm=MPI.COMM_SELF)[-1] - exact) for n in counts]
    observed = orders(errors, [1.0 / n for n in counts])
    assert errors[-1] < 1e-3 * abs(exact)
    if kernel == "fractional":
        assert abs(observed[-1] - 1.5) < 0.1, observed           # beta = 0.5
    elif rule == "trapezoid":
        assert observed[-1] > 1.9, observed
    else:
        assert observed[-1] > 1.6, observed


def test_paper_rule_stability_limit_for_the_fractional_kernel():
    """The explicit weight c = alpha k^(1-beta) / Gamma(2-beta) of the paper's variant against
    the uniaxial modulus M = lambda + 2 mu = 134.6: c/M = 0.80 decays, c/M = 1.32 blows up."""
    stable = uniaxial("fractional", "paper", 10.0, 100, memory={"alpha": 300.0},
                      comm=MPI.COMM_SELF)
    unstable = uniaxial("fractional", "paper", 6.0, 60, memory={"alpha": 500.0},
                        comm=MPI.COMM_SELF)
    assert abs(stable[-1]) < 0.1 * abs(stable[0])
    assert np.all(np.abs(np.diff(stable)) < abs(stable[0]))
    assert abs(unstable[-1]) > 1e6 * abs(unstable[0])


PAPER = ["geometry.cells=[8, 8]", "output.probes=[]"]
KERNELS = {"power": ["memory.kernel='power'", "memory.alpha=100.0", "memory.tau=0.1",
                     "memory.beta=0.5"],
           "fractional": ["memory.kernel='fractional'", "memory.alpha=100.0",
                          "memory.beta=0.5"]}


@pytest.mark.parametrize("kernel", KERNELS)
@pytest.mark.parametrize("rule", ["paper", "trapezoid"])
def test_paper_scene_fitted_against_direct_sum(kernel, rule):
    """The paper scene (coarse, 10 steps) with the sum of exponentials against the direct sum
    with the exact kernel: u agrees to the stated tolerance, and so do the contact states."""
    tol = 1e-6
    runs = {}
    for summation in ("soe", "direct"):
        scene = scene_module.load("paper", PAPER + KERNELS[kernel] + [
            f"time.rule='{rule}'", f"memory.summation='{summation}'",
            f"memory.tolerance={tol}"])
        runs[summation] = simulate(scene, comm=COMM, progress=False)
    u_soe, u_direct = (runs[s].problem.u.x.array for s in ("soe", "direct"))
    difference = COMM.allreduce(np.max(np.abs(u_soe - u_direct)), MPI.MAX)
    size = COMM.allreduce(np.max(np.abs(u_direct)), MPI.MAX)
    assert size > 1e-2 and difference <= tol * size, difference / size
    assert [s["status_counts"] for s in runs["soe"].steps] == \
        [s["status_counts"] for s in runs["direct"].steps]


@pytest.mark.mpi
@pytest.mark.skipif(COMM.size == 1, reason="needs mpirun -n 2 or more")
@pytest.mark.parametrize("kernel, rule", [("power", "paper"), ("fractional", "trapezoid")])
def test_ranks_agree(kernel, rule):
    """The distributed run and the one-rank run (COMM_SELF) give the same contact values."""
    scene = scene_module.load("paper", ["geometry.cells=[16, 8]", "time.steps=4",
                                        "output.probes=[]", f"time.rule='{rule}'"]
                              + KERNELS[kernel])
    world = simulate(scene, comm=COMM, progress=False, keep_tables=True)
    single = simulate(scene, comm=MPI.COMM_SELF, progress=False, keep_tables=True)
    for a, b in zip(world.tables, single.tables):
        for key in ("x", "u_nu", "u_tau", "reaction_nu"):
            assert np.max(np.abs(a[key] - b[key])) < 1e-10, key
        assert np.array_equal(a["status"], b["status"])


@pytest.mark.mpi
@pytest.mark.parametrize("kernel", KERNELS)
def test_checkpoint_restores_the_fitted_history(kernel, tmp_path_factory):
    """A problem restored from the checkpoint after 3 steps continues exactly like the one
    that wrote it (same history stress at the next steps)."""
    folder = tmp_path_factory.mktemp("restart") if COMM.rank == 0 else None
    folder = COMM.bcast(str(folder) if folder else None)
    scene = scene_module.load("paper", PAPER + KERNELS[kernel] + ["time.rule='trapezoid'",
                                                                 "time.steps=6"])
    k = scene["time"]["T"] / scene["time"]["steps"]

    def make():
        problem = problem_module.build(scene, geometry.build(scene, COMM))
        return problem, BlockSNES(problem.F, problem.J, problem.unknowns, problem.bcs, COMM)

    first, snes = make()
    for n in range(4):
        first.time.stage(n * k)
        snes.solve()
        first.time.commit()
    checkpoint.save(folder, first, COMM, 3 * k, 4, k)
    second, snes2 = make()
    checkpoint.load(folder, second, COMM)
    assert second.time.committed == first.time.committed == 3 * k
    for problem, solver in ((first, snes), (second, snes2)):
        for n in (4, 5):
            problem.time.stage(n * k)
            solver.solve()
            problem.time.commit()
    assert np.max(np.abs(first.memory.H.x.array)) > 1e-3
    assert np.max(np.abs(first.memory.H.x.array - second.memory.H.x.array)) < 1e-12
    assert np.max(np.abs(first.u.x.array - second.u.x.array)) < 1e-10


@pytest.mark.parametrize("override, words", [
    ("memory.beta=1.0", "memory.beta must lie in [0.01, 0.99] for the fractional"),
    ("memory.beta=-0.2", "memory.beta must lie in"),
    ("memory.tolerance=0.5", "memory.tolerance must be a number in [1e-12, 1e-2]"),
    ("memory.tolerance='small'", "memory.tolerance must be a number"),
    ("memory.part='shear'", "memory.part must be full, deviatoric or volumetric"),
    ("memory.summation='fast'", "memory.summation must be soe or direct"),
])
def test_bad_fractional_keys(override, words):
    with pytest.raises(SceneError, match=words.replace("[", r"\[")
                       .replace("]", r"\]").replace("(", r"\(")):
        scene_module.load("paper", KERNELS["fractional"] + [override])


@pytest.mark.parametrize("override, words", [
    ("memory.tau=0.0", "memory.tau must be a number > 0"),
    ("memory.tau=[0.1]", "memory.tau must be a number > 0"),
    ("memory.beta=0", "memory.beta must be a number in (0, 20]"),
])
def test_bad_power_keys(override, words):
    with pytest.raises(SceneError, match=words.replace("(", r"\(")
                       .replace("]", r"\]")):
        scene_module.load("paper", KERNELS["power"] + [override])
