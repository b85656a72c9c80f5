"""The interface between two deformable bodies: a slave boundary paired with a master boundary
by a projection operator Pi, so that a slave node's displacement relative to the master is

    u_rel,i = u_i - sum_k Pi_ik u_k        (i: slave nodes, k: master nodes).

Two pairings build Pi:

- node_to_segment: Pi_ik = N_k(p_i), N_k the master's P1 shape functions at the closest point
  p_i of slave node i on the master facets (2D segments, 3D triangles);
- mortar: Pi = D^-1 M with D_i = int_{Gamma_s} N_i ds (the slave vertex weights) and
  M_ik = int_{Gamma_s} Phi_i (N_k^m o chi) ds, Phi_i the dual basis of the slave trace
  (Phi_1 = 2 N_1 - N_2, Phi_2 = 2 N_2 - N_1 on a segment, Phi_i = 4 N_i - 1 on a triangle;
  biorthogonal: int Phi_i N_j = delta_ij int N_j; Wohlmuth, SIAM J. Numer. Anal. 38 (2000)
  989; Popp, Gee & Wall, IJNME 79 (2009) 1354). chi maps a point of a slave facet to the
  master facet in front of it along the slave facet's normal, an affine map on each piece of
  the slave facet cut at the projected master facets (2D: at the projections of the master
  nodes; 3D: projected master triangles clipped by the slave triangle, Puso & Laursen, CMAME
  193 (2004) 601); on each piece Phi_i and N_k^m o chi are linear and a rule exact for their
  product integrates M exactly.

Both boundaries' facets are gathered on every rank (O(N^((d-1)/d)) numbers for N nodes in d
dimensions); each rank computes the rows of the slave nodes it owns. Nothing of the solver
uses this module yet.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from contactvisco.errors import SceneError
from contactvisco.fem import compat

#: Slave nodes projected per block of the closest-point search, at most (memory: block x
#: facets x the bytes of one node-facet pair, _PAIR_BYTES).
_BLOCK = 256
#: The closest-point search's temporaries per node-facet pair, measured (tracemalloc): 48
#: bytes against segments, 195 against triangles (docs/interface.md), rounded up.
_PAIR_BYTES = {2: 64, 3: 256}
#: The most the closest-point search allocates at once: the block shrinks below _BLOCK nodes
#: for a master boundary of more than 2**26 / (256 x 256) = 1024 triangles (4096 segments).
_SEARCH_BYTES = 2 ** 26

#: Pieces of a slave facet shorter (2D) or smaller (3D) than this in its reference coordinates
#: are left out: a master facet that only touches the slave facet at a point or along an edge.
_SLIVER = 1e-14

#: Two Gauss points on [0, 1]: exact for polynomials of degree 3.
_GAUSS2 = (0.5 - 0.5 / np.sqrt(3.0), 0.5 + 0.5 / np.sqrt(3.0))


@dataclass
class Surface:
    """A boundary's facets, gathered on every rank, in an order that does not depend on the
    partition (by facet centroid), each oriented so that its normal points out of its body.

    Parameters
    ----------
    coordinates : numpy.ndarray
        (facets, d, gdim) vertex coordinates; a segment (a, b) has outward normal
        (t_y, -t_x)/|t| with t = b - a, a triangle (a, b, c) has (b - a) x (c - a) outward.
    nodes : numpy.ndarray
        (facets, d) global indices of the vertices' P1 nodes (blocks of a vector space).
    normals : numpy.ndarray
        (facets, gdim) outward unit normals.
    """
    coordinates: np.ndarray
    nodes: np.ndarray
    normals: np.ndarray

    @classmethod
    def from_arrays(cls, coordinates, nodes) -> "Surface":
        """A surface from its facets' vertices, ordered so that the normals of the returned
        surface follow the vertex order (see the class); for tests and plain geometry.

        Parameters
        ----------
        coordinates : array_like
            (facets, d, gdim) vertex coordinates, each facet ordered as in the class.
        nodes : array_like
            (facets, d) node numbers of the vertices.

        Returns
        -------
        Surface
            The facets sorted by centroid, with their normals n = (t_y, -t_x)/|t| (2D) or
            (b - a) x (c - a)/|.| (3D).
        """
        return _canonical(np.asarray(coordinates, dtype=float),
                          np.asarray(nodes, dtype=np.int64))


@dataclass
class Projection:
    """The closest points of slave nodes on a master surface.

    Parameters
    ----------
    facet : numpy.ndarray
        (n,) the master facet (row of the Surface) of each node's closest point, -1 if none
        lies within the search distance.
    local : numpy.ndarray
        (n, d - 1) the closest point's local coordinates: xi in [0, 1] from a to b (2D),
        (xi_1, xi_2) with p = a + xi_1 (b - a) + xi_2 (c - a) (3D).
    shape : numpy.ndarray
        (n, d) the master facet's P1 shape functions at the closest point (they sum to 1).
    gap : numpy.ndarray
        (n,) the signed gap g = (x - p) . n_m, > 0 on the outer side of the master (for a
        point whose closest point is a vertex, along the normal of the facet taken).
    normal : numpy.ndarray
        (n, gdim) the master facet's outward unit normal n_m.
    missing : list
        The positions (in the input order) of the nodes with no facet within the search
        distance; the caller turns a non-empty list into an error.
    """
    facet: np.ndarray
    local: np.ndarray
    shape: np.ndarray
    gap: np.ndarray
    normal: np.ndarray
    missing: list


@dataclass
class Pairing:
    """A projection operator Pi as a list of entries: Pi[rows[j], cols[j]] = values[j], rows
    the global slave nodes (each rank's owned ones), cols the global master nodes.

    Parameters
    ----------
    rows, cols : numpy.ndarray
        Global slave and master node indices of the entries.
    values : numpy.ndarray
        Pi's entries.
    slave_nodes : numpy.ndarray
        The global slave nodes this rank owns (a node with no entry has no master within
        reach: see `unpaired`).
    weights : numpy.ndarray
        Per slave node, D_i = int N_i ds over the slave trace (mortar) or 1
        (node_to_segment).
    mortar : numpy.ndarray
        The entries of M before division by D (mortar), else the values themselves.
    unpaired : list
        The slave nodes (global indices) with no master facet within the search distance.
    """
    rows: np.ndarray
    cols: np.ndarray
    values: np.ndarray
    slave_nodes: np.ndarray
    weights: np.ndarray
    mortar: np.ndarray
    unpaired: list = field(default_factory=list)

    def as_dict(self) -> dict:
        """{(slave node, master node): Pi_ik} of this rank's entries.

        Returns
        -------
        dict
            Pi's entries keyed by (global slave node, global master node).
        """
        out = {}
        for i, k, v in zip(self.rows.tolist(), self.cols.tolist(), self.values.tolist()):
            out[(i, k)] = out.get((i, k), 0.0) + v
        return out

    def apply(self, values) -> dict:
        """(Pi u)_i = sum_k Pi_ik u_k for a field given at the master nodes.

        Parameters
        ----------
        values : dict or callable
            u_k: a mapping from global master node to its value (a number or a vector).

        Returns
        -------
        dict
            Global slave node -> (Pi u)_i, for every owned slave node.
        """
        get = values if callable(values) else values.__getitem__
        out = {int(i): 0.0 for i in self.slave_nodes}
        for i, k, v in zip(self.rows.tolist(), self.cols.tolist(), self.values.tolist()):
            out[i] = out[i] + v * np.asarray(get(k), dtype=float)
        return out

    def matrix(self, comm, rows: tuple[int, int], columns: tuple[int, int],
               block_size: int = 1) -> PETSc.Mat:
        """Pi as a PETSc AIJ matrix: owned slave rows, master columns anywhere, global
        indices; with block_size b, Pi (x) I_b acting on blocked (vector) P1 dofs:
        entry (i b + c, k b + c) = Pi_ik for c < b.

        Parameters
        ----------
        comm : mpi4py.MPI.Comm
            The communicator of the matrix.
        rows : tuple of int
            (owned, global) numbers of nodes of the slave space's index map; this rank's
            rows are its owned range (index_map.local_range).
        columns : tuple of int
            (owned, global) numbers of nodes of the master space's index map.
        block_size : int, optional
            Components per node (1: nodes, gdim: the vector P1 dofs).

        Returns
        -------
        petsc4py.PETSc.Mat
            The assembled matrix of global size (rows[1] b) x (columns[1] b).
        """
        b = int(block_size)
        owned, size = rows
        start = comm.scan(owned) - owned
        local = (self.rows - start).astype(np.int64)
        if np.any((local < 0) | (local >= owned)):
            raise SceneError("interface: Pi has rows outside this rank's owned range; the "
                             "slave space and the pairing do not belong together")
        spread = np.arange(b)
        csr_rows = (local[:, None] * b + spread).ravel()
        csr_cols = (self.cols[:, None] * b + spread).ravel()
        csr_vals = np.repeat(self.values, b)
        order = np.lexsort((csr_cols, csr_rows))
        counts = np.bincount(csr_rows, minlength=owned * b)
        indptr = np.concatenate([[0], np.cumsum(counts)]).astype(PETSc.IntType)
        indices = csr_cols[order].astype(PETSc.IntType)
        data = csr_vals[order].astype(PETSc.ScalarType)
        A = PETSc.Mat().createAIJ(((owned * b, size * b), (columns[0] * b, columns[1] * b)),
                                  csr=(indptr, indices, data), comm=comm)
        A.assemble()
        return A


# ------------------------------------------------------------------ plain geometry

def _normals(coordinates: np.ndarray) -> np.ndarray:
    """Unit normals of facets given by their vertices: (t_y, -t_x) for a segment,
    (b - a) x (c - a) for a triangle, normalized."""
    d = coordinates.shape[1]
    if d == 2:
        t = coordinates[:, 1] - coordinates[:, 0]
        n = np.stack([t[:, 1], -t[:, 0]], axis=1)
    elif d == 3:
        n = np.cross(coordinates[:, 1] - coordinates[:, 0], coordinates[:, 2] - coordinates[:, 0])
    else:
        raise SceneError(f"interface: facets of {d} vertices; segments (2) and triangles (3) "
                         "are allowed")
    length = np.linalg.norm(n, axis=1)
    if np.any(length == 0.0):
        raise SceneError("interface: a facet of zero length or area")
    return n / length[:, None]


def _canonical(coordinates, nodes) -> Surface:
    """The facets sorted by centroid, each triangle's vertices turned cyclically (its normal
    kept) to start at its least vertex in lexicographic order: the same facets in the same
    order, computed the same way, on any number of ranks."""
    if not len(coordinates):
        return Surface(coordinates, nodes, np.zeros((0, coordinates.shape[-1])))
    if coordinates.shape[1] == 3:
        least = np.array([min(range(3), key=lambda j, f=f: tuple(f[j])) for f in coordinates])
        turn = (least[:, None] + np.arange(3)) % 3
        coordinates = np.take_along_axis(coordinates, turn[:, :, None], axis=1)
        nodes = np.take_along_axis(nodes, turn, axis=1)
    centroid = coordinates.mean(axis=1)
    order = np.lexsort(centroid.T[::-1])
    coordinates = coordinates[order]
    return Surface(coordinates, nodes[order], _normals(coordinates))


def _closest_on_segments(x, a, b):
    """Closest points of points x (n, g) on segments (m, 2 vertices): local coordinate
    (n, m, 1) and squared distance (n, m)."""
    t = b - a                                                  # (m, g)
    tt = np.einsum("mg,mg->m", t, t)
    xi = np.einsum("nmg,mg->nm", x[:, None, :] - a[None], t) / tt
    xi = np.clip(xi, 0.0, 1.0)
    p = a[None] + xi[..., None] * t[None]
    return xi[..., None], np.sum((x[:, None, :] - p) ** 2, axis=2)


def _closest_on_triangles(x, a, b, c):
    """Closest points of points x (n, 3) on triangles: local coordinates (xi_1, xi_2) with
    p = a + xi_1 (b - a) + xi_2 (c - a), (n, m, 2), and squared distance (n, m). The point in
    the triangle's plane when its barycentric coordinates are >= 0, else the nearest point of
    the three edges."""
    e1, e2 = b - a, c - a
    g11 = np.einsum("mg,mg->m", e1, e1)
    g12 = np.einsum("mg,mg->m", e1, e2)
    g22 = np.einsum("mg,mg->m", e2, e2)
    det = g11 * g22 - g12 ** 2
    r = x[:, None, :] - a[None]
    r1 = np.einsum("nmg,mg->nm", r, e1)
    r2 = np.einsum("nmg,mg->nm", r, e2)
    xi1 = (g22 * r1 - g12 * r2) / det
    xi2 = (g11 * r2 - g12 * r1) / det
    inside = (xi1 >= 0) & (xi2 >= 0) & (xi1 + xi2 <= 1)
    best = np.stack([xi1, xi2], axis=2)
    p = a[None] + xi1[..., None] * e1[None] + xi2[..., None] * e2[None]
    dist = np.where(inside, np.sum((x[:, None, :] - p) ** 2, axis=2), np.inf)
    # The edges a-b (xi_2 = 0), a-c (xi_1 = 0), b-c (xi_1 + xi_2 = 1).
    for start, end, to_local in ((a, b, lambda s: (s, 0 * s)), (a, c, lambda s: (0 * s, s)),
                                 (b, c, lambda s: (1 - s, s))):
        s, d2 = _closest_on_segments(x, start, end)
        better = d2 < dist
        l1, l2 = to_local(s[..., 0])
        best[..., 0] = np.where(better, l1, best[..., 0])
        best[..., 1] = np.where(better, l2, best[..., 1])
        dist = np.where(better, d2, dist)
    return best, dist


def project(points, master: Surface, search_distance: float) -> Projection:
    """Closest-point projection of points onto a master surface.

    For each point x, the closest point p over all master facets (a segment or a triangle,
    boundary included), its facet, local coordinates and shape functions N_k(p), the signed
    gap g = (x - p) . n_m along the facet's outward normal n_m. Of facets at the same distance
    (a point above a shared vertex) the first in the surface's order is taken, so the answer
    does not depend on the partition.

    Parameters
    ----------
    points : array_like
        (n, gdim) the points (slave nodes).
    master : Surface
        The master facets.
    search_distance : float
        A point whose closest point is farther than this is reported in `missing`.

    Returns
    -------
    Projection
        The facet, local coordinates, shape functions, gap and normal of every point
        (facet -1 for a missing point).
    """
    x = np.atleast_2d(np.asarray(points, dtype=float))
    v = master.coordinates
    n, d = len(x), (v.shape[1] if len(v) else x.shape[1])
    facet = np.full(n, -1, dtype=np.int64)
    local = np.zeros((n, d - 1))
    dist2 = np.full(n, np.inf)
    scale = np.max(np.abs(v)) ** 2 if len(v) else 0.0
    step = max(1, min(_BLOCK, _SEARCH_BYTES // (_PAIR_BYTES[d] * max(len(v), 1))))
    for start in range(0, n if len(v) else 0, step):
        block = slice(start, min(n, start + step))
        if d == 2:
            xi, d2 = _closest_on_segments(x[block], v[:, 0], v[:, 1])
        else:
            xi, d2 = _closest_on_triangles(x[block], v[:, 0], v[:, 1], v[:, 2])
        # The first facet within a rounding of the least distance.
        least = d2.min(axis=1)
        first = np.argmax(d2 <= least[:, None] + 1e-24 * scale + 1e-14 * least[:, None],
                          axis=1)
        rows = np.arange(len(first))
        facet[block] = first
        local[block] = xi[rows, first]
        dist2[block] = d2[rows, first]
    far = ~(np.sqrt(dist2) <= search_distance)
    facet[far] = -1
    shape = np.zeros((n, d))
    if d == 2:
        shape[:, 0], shape[:, 1] = 1.0 - local[:, 0], local[:, 0]
    else:
        shape[:, 0] = 1.0 - local[:, 0] - local[:, 1]
        shape[:, 1], shape[:, 2] = local[:, 0], local[:, 1]
    ok = facet >= 0
    normal = np.zeros((n, x.shape[1]))
    gap = np.zeros(n)
    if ok.any():
        p = np.einsum("nk,nkg->ng", shape[ok], v[facet[ok]])
        normal[ok] = master.normals[facet[ok]]
        gap[ok] = np.einsum("ng,ng->n", x[ok] - p, normal[ok])
    shape[~ok] = 0.0
    local[~ok] = 0.0
    return Projection(facet, local, shape, gap, normal, np.flatnonzero(~ok).tolist())


def node_to_segment(nodes, points, master: Surface, search_distance: float) -> Pairing:
    """The node-to-segment projection operator: Pi_ik = N_k(p_i), p_i the closest point of
    slave node i on the master (see `project`).

    Parameters
    ----------
    nodes : array_like
        (n,) the global indices of the slave nodes.
    points : array_like
        (n, gdim) their coordinates.
    master : Surface
        The master facets.
    search_distance : float
        A slave node farther than this from every master facet gets no entry and is listed
        in the result's `unpaired`.

    Returns
    -------
    Pairing
        d entries per paired node (the vertices of its facet), weights 1.
    """
    nodes = np.asarray(nodes, dtype=np.int64)
    found = project(points, master, search_distance)
    ok = found.facet >= 0
    d = found.shape.shape[1]
    rows = np.repeat(nodes[ok], d)
    cols = master.nodes[found.facet[ok]].ravel() if ok.any() else np.zeros(0, np.int64)
    values = found.shape[ok].ravel()
    return Pairing(rows, cols.astype(np.int64), values, nodes, np.ones(len(nodes)),
                   values.copy(), [int(nodes[j]) for j in found.missing])


def mortar(nodes, slave: Surface, master: Surface, search_distance: float,
           where: str = "contact.pairing") -> Pairing:
    """The mortar projection operator with the dual basis of the slave trace: Pi = D^-1 M,

        D_i = int_{Gamma_s} N_i ds,    M_ik = int_{Gamma_s} Phi_i (N_k^m o chi) ds,

    Phi_i the dual basis, biorthogonal to the P1 basis (int Phi_i N_j = delta_ij int N_j):
    Phi_1 = 2 N_1 - N_2, Phi_2 = 2 N_2 - N_1 on a slave segment, Phi_i = 4 N_i - 1 on a slave
    triangle. chi maps a point of a slave facet to the point of a master facet whose orthogonal
    projection onto the slave facet's line (plane) it is, i.e. along the slave facet's normal.
    2D: each slave segment is cut at the projections of the master nodes; 3D: each master
    triangle projected onto the slave triangle's plane is clipped by the slave triangle (both
    are convex) and the polygon cut into triangles from one vertex (Puso & Laursen, CMAME 193
    (2004) 601). On each piece chi is affine, Phi_i and N_k^m o chi are linear, and the rule
    used (two Gauss points on a piece of segment, the three edge midpoints of a triangle) is
    exact for their product: M is exact. A master facet is paired with a slave facet when
    their outward normals face each other (n_s . n_m < 0) and the distance between them along
    the slave normal is within search_distance at a vertex of the piece.

    Parameters
    ----------
    nodes : array_like
        The global slave nodes whose rows are wanted (this rank's owned ones).
    slave : Surface
        The slave trace: all its facets (gathered), for the weights of the rows wanted.
    master : Surface
        The master facets (of the same kind: segments or triangles).
    search_distance : float
        The largest distance between paired points of the two traces.
    where : str, optional
        The key named by the error of traces of different kinds.

    Returns
    -------
    Pairing
        Pi's entries of the rows wanted; `weights` holds D_i, `mortar` M's entries, and
        `unpaired` the nodes with no master piece on their support.
    """
    nodes = np.asarray(nodes, dtype=np.int64)
    d = slave.coordinates.shape[1]
    if len(master.coordinates) and master.coordinates.shape[1] != d:
        raise SceneError(f"{where}: the slave and master traces must both be segments (2D) or "
                         "both triangles (3D)", key=where)
    wanted = {int(i): j for j, i in enumerate(nodes)}
    weights = np.zeros(len(nodes))
    entries: dict[tuple[int, int], float] = {}
    integrate = _mortar_segments if d == 2 else _mortar_triangles
    integrate(wanted, weights, entries, slave, master, search_distance)
    keys = sorted(entries)
    rows = np.array([k[0] for k in keys], dtype=np.int64)
    cols = np.array([k[1] for k in keys], dtype=np.int64)
    m_values = np.array([entries[k] for k in keys], dtype=float)
    values = m_values / weights[[wanted[r] for r in rows]] if len(rows) else m_values
    paired = set(rows.tolist())
    unpaired = [int(i) for i in nodes if int(i) not in paired]
    return Pairing(rows, cols, values, nodes, weights, m_values, unpaired)


def _add(entries, key, value):
    entries[key] = entries.get(key, 0.0) + value


def _mortar_segments(wanted, weights, entries, slave, master, search_distance):
    """D and M of a 2D interface, added into weights and entries (see `mortar`)."""
    P, Q = (master.coordinates[:, 0], master.coordinates[:, 1]) if len(master.coordinates) \
        else (np.zeros((0, 2)), np.zeros((0, 2)))
    for (A, B), (iA, iB), n_s in zip(slave.coordinates, slave.nodes, slave.normals):
        rows = [r for r in (int(iA), int(iB)) if r in wanted]
        if not rows:
            continue
        t = B - A
        L = float(np.hypot(*t))
        for r in rows:
            weights[wanted[r]] += 0.5 * L
        xi_P = (P - A) @ t / L ** 2
        xi_Q = (Q - A) @ t / L ** 2
        facing = master.normals @ n_s < 0.0
        lo = np.maximum(0.0, np.minimum(xi_P, xi_Q))
        hi = np.minimum(1.0, np.maximum(xi_P, xi_Q))
        span = xi_Q - xi_P
        for m in np.flatnonzero(facing & (hi - lo > _SLIVER) & (np.abs(span) > 1e-14)):
            # Distances between the slave points at the piece's ends and their images.
            ends = np.array([lo[m], hi[m]])
            eta = (ends - xi_P[m]) / span[m]
            gaps = np.linalg.norm(P[m] + eta[:, None] * (Q[m] - P[m])
                                  - (A + ends[:, None] * t), axis=1)
            if gaps.min() > search_distance:
                continue
            k_P, k_Q = (int(k) for k in master.nodes[m])
            for g in _GAUSS2:
                xi = lo[m] + g * (hi[m] - lo[m])
                w = 0.5 * (hi[m] - lo[m]) * L
                e = (xi - xi_P[m]) / span[m]
                phi = {int(iA): 2.0 - 3.0 * xi, int(iB): 3.0 * xi - 1.0}
                for r in rows:
                    for k, N in ((k_P, 1.0 - e), (k_Q, e)):
                        _add(entries, (r, k), w * phi[r] * N)


def _clip(polygon: list, coefficients) -> list:
    """A convex polygon (a list of 2D points) clipped by the half-plane c0 + c1 xi + c2 eta
    >= 0 (Sutherland-Hodgman)."""
    c0, c1, c2 = coefficients
    out = []
    for j, p in enumerate(polygon):
        q = polygon[(j + 1) % len(polygon)]
        fp, fq = c0 + c1 * p[0] + c2 * p[1], c0 + c1 * q[0] + c2 * q[1]
        if fp >= 0:
            out.append(p)
        if (fp >= 0) != (fq >= 0):
            s = fp / (fp - fq)
            out.append(p + s * (q - p))
    return out


#: The slave reference triangle xi >= 0, eta >= 0, 1 - xi - eta >= 0 as half-planes.
_REFERENCE = ((0.0, 1.0, 0.0), (0.0, 0.0, 1.0), (1.0, -1.0, -1.0))


def _mortar_triangles(wanted, weights, entries, slave, master, search_distance):
    """D and M of a 3D interface, added into weights and entries (see `mortar`): in the slave
    triangle's affine coordinates (xi, eta), X = A + xi (B - A) + eta (C - A), the master
    triangle projected along the slave normal is clipped by the reference triangle."""
    V = master.coordinates
    for (A, B, C), slave_nodes, n_s in zip(slave.coordinates, slave.nodes, slave.normals):
        rows = [(r, j) for j, r in enumerate(int(i) for i in slave_nodes) if r in wanted]
        if not rows:
            continue
        E = np.stack([B - A, C - A], axis=1)                   # (3, 2)
        jacobian = float(np.linalg.norm(np.cross(B - A, C - A)))
        for r, _ in rows:
            weights[wanted[r]] += jacobian / 6.0
        if not len(V):
            continue
        # Affine coordinates of the master vertices' projections onto the slave plane.
        local = (V - A) @ (np.linalg.inv(E.T @ E) @ E.T).T      # (masters, 3 vertices, 2)
        facing = master.normals @ n_s < 0.0
        near = ((local[..., 0].max(axis=1) > 0) & (local[..., 1].max(axis=1) > 0)
                & (local.sum(axis=2).min(axis=1) < 1))
        for m in np.flatnonzero(facing & near):
            p0, p1, p2 = local[m]
            (a, b), (c, d) = p1 - p0, p2 - p0                  # F = [[a, c], [b, d]]
            det = a * d - b * c
            if abs(det) <= 1e-14:
                continue
            F_inv = np.array([[d, -c], [-b, a]]) / det          # master barycentrics
            polygon = [p0, p1, p2]
            for half in _REFERENCE:
                polygon = _clip(polygon, half)
                if not polygon:
                    break
            if len(polygon) < 3:
                continue
            polygon = np.array(polygon)
            lam = (polygon - p0) @ F_inv.T                     # (points, 2)
            images = (V[m, 0] + lam[:, :1] * (V[m, 1] - V[m, 0])
                      + lam[:, 1:] * (V[m, 2] - V[m, 0]))
            gaps = np.linalg.norm(images - (A + polygon @ E.T), axis=1)
            if gaps.min() > search_distance:
                continue
            # The polygon cut into triangles (q0, q1, q2) from its first vertex; the rule: the
            # three edge midpoints, weight area / 3 each.
            q0, q1, q2 = polygon[0], polygon[1:-1], polygon[2:]
            area = 0.5 * np.abs((q1[:, 0] - q0[0]) * (q2[:, 1] - q0[1])
                                - (q1[:, 1] - q0[1]) * (q2[:, 0] - q0[0]))
            keep = area > _SLIVER
            if not keep.any():
                continue
            q1, q2, area = q1[keep], q2[keep], area[keep]
            points = np.concatenate([0.5 * (q0 + q1), 0.5 * (q1 + q2), 0.5 * (q2 + q0)])
            w = np.concatenate([jacobian * area / 3.0] * 3)
            N_s = np.stack([1.0 - points[:, 0] - points[:, 1], points[:, 0], points[:, 1]], 1)
            lam = (points - p0) @ F_inv.T
            N_m = np.stack([1.0 - lam[:, 0] - lam[:, 1], lam[:, 0], lam[:, 1]], axis=1)
            block = np.einsum("q,qi,qk->ik", w, 4.0 * N_s - 1.0, N_m)
            for r, j_s in rows:
                for k, value in zip(master.nodes[m], block[j_s]):
                    _add(entries, (r, int(k)), float(value))


def weighted_gap(pairing: Pairing, slave_points: dict, master_points: dict,
                 normals: dict) -> dict:
    """The gap of each slave node measured through Pi: g_i = n_i . (x_i - sum_k Pi_ik x_k),
    x the positions (or displacements) of the nodes and n_i a normal per slave node (the
    master's outward normal at the node's projection, for instance). With the mortar pairing
    and n_i constant it is the weighted gap D_i^-1 int Phi_i (x - x o chi) . n_i ds (the
    biorthogonality int Phi_i = D_i gives the x_i term). With displacements in place of
    positions it is the normal part n_i . u_rel,i of the relative displacement.

    Parameters
    ----------
    pairing : Pairing
        Pi.
    slave_points : dict
        Global slave node -> x_i (a vector).
    master_points : dict
        Global master node -> x_k (a vector).
    normals : dict
        Global slave node -> n_i.

    Returns
    -------
    dict
        Global slave node -> g_i, for every slave node of the pairing.
    """
    image = pairing.apply(master_points)
    return {i: float(np.dot(normals[i], np.asarray(slave_points[i], float) - image[i]))
            for i in image}


# ------------------------------------------------------------------ DOLFINx meshes

@dataclass
class SlaveSide:
    """The slave boundary as a rank sees it.

    Parameters
    ----------
    nodes : numpy.ndarray
        (n,) the global indices of the slave P1 nodes this rank owns, increasing.
    coordinates : numpy.ndarray
        (n, gdim) their coordinates.
    trace : Surface
        All the slave boundary's facets (gathered), for the mortar weights.
    """
    nodes: np.ndarray
    coordinates: np.ndarray
    trace: Surface


def _vertex_dofs(space) -> tuple[np.ndarray, np.ndarray]:
    """The P1 node (block) of every local vertex, from the cells' vertices and dofs, and the
    coordinates of every local node copied from the mesh geometry (tabulated dof coordinates
    are pushed forward from the reference cell, with roundoff that depends on the cell, hence
    on the partition)."""
    mesh = space.mesh
    tdim = mesh.topology.dim
    mesh.topology.create_connectivity(tdim, 0)
    c2v = mesh.topology.connectivity(tdim, 0).array.reshape(-1, tdim + 1)
    dofs = compat.cell_dofs(space.dofmap)
    layout = space.dofmap.dof_layout
    vertex_map = mesh.topology.index_map(0)
    out = np.full(vertex_map.size_local + vertex_map.num_ghosts, -1, dtype=np.int64)
    geometry = compat.geometry_nodes(mesh)
    index_map = space.dofmap.index_map
    x = np.zeros((index_map.size_local + index_map.num_ghosts, mesh.geometry.dim))
    for j in range(tdim + 1):
        column = dofs[:, layout.entity_dofs(0, j)[0]]
        out[c2v[:, j]] = column
        x[column] = mesh.geometry.x[geometry[:, j], :mesh.geometry.dim]
    return out, x


def boundary_surface(space, facet_tags, tag: int, where: str = "contact.boundary") -> Surface:
    """The facets of a tagged boundary, gathered on every rank (allgather of each rank's
    owned facets: d vertex coordinates and d global P1 nodes per facet, O(N^((d-1)/d))
    numbers for N nodes), each facet's vertices ordered so that its normal points out of its
    cell, the facets ordered by centroid (see Surface).

    Parameters
    ----------
    space : dolfinx.fem.FunctionSpace
        A P1 (scalar or vector) space of the mesh; its nodes number the vertices.
    facet_tags : dolfinx.mesh.MeshTags
        The mesh's facet tags.
    tag : int
        The tag value of the boundary.
    where : str, optional
        The key named by an error (an empty boundary, a space that is not P1).

    Returns
    -------
    Surface
        The boundary's facets, the outward normal n = (t_y, -t_x)/|t| of a segment (a, b)
        or (b - a) x (c - a)/|.| of a triangle pointing away from the facet's cell.
    """
    mesh = space.mesh
    if compat.element_degree(space) != 1 or compat.is_discontinuous(space):
        raise SceneError(f"{where}: an interface is paired on a continuous P1 space, got "
                         f"degree {compat.element_degree(space)}", key=where)
    tdim, gdim = mesh.topology.dim, mesh.geometry.dim
    fdim = tdim - 1
    for a, b in ((fdim, tdim), (fdim, 0), (tdim, 0)):
        mesh.topology.create_connectivity(a, b)
    facets = facet_tags.indices[facet_tags.values == tag]
    facets = facets[facets < mesh.topology.index_map(fdim).size_local]
    f2v = mesh.topology.connectivity(fdim, 0).array.reshape(-1, tdim)
    f2c = mesh.topology.connectivity(fdim, tdim)
    c2v = mesh.topology.connectivity(tdim, 0).array.reshape(-1, tdim + 1)
    vertex_dofs, x = _vertex_dofs(space)
    verts = f2v[facets]
    cells = f2c.array[f2c.offsets[facets]]
    cell_verts = c2v[cells]
    opposite = cell_verts[~(cell_verts[:, :, None] == verts[:, None, :]).any(axis=2)]
    dofs = vertex_dofs[verts]
    coords = x[dofs]
    if len(facets):
        normals = _normals(coords)
        outward = np.einsum("fg,fg->f", normals, x[vertex_dofs[opposite]] - coords[:, 0]) < 0
        swap = [1, 0] if tdim == 2 else [0, 2, 1]
        dofs = np.where(outward[:, None], dofs, dofs[:, swap])
        coords = x[dofs]
    nodes = space.dofmap.index_map.local_to_global(
        np.ascontiguousarray(dofs.ravel(), dtype=np.int32)).reshape(-1, tdim)
    comm = mesh.comm
    parts = comm.allgather((coords.reshape(-1, tdim, gdim), np.asarray(nodes, np.int64)))
    coords = np.concatenate([p[0] for p in parts])
    if not len(coords):
        raise SceneError(f"{where}: the boundary tagged {tag} has no facets in this mesh",
                         key=where)
    return _canonical(coords, np.concatenate([p[1] for p in parts]))


def slave_side(space, facet_tags, tag: int, where: str = "contact.boundary") -> SlaveSide:
    """The slave boundary: its nodes owned by this rank (those of the gathered trace inside
    the index map's owned range) and the whole trace.

    Parameters
    ----------
    space : dolfinx.fem.FunctionSpace
        A P1 space of the slave body's mesh.
    facet_tags : dolfinx.mesh.MeshTags
        The mesh's facet tags.
    tag : int
        The tag value of the slave boundary.
    where : str, optional
        The key named by an error.

    Returns
    -------
    SlaveSide
        The owned slave nodes, their coordinates and the gathered trace.
    """
    trace = boundary_surface(space, facet_tags, tag, where)
    lo, hi = space.dofmap.index_map.local_range
    every, first = np.unique(trace.nodes.ravel(), return_index=True)
    mine = (every >= lo) & (every < hi)
    coords = trace.coordinates.reshape(-1, trace.coordinates.shape[2])[first[mine]]
    return SlaveSide(every[mine], coords, trace)


def pair(slave: SlaveSide, master: Surface, method: str, search_distance: float,
         where: str = "contact.pairing") -> Pairing:
    """Pi of a slave side and a master surface by the method named.

    Parameters
    ----------
    slave : SlaveSide
        The slave nodes and trace (`slave_side`).
    master : Surface
        The master facets (`boundary_surface`).
    method : str
        "node_to_segment" (Pi_ik = N_k(p_i)) or "mortar" (Pi = D^-1 M).
    search_distance : float
        The largest distance at which a slave node (or piece of slave segment) is paired.
    where : str, optional
        The key named by an error.

    Returns
    -------
    Pairing
        Pi's entries of this rank's slave nodes.
    """
    if not (np.isfinite(search_distance) and search_distance > 0):
        raise SceneError(f"{where}: the search distance must be a finite number > 0, got "
                         f"{search_distance!r}", key=where)
    if method == "node_to_segment":
        return node_to_segment(slave.nodes, slave.coordinates, master, search_distance)
    if method == "mortar":
        return mortar(slave.nodes, slave.trace, master, search_distance, where)
    raise SceneError(f"{where} must be 'node_to_segment' or 'mortar', got {method!r}",
                     key=where)


def index_sizes(space) -> tuple[int, int]:
    """(owned, global) numbers of nodes of a space's index map: the row or column layout
    that Pairing.matrix takes.

    Parameters
    ----------
    space : dolfinx.fem.FunctionSpace
        The slave or master P1 space.

    Returns
    -------
    tuple of int
        (index_map.size_local, index_map.size_global).
    """
    index_map = space.dofmap.index_map
    return index_map.size_local, index_map.size_global


def two_blocks(comm=MPI.COMM_WORLD, rotation: float = 0.0, **parameters):
    """The two-block mesh of meshes/two_blocks.py (a slave block above a master block, the
    interface nodes not shared), made by gmsh on first use and cached like a scene's mesh.

    Parameters
    ----------
    comm : mpi4py.MPI.Comm, optional
        The communicator of the mesh.
    rotation : float, optional
        Degrees by which the mesh is turned about the origin.
    **parameters
        The script's parameters: length, height, h_slave, h_master.

    Returns
    -------
    contactvisco.fem.geometry.Geometry
        The mesh, its facet tags and the tag of each boundary name ("slave", "master", ...).
    """
    from contactvisco.fem import geometry
    scene = {"geometry": {"type": "gmsh", "script": "two_blocks", "file": None,
                          "parameters": dict(parameters), "rotation": float(rotation)},
             "material": {"model": "plane_strain"}, "output": {"probes": []}}
    return geometry.build(scene, comm)
