"""The connected parts of a mesh (the bodies of a two-body scene) and their rigid motions.

Two bodies in contact are one mesh of two parts that share no node. Elasticity does not see a
rigid motion of either part, m(x) = a + W (x - c_p) on part p alone (W skew: 3 motions per part
in 2D, 6 in 3D): those are the near-nullspace an algebraic multigrid needs, one set per part.
A part's rigid motion that moves no prescribed component is *floating*: only the contact holds
it, and a Newton matrix whose active contact conditions do not hold it is singular (the upper
of two cylinders touching at one node before loading, free to turn about a point of its
held diameter).

The parts are the connected components of the graph of P1 nodes linked by cells: each rank
labels its own cells' components (components), then the ranks agree on the smallest global node
number of every component through the ghosts, until no label changes.
"""
from __future__ import annotations

import numpy as np
from dolfinx import fem
from mpi4py import MPI
from petsc4py import PETSc

from contactvisco.fem import compat

#: Eigenvalue of the Gram matrix of a part's rigid motions on its prescribed components
#: (each motion scaled to norm 1) below which a combination moves none of them (floating).
FLOATING_TOLERANCE = 1e-10


def part_labels(V) -> tuple[np.ndarray, int]:
    """The connected part of every local node of a Lagrange space (owned and ghosts).

    Parameters
    ----------
    V : dolfinx.fem.FunctionSpace
        A Lagrange space of any degree (blocked or not); its nodes are its dofs' blocks.

    Returns
    -------
    numpy.ndarray, int
        Per local node its part number p in 0 .. count - 1, the same on every rank (parts
        numbered by their smallest global node number), and count.
    """
    index_map = V.dofmap.index_map
    n = index_map.size_local + index_map.num_ghosts
    component = components(compat.cell_dofs(V.dofmap), n)
    value = index_map.local_to_global(np.arange(n, dtype=np.int32)).astype(float)
    # the ghost exchange runs on the scalar space of V's own degree, whose dof layout is V's
    # nodes (P1's held only the vertices, too few for a P2 space)
    scalar = compat.scalar_space(V.mesh, "Lagrange", compat.element_degree(V))
    carrier = fem.Function(scalar)
    vec = compat.petsc_vector(carrier)
    comm = V.mesh.comm
    while True:
        smallest = np.full(component.max(initial=-1) + 1, np.inf)
        np.minimum.at(smallest, component, value)
        value = smallest[component]
        with vec.localForm() as local:
            local.array[:] = -value
        vec.ghostUpdate(addv=PETSc.InsertMode.MAX_VALUES, mode=PETSc.ScatterMode.REVERSE)
        vec.ghostUpdate(addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)
        with vec.localForm() as local:
            new = -local.array.copy()
        changed = comm.allreduce(bool(np.any(new != value)), op=MPI.LOR)
        value = new
        if not changed:
            break
    owned = np.unique(value[:index_map.size_local])
    names = np.unique(np.concatenate(comm.allgather(owned)))
    return np.searchsorted(names, value).astype(np.int32), int(names.size)


def components(cells: np.ndarray, n: int) -> np.ndarray:
    """The connected components of n nodes linked by cells (rows of node numbers).

    Parameters
    ----------
    cells : numpy.ndarray
        (cells, k) node numbers.
    n : int
        The number of nodes.

    Returns
    -------
    numpy.ndarray
        Per node the smallest node number of its component: r(i) = min { j : j ~ i }, by
        hooking every cell's roots onto the smallest and halving the paths to the roots
        until no root changes.
    """
    root = np.arange(n)
    first = np.repeat(cells[:, 0], cells.shape[1] - 1)
    other = cells[:, 1:].ravel()
    while True:
        a, b = root[first], root[other]
        hooked = root.copy()
        np.minimum.at(hooked, np.maximum(a, b), np.minimum(a, b))
        while True:                                    # to the roots
            deeper = hooked[hooked]
            if np.array_equal(deeper, hooked):
                break
            hooked = deeper
        if np.array_equal(hooked, root):
            return root
        root = hooked


def rigid_motions(X: np.ndarray, labels: np.ndarray, count: int, comm) -> list[np.ndarray]:
    """The rigid motions of every part at nodes X, each about its part's centroid.

    Parameters
    ----------
    X : numpy.ndarray
        (n, d) coordinates of this rank's owned nodes.
    labels : numpy.ndarray
        (n,) their parts (part_labels).
    count : int
        The number of parts.
    comm : mpi4py.MPI.Comm
        The mesh's communicator.

    Returns
    -------
    list of numpy.ndarray
        Per part p, an array (m, n, d) of its m = d (d + 1) / 2 motions
        m(x) = a + W (x - c_p) (translations, then rotations), zero off the part;
        c_p the mean of its nodes.
    """
    n, d = X.shape
    sums = np.zeros((count, d + 1))
    np.add.at(sums, labels, np.hstack([X, np.ones((n, 1))]))
    sums = comm.allreduce(sums, op=MPI.SUM)
    centres = sums[:, :d] / np.maximum(sums[:, d:], 1.0)
    out = []
    for p in range(count):
        on = labels == p
        Y = np.where(on[:, None], X - centres[p], 0.0)
        modes = []
        for c in range(d):                                 # translations
            mode = np.zeros((n, d))
            mode[on, c] = 1.0
            modes.append(mode)
        for a, b in ([(0, 1)] if d == 2 else [(0, 1), (1, 2), (2, 0)]):   # rotations
            mode = np.zeros((n, d))
            mode[:, a], mode[:, b] = -Y[:, b], Y[:, a]
            modes.append(mode)
        out.append(np.array(modes))
    return out


def floating_motions(V, fixed: np.ndarray, labels: np.ndarray, count: int) -> list[np.ndarray]:
    """The rigid motions of single parts that move no prescribed component.

    Parameters
    ----------
    V : dolfinx.fem.FunctionSpace
        The displacement space (Lagrange, block size d).
    fixed : numpy.ndarray
        (local nodes, d) > 0 on prescribed components (Problem.u_fixed).
    labels, count
        The parts of the local nodes (part_labels).

    Returns
    -------
    list of numpy.ndarray
        Arrays (owned nodes, d): a basis of the null space of the Gram matrix
        G_p = sum_(i,h prescribed) m_k(x_i)_h m_l(x_i)_h of each part's motions m_k,
        scaled by the motions' norms, eigenvalues below FLOATING_TOLERANCE (all of the
        part's motions if nothing of it is prescribed).
    """
    d = V.dofmap.index_map_bs
    owned = V.dofmap.index_map.size_local
    X = V.tabulate_dof_coordinates()[:owned, :d]
    comm = V.mesh.comm
    held = fixed.reshape(-1, d)[:owned] > 0
    out = []
    for modes in rigid_motions(X, labels[:owned], count, comm):
        values = modes[:, held]                            # (m, prescribed components)
        gram = comm.allreduce(values @ values.T, op=MPI.SUM)
        norms = comm.allreduce((modes.reshape(len(modes), -1) ** 2).sum(axis=1), op=MPI.SUM)
        scaled = gram / np.sqrt(np.outer(norms, norms))
        w, vectors = np.linalg.eigh(scaled)
        free = vectors[:, w <= FLOATING_TOLERANCE]
        for combination in free.T:
            out.append(np.tensordot(combination / np.sqrt(norms), modes, axes=1))
    return out
