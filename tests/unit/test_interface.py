"""The projection operators of an interface between two bodies (contactvisco.fem.interface):
node-to-segment and mortar Pi on plain arrays (flat, inclined and curved traces, matching and
not) and on a DOLFINx mesh of two blocks, on 1 and 2 ranks."""
import numpy as np
import pytest
from mpi4py import MPI

from contactvisco.errors import SceneError
from contactvisco.fem import interface

METHODS = ("node_to_segment", "mortar")
SEARCH = 0.05


def rotation(degrees):
    a = np.deg2rad(degrees)
    return np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])


def arc(n, curvature=0.0, start=0.0, end=1.0):
    """n + 1 points of the curve y = curvature x (1 - x) over [start, end]."""
    x = np.linspace(start, end, n + 1)
    return np.stack([x, curvature * x * (1.0 - x)], axis=1)


def master_of(points, first=1000):
    """A master trace below the curve through `points` (outward normal up): segments from right
    to left, nodes first + j."""
    nodes = np.arange(first, first + len(points))
    return interface.Surface.from_arrays(
        np.stack([points[1:], points[:-1]], axis=1), np.stack([nodes[1:], nodes[:-1]], axis=1))


def slave_of(points):
    """A slave trace above the curve (outward normal down): segments from left to right, nodes
    0, 1, ..."""
    nodes = np.arange(len(points))
    return nodes, interface.Surface.from_arrays(
        np.stack([points[:-1], points[1:]], axis=1), np.stack([nodes[:-1], nodes[1:]], axis=1))


def pairing(method, slave_points, master_points, search=SEARCH):
    nodes, trace = slave_of(slave_points)
    master = master_of(master_points)
    if method == "mortar":
        return interface.mortar(nodes, trace, master, search)
    return interface.node_to_segment(nodes, slave_points, master, search)


def positions(points, first=0):
    return {first + j: p for j, p in enumerate(points)}


def linear(p):
    return 3.0 * p[0] - 2.0 * p[1] + 1.0


# ------------------------------------------------------------------ plain arrays

@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("degrees", [0.0, 30.0])
def test_non_matching_flat_traces_reproduce_constants_and_linear_fields(method, degrees):
    """10 master against 13 slave segments on a line (turned by 0 or 30 degrees): every row
    of Pi sums to 1 and a linear field of the master is the field at the slave nodes."""
    R = rotation(degrees)
    slave, master = arc(13) @ R.T, arc(10) @ R.T
    pi = pairing(method, slave, master)
    assert not pi.unpaired
    ones = pi.apply(lambda k: 1.0)
    assert max(abs(v - 1.0) for v in ones.values()) < 1e-14
    image = pi.apply(lambda k: linear(master[k - 1000]))
    assert max(abs(image[i] - linear(slave[i])) for i in image) < 1e-13
    # Pi is not the trivial operator: most slave nodes take more than one master node.
    assert len(pi.rows) > len(slave) + 5


def test_node_to_segment_on_a_curved_trace_takes_the_field_at_the_closest_point():
    """Slave nodes anywhere on a curved master polyline get the master's linear field there
    exactly; lifted off it along the facet normal by g, they get the gap g, that normal and
    the field at their foot."""
    rng = np.random.default_rng(3)
    master = arc(10, curvature=0.8)
    facet = rng.integers(0, 10, size=25)
    s = rng.uniform(0.0, 1.0, size=25)
    on = master[facet] + s[:, None] * (master[facet + 1] - master[facet])
    surface = master_of(master)
    nodes = np.arange(len(on))
    pi = interface.node_to_segment(nodes, on, surface, SEARCH)
    image = pi.apply(lambda k: linear(master[k - 1000]))
    assert max(abs(image[i] - linear(on[i])) for i in nodes) < 1e-13
    t = master[facet + 1] - master[facet]
    normal = np.stack([-t[:, 1], t[:, 0]], axis=1) / np.linalg.norm(t, axis=1)[:, None]
    gap = rng.uniform(-0.01, 0.01, size=25)
    found = interface.project(on + gap[:, None] * normal, surface, SEARCH)
    assert np.max(np.abs(found.gap - gap)) < 1e-13
    assert np.max(np.abs(found.normal - normal)) < 1e-13
    foot = np.einsum("nk,nkg->ng", found.shape, surface.coordinates[found.facet])
    assert np.max(np.abs(foot - on)) < 1e-13


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("curvature", [0.0, 0.8])
def test_matching_traces_give_the_identity_incidence(method, curvature):
    """The same nodes on both sides (flat or curved): Pi_ik = 1 for the master node at slave
    node i, 0 elsewhere."""
    points = arc(12, curvature)
    pi = pairing(method, points, points).as_dict()
    expected = {(i, 1000 + i): 1.0 for i in range(len(points))}
    assert {key for key, v in pi.items() if abs(v) > 1e-13} == set(expected)
    assert max(abs(pi[key] - 1.0) for key in expected) < 1e-13


def _plain_mortar(slave, master, points):
    """M_ik by `points`-point Gauss on each whole slave segment (no cutting), the master point
    of a slave point X found by intersecting the line X + s n_s with the master segments."""
    nodes, trace = slave_of(slave)
    surface = master_of(master)
    xg, wg = np.polynomial.legendre.leggauss(points)
    xg, wg = 0.5 * (xg + 1.0), 0.5 * wg
    M = {}
    for (A, B), (iA, iB), n in zip(trace.coordinates, trace.nodes, trace.normals):
        L = np.linalg.norm(B - A)
        for xi, w in zip(xg, wg):
            X = A + xi * (B - A)
            for (P, Q), (kP, kQ) in zip(surface.coordinates, surface.nodes):
                # X + s n = P + eta (Q - P)
                s, eta = np.linalg.solve(np.stack([n, P - Q], axis=1), P - X)
                if 0.0 <= eta <= 1.0:
                    break
            else:
                continue
            for i, phi in ((iA, 2.0 - 3.0 * xi), (iB, 3.0 * xi - 1.0)):
                for k, N in ((kP, 1.0 - eta), (kQ, eta)):
                    M[(i, k)] = M.get((i, k), 0.0) + w * L * phi * N
    return M


def test_mortar_integrals_are_exact_where_plain_quadrature_converges():
    """M of the cut segments against 20-, 40- and 160-point Gauss on whole slave segments (a
    curved interface, 13 slave and 10 master segments): the plain quadrature's error (summed
    over M's entries) falls as it is refined, about as n^-2 (the integrand has kinks at the
    master nodes), towards the cut value."""
    slave, master = arc(13, 0.3), arc(10, 0.3)
    cut = pairing("mortar", slave, master)
    exact = {(int(i), int(k)): v for i, k, v in zip(cut.rows, cut.cols, cut.mortar)}

    def error(points):
        plain = _plain_mortar(slave, master, points)
        keys = set(plain) | set(exact)
        return sum(abs(plain.get(key, 0.0) - exact.get(key, 0.0)) for key in keys)

    errors = [error(n) for n in (20, 40, 160)]
    assert errors[0] > 1e-6, errors                      # the plain rule is not exact
    assert errors[1] < errors[0] / 2.5 and errors[2] < errors[1] / 4, errors
    assert errors[2] < 2e-5, errors


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("degrees", [0.0, 30.0])
def test_weighted_gap_of_a_rigid_translation_is_its_normal_component(method, degrees):
    """The master moved by (a, b), Pi rebuilt on the moved master (the cut points move with
    it): every slave node's gap n . (x_i - sum_k Pi_ik x_k) changes by -(a, b) . n exactly;
    and the gap of the displacement field u_m = (a, b), u_s = 0 is -(a, b) . n."""
    R = rotation(degrees)
    slave, master = arc(13) @ R.T + R @ [0.0, 0.01], arc(10) @ R.T
    normal = R @ [0.0, 1.0]
    shift = np.array([0.037, -0.004])
    normals = {i: normal for i in range(len(slave))}
    before = interface.weighted_gap(pairing(method, slave, master), positions(slave),
                                    positions(master, 1000), normals)
    moved = pairing(method, slave, master + shift)
    after = interface.weighted_gap(moved, positions(slave), positions(master + shift, 1000),
                                   normals)
    # The nodes whose support the moved master covers (x +- h in [a, 1 + a] along the line).
    along, h = (R.T @ shift)[0], 1.0 / 13
    inner = [i for i in range(len(slave)) if i * h - h >= along and i * h + h <= 1.0 + along]
    assert len(inner) >= 9
    assert max(abs(after[i] - before[i] + shift @ normal) for i in inner) < 1e-13
    assert max(abs(before[i] - 0.01) for i in before) < 1e-13
    u = interface.weighted_gap(moved, {i: np.zeros(2) for i in range(len(slave))},
                               {1000 + k: shift for k in range(len(master))}, normals)
    assert max(abs(u[i] + shift @ normal) for i in inner) < 1e-13


def test_nodes_beyond_the_master_are_reported():
    """A slave trace longer than the master: node_to_segment reports the nodes farther than
    the search distance, mortar the nodes with no master on their support; the nodes whose
    support the master covers keep rows that sum to 1."""
    slave, master = arc(12, start=-0.5, end=1.5), arc(10)
    n2s = pairing("node_to_segment", slave, master)
    far = [i for i, p in enumerate(slave) if p[0] < -SEARCH or p[0] > 1.0 + SEARCH]
    assert n2s.unpaired == far and far
    mortar = pairing("mortar", slave, master)
    h = 2.0 / 12
    bare = [i for i, p in enumerate(slave) if p[0] + h <= 1e-12 or p[0] - h >= 1.0 - 1e-12]
    assert mortar.unpaired == bare and bare
    ones = mortar.apply(lambda k: 1.0)
    covered = [i for i, p in enumerate(slave) if p[0] - h >= -1e-12 and p[0] + h <= 1 + 1e-12]
    assert max(abs(ones[i] - 1.0) for i in covered) < 1e-14
    partly = [i for i in range(len(slave)) if i not in covered and i not in bare]
    assert all(abs(ones[i] - 1.0) > 1e-3 for i in partly)


def test_closest_points_on_triangles():
    """3D: points above and beside a triangulated patch of the plane z = x/2: the closest
    point's distance is the least over a dense sampling of the triangles (never more, and
    within the sampling's resolution), the shape functions reproduce a linear field at the
    closest point, and the gap of a point above the patch is its height along the normal."""
    rng = np.random.default_rng(5)
    grid = np.array([[x, y, 0.5 * x] for y in (0.0, 0.5, 1.0) for x in (0.0, 0.5, 1.0)])
    triangles = []
    for j in range(2):
        for i in range(2):
            a, b, c, d = 3 * j + i, 3 * j + i + 1, 3 * j + i + 4, 3 * j + i + 3
            triangles += [(a, b, c), (a, c, d)]
    triangles = np.array(triangles)
    surface = interface.Surface.from_arrays(grid[triangles], triangles)
    normal = np.array([-0.5, 0.0, 1.0]) / np.sqrt(1.25)
    assert np.allclose(surface.normals, normal)
    points = rng.uniform([-0.3, -0.3, -0.2], [1.3, 1.3, 0.8], size=(40, 3))
    found = interface.project(points, surface, 10.0)
    assert not found.missing
    foot = np.einsum("nk,nkg->ng", found.shape, surface.coordinates[found.facet])
    distance = np.linalg.norm(points - foot, axis=1)
    u, v = np.meshgrid(np.linspace(0, 1, 201), np.linspace(0, 1, 201))
    keep = u + v <= 1.0
    u, v = u[keep], v[keep]
    samples = np.concatenate([tri[0] + u[:, None] * (tri[1] - tri[0])
                              + v[:, None] * (tri[2] - tri[0]) for tri in grid[triangles]])
    sampled = np.min(np.linalg.norm(points[:, None, :] - samples[None], axis=2), axis=1)
    assert np.all(distance <= sampled + 1e-14)
    assert np.all(sampled - distance < 0.5 * 0.5 / 200 * 1.5)
    field = lambda p: 2.0 * p[..., 0] - p[..., 1] + 4.0 * p[..., 2]       # noqa: E731
    values = np.einsum("nk,nk->n", found.shape, field(surface.coordinates[found.facet]))
    assert np.max(np.abs(values - field(foot))) < 1e-13
    above = interface.project(np.array([[0.3, 0.6, 0.15]]) + 0.02 * normal, surface, 0.1)
    assert abs(above.gap[0] - 0.02) < 1e-14
    assert interface.project(np.array([[0.3, 0.6, 0.5]]), surface, 0.1).missing == [0]


def test_bad_pairing_requests_are_scene_errors():
    """An unknown method or a search distance that is not > 0 is a SceneError naming the key."""
    nodes, trace = slave_of(arc(3))
    side = interface.SlaveSide(nodes, arc(3), trace)
    for method, search in (("closest", 0.1), ("mortar", 0.0), ("mortar", float("nan"))):
        with pytest.raises(SceneError, match="node_to_segment|search distance") as info:
            interface.pair(side, master_of(arc(2)), method, search)
        assert info.value.key == "contact.pairing"


def square_grid(n, flip=False, first=0):
    """The unit square z = 0 cut into n x n squares of two triangles each (diagonals one way
    or the other), counter-clockwise seen from +z: (vertices, triangles with node numbers)."""
    t = np.linspace(0.0, 1.0, n + 1)
    points = np.array([[x, y, 0.0] for y in t for x in t])
    triangles = []
    for j in range(n):
        for i in range(n):
            a, b, c, d = (j * (n + 1) + i, j * (n + 1) + i + 1, (j + 1) * (n + 1) + i + 1,
                          (j + 1) * (n + 1) + i)
            triangles += [(a, b, d), (b, c, d)] if flip else [(a, b, c), (a, c, d)]
    return points, np.array(triangles) + first


def mortar_3d(slave_grid, master_grid, turn=np.eye(3), lift=0.0):
    """Pi of a slave grid (normal -z) above a master grid (normal +z), both turned by `turn`."""
    (xs, ts), (xm, tm) = slave_grid, master_grid
    xs, xm = (xs + [0.0, 0.0, lift]) @ turn.T, xm @ turn.T
    slave = interface.Surface.from_arrays(xs[ts[:, ::-1]], ts[:, ::-1])
    master = interface.Surface.from_arrays(xm[tm - 1000], tm)
    return xs, xm, interface.mortar(np.arange(len(xs)), slave, master, SEARCH)


TURN = np.array([[0.6, 0.0, -0.8], [0.0, 1.0, 0.0], [0.8, 0.0, 0.6]])


@pytest.mark.parametrize("turn", [np.eye(3), TURN], ids=["flat", "turned"])
def test_mortar_3d_reproduces_constants_and_linear_fields(turn):
    """A 5 x 5 slave grid against a 4 x 4 master grid with the other diagonals (a plane, turned
    or not): rows sum to 1 and a linear field of the master is the field at the slave
    nodes, to 1e-13."""
    xs, xm, pi = mortar_3d(square_grid(5), square_grid(4, flip=True, first=1000), turn)
    assert not pi.unpaired
    ones = pi.apply(lambda k: 1.0)
    assert max(abs(v - 1.0) for v in ones.values()) < 1e-13
    field = lambda p: 1.0 + 2.0 * p[0] - 3.0 * p[1] + 0.7 * p[2]              # noqa: E731
    image = pi.apply(lambda k: field(xm[k - 1000]))
    assert max(abs(image[i] - field(xs[i])) for i in image) < 1e-13
    assert len(pi.rows) > 3 * len(xs)


def test_mortar_3d_matching_grids_give_the_identity_incidence():
    xs, xm, pi = mortar_3d(square_grid(4), square_grid(4, first=1000), TURN)
    entries = {key: v for key, v in pi.as_dict().items() if abs(v) > 1e-13}
    assert set(entries) == {(i, 1000 + i) for i in range(len(xs))}
    assert max(abs(v - 1.0) for v in entries.values()) < 1e-13


def test_mortar_3d_weighted_gap_of_a_rigid_translation():
    """The master grid moved by (a, b, c) in its plane and across it, Pi rebuilt: the gap
    n . (x_i - sum_k Pi_ik x_k) of every slave node whose support the moved master covers
    changes by exactly -(a, b, c) . n."""
    shift = np.array([0.03, -0.02, 0.004])
    normal = TURN @ [0.0, 0.0, 1.0]
    xs, xm, before = mortar_3d(square_grid(5), square_grid(4, True, 1000), TURN, 0.01)
    slave, master = square_grid(5), square_grid(4, True, 1000)
    master = (master[0] + shift @ TURN, master[1])          # TURN^T shift: moved by shift
    xs, xm_moved, after = mortar_3d(slave, master, TURN, 0.01)
    assert np.allclose(xm_moved - xm, shift)
    normals = {i: normal for i in range(len(xs))}
    g0 = interface.weighted_gap(before, positions(xs), positions(xm, 1000), normals)
    g1 = interface.weighted_gap(after, positions(xs), positions(xm_moved, 1000), normals)
    h = 0.2
    inner = [i for i, p in enumerate(square_grid(5)[0])
             if p[0] - h >= 0.03 and p[1] + h <= 0.98]
    assert len(inner) >= 12
    assert max(abs(g0[i] - 0.01) for i in g0) < 1e-13
    assert max(abs(g1[i] - g0[i] + shift @ normal) for i in inner) < 1e-13


def _plain_mortar_3d(xs, ts, xm, tm, k):
    """M_ik of 3D grids on z = 0 by the edge-midpoint rule on k x k sub-triangles of each slave
    triangle (no clipping), the master triangle of a point found by its barycentrics."""
    M = {}
    slave_tri = ts[:, ::-1]
    for tri in slave_tri:
        A, B, C = xs[tri]
        J = np.linalg.norm(np.cross(B - A, C - A))
        for a in range(k):
            for b in range(k - a):
                cells = [((a, b), (a + 1, b), (a, b + 1))]
                if a + b + 1 < k:
                    cells.append(((a + 1, b), (a + 1, b + 1), (a, b + 1)))
                for cell in cells:
                    q = np.array(cell, float) / k
                    for mid in (0.5 * (q[0] + q[1]), 0.5 * (q[1] + q[2]), 0.5 * (q[2] + q[0])):
                        X = A + mid[0] * (B - A) + mid[1] * (C - A)
                        N_s = (1.0 - mid[0] - mid[1], mid[0], mid[1])
                        for mtri in tm:
                            P = xm[mtri - 1000]
                            l1, l2 = np.linalg.solve(np.stack([P[1, :2] - P[0, :2],
                                                               P[2, :2] - P[0, :2]], axis=1),
                                                     X[:2] - P[0, :2])
                            if min(l1, l2, 1 - l1 - l2) >= -1e-15:
                                break
                        w = J * 0.5 / k ** 2 / 3.0
                        for i, N_i in zip(tri, N_s):
                            for kk, N in zip(mtri, (1 - l1 - l2, l1, l2)):
                                M[(i, kk)] = M.get((i, kk), 0.0) + w * (4 * N_i - 1) * N
    return M


def test_mortar_3d_integrals_are_exact_where_plain_quadrature_converges():
    """M of the clipped triangles against the edge-midpoint rule on 3, 5 and 9 subdivisions of
    each slave triangle (3 x 3 slave against 2 x 2 master grids; odd counts, so that no
    sub-triangle edge falls on a master edge): the plain rule's error, summed over M's
    entries, falls about as k^-2 towards the clipped value."""
    (xs, ts), (xm, tm) = square_grid(3), square_grid(2, True, 1000)
    _, _, pi = mortar_3d((xs, ts), (xm, tm))
    exact = {(int(i), int(k)): v for i, k, v in zip(pi.rows, pi.cols, pi.mortar)}

    def error(k):
        plain = _plain_mortar_3d(xs, ts, xm, tm, k)
        return sum(abs(plain.get(key, 0.0) - exact.get(key, 0.0))
                   for key in set(plain) | set(exact))

    errors = [error(k) for k in (3, 5, 9)]
    assert errors[0] > 1e-6, errors                      # the plain rule is not exact
    assert errors[1] < errors[0] / 2 and errors[2] < errors[1] / 2.5, errors


def test_mixed_traces_are_refused():
    triangle = interface.Surface.from_arrays(np.eye(3)[None], [[0, 1, 2]])
    segment = interface.Surface.from_arrays(np.eye(2)[None], [[0, 1]])
    with pytest.raises(SceneError, match="both triangles") as info:
        interface.mortar([0], segment, triangle, 1.0)
    assert info.value.key == "contact.pairing"


# ------------------------------------------------------------------ DOLFINx meshes

def _mesh_pairing(comm, method, degrees=0.0, **parameters):
    from contactvisco.fem import compat
    geometry = interface.two_blocks(comm, rotation=degrees, **parameters)
    V = compat.vector_space(geometry.mesh, "CG", 1)
    master = interface.boundary_surface(V, geometry.facet_tags, geometry.names["master"])
    slave = interface.slave_side(V, geometry.facet_tags, geometry.names["slave"])
    return V, slave, master, interface.pair(slave, master, method, SEARCH)


@pytest.mark.mpi
@pytest.mark.parametrize("method", METHODS)
def test_two_block_mesh_reproduces_a_linear_field_through_the_petsc_matrix(method):
    """The two-block mesh turned by 30 degrees, 13 slave against 10 master segments: the
    outward normals face each other, and Pi (x) I_2 as a PETSc matrix applied to a linear
    vector field gives the field at every owned slave node."""
    from contactvisco.fem import compat
    from dolfinx import fem
    V, slave, master, pi = _mesh_pairing(MPI.COMM_WORLD, method, 30.0)
    R = rotation(30.0)
    assert np.allclose(master.normals, R @ [0.0, 1.0])
    assert np.allclose(slave.trace.normals, R @ [0.0, -1.0])
    assert len(slave.trace.nodes) == 13 and len(master.nodes) == 10
    assert not pi.unpaired
    assert MPI.COMM_WORLD.allreduce(len(slave.nodes)) == 14
    u = fem.Function(V)
    field = lambda x: np.stack([1.0 + 2.0 * x[0] - x[1], -0.5 + 0.3 * x[0] + 4.0 * x[1]])  # noqa
    u.interpolate(field)
    sizes = interface.index_sizes(V)
    A = pi.matrix(MPI.COMM_WORLD, sizes, sizes, block_size=2)
    x = compat.petsc_vector(u)
    y = x.duplicate()
    A.mult(x, y)
    start = V.dofmap.index_map.local_range[0]
    values = y.getArray().reshape(-1, 2)[slave.nodes - start]
    assert len(values) == len(slave.nodes)
    if len(values):
        assert np.max(np.abs(values - field(slave.coordinates.T).T)) < 1e-13


@pytest.mark.mpi
@pytest.mark.parametrize("method", METHODS)
def test_two_block_mesh_with_matching_traces_gives_the_identity_incidence(method):
    """Both blocks with 10 interface segments: each slave node's row is a single 1 at the
    master node at the same place."""
    V, slave, master, pi = _mesh_pairing(MPI.COMM_WORLD, method, h_slave=0.1, h_master=0.1)
    at = {int(k): p for k, p in zip(master.nodes.ravel(), master.coordinates.reshape(-1, 2))}
    mine = dict(zip(slave.nodes.tolist(), slave.coordinates))
    entries = {key: v for key, v in pi.as_dict().items() if abs(v) > 1e-13}
    assert sorted(i for i, _ in entries) == sorted(mine)
    for (i, k), v in entries.items():
        assert abs(v - 1.0) < 1e-13
        assert np.linalg.norm(at[k] - mine[i]) < 1e-13


def _box_pairing(comm, method):
    """Pi of a slave box (4 x 4 cells across) on a master box (3 x 3), two meshes on comm."""
    Vs, slave_tags = _box([0.0, 0.0, 0.0], [1.0, 1.0, 0.5], [4, 4, 1], comm)
    Vm, master_tags = _box([0.0, 0.0, -0.5], [1.0, 1.0, 0.0], [3, 3, 1], comm)
    slave = interface.slave_side(Vs, slave_tags, 1)
    master = interface.boundary_surface(Vm, master_tags, 2)
    return Vs, Vm, slave, master, interface.pair(slave, master, method, SEARCH)


def _by_place(comm, method, d):
    """Pi's entries keyed by the rounded places of the slave and master node, gathered, and
    whether every rank owns slave nodes."""
    if d == 2:
        _, slave, master, pi = _mesh_pairing(comm, method)
    else:
        _, _, slave, master, pi = _box_pairing(comm, method)
    at_slave, at_master = ({int(k): tuple(np.round(p, 12)) for k, p in
                            zip(side.nodes.ravel(), side.coordinates.reshape(-1, d))}
                           for side in (slave.trace, master))
    mine = {(at_slave[i], at_master[k]): v for (i, k), v in pi.as_dict().items()}
    out = {}
    for part in comm.allgather(mine):
        assert not set(part) & set(out)                  # each slave row on one rank
        out.update(part)
    return out, comm.allreduce(len(slave.nodes) > 0, MPI.LAND)


@pytest.mark.mpi
@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("d", [2, 3])
@pytest.mark.skipif(MPI.COMM_WORLD.size == 1, reason="compares a partitioned mesh with one "
                                                      "rank's; run on 2 ranks")
def test_ranks_give_the_same_operator(method, d):
    """Pi of the meshes split over the ranks (every rank owning slave nodes), gathered, is Pi
    of the whole meshes on one rank: the two-block mesh (2D), the two boxes (3D)."""
    world, split = _by_place(MPI.COMM_WORLD, method, d)
    alone, _ = _by_place(MPI.COMM_SELF, method, d)
    assert split
    assert set(world) == set(alone)
    assert max(abs(world[key] - alone[key]) for key in alone) < 1e-14


def _box(lower, upper, cells, comm=MPI.COMM_WORLD):
    """A box of tetrahedra with its faces z = lower (tag 1) and z = upper (tag 2) tagged, and
    its vector P1 space."""
    from dolfinx import mesh as dmesh

    from contactvisco.fem import compat
    box = dmesh.create_box(comm, [np.array(lower, float), np.array(upper, float)], cells,
                           dmesh.CellType.tetrahedron)
    found = [dmesh.locate_entities_boundary(box, 2, lambda x, z=z: np.isclose(x[2], z))
             for z in (lower[2], upper[2])]
    indices = np.concatenate(found)
    values = np.concatenate([np.full(len(f), tag, np.int32) for f, tag in zip(found, (1, 2))])
    order = np.argsort(indices)
    return compat.vector_space(box, "CG", 1), dmesh.meshtags(box, 2, indices[order],
                                                             values[order])


@pytest.mark.mpi
def test_box_faces_are_gathered_with_outward_normals():
    """3D: the top and bottom faces of a 3 x 3 x 3 box of tetrahedra, gathered on every rank
    (18 triangles each), have outward normals +z and -z whatever the partition, and
    node_to_segment of points above the top face reproduces a linear field at their foot."""
    V, tags = _box([0.0, 0.0, 0.0], [1.0, 1.0, 1.0], [3, 3, 3])
    bottom, top = (interface.boundary_surface(V, tags, tag) for tag in (1, 2))
    assert len(top.nodes) == len(bottom.nodes) == 18
    assert np.allclose(top.normals, [0.0, 0.0, 1.0])
    assert np.allclose(bottom.normals, [0.0, 0.0, -1.0])
    rng = np.random.default_rng(7)
    points = np.concatenate([rng.uniform(0.0, 1.0, size=(20, 2)), np.full((20, 1), 1.01)],
                            axis=1)
    pi = interface.node_to_segment(np.arange(20), points, top, SEARCH)
    at = {int(k): p for k, p in zip(top.nodes.ravel(), top.coordinates.reshape(-1, 3))}
    field = lambda p: 1.0 + p[0] - 2.0 * p[1] + 0.5 * p[2]                 # noqa: E731
    image = pi.apply(lambda k: field(at[k]))
    assert max(abs(image[i] - field(points[i] - [0.0, 0.0, 0.01])) for i in image) < 1e-13


@pytest.mark.mpi
@pytest.mark.parametrize("method", METHODS)
def test_two_box_meshes_reproduce_a_linear_field_through_the_petsc_matrix(method):
    """3D, two meshes: a slave box (4 x 4 cells across) on a master box (3 x 3), each
    partitioned over the ranks; Pi (x) I_3 from the master's P1 dofs to the slave's, applied
    to a linear field of the master, gives the field at every owned slave node of the
    interface z = 0."""
    from dolfinx import fem

    from contactvisco.fem import compat
    Vs, Vm, slave, master, pi = _box_pairing(MPI.COMM_WORLD, method)
    assert not pi.unpaired
    assert MPI.COMM_WORLD.allreduce(len(slave.nodes)) == 25
    field = lambda x: np.stack([1.0 + x[0] - x[1], 2.0 * x[1] + 0.5 * x[0],     # noqa: E731
                                -1.0 + 3.0 * x[0] + x[2]])
    u = fem.Function(Vm)
    u.interpolate(field)
    A = pi.matrix(MPI.COMM_WORLD, interface.index_sizes(Vs), interface.index_sizes(Vm), 3)
    image = fem.Function(Vs)              # kept alive: its PETSc vector wraps its memory
    y = compat.petsc_vector(image)
    A.mult(compat.petsc_vector(u), y)
    start = Vs.dofmap.index_map.local_range[0]
    values = y.getArray().reshape(-1, 3)[slave.nodes - start]
    if len(values):
        assert np.max(np.abs(values - field(slave.coordinates.T).T)) < 1e-13
