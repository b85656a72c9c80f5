"""Contact of two deformable bodies of one mesh: the slave boundary (contact.boundary) against
the master boundary of another body (obstacle.shape = "body", obstacle.boundary).

The law of contactvisco.model.contact_law holds at each slave node i for the displacement
relative to the master,

    u_rel,i = u_i - sum_k Pi_ik u_k        (k: master nodes),

with Pi the projection operator of contactvisco.fem.interface (mortar or node to segment),
built once in the reference configuration (small sliding). The law sees the master as an
obstacle whose displacement at the slave nodes is the P1 field D = Pi u, its direction nu_i
and gap h_i fixed:

    nu_i = -n_m(p_i),    h_i = n_m(p_i) . (x_i - sum_k Pi_ik x_k),

n_m(p_i) the outward normal of the master facet of the closest point p_i of x_i
(interface.project), so that s_i = (u_i - (Pi u)_i) . nu_i - h_i is the penetration. For node
to segment h_i is the closest-point gap; for mortar it is the weighted gap (docs/interface.md).

The master receives -Pi^T of the slave's nodal contact forces c: with T = I - P, P the matrix
Pi (x) I_d on the dofs of u (slave rows, master columns), the residual and Jacobian are

    F = F_el + T^T c(T u),        J = J_el + T^T K_c T,

where K_c = dc/du_rel. The forms of the problem assemble F_el + c and J_el + K_c with D held
fixed; the solver (contactvisco.solver.interface_newton) adds -P^T c and T^T K_c T - K_c.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from dolfinx import fem
from mpi4py import MPI
from petsc4py import PETSc

from contactvisco.errors import SceneError
from contactvisco.fem import compat, interface, parts

_INSERT, _FORWARD = PETSc.InsertMode.INSERT, PETSc.ScatterMode.FORWARD

#: Without contact.search_distance, a slave node may lie this fraction of the mesh's extent
#: away from the master boundary.
SEARCH_FRACTION = 0.1


@dataclass
class BodyContact:
    """The master body as the slave nodes' obstacle: nu (``normal``, W) and h (``gap``, Q)
    fixed, D = Pi u (``D``, W) following u (follow()), P = Pi (x) I_d on u's dofs, the pairing
    itself, and the contact terms of F_u (``contact_form``, UFL), set by the problem."""
    normal: fem.Function
    gap: fem.Function
    D: fem.Function
    P: PETSc.Mat
    pairing: interface.Pairing
    method: str
    D_previous: fem.Function | None = None
    contact_form: object | None = None
    force_forms: dict | None = None
    rigid: bool = False                # no position of its own: D follows u
    slide_nodes: np.ndarray | None = None      # owned slave nodes (local P1 numbers)
    slide_points: np.ndarray | None = None     # their reference coordinates
    slide_limits: np.ndarray | None = None     # contact.sliding_limit of their facet
    sliding_limit: float = 0.5                 # contact.sliding_limit
    facet_at: np.ndarray | None = None   # per local P1 node: its projection's master facet
    boundaries: tuple = ("", "")       # (slave, master) boundary names
    master_nodes: np.ndarray | None = None   # global P1 nodes of the master boundary
    facet_nodes: np.ndarray | None = None    # (facets, d) global P1 nodes of each master facet
    _compiled: object | None = None
    _vectors: tuple | None = None
    _master_rows: tuple | None = None

    def sliding(self, u: fem.Function) -> tuple | None:
        """The slave node whose tangential displacement relative to the master goes furthest
        past the small-sliding limit of its pairing, if one does (collective).

        The pairing is made once in the reference configuration; it holds while each slave
        node stays on its master facet, which is checked as

            |u_rel,tau,i| <= l_i,    u_rel,tau = u_rel - (u_rel . nu) nu,
            u_rel,i = u_i - (Pi u)_i,

        l_i the fraction contact.sliding_limit (a half by default) of the length (2D) or of
        the smallest height (3D) of the master facet of x_i's closest point.

        Parameters
        ----------
        u : dolfinx.fem.Function
            The displacement (P1, D's layout).

        Returns
        -------
        tuple or None
            (position x_i, slip |u_rel,tau,i|, limit l_i) of the node of the largest ratio
            slip / limit above 1 over every rank, or None when every node is within.
        """
        self.follow(u)
        d = self.D.function_space.mesh.geometry.dim
        nodes = self.slide_nodes
        worst = (0.0, None)
        if nodes is not None and nodes.size:
            rel = (u.x.array.reshape(-1, d)[nodes] - self.D.x.array.reshape(-1, d)[nodes])
            nu = self.normal.x.array.reshape(-1, d)[nodes]
            tangential = rel - np.einsum("nd,nd->n", rel, nu)[:, None] * nu
            slip = np.linalg.norm(tangential, axis=1)
            ratio = slip / self.slide_limits
            j = int(np.argmax(ratio))
            worst = (float(ratio[j]), (tuple(float(c) for c in self.slide_points[j]),
                                       float(slip[j]), float(self.slide_limits[j])))
        comm = self.D.function_space.mesh.comm
        ratio, where = max(comm.allgather(worst), key=lambda item: item[0])
        return where if ratio > 1.0 else None

    @property
    def controlled(self) -> list:
        """No force-controlled component: the master moves with the solution."""
        return []

    def displacement(self) -> np.ndarray:
        """The zero vector: the master has no rigid displacement of its own."""
        return np.zeros(self.D.function_space.mesh.geometry.dim)

    def follow(self, u: fem.Function) -> None:
        """D = P u, the master's displacement carried to the slave nodes (ghosts updated).

        Parameters
        ----------
        u : dolfinx.fem.Function
            The displacement (P1, the layout of D).
        """
        target = compat.petsc_vector(self.D)
        self.P.mult(compat.petsc_vector(u), target)
        target.ghostUpdate(addv=_INSERT, mode=_FORWARD)

    def nodal_forces(self) -> tuple:
        """The contact forces on each body's nodes at the current u and D (collective).

        With c the contact terms of the slave's residual (the assembled ``contact_form``),
        the slave's nodes receive f_s = -c and the master's nodes f_m = P^T c, so that
        sum f_m = -sum f_s wherever every row of Pi sums to 1.

        Returns
        -------
        tuple of petsc4py.PETSc.Vec
            (f_s, f_m), vectors of u's layout (owned entries complete; owned by this
            object, overwritten by the next call).
        """
        from dolfinx.fem.petsc import assemble_vector
        if self._vectors is None:
            self._compiled = (None if self.contact_form is None
                              else fem.form(self.contact_form))
            c = compat.ghosted_vector(self.D.function_space, self.P.getComm().tompi4py())
            self._vectors = (c, c.copy(), c.copy())
        c, slave, master = self._vectors
        with c.localForm() as local:
            local.set(0.0)
        if self._compiled is not None:
            assemble_vector(c, self._compiled)
            c.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        c.copy(slave)
        slave.scale(-1.0)
        self.P.multTranspose(c, master)
        return slave, master

    def resultants(self) -> dict:
        """The resultant contact force on each body (collective): F_s = -sum_i c_i over the
        slave nodes, F_m = sum_k (Pi^T c)_k over the master nodes (nodal_forces), equal and
        opposite where the master covers every slave node's support.

        Returns
        -------
        dict
            ``slave_force`` and ``master_force``, lists of d floats (every rank).
        """
        d = self.D.function_space.mesh.geometry.dim
        comm = self.D.function_space.mesh.comm
        owned = self.D.function_space.dofmap.index_map.size_local
        out = {}
        for name, vector in zip(("slave_force", "master_force"), self.nodal_forces()):
            mine = vector.array_r.reshape(-1, d)[:owned].sum(axis=0)
            out[name] = comm.allreduce(mine, MPI.SUM).tolist()
        return out

    def interface_values(self, own: np.ndarray) -> dict:
        """The slave's columns of the interface table at the owned contact nodes `own` (local
        P1 node indices; collective): the master facet of each node's closest point (its
        index in the gathered master boundary, whose order does not depend on the partition)
        and the node's contact force f_s = -c_i (nodal_forces).

        Parameters
        ----------
        own : numpy.ndarray
            Local indices of the owned contact (slave) nodes.

        Returns
        -------
        dict
            ``facet`` (n,) and ``force`` (n, d).
        """
        d = self.D.function_space.mesh.geometry.dim
        slave, _ = self.nodal_forces()
        with slave.localForm() as local:
            force = local.array_r.reshape(-1, d)[own].copy()
        return {"facet": self.facet_at[own].copy(), "force": force}

    def master_values(self) -> dict:
        """The master's rows of the interface table: the owned master boundary nodes, their
        coordinates and contact forces f_m = (Pi^T c)_k (nodal_forces; collective). Rows of
        this rank only, to be gathered.

        Returns
        -------
        dict
            ``x`` (m, d) and ``force`` (m, d).
        """
        space = self.D.function_space
        d = space.mesh.geometry.dim
        if self._master_rows is None:        # once: the coordinates are O(local nodes)
            start, end = space.dofmap.index_map.local_range
            mine = self.master_nodes[(self.master_nodes >= start)
                                     & (self.master_nodes < end)] - start
            self._master_rows = (mine, space.tabulate_dof_coordinates()[mine, :d].copy())
        mine, x = self._master_rows
        _, master = self.nodal_forces()
        return {"x": x.copy(), "force": master.array_r.reshape(-1, d)[mine].copy()}

    def record(self) -> dict:
        """The obstacle entry of a step record: what the master is (another body of the
        mesh, no rigid position of its own) and each body's resultant contact force
        (resultants).

        Returns
        -------
        dict
            ``shape`` = "body", ``slave`` and ``master`` (the boundary names),
            ``pairing``, ``slave_force``, ``master_force``.
        """
        return {"shape": "body", "slave": self.boundaries[0], "master": self.boundaries[1],
                "pairing": self.method, **self.resultants()}

    def prepare(self, committed) -> None:
        """Nothing to prepare between steps (the pairing is fixed)."""

    def commit(self) -> None:
        """Nothing to commit (the pairing is fixed)."""

    def move_to(self) -> None:
        """Nothing follows the time."""


def search_distance(scene: dict, length_scale: float) -> float:
    """contact.search_distance, or SEARCH_FRACTION times the mesh's extent.

    Parameters
    ----------
    scene : dict
        The resolved scene.
    length_scale : float
        The largest extent of the mesh's bounding box.

    Returns
    -------
    float
        The largest distance of a slave node from the master boundary.
    """
    given = scene["contact"]["search_distance"]
    return float(given) if given is not None else SEARCH_FRACTION * length_scale


def overlap(comm, slave, master, found, reach: float, slave_name: str, master_name: str,
            gaps=None) -> None:
    """Stop when the bodies overlap in the reference configuration by more than the search
    distance: a slave node whose signed gap to the master boundary (its closest point's,
    over all master facets, or `gaps` when given: the gap h of the pairing) is below -reach
    (collective).

    Parameters
    ----------
    comm : mpi4py.MPI.Comm
        The mesh's communicator.
    slave : contactvisco.fem.interface.SlaveSide
        The owned slave nodes and their coordinates.
    master : contactvisco.fem.interface.Surface
        The gathered master boundary.
    found : contactvisco.fem.interface.Projection
        The slave nodes' projection within `reach` (nodes beyond it are projected again
        without a limit).
    reach : float
        contact.search_distance.
    slave_name, master_name : str
        The boundaries, for the message.
    gaps : numpy.ndarray, optional
        The signed gaps of the owned slave nodes, in place of the closest points'.

    Raises
    ------
    SceneError
        Naming contact.search_distance: how many slave nodes lie inside the master by more
        than it, the deepest and where.
    """
    if gaps is None:
        gaps = found.gap.copy()
        if found.missing:
            again = interface.project(slave.coordinates[found.missing], master, np.inf)
            gaps[found.missing] = again.gap
    inside = np.flatnonzero(gaps < -reach)
    deepest = None
    if len(inside):
        j = inside[np.argmin(gaps[inside])]
        deepest = (float(gaps[j]), ", ".join(f"{c:.6g}" for c in slave.coordinates[j]))
    count = comm.allreduce(len(inside), MPI.SUM)
    if not count:
        return
    depth, where = min(g for g in comm.allgather(deepest) if g is not None)
    raise SceneError(f"contact.search_distance: the bodies overlap in the reference "
                     f"configuration: {count} slave node(s) of '{slave_name}' lie inside the "
                     f"master body (obstacle.boundary '{master_name}') by more than "
                     f"contact.search_distance = {reach:g}, the deepest by {-depth:.6g} at "
                     f"({where}); move the bodies apart (contact.search_distance bounds the "
                     "initial penetration that is accepted)", key="contact.search_distance")


def separate_bodies(geometry, V, slave_name: str, master_name: str) -> None:
    """Refuse a master boundary on the slave's own body (one connected part of the mesh): the
    contact force would then pass through that body itself, from one of its faces to another.

    Parameters
    ----------
    geometry : contactvisco.fem.geometry.Geometry
        The mesh and its named boundaries.
    V : dolfinx.fem.FunctionSpace
        The P1 displacement space.
    slave_name, master_name : str
        contact.boundary and obstacle.boundary.

    Raises
    ------
    SceneError
        Naming obstacle.boundary (collective: every rank alike).
    """
    labels, _ = parts.part_labels(V)
    fdim = geometry.mesh.topology.dim - 1
    found = {}
    for name, key in ((slave_name, "contact.boundary"), (master_name, "obstacle.boundary")):
        dofs = fem.locate_dofs_topological(V, fdim, geometry.facets(name, key))
        mine = np.unique(labels[dofs]).tolist()
        found[key] = set().union(*geometry.mesh.comm.allgather(mine))
    shared = found["contact.boundary"] & found["obstacle.boundary"]
    if shared:
        raise SceneError(f"obstacle.boundary = '{master_name}' is a face of the same body as "
                         f"contact.boundary = '{slave_name}' (one connected part of the mesh): "
                         "the contact force would pass through that body itself; give the "
                         "boundary of another body (a part of the mesh not joined to the "
                         "slave's)", key="obstacle.boundary")


def build(scene: dict, geometry, V, Q, W, nodes, length_scale: float) -> BodyContact:
    """The pairing of the contact boundary (slave) with obstacle.boundary (master), and the
    fields nu, h and D at the slave nodes (module description).

    Parameters
    ----------
    scene : dict
        The resolved scene (contact.pairing, contact.search_distance, obstacle.boundary).
    geometry : contactvisco.fem.geometry.Geometry
        The mesh and its boundary names.
    V : dolfinx.fem.FunctionSpace
        The displacement's space (P1).
    Q, W : dolfinx.fem.FunctionSpace
        The scalar and vector P1 spaces of the contact fields.
    nodes : contactvisco.fem.contact_terms.ContactNodes
        The slave nodes; their normals become nu.
    length_scale : float
        The mesh's extent (the default search distance).

    Returns
    -------
    BodyContact
        nu, h, D and P = Pi (x) I_d, Pi_ik = N_k(p_i) (node to segment) or (D^-1 M)_ik
        (mortar).

    Raises
    ------
    SceneError
        A slave node farther than the search distance from the master boundary, or inside
        the master by more than it (overlap; both naming contact.search_distance), or a
        boundary name the mesh does not have.
    """
    mesh = geometry.mesh
    comm = mesh.comm
    d = mesh.geometry.dim
    if compat.element_degree(V) != 1:
        raise SceneError("obstacle.shape = 'body' needs discretization.degree = 1 (the "
                         "interface pairs P1 nodes)", key="discretization.degree")
    contact, obstacle = scene["contact"], scene["obstacle"]
    mu = contact["mu"]
    if (isinstance(mu, str) or mu > 0) and contact["slip"] == "increment":
        raise SceneError("contact.slip = 'increment' with obstacle.shape = 'body': the slip of "
                         "a step relative to another body is not built; use contact.slip = "
                         "'total'", key="contact.slip")
    slave_name, master_name = contact["boundary"], obstacle["boundary"]
    slave_name = slave_name if isinstance(slave_name, str) else slave_name[0]
    separate_bodies(geometry, V, slave_name, master_name)
    reach = search_distance(scene, length_scale)
    slave = interface.slave_side(V, geometry.facet_tags, geometry.names[slave_name])
    master = interface.boundary_surface(V, geometry.facet_tags, geometry.names[master_name],
                                        "obstacle.boundary")
    found = interface.project(slave.coordinates, master, reach)
    method = contact["pairing"]
    pairing = interface.pair(slave, master, method, reach)
    overlap(comm, slave, master, found, reach, slave_name, master_name)
    far = sorted(set(slave.nodes[found.missing].tolist()) | set(pairing.unpaired))
    first = None
    if far:
        j = int(np.flatnonzero(slave.nodes == far[0])[0])
        first = ", ".join(f"{c:.6g}" for c in slave.coordinates[j])
    where = [w for w in comm.allgather(first) if w is not None]
    count = comm.allreduce(len(far), MPI.SUM)
    if count:
        raise SceneError(f"contact.search_distance: {count} slave node(s) of "
                         f"'{slave_name}' have no master facet of '{master_name}' within "
                         f"{reach:g} (contact.pairing = '{method}'), the first at "
                         f"({where[0]}); raise contact.search_distance or check the "
                         "boundaries", key="contact.search_distance")
    # nu = -n_m and the gap h = n_m . (x_i - (Pi x)_i) at the owned slave nodes.
    where_x = {int(k): x for k, x in zip(master.nodes.ravel(),
                                         master.coordinates.reshape(-1, d))}
    carried = pairing.apply(where_x)
    start = V.dofmap.index_map.local_range[0]
    local = slave.nodes - start
    normal, gap = fem.Function(W), fem.Function(Q)
    n_m = found.normal
    projected = np.array([carried[int(i)] for i in slave.nodes]).reshape(-1, d)
    normal.x.array.reshape(-1, d)[local] = -n_m
    gap.x.array[local] = np.einsum("ng,ng->n", n_m, slave.coordinates - projected)
    for f in (normal, gap):
        compat.petsc_vector(f).ghostUpdate(addv=_INSERT, mode=_FORWARD)
    nodes.normals = normal.x.array.reshape(-1, d)[nodes.nodes].copy()
    nodes.corners = np.zeros(0, dtype=nodes.nodes.dtype)
    deepest = float(gap.x.array[local].min(initial=np.inf))
    if comm.allreduce(deepest, MPI.MIN) < -reach:       # the weighted gap (mortar)
        overlap(comm, slave, master, found, reach, slave_name, master_name,
                gaps=gap.x.array[local])
    facet_at = np.full(len(gap.x.array), -1, dtype=np.int64)
    facet_at[local] = found.facet
    sizes = interface.index_sizes(V)
    # On a lasting communicator: P and the force vectors live as long as the problem, and
    # whenever it is dropped the next run can still destroy them (compat.lasting_comm).
    P = pairing.matrix(compat.lasting_comm(comm), sizes, sizes, d)
    return BodyContact(normal=normal, gap=gap, D=fem.Function(W), P=P, pairing=pairing,
                       method=method, slide_nodes=local, slide_points=slave.coordinates,
                       sliding_limit=contact["sliding_limit"],
                       slide_limits=2.0 * contact["sliding_limit"]
                       * facet_sizes(master.coordinates)[found.facet],
                       facet_at=facet_at, boundaries=(slave_name, master_name),
                       master_nodes=np.unique(master.nodes), facet_nodes=master.nodes)


def facet_sizes(coordinates: np.ndarray) -> np.ndarray:
    """The small-sliding limit of each master facet: half a segment's length (2D), half a
    triangle's smallest height (3D).

    Parameters
    ----------
    coordinates : numpy.ndarray
        (facets, d, gdim) the facets' vertices (interface.Surface.coordinates).

    Returns
    -------
    numpy.ndarray
        (facets,) l = |b - a| / 2 for a segment (a, b); l = A / max_k |e_k| for a triangle
        of area A and edges e_k (half of its smallest height 2 A / max_k |e_k|).
    """
    if coordinates.shape[1] == 2:
        return 0.5 * np.linalg.norm(coordinates[:, 1] - coordinates[:, 0], axis=1)
    a, b, c = coordinates[:, 0], coordinates[:, 1], coordinates[:, 2]
    area = 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1)
    longest = np.max([np.linalg.norm(e, axis=1) for e in (b - a, c - b, a - c)], axis=0)
    return area / longest
