"""The displacement-only (condensed) Newton system against the coupled one.

The node-wise elimination of the multipliers must be exact: the same linear-system solution as
the coupled saddle point, hence the same Newton iterates, iteration counts and converged answer
to round-off, on 1 and 2 ranks; and the iterative solver must reach the direct solver's answer
with a Krylov count that does not grow with the mesh.
"""
import numpy as np
import pytest
from mpi4py import MPI

from contactvisco import geometry, problem as problem_module, scene as scene_module
from contactvisco import solver as solver_module
from contactvisco.condensed import eliminate, recover
from contactvisco.run import simulate


def _dense_and_condensed(rng, n, d, m, kinds):
    """A random node-wise system: J dense (n d x n d), per node B_i, C_i, D_i with D_i of the
    given kind (regular, zero, or rank-deficient with the symmetric saddle-point structure of
    an active condition). Returns the solution of the full system and of the condensed one."""
    N = n * d
    M = rng.standard_normal((N, N))
    J = M @ M.T + N * np.eye(N)
    B, C, D = np.zeros((n, d, m)), np.zeros((n, m, d)), np.zeros((n, m, m))
    for i, kind in enumerate(kinds):
        B[i] = rng.standard_normal((d, m))
        C[i] = rng.standard_normal((m, d))
        if kind == "regular":
            D[i] = rng.standard_normal((m, m)) + 3 * np.eye(m)
        elif kind == "zero":                       # every condition active: C ~ B^T
            C[i] = -B[i].T
        else:                                      # one active direction, the rest regular
            q = np.linalg.qr(rng.standard_normal((m, m)))[0]
            D[i] = q[:, 1:] @ np.diag(rng.uniform(1, 2, m - 1)) @ q[:, 1:].T
            C[i] = C[i] + np.outer(q[:, 0], B[i] @ q[:, 0] - C[i].T @ q[:, 0])
    F, G = rng.standard_normal((n, d)), rng.standard_normal((n, m))
    # The full system [J B; C D] [du; dl] = -[F; G].
    size = N + n * m
    K = np.zeros((size, size))
    K[:N, :N] = J
    for i in range(n):
        u, lam = slice(i * d, i * d + d), slice(N + i * m, N + i * m + m)
        K[u, lam], K[lam, u], K[lam, lam] = B[i], C[i], D[i]
    full = np.linalg.solve(K, -np.concatenate([F.ravel(), G.ravel()]))
    scale = np.full(n, np.mean(np.diag(J)))
    parts = eliminate(B, C, D, F, G, scale, np.ones(n))
    S = np.zeros((N, N))
    L = np.zeros((N, N))
    for i in range(n):
        u = slice(i * d, i * d + d)
        S[u, u], L[u, u] = parts["P"][i], parts["L"][i]
    du = np.linalg.solve(S @ J + L, -parts["F_red"].ravel())
    dl = recover(parts, B, C, F, G, du.reshape(n, d), (J @ du).reshape(n, d))
    return full, np.concatenate([du, dl.ravel()]), parts


@pytest.mark.parametrize("d, m", [(2, 1), (2, 3), (3, 4)])
def test_elimination_is_exact(d, m):
    """Condensed solve + node-wise recovery = the full saddle-point solve, for regular, zero and
    rank-deficient multiplier blocks."""
    rng = np.random.default_rng(d * 10 + m)
    # D_i = 0 needs m <= d: more active conditions than displacement components is singular.
    kinds = ["regular", "deficient", "regular", "deficient"] if m > 1 else []
    kinds += ["zero", "regular", "zero"] if m <= d else []
    full, condensed, parts = _dense_and_condensed(rng, len(kinds), d, m, kinds)
    assert np.max(np.abs(full - condensed)) <= 1e-10 * np.max(np.abs(full))
    expected_k = {"regular": 0, "zero": m, "deficient": 1}
    assert list(parts["nullity"]) == [expected_k[k] for k in kinds]


def test_constraint_rows_have_positive_diagonal():
    """Where a condition is active, the condensed rows of the node are s_i I on the constrained
    directions (what multigrid smoothers need), whatever basis the SVD returned."""
    rng = np.random.default_rng(3)
    d = m = 3
    B = np.zeros((1, d, m))
    B[0] = -np.diag([1.0, 1.0, 0.0])          # two tangential reactions, as in sticking
    C = np.transpose(B, (0, 2, 1)).copy()
    D = np.zeros((1, m, m))
    D[0, 2, 2] = -1.0
    parts = eliminate(B, C, D, rng.standard_normal((1, d)), rng.standard_normal((1, m)),
                      np.array([7.0]), np.array([1.0]))
    assert parts["nullity"][0] == 2
    assert np.allclose(parts["L"][0], np.diag([7.0, 7.0, 0.0]), atol=1e-12)
    assert np.allclose(parts["P"][0], np.diag([0.0, 0.0, 1.0]), atol=1e-12)


SCENES = {
    "paper": ["geometry.cells=[16, 16]", "time.T=0.4", "time.steps=4"],
    "ironing": ["time.steps=8", "time.T=0.4"],
    "block3d": ["geometry.parameters.h=0.25", "time.T=0.5", "time.steps=5"],
    "hertz": [],
}


def _run(name, sets, system, linear_solver="direct", comm=MPI.COMM_WORLD):
    scene = scene_module.load(name, sets + [f"solver.linear_system='{system}'",
                                            f"solver.linear_solver='{linear_solver}'"])
    scene["output"]["probes"] = []
    return simulate(scene, comm=comm, progress=False, keep_tables=True)


@pytest.mark.parametrize("name", list(SCENES))
def test_condensed_equals_coupled(name):
    """Same Newton iteration counts and the same contact values to round-off (every step)."""
    coupled = _run(name, SCENES[name], "coupled")
    condensed = _run(name, SCENES[name], "condensed")
    assert condensed.linear_system == "condensed" and coupled.linear_system == "coupled"
    assert [s["newton_iterations"] for s in condensed.steps] == \
        [s["newton_iterations"] for s in coupled.steps]
    for a, b in zip(coupled.tables, condensed.tables):
        for key in ("u_nu", "u_tau", "lambda_nu", "reaction_nu", "reaction_tau"):
            scale = max(1e-12, np.max(np.abs(a[key])))
            assert np.max(np.abs(a[key] - b[key])) <= 1e-10 * scale, key
        assert np.array_equal(a["status"], b["status"])


#: BoomerAMG where PETSc has hypre, else GAMG.
AMG = "gmres/" + solver_module.iterative_options()["pc_type"]


def test_iterative_reaches_the_direct_answer():
    """GMRES + algebraic multigrid on the condensed system: the direct solver's contact values to the
    Newton tolerance, with a Krylov count per Newton step that stays bounded from 16^2 to
    48^2 cells."""
    counts = {}
    for cells in (16, 48):
        sets = [f"geometry.cells=[{cells}, {cells}]", "time.T=0.3", "time.steps=3"]
        direct = _run("paper", sets, "condensed", "direct")
        iterative = _run("paper", sets, "condensed", "iterative")
        assert iterative.linear_solver == AMG
        a, b = direct.tables[-1], iterative.tables[-1]
        assert np.array_equal(a["status"], b["status"])
        assert np.max(np.abs(a["u_nu"] - b["u_nu"])) <= 1e-9
        assert np.max(np.abs(a["lambda_nu"] - b["lambda_nu"])) <= 1e-7 * np.max(np.abs(a["lambda_nu"]))
        counts[cells] = max(k for s in iterative.steps for k in s["krylov_iterations"])
    assert counts[48] <= 1.5 * counts[16] and counts[48] <= 40, counts


def test_auto_choice():
    """auto: condensed for nodal quadrature, coupled for Gauss; direct below the size
    threshold, iterative above it (threshold lowered to test the switch)."""
    scene = scene_module.load("paper", ["geometry.cells=[4, 4]"])
    geo = geometry.build(scene, MPI.COMM_WORLD)
    problem = problem_module.build(scene, geo)
    newton = solver_module.create(problem, MPI.COMM_WORLD)
    assert (newton.system_kind, newton.linear_solver()) == ("condensed", "preonly/lu")
    thresholds = (solver_module.AUTO_ITERATIVE, solver_module.AUTO_ITERATIVE_GAMG)
    saved = [dict(t) for t in thresholds]
    try:
        for t in thresholds:
            t[2] = 10
        newton = solver_module.create(problem, MPI.COMM_WORLD)
        assert newton.linear_solver() == AMG
    finally:
        for t, old in zip(thresholds, saved):
            t.update(old)
    scene = scene_module.load("paper", ["geometry.cells=[4, 4]",
                                        "discretization.contact_quadrature='gauss'"])
    problem = problem_module.build(scene, geometry.build(scene, MPI.COMM_WORLD))
    assert solver_module.create(problem, MPI.COMM_WORLD).system_kind == "coupled"


@pytest.mark.parametrize("sets, message", [
    (["solver.linear_system='schur'"], "solver.linear_system must be"),
    (["solver.linear_solver='cg'"], "solver.linear_solver must be"),
    (["solver.linear_system='condensed'", "discretization.contact_quadrature='gauss'"],
     "needs discretization.contact_quadrature = 'nodal'"),
])
def test_bad_solver_keys(sets, message):
    with pytest.raises(scene_module.SceneError, match=message):
        scene_module.load("paper", sets)


def test_iterative_needs_condensed():
    scene = scene_module.load("paper", ["geometry.cells=[4, 4]", "solver.linear_system='coupled'",
                                        "solver.linear_solver='iterative'"])
    problem = problem_module.build(scene, geometry.build(scene, MPI.COMM_WORLD))
    with pytest.raises(scene_module.SceneError, match="needs the displacement-only system"):
        solver_module.create(problem, MPI.COMM_WORLD)
