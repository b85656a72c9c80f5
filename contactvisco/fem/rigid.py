"""Rigid-body motions a scene leaves free: found before solving, because elasticity does not
see them and Newton would return one of infinitely many answers (which one depends on the
partition).

A rigid motion is m(x) = a + W (x - c) with W skew (2D: 3 motions, 3D: 6). It is restrained
when it moves some constrained quantity:

- a Dirichlet condition on component i at a node x: m_i(x) != 0;
- the contact law at a contact node with normal nu: m(x) . nu != 0 (a compliance stiffness or
  a bound g resists normal motion);
- friction (contact.mu > 0): also the tangential part m(x) - (m(x) . nu) nu.

The rule is conservative in one respect and documented: contact counts as a restraint whether
or not the body is pressed into it, and friction restrains sliding only while the body is
pressed. The restrained motions form the range of the Gram matrix G = sum_k mean_r c_r c_r^T
of the constraint rows c_r (one entry per basis motion), averaged per kind k (Dirichlet,
normal, tangential) so that a short clamped boundary weighs as much as a long contact one; the
free ones are its null space. Eigenvalues below RESTRAINT_TOLERANCE times the largest count as
zero: a frictionless circular contact boundary alone resists the rotation about its centre
only through the chords of its end facets (a relative eigenvalue of about 1e-5 on the Hertz
mesh, against 0.07 and more for every held built-in scene), which is no restraint.
"""
from __future__ import annotations

import numpy as np
from mpi4py import MPI

from contactvisco.errors import SceneError

AXES = "xyz"

#: Relative eigenvalue of the constraint Gram matrix below which a motion counts as free.
RESTRAINT_TOLERANCE = 1e-4


def _basis(X: np.ndarray, centre: np.ndarray, scale: float) -> tuple[np.ndarray, list[str]]:
    """Rigid motions evaluated at points X (n, d): array (modes, n, d) and their names."""
    n, d = X.shape
    Y = (X - centre) / scale
    modes, names = [], []
    for c in range(d):
        mode = np.zeros((n, d))
        mode[:, c] = 1.0
        modes.append(mode)
        names.append(f"translation along {AXES[c]}")
    pairs = [(0, 1, "z")] if d == 2 else [(1, 2, "x"), (2, 0, "y"), (0, 1, "z")]
    for a, b, axis in pairs:                  # rotation about `axis`: e_a -> e_b
        mode = np.zeros((n, d))
        mode[:, a], mode[:, b] = -Y[:, b], Y[:, a]
        modes.append(mode)
        names.append(f"rotation about {axis}")
    return np.array(modes).reshape(len(modes), n, d), names


def _bounding_box(mesh) -> tuple[np.ndarray, float]:
    """Centre and largest side of the mesh's bounding box over all ranks: the point and
    length the basis motions are scaled by, so the Gram matrix is free of units."""
    comm = mesh.comm
    d = mesh.geometry.dim
    x = mesh.geometry.x[:, :d]
    lower, upper = np.empty(d), np.empty(d)
    comm.Allreduce(x.min(axis=0), lower, op=MPI.MIN)
    comm.Allreduce(x.max(axis=0), upper, op=MPI.MAX)
    return 0.5 * (lower + upper), float(np.max(upper - lower))


def _gram(problem, centre: np.ndarray, scale: float, modes: int) -> np.ndarray:
    """G = sum_k mean_r c_r c_r^T over the constraint rows c_r of each kind k (Dirichlet,
    normal, tangential), summed over ranks; each rank adds its owned nodes only."""
    comm = problem.V.mesh.comm
    d = problem.V.mesh.geometry.dim
    owned = problem.V.dofmap.index_map.size_local
    X = problem.V.tabulate_dof_coordinates()[:owned, :d]
    kinds = {"dirichlet": [np.zeros((modes, modes)), 0],
             "normal": [np.zeros((modes, modes)), 0],
             "tangential": [np.zeros((modes, modes)), 0]}

    def add(kind, rows):
        kinds[kind][0] += rows @ rows.T
        kinds[kind][1] += rows.shape[1]

    fixed = problem.u_fixed[:owned] > 0
    for c in range(d):          # the motions evaluated at the constrained nodes only
        add("dirichlet", _basis(X[fixed[:, c]], centre, scale)[0][:, :, c])
    part = problem.contact
    if part is not None:
        nodes, on = part.nodes, part.nodes.owned
        Xc = part.Q_coordinates[nodes.nodes[on], :d]
        normals = nodes.normals[on]
        motion, _ = _basis(Xc, centre, scale)
        _add_contact_rows(add, motion, normals, part.lambda_tau is not None)
    return _summed_gram(kinds, modes, comm)


def _add_contact_rows(add, motion: np.ndarray, normals: np.ndarray, friction: bool) -> None:
    """Hand `add` the rows a contact boundary holds: the motions' normal components at its
    nodes, and with friction (mu > 0 with a compliance law) their tangential components."""
    normal = np.einsum("mnd,nd->mn", motion, normals)
    add("normal", normal)
    if friction:
        tangential = motion - normal[:, :, None] * normals[None]
        for c in range(motion.shape[2]):
            add("tangential", tangential[:, :, c])


def _summed_gram(kinds: dict, size: int, comm) -> np.ndarray:
    """The sum over the kinds of conditions of each kind's Gram matrix over all ranks divided
    by its number of rows (each kind weighs the same, whatever its number of points)."""
    G = np.zeros((size, size))
    for gram, rows in kinds.values():
        gram, rows = comm.allreduce(gram, op=MPI.SUM), comm.allreduce(rows, op=MPI.SUM)
        if rows:
            G += gram / rows
    return G


def _describe(null: np.ndarray, names: list[str], centre: np.ndarray,
              scale: float) -> list[str]:
    """Names of the motions spanning the null space `null` (modes, k) of G: basis motions
    lying (nearly) in it are named as they are; the rest of it is named from its orthonormal
    basis (2D: a rotation about some point, else a translation or a combination)."""
    modes = len(names)
    d = len(centre)
    projection = null @ null.T
    pure = [k for k in range(modes) if projection[k, k] > 0.999]
    free = [names[k] for k in pure]
    rest = null - np.eye(modes)[:, pure] @ (np.eye(modes)[:, pure].T @ null)
    directions, singular_values, _ = np.linalg.svd(rest, full_matrices=False)
    described = []
    for v in directions[:, singular_values > 1e-3].T:
        v = v / v[np.argmax(np.abs(v))]
        if d == 2 and abs(v[2]) > 1e-8:
            # a Tx + b Ty + c R about the centre = c (rotation about the point p)
            p = centre + scale * np.array([-v[1], v[0]]) / v[2]
            p[np.abs(p) < 1e-9 * scale] = 0.0
            described.append(f"rotation about z about the point ({p[0]:.4g}, {p[1]:.4g})")
        elif np.all(np.abs(v[d:]) < 1e-8):
            direction = v[:d] / np.linalg.norm(v[:d])
            described.append("translation along (" + ", ".join(f"{c:.3g}" for c in direction)
                             + ")")
        else:
            described.append("the combination " + " + ".join(
                f"{coef:.3g} ({name})" for coef, name in zip(v, names) if abs(coef) > 1e-8))
    return free + described


def free_motions(problem) -> list[str]:
    """Names of the rigid motions that neither the Dirichlet conditions nor the contact law
    of a built Problem restrain (empty when the body is held): the null space of the
    constraint Gram matrix G, eigenvalues below RESTRAINT_TOLERANCE times the largest."""
    mesh = problem.V.mesh
    centre, scale = _bounding_box(mesh)
    names = _basis(np.zeros((0, mesh.geometry.dim)), centre, scale)[1]
    G = _gram(problem, centre, scale, len(names))
    w, vectors = np.linalg.eigh(G)
    null = vectors[:, w <= RESTRAINT_TOLERANCE * max(w.max(), 1e-300)]
    if null.shape[1] == 0:
        return []
    return _describe(null, names, centre, scale)


def check(problem) -> None:
    """Stop with a scene error naming the free rigid motions, if any (two bodies in contact:
    check_bodies)."""
    if hasattr(problem.contact and problem.contact.obstacle, "pairing"):
        check_bodies(problem)
        return
    free = free_motions(problem)
    if not free:
        return
    contact = problem.scene["contact"]
    frictionless = contact is not None and problem.contact.lambda_tau is None
    raise SceneError(
        f"dirichlet: the body is free to move rigidly ({'; '.join(free)}): neither the "
        "Dirichlet conditions nor the contact law hold it, so the solution is not unique. "
        "Add a [[dirichlet]] condition on the free components"
        + ("; a contact boundary without friction (contact.mu = 0, or no compliance "
           "stiffness) leaves sliding along it free" if frictionless else "")
        + " (a contact boundary restrains normal motion, with friction mu > 0 also "
          "sliding)")


# ---- several bodies: the mesh's connected parts, coupled through the interface ----

def components(space) -> tuple[np.ndarray, int]:
    """The connected parts of the mesh (two cells are in one part when they share a node):
    per local node of the P1 space `space` (ghosts included) its part's number 0..m-1, the
    same on every rank and numbered in the order of each part's least global node.

    Each rank labels its own cells' nodes (a label is the least local node reachable, by
    hooking and pointer jumping), then the parts that meet at a ghost node are joined over
    the ranks: O(local cells) work and O(ghost nodes) numbers exchanged.

    Parameters
    ----------
    space : dolfinx.fem.FunctionSpace
        A P1 space of the mesh.

    Returns
    -------
    tuple
        (labels (local nodes,), number of parts m).
    """
    from contactvisco.fem import compat
    mesh = space.mesh
    comm = mesh.comm
    imap = space.dofmap.index_map
    n = imap.size_local + imap.num_ghosts
    cells = compat.cell_dofs(space.dofmap)[:mesh.topology.index_map(mesh.topology.dim)
                                           .size_local]
    labels = np.arange(n)
    # the cells of each node, as runs of one sorted list (for a minimum per node)
    order = np.argsort(cells.ravel(), kind="stable")
    sorted_nodes = cells.ravel()[order]
    runs = np.flatnonzero(np.r_[True, sorted_nodes[1:] != sorted_nodes[:-1]])
    touched = sorted_nodes[runs]
    while True:
        least = labels[cells].min(axis=1)
        new = labels.copy()
        if len(runs):
            reached = np.minimum.reduceat(np.repeat(least, cells.shape[1])[order], runs)
            new[touched] = np.minimum(new[touched], reached)
        while True:                              # pointer jumping: new[i] <= i throughout
            jumped = new[new]
            if np.array_equal(jumped, new):
                break
            new = jumped
        if np.array_equal(new, labels):
            break
        labels = new
    global_nodes = np.asarray(imap.local_to_global(np.arange(n, dtype=np.int32)), np.int64)
    roots, inverse = np.unique(labels, return_inverse=True)
    # a part of this rank is named by the least global node in it
    least = np.full(len(roots), np.iinfo(np.int64).max)
    np.minimum.at(least, inverse, global_nodes)
    name = least[inverse]
    ghosts = np.asarray(global_nodes[imap.size_local:], dtype=np.int64)
    parts = comm.allgather((ghosts, name[imap.size_local:]))
    start, end = imap.local_range
    links = []
    for ghost, their in parts:
        mine = (ghost >= start) & (ghost < end)
        links += list(zip(name[ghost[mine] - start].tolist(), their[mine].tolist()))
    links = [link for part in comm.allgather(links) for link in part]
    parent = {}

    def find(a):
        parent.setdefault(a, a)
        while parent[a] != a:
            parent[a] = parent[parent[a]]
            a = parent[a]
        return a

    for a, b in links:
        a, b = find(a), find(b)
        if a != b:
            parent[max(a, b)] = min(a, b)
    every = sorted({find(a) for part in comm.allgather(least.tolist()) for a in part})
    number = {a: i for i, a in enumerate(every)}
    mapped = np.array([number[find(int(a))] for a in least], dtype=np.int64)
    return mapped[inverse], len(every)


def body_gram(problem) -> tuple[np.ndarray, int, list[str]]:
    """The constraint Gram matrix of the rigid motions of every part of a mesh whose contact
    boundary meets another part (fem.body_contact): the motions m_b of all parts b at once
    (a block of 3 in 2D, 6 in 3D, per part), G = sum_k mean_r c_r c_r^T per kind k as in
    _gram, with the rows

    - Dirichlet on component i at a node x of part b: m_b,i(x);
    - the interface at a slave node x_i of part s whose closest point lies on part m, with
      the law's normal nu_i: (m_s(x_i) - m_m(x_i)) . nu_i, the relative motion the law sees
      (u_rel = u - Pi u, Pi carrying a rigid motion of the master to x_i);
    - with friction (multiplier lambda_tau): the tangential part of m_s(x_i) - m_m(x_i).

    Returns
    -------
    tuple
        (G, number of parts, the basis motions' names).
    """
    V = problem.V
    mesh = V.mesh
    comm = mesh.comm
    d = mesh.geometry.dim
    centre, scale = _bounding_box(mesh)
    names = _basis(np.zeros((0, d)), centre, scale)[1]
    modes = len(names)
    labels, count = components(V)
    owned = V.dofmap.index_map.size_local
    X = V.tabulate_dof_coordinates()[:owned, :d]
    size = modes * count
    kinds = {kind: [np.zeros((size, size)), 0] for kind in ("dirichlet", "normal",
                                                             "tangential")}

    def add(kind, rows):
        kinds[kind][0] += rows @ rows.T
        kinds[kind][1] += rows.shape[1]

    fixed = problem.u_fixed[:owned] > 0
    for c in range(d):
        at = np.flatnonzero(fixed[:, c])
        rows = np.zeros((size, len(at)))
        values = _basis(X[at], centre, scale)[0][:, :, c]
        for b in range(count):
            mine = labels[at] == b
            rows[b * modes:(b + 1) * modes, mine] = values[:, mine]
        add("dirichlet", rows)
    part = problem.contact
    link = part.obstacle
    nodes, on = part.nodes, part.nodes.owned
    own = nodes.nodes[on]
    Xc = part.Q_coordinates[own, :d]
    normals = nodes.normals[on]
    # the part of each master boundary node, from the owner of that node
    start, end = V.dofmap.index_map.local_range
    mine = link.master_nodes[(link.master_nodes >= start) & (link.master_nodes < end)]
    master_part = {}
    for k, b in comm.allgather((mine, labels[mine - start])):
        master_part.update(zip(k.tolist(), b.tolist()))
    facet = link.facet_at[own]
    slave_of = labels[own]
    master_of = np.array([master_part[int(link.facet_nodes[f, 0])] for f in facet],
                         dtype=np.int64)
    motion, _ = _basis(Xc, centre, scale)
    relative = np.zeros((size, len(own), d))
    for b in range(count):
        block = slice(b * modes, (b + 1) * modes)
        relative[block] += np.where((slave_of == b)[None, :, None], motion, 0.0)
        relative[block] -= np.where((master_of == b)[None, :, None], motion, 0.0)
    _add_contact_rows(add, relative, normals, part.lambda_tau is not None)
    return _summed_gram(kinds, size, comm), count, names


def free_body_motions(problem) -> list[str]:
    """The rigid motions of the parts of a two-body mesh that nothing holds (body_gram's
    null space, eigenvalues below RESTRAINT_TOLERANCE times the largest), each as the parts
    it moves and how: "the slave body (contact.boundary 'slave'): translation along y".

    Parameters
    ----------
    problem : contactvisco.fem.problem.Problem
        A built problem with obstacle.shape = "body".

    Returns
    -------
    list of str
        Empty when every part is held.
    """
    G, count, names = body_gram(problem)
    modes = len(names)
    w, vectors = np.linalg.eigh(G)
    null = vectors[:, w <= RESTRAINT_TOLERANCE * max(w.max(), 1e-300)]
    if null.shape[1] == 0:
        return []
    mesh = problem.V.mesh
    centre, scale = _bounding_box(mesh)
    which = _part_names(problem, count)
    out = []
    for b in range(count):
        block = null[b * modes:(b + 1) * modes]
        directions, singular_values, _ = np.linalg.svd(block, full_matrices=False)
        moving = directions[:, singular_values > 1e-3]
        if moving.shape[1]:
            q, _ = np.linalg.qr(moving)
            out.append(f"{which[b]}: " + "; ".join(_describe(q, names, centre, scale)))
    return out


def interface_parts(problem) -> np.ndarray:
    """Per local P1 node (ghosts included) of a two-body problem, its body: 0 the slave's
    part of the mesh (the contact boundary's), 1 the master's (obstacle.boundary's), 2, 3, ...
    any other part, in the order of its first node by position (x, then y, then z), so that
    the numbers do not depend on the partition (collective).

    Parameters
    ----------
    problem : contactvisco.fem.problem.Problem
        A built problem with obstacle.shape = "body".

    Returns
    -------
    numpy.ndarray
        The body number of every local node.
    """
    V = problem.V
    comm = V.mesh.comm
    d = V.mesh.geometry.dim
    labels, count = components(V)
    link = problem.contact.obstacle
    nodes = problem.contact.nodes
    start, end = V.dofmap.index_map.local_range
    mine = link.master_nodes[(link.master_nodes >= start) & (link.master_nodes < end)]
    x = V.tabulate_dof_coordinates()[:, :d]
    first = {}
    for b in range(count):
        at = np.flatnonzero(labels == b)
        if len(at):
            first[b] = tuple(x[at[np.lexsort(x[at].T[::-1])[0]]].tolist())
    gathered = comm.allgather((set(labels[nodes.nodes[nodes.owned]].tolist()),
                               set(labels[mine - start].tolist()), first))
    slave = set().union(*(g[0] for g in gathered))
    master = set().union(*(g[1] for g in gathered))
    where = {b: min(g[2][b] for g in gathered if b in g[2]) for b in range(count)}
    order = sorted(slave) + sorted(master - slave)
    order += sorted((b for b in range(count) if b not in order), key=lambda b: where[b])
    number = np.empty(count, dtype=np.int64)
    number[order] = np.arange(count)
    return number[labels]


def _part_names(problem, count: int) -> list[str]:
    """How a message names each part: the slave or master body by its boundary, any other
    by its least node's position."""
    V = problem.V
    comm = V.mesh.comm
    d = V.mesh.geometry.dim
    labels, _ = components(V)
    link = problem.contact.obstacle
    scene = problem.scene
    slave_name = scene["contact"]["boundary"]
    slave_name = slave_name if isinstance(slave_name, str) else slave_name[0]
    nodes = problem.contact.nodes
    own = nodes.nodes[nodes.owned]
    start, end = V.dofmap.index_map.local_range
    mine = link.master_nodes[(link.master_nodes >= start) & (link.master_nodes < end)]
    owned = V.dofmap.index_map.size_local
    X = V.tabulate_dof_coordinates()[:owned, :d]
    first = {}
    for b in range(count):
        at = np.flatnonzero(labels[:owned] == b)
        first[b] = X[at[0]].tolist() if len(at) else None
    gathered = comm.allgather((set(labels[own].tolist()), set(labels[mine - start].tolist()),
                               first))
    slave = set().union(*(g[0] for g in gathered))
    master = set().union(*(g[1] for g in gathered))
    out = []
    for b in range(count):
        if b in slave:
            out.append(f"the slave body (contact.boundary '{slave_name}')")
        elif b in master:
            out.append(f"the master body (obstacle.boundary '{scene['obstacle']['boundary']}')")
        else:
            point = next(g[2][b] for g in gathered if g[2][b] is not None)
            out.append("the body through (" + ", ".join(f"{c:.4g}" for c in point) + ")")
    return out


def check_bodies(problem) -> None:
    """Stop with a scene error naming each part of a two-body mesh that is free to move
    rigidly, and how (free_body_motions). The interface holds the relative normal motion
    of the slave and master (any contact law: a compliance, a bound g including Signorini's
    g = 0, a prescribed p_nu), with friction also the relative sliding; a part held only
    through the interface is held when the part across it is."""
    free = free_body_motions(problem)
    if not free:
        return
    frictionless = problem.contact.lambda_tau is None
    raise SceneError(
        f"dirichlet: a body is free to move rigidly ({'; '.join(free)}): neither the "
        "Dirichlet conditions nor the interface with the other body hold it, so the "
        "solution is not unique. Add a [[dirichlet]] condition on the free components of "
        "that body"
        + ("; the interface without friction leaves sliding along it free"
           if frictionless else "")
        + " (the interface holds the motion of one body relative to the other across it, "
          "normal to it, with friction mu > 0 also sliding)", key="dirichlet")
