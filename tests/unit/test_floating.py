"""Two bodies with a body held only by contact (contactvisco.fem.parts,
contactvisco.solver.floating).

The upper of two cylinders (and the cylinder on the block) is held in x at its diameter and
otherwise only by the contact: before loading one slave node touches, frictionless, and the
first Newton matrix is singular (the upper body turns about a point of its diameter). The
iterative solver is handed that null space and the per-part rigid motions as its AMG's
near-nullspace; it must then reach the direct solver's contact forces. The direct solver
gets that matrix stabilized on the floating components, which fixes its step along the free
motion by the load instead of by round-off.
"""
import numpy as np
import pytest
from mpi4py import MPI
from petsc4py import PETSc

from contactvisco.fem import compat
from contactvisco.fem import geometry as geometry_module
from contactvisco.fem import parts
from contactvisco.fem.problem import build
from contactvisco.scene import loader
from contactvisco.errors import SceneError
from contactvisco.solver import floating
from contactvisco.solver import newton as newton_module
from contactvisco.solver.newton import create, near_nullspace
from test_body_contact import (hertz_scene, patch_scene, rigid_limit_scene,
                               two_cylinders_scene)

H = 0.02          # the contact's node spacing: 1857 (two cylinders) and 2002 nodes


def _problem(raw):
    comm = MPI.COMM_WORLD
    scene = loader.resolve(raw)
    return build(scene, geometry_module.build(scene, comm))


def test_components_of_a_graph():
    """Nodes linked by cells: each node gets the smallest node of its component, whatever
    the order of the links (a chain numbered backwards, a node alone, a triangle)."""
    cells = np.array([[5, 4], [4, 3], [3, 2], [2, 1], [7, 8], [8, 7], [10, 12], [12, 11]])
    assert parts.components(cells, 13).tolist() == [0, 1, 1, 1, 1, 1, 6, 7, 7, 9, 10, 10, 10]
    triangles = np.array([[6, 2, 9], [9, 0, 3], [1, 4, 5]])
    assert parts.components(triangles, 10).tolist() == [0, 1, 0, 0, 1, 1, 0, 7, 8, 0]


@pytest.mark.mpi
@pytest.mark.parametrize("scene, floating", [("two_cylinders", 2), ("patch", 1)])
def test_parts_and_their_floating_motions(scene, floating):
    """Two parts that share no node, numbered alike on every rank; the floating motions are
    those of the slave body alone that move no prescribed component: the upper cylinder
    (held in x at its diameter) moves up and turns about a point of its diameter (2), the
    patch's upper block (held in x at its sides) only moves up (1)."""
    raw = two_cylinders_scene(h=H)[0] if scene == "two_cylinders" else patch_scene()
    problem = _problem(raw)
    comm = MPI.COMM_WORLD
    V = problem.V
    labels, count = parts.part_labels(V)
    assert count == 2
    owned = V.dofmap.index_map.size_local
    total = comm.allreduce(owned, MPI.SUM)
    sizes = comm.allreduce(np.bincount(labels[:owned], minlength=count), MPI.SUM)
    assert sizes.sum() == total and sizes.min() > 0
    # a node and its ghost copies carry one label: the labels of each cell's nodes agree
    cells = compat.cell_dofs(V.dofmap)
    assert np.all(labels[cells] == labels[cells[:, :1]])
    motions = parts.floating_motions(V, problem.u_fixed, labels, count)
    assert len(motions) == floating
    held = problem.u_fixed.reshape(-1, 2)[:owned] > 0
    X = V.tabulate_dof_coordinates()[:owned, :2]
    highest = np.full(count, -np.inf)
    np.maximum.at(highest, labels[:owned], X[:, 1])
    everywhere = np.empty_like(highest)
    comm.Allreduce(highest, everywhere, op=MPI.MAX)
    slave = int(np.argmax(everywhere))                         # the upper body
    for motion in motions:
        assert comm.allreduce(float(np.abs(motion[held]).max(initial=0.0)), MPI.MAX) < 1e-12
        on_master = labels[:owned] != slave
        assert comm.allreduce(float(np.abs(motion[on_master]).max(initial=0.0)),
                              MPI.MAX) == 0.0
        strain = _rigid_residual(X[~on_master], motion[~on_master], comm)
        assert strain < 1e-12
    modes = near_nullspace(problem)
    vectors = modes.getVecs()
    assert len(vectors) == 3 * count
    gram = np.array([[a.dot(b) for b in vectors] for a in vectors])
    assert np.allclose(gram, np.eye(3 * count), atol=1e-12)


def _rigid_residual(X, m, comm):
    """How far the field m at points X is from a rigid motion a + w (-y, x): the least
    squares residual over the largest |m| (0 for a rigid motion)."""
    rows = np.zeros((len(X), 2, 3))
    rows[:, 0, 0] = rows[:, 1, 1] = 1.0
    rows[:, 0, 2], rows[:, 1, 2] = -X[:, 1], X[:, 0]
    A = rows.reshape(-1, 3)
    normal = comm.allreduce(A.T @ A, MPI.SUM)
    rhs = comm.allreduce(A.T @ m.ravel(), MPI.SUM)
    coefficients = np.linalg.solve(normal, rhs)
    residual = comm.allreduce(float(np.abs(A @ coefficients - m.ravel()).max(initial=0.0)),
                              MPI.MAX)
    return residual / comm.allreduce(float(np.abs(m).max(initial=0.0)), MPI.MAX)


def _solve(raw, kind):
    """One load step with solver.linear_solver = kind: the slave's nodal contact forces and
    displacements at every contact node (sorted by place), Newton's and Krylov's iterations and the null spaces
    found."""
    raw = {**raw, "solver": {**raw["solver"], "linear_solver": kind}}
    problem = _problem(raw)
    snes = create(problem, MPI.COMM_WORLD)
    problem.time.stage(1.0)
    iterations = snes.solve()
    nodes = problem.contact.nodes
    own = nodes.nodes[nodes.owned]
    c = getattr(snes, "system", snes).contact_forces().array.reshape(-1, 2)[own]
    u = problem.u.x.array.reshape(-1, 2)[own]
    x = problem.V.tabulate_dof_coordinates()[own, :2]
    # every rank gets the slave nodes' values sorted by their places (the two solves need
    # not partition the mesh alike)
    x, c, u = (np.concatenate(MPI.COMM_WORLD.allgather(a)) for a in (x, c, u))
    order = np.lexsort((x[:, 1], x[:, 0]))
    found = list(snes.floating.found) if snes.floating is not None else None
    out = dict(c=c[order], u=u[order], iterations=iterations,
               krylov=list(snes.krylov_iterations), found=found, kind=snes.linear_solver())
    snes.destroy()
    return out


@pytest.mark.mpi
@pytest.mark.parametrize("scene", ["two_cylinders", "cylinder_on_block"])
@pytest.mark.parametrize("pairing", ["mortar", "node_to_segment"])
def test_iterative_solver_reaches_the_direct_contact_forces(scene, pairing):
    """GMRES with the AMG of this PETSc (BoomerAMG or GAMG) on the two-body Hertz scenes at
    h = 0.02: the first Newton matrix has one null motion among the floating ones (the
    upper body's turn), none later (for both solvers); the contact forces and displacements are the direct solver's within
    1e-8 of their largest values (at the slave nodes), and the Krylov iterations per Newton step stay below 100
    (measured: docs/interface.md)."""
    maker = two_cylinders_scene if scene == "two_cylinders" else hertz_scene
    raw, P = maker(pairing, h=H)
    direct = _solve(raw, "direct")
    iterative = _solve(raw, "iterative")
    print(f"{scene}, {pairing}: direct {direct['iterations']} Newton iterations; "
          f"{iterative['kind']} {iterative['iterations']}, Krylov {iterative['krylov']}, "
          f"null motions per Jacobian {iterative['found']}")
    for solved in (direct, iterative):
        assert solved["found"][0] == 1 and not any(solved["found"][1:])
    assert max(iterative["krylov"]) < 100
    for key in ("c", "u"):
        scale = np.abs(direct[key]).max()
        gap = np.abs(direct[key] - iterative[key]).max()
        assert scale > 0.0 and gap <= 1e-8 * scale, (key, gap / scale)
    resultant = iterative["c"].sum(axis=0)
    assert resultant[1] == pytest.approx(-P, rel=1e-10)


def test_a_held_body_attaches_nothing():
    """The patch scene's slave block is held up only by the compliance of its contact,
    which every interface node feels: the iterative solver finds no null motion in any
    Newton matrix and reaches the direct solver's contact forces."""
    raw = patch_scene()
    raw["solver"]["petsc_options"] = {}        # Newton's default tolerances (1e-10)
    direct, iterative = _solve(raw, "direct"), _solve(raw, "iterative")
    assert iterative["found"] and not any(iterative["found"])
    scale = np.abs(direct["c"]).max()
    assert np.abs(direct["c"] - iterative["c"]).max() <= 1e-8 * scale


def test_an_unheld_load_stops_the_krylov_solver_by_name():
    """The two cylinders at h = 0.01: no slave node is active at the first iterate, the load
    pushes the upper body down freely and the least-squares step never moves it; the
    iterative solver stops after two such Newton matrices with a SceneError naming
    solver.linear_solver (the direct solver converges: test_hertz_two_cylinders)."""
    raw, _ = two_cylinders_scene(h=0.01)
    with pytest.raises(SceneError) as err:
        _solve(raw, "iterative")
    assert err.value.key == "solver.linear_solver"
    assert "held only by contact" in str(err.value)


@pytest.mark.parametrize("scene, kind", [("two_cylinders", "preonly/lu"),
                                         ("rigid_limit", "gmres/")])
def test_auto_takes_the_direct_solver_for_a_body_held_by_contact(scene, kind, monkeypatch):
    """linear_solver = "auto" above its size threshold (set to 0 here): the direct solver
    where a body is held only by the contact (the upper cylinder), the iterative one where
    both bodies are clamped (the rigid-limit scene: the body at its left side, the layer at
    its bottom)."""
    monkeypatch.setattr(newton_module, "auto_iterative_size", lambda d: 0)
    raw = two_cylinders_scene(h=H)[0] if scene == "two_cylinders" else rigid_limit_scene(1e4)
    problem = _problem(raw)
    snes = create(problem, MPI.COMM_WORLD)
    try:
        assert snes.linear_solver().startswith(kind)
    finally:
        snes.destroy()


def _chain(springs, n=4):
    """The stiffness matrix of n nodes on a line joined by unit springs (i, j) (COMM_SELF)."""
    A = PETSc.Mat().createAIJ([n, n], nnz=n, comm=MPI.COMM_SELF)
    for i in range(n):
        A.setValue(i, i, 0.0, addv=PETSc.InsertMode.ADD_VALUES)
    for i, j in springs:
        A.setValues([i, j], [i, j], [[1.0, -1.0], [-1.0, 1.0]], addv=PETSc.InsertMode.ADD_VALUES)
    A.assemble()
    return A


def _vector(values):
    vec = PETSc.Vec().createSeq(len(values), comm=MPI.COMM_SELF)
    vec.array[:] = values
    return vec


@pytest.mark.mpi
def test_the_direct_stabilization_moves_a_free_body_along_its_load():
    """Two bodies on a line: nodes 0-1 held at node 0 (its row and column the identity's),
    nodes 2-3 free, f = (0, 0, 1, 1)/sqrt(2) their floating translation. Where no spring
    joins them, J f = 0: stabilize adds eps = STABILIZATION ||J||_inf on the diagonal at
    nodes 2 and 3 only, and the step of (J + eps M) du = -F for a load F on node 3 moves the
    free body by -(f . F)/eps along f, towards where the load pushes, and stretches its
    spring by what the load leaves it. Joined by a spring (the contact holds it), J is left as it was."""
    f = _vector([0.0, 0.0, 1.0, 1.0] / np.sqrt(2.0))
    free = _chain([(0, 1), (2, 3)])
    free.zeroRowsColumns([0], diag=1.0)
    held = _chain([(0, 1), (1, 2), (2, 3)])
    held.zeroRowsColumns([0], diag=1.0)
    diagonal_before = held.getDiagonal().array.copy()
    motions = floating.FloatingNullSpace([f], direct=True)
    try:
        assert motions.prepare(held) == 0
        assert np.array_equal(held.getDiagonal().array, diagonal_before)
        before = free.getDiagonal().array.copy()
        assert motions.prepare(free) == 1
        eps = floating.STABILIZATION * 2.0                     # ||J||_inf = 2
        assert free.getDiagonal().array - before == pytest.approx([0.0, 0.0, eps, eps],
                                                                  rel=1e-6, abs=1e-15)
        F = _vector([0.0, 0.0, 0.0, 1e-3])                     # -F pushes node 3 along -x
        du = F.duplicate()
        ksp = PETSc.KSP().create(comm=MPI.COMM_SELF)
        ksp.setOperators(free)
        ksp.setType("preonly")
        ksp.getPC().setType("lu")
        minus_F = F.copy()
        minus_F.scale(-1.0)
        ksp.solve(minus_F, du)
        along = du.dot(f)
        assert along == pytest.approx(-f.dot(F) / eps, rel=1e-6)
        # The spring carries the half of the load that node 2's added stiffness takes.
        assert du.array[3] - du.array[2] == pytest.approx(-0.5e-3, rel=1e-6)
        assert motions.found == [0, 1]
        for obj in (ksp, minus_F, du, F):
            obj.destroy()
    finally:
        motions.destroy()
        for obj in (free, held):
            obj.destroy()
