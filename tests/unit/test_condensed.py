"""The displacement-only (condensed) Newton system against the coupled one.

The node-wise elimination of the multipliers must be exact: the same linear-system solution as
the coupled saddle point, hence the same Newton iterates, iteration counts and converged answer
to round-off, on 1 and 2 ranks; and the iterative solver must reach the direct solver's answer
with a Krylov count that does not grow with the mesh. The node blocks the elimination starts
from are the entries of the assembled coupled Jacobian, and reading them refuses a contact row
that couples unknowns of other nodes.
"""
import numpy as np
import pytest
from mpi4py import MPI

from petsc4py import PETSc

from contactvisco.errors import SceneError
from contactvisco.fem import compat, contact_state, geometry, problem as problem_module
from contactvisco.scene import loader as scene_module
from contactvisco.solver import newton as solver_module
from contactvisco.solver.condensed import (NodalCondensation, NodeBlocks, eliminate, node_blocks,
                                           recover)
from contactvisco.solver.time_loop import simulate
from helpers import condensed_at


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


def _coupled_node_blocks(system, bcs):
    """Per owned contact node, the (d + m) x (d + m) block of the coupled Jacobian [[J, B],
    [C, D]] on the node's own unknowns, assembled with the coupled system's Dirichlet rows
    and columns (diagonal 1), as the coupled Newton method solves it; from the forms the
    system compiled (J_uu and the coupling blocks), so no form is compiled twice."""
    count = 1 + len(system.fields)
    forms = [[None] * count for _ in range(count)]
    forms[0][0] = system.J_uu
    for (i, j), (form, _) in system.couplings.items():
        forms[i][j] = form
    A = compat.block_matrix(forms)
    # Multiplier dofs off Gamma_C have no diagonal in the ds blocks' pattern: their Dirichlet
    # rows get one here (the coupled solver adds a zero dx mass term for it).
    A.setOption(PETSc.Mat.Option.NEW_NONZERO_ALLOCATION_ERR, False)
    A.zeroEntries()
    compat.assemble_block_matrix(A, forms, bcs, diagonal=1.0)
    A.assemble()
    # Blocked layout: on each rank the owned dofs of u, then of each multiplier.
    spaces = [system.V] + [f.function_space for f in system.fields]
    sizes = [V.dofmap.index_map.size_local * V.dofmap.index_map_bs for V in spaces]
    start = A.getOwnershipRange()[0] + np.concatenate([[0], np.cumsum(sizes)])
    index = np.concatenate([start[k] + (system.own[:, None] * V.dofmap.index_map_bs
                                        + np.arange(V.dofmap.index_map_bs))
                            for k, V in enumerate(spaces)], axis=1).astype(PETSc.IntType)
    n, size = index.shape
    dense = A.getValues(index.ravel(), index.ravel()).reshape(n, size, n, size)
    A.destroy()
    return np.einsum("iaib->iab", dense)


NODE_BLOCK_SCENES = {     # states with bound, sticking and prescribed contact nodes
    "paper bound + stick": ("paper", ["geometry.cells=[16, 16]", "time.T=0.2", "time.steps=2",
                                      "contact.mu=3.0"], {1, 2}),
    "3D bound + stick": ("block3d", ["geometry.parameters.h=0.25", "time.T=0.4",
                                     "time.steps=2"], {1, 3}),
}


@pytest.mark.mpi
@pytest.mark.parametrize("label", list(NODE_BLOCK_SCENES))
def test_node_blocks_are_the_coupled_jacobian(label):
    """B_i, C_i, D_i read from the assembled coupling blocks equal the entries of the coupled
    Jacobian on node i's unknowns, with its Dirichlet rows and columns: B zero on prescribed
    u rows and multiplier columns, D the identity on prescribed multipliers. C keeps its
    columns of prescribed u components (the coupled matrix zeroes them; du is zero there),
    so those are left out. The named null-space sizes must occur (the blocks are not
    trivially zero)."""
    name, sets, nullities = NODE_BLOCK_SCENES[label]
    comm = MPI.COMM_WORLD
    scene = scene_module.load(name, sets)
    scene["output"]["probes"] = []
    problem = simulate(scene, comm=comm, progress=False).problem
    system, x = condensed_at(problem)
    system.residual(x, x.duplicate())
    B, C, D = system.local_blocks()
    K = _coupled_node_blocks(system, problem.bcs)
    d = system.d
    free_u = ~system.fixed_u[:, None, :]
    scale = comm.allreduce(np.max(np.abs(K[:, d:, :]), initial=0.0), MPI.MAX)
    for got, expected in ((B, K[:, :d, d:]), (C * free_u, K[:, d:, :d] * free_u),
                          (D, K[:, d:, d:])):
        error = comm.allreduce(np.max(np.abs(got - expected), initial=0.0), MPI.MAX)
        assert error <= 1e-12 * scale, (error, scale)
    seen = set().union(*comm.allgather(set(system.parts["nullity"].tolist())))
    assert nullities <= seen, seen


def _synthetic(comm, stray):
    """An MPI matrix with 4 rows per rank: two nodes of 2 rows each, whose columns are the
    first 4 columns of the next rank (so global, off-rank columns are read). Node 0's rows
    also store an explicit zero in node 1's columns (allowed); with `stray`, rank 0's last
    row gets a non-zero in its node 0's columns. Returns (matrix, rows, columns, blocks)."""
    size = 4 * comm.size
    base = 4 * ((comm.rank + 1) % comm.size)
    A = PETSc.Mat().createAIJ(((4, size), (4, size)), nnz=(4, 4), comm=comm)
    rows = 4 * comm.rank + np.arange(4, dtype=PETSc.IntType).reshape(2, 2)
    columns = base + np.arange(4, dtype=PETSc.IntType).reshape(2, 2)
    expected = 10.0 * comm.rank + 1.0 + np.arange(8.0).reshape(2, 2, 2)
    for i in range(2):
        A.setValues(rows[i], columns[i], expected[i])
    A.setValues(rows[0], columns[1], np.zeros((2, 2)))
    if stray and comm.rank == 0:
        A.setValues([rows[1, 1]], [columns[0, 0]], [3.5])
    A.assemble()
    return A, rows, columns, expected


def test_node_blocks_refuse_a_row_outside_the_vertex_rule():
    """node_blocks reads each node's block (columns on another rank included) and ignores
    stored zeros; a non-zero entry of a node's row in another node's column (on rank 0 only)
    raises on every rank, naming the block, that row and that column."""
    comm = MPI.COMM_WORLD
    A, rows, columns, expected = _synthetic(comm, stray=False)
    assert np.array_equal(node_blocks(A, rows, columns), expected)
    A.destroy()
    A, rows, columns, _ = _synthetic(comm, stray=True)
    row, column = comm.bcast((int(rows[1, 1]), int(columns[0, 0])), root=0)
    with pytest.raises(ValueError, match=rf"^B block: row {row} of a contact node holds 3.5 "
                                         rf"in column {column}, outside"):
        node_blocks(A, rows, columns, "B block")
    A.destroy()


@pytest.mark.mpi
def test_kept_node_blocks_follow_new_values_and_refuse_a_stray_one():
    """NodeBlocks keeps its index sets, submatrix and entry layout across reads of one
    pattern: a second read gives the new values, and a stored zero outside a node's columns
    that has become non-zero (node 0's rows in node 1's columns, on the last rank) raises
    on every rank, as a fresh node_blocks does."""
    comm = MPI.COMM_WORLD
    A, rows, columns, expected = _synthetic(comm, stray=False)
    reader = NodeBlocks(rows, columns, "B block")
    assert np.array_equal(reader.read(A), expected)
    for i in range(2):
        A.setValues(rows[i], columns[i], -2.0 * expected[i])
    A.assemble()
    assert np.array_equal(reader.read(A), -2.0 * expected)
    if comm.rank == comm.size - 1:
        A.setValues([rows[0, 1]], [columns[1, 0]], [7.25])
    A.assemble()
    row, column = comm.bcast((int(rows[0, 1]), int(columns[1, 0])), root=comm.size - 1)
    for read in (reader.read, lambda M: node_blocks(M, rows, columns, "B block")):
        with pytest.raises(ValueError, match=rf"^B block: row {row} of a contact node holds "
                                             rf"7.25 in column {column}, outside"):
            read(A)
    reader.destroy()
    A.destroy()


def test_gauss_contact_rows_are_refused():
    """With Gauss quadrature on Gamma_C a contact row couples the neighbouring nodes: reading
    the node blocks of that real scene raises on every rank, naming a Jacobian block."""
    scene = scene_module.load("paper", ["geometry.cells=[4, 4]",
                                        "discretization.contact_quadrature='gauss'"])
    problem = problem_module.build(scene, geometry.build(scene, MPI.COMM_WORLD))
    with pytest.raises(ValueError, match=r"^the Jacobian block \(rows of .*, columns of .*\): "
                                         r"row \d+ of a contact node holds .* outside"):
        NodalCondensation(problem).local_blocks()


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


@pytest.mark.mpi
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


@pytest.mark.mpi
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


@pytest.mark.mpi
def test_iterative_reaches_the_direct_answer_with_slip_in_3d():
    """The same in 3D with nodes sliding on the friction disc, whose condensed rows are not
    symmetric: the Chebyshev smoothing of the V-cycle (its eigenvalue bound estimated as for
    a symmetric matrix) still gives the direct solver's contact states and values."""
    sets = ["time.T=0.6", "time.steps=6"]
    direct = _run("block3d", sets, "condensed", "direct")
    iterative = _run("block3d", sets, "condensed", "iterative")
    assert iterative.linear_solver == AMG
    a, b = direct.tables[-1], iterative.tables[-1]
    slip = contact_state.STICK_SLIP_STATES.index("slip")
    assert np.count_nonzero(a["friction"] == slip) >= 10, np.unique(a["friction"])
    assert np.array_equal(a["status"], b["status"])
    assert np.array_equal(a["friction"], b["friction"])
    for key in ("u_nu", "u_tau", "lambda_nu", "reaction_nu", "reaction_tau"):
        scale = np.max(np.abs(a[key]))
        assert np.max(np.abs(a[key] - b[key])) <= 1e-9 * scale, key
    assert max(k for s in iterative.steps for k in s["krylov_iterations"]) <= 60


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
    (["solver.line_search='bt'"], "solver.line_search must be"),
    (["solver.linear_system='condensed'", "discretization.contact_quadrature='gauss'"],
     "needs discretization.contact_quadrature = 'nodal'"),
])
def test_bad_solver_keys(sets, message):
    with pytest.raises(SceneError, match=message):
        scene_module.load("paper", sets)


def test_iterative_needs_condensed():
    scene = scene_module.load("paper", ["geometry.cells=[4, 4]", "solver.linear_system='coupled'",
                                        "solver.linear_solver='iterative'"])
    problem = problem_module.build(scene, geometry.build(scene, MPI.COMM_WORLD))
    with pytest.raises(SceneError, match="needs the displacement-only system"):
        solver_module.create(problem, MPI.COMM_WORLD)


@pytest.mark.mpi
def test_kept_bulk_matrix_equals_the_whole_assembly():
    """J_uu from the kept cell part plus the facet part of Gamma_C (BulkPart) is J_uu
    assembled whole, pattern and values (to 1e-14 of the largest entry), at a contact state
    with active nodes and after a Constant of the cell part (the Lame constant mu) changed;
    a law whose cell part uses a Function (Hencky) is assembled whole."""
    scene = scene_module.load("paper", ["geometry.cells=[6, 6]"])
    problem = problem_module.build(scene, geometry.build(scene, MPI.COMM_WORLD))
    system = NodalCondensation(problem)
    assert system._bulk.split
    whole = system.A.duplicate()

    def compare():
        system._assemble_J()
        whole.zeroEntries()
        compat.assemble_matrix(whole, system.J_uu, system.bcs, diagonal=1.0)
        whole.assemble()
        a, b = system.A.getValuesCSR(), whole.getValuesCSR()
        assert np.array_equal(a[0], b[0]) and np.array_equal(a[1], b[1])
        assert np.max(np.abs(a[2] - b[2])) <= 1e-14 * np.max(np.abs(b[2]))

    problem.u.x.array.reshape(-1, 2)[:, 1] = -np.linspace(0.0, 0.3, len(problem.u.x.array) // 2)
    compare()
    problem.constants["lame_mu"].value *= 1.5      # a Constant of the cell part changes
    compare()
    hencky = scene_module.load("paper", ["geometry.cells=[4, 4]", "material.law='hencky'"])
    problem = problem_module.build(hencky, geometry.build(hencky, MPI.COMM_WORLD))
    assert not NodalCondensation(problem)._bulk.split
