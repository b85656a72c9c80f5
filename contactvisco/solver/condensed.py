"""Newton on the displacement alone: the nodal multipliers eliminated node by node.

With the vertex rule on Gamma_C the multiplier equations of contact node i involve only u_i and
lambda_i, and lambda_i enters only the rows of u_i. The Newton system of the coupled problem,

    [ J    B ] [du]     [F_u]
    [ C    D ] [dl] = - [G  ],

is therefore made of one d x m, m x d and m x m block per node: B_i, C_i, D_i (m = 1, d or d + 1
multiplier components). D_i is singular where a condition is active: lambda_i is then a
reaction, and its equation a constraint on u_i (u_nu = g at a bound node, u_tau = 0 at a
sticking one). D_i need not be symmetric: with Coulomb's law (contact.friction_law = "coulomb")
lambda_tau's ball has the radius mu (p_nu + R_nu), so a sliding node's lambda_tau rows depend
on lambda_nu and not the other way round; the SVD below keeps the left (U_0) and right (V_0)
null vectors apart, so the elimination holds for any D_i. With the SVD D_i = U S V^T split into range (r) and null (0) parts:

    dl_i = D_i^+ (-G_i - C_i du_i) + V_0 b_i,      D_i^+ = V_r S_r^-1 U_r^T,
    U_0^T C_i du_i = -U_0^T G_i                    (m - r constraints on du_i),
    (J du)_i + B_i dl_i = -F_u,i.

With Z_i = B_i V_0 = Q_i R_i, the projection P_i = I - Q_i Q_i^T removes b_i from the rows of
u_i and the m - r constraints take its place in the directions Q_i, scaled by s_i (the size of J's
diagonal at the node):

    P_i (J du)_i + L_i du_i = -[P_i (F_u,i - E_i G_i) + s_i Q_i U_0^T G_i],
    E_i = B_i D_i^+,   L_i = -P_i E_i C_i + s_i Q_i U_0^T C_i.

The linear system keeps the size of u: J_red = S J + L with S = diag(P_i) (the identity off the
active nodes), built in place: only the rows of contact nodes change. After the solve, dl_i follows node by node with
b_i = R_i^-1 Q_i^T (-F_u,i - (J du)_i - B_i a_i), a_i = D_i^+ (-G_i - C_i du_i). Newton's
iterates are the coupled method's to round-off (the same converged answer and iteration count),
while the linear algebra pays for the contact boundary only.

The pieces: the node blocks are read from the assembled coupling blocks of the Jacobian
(dF_u/dlambda, dG/du, dG/dlambda: matrices whose pattern holds the integrals over Gamma_C only)
by node_blocks, which refuses a contact row with an entry outside its node's own columns;
eliminate and recover are the formulas above, batched over nodes; replace_rows writes the
condensed rows into J and refuses a pattern without the node's own columns.
"""
from __future__ import annotations

import numpy as np
import ufl
from dolfinx import fem
from dolfinx.fem.petsc import assemble_vector, create_matrix
from mpi4py import MPI
from petsc4py import PETSc

from contactvisco.fem import compat

_INSERT, _ADD = PETSc.InsertMode.INSERT, PETSc.InsertMode.ADD
_FORWARD, _REVERSE = PETSc.ScatterMode.FORWARD, PETSc.ScatterMode.REVERSE

#: Singular values of D_i below this fraction of the node's natural scale w_i / r are zero.
RANK_TOLERANCE = 1e-10

#: The lifting of the Dirichlet rows is skipped when the iterate x is within this fraction of
#: |x|_inf of the prescribed values everywhere (NodalCondensation.lifting_needed).
LIFTING_TOLERANCE = 1e-14


def eliminate(B, C, D, F, G, scale, d_scale):
    """The node-wise elimination above, batched over nodes.

    B (n, d, m), C (n, m, d), D (n, m, m), F (n, d) = F_u,i, G (n, m), scale (n,) = s_i,
    d_scale (n,) = the size of a non-zero D_i. Returns a dict of arrays: F_red (n, d),
    L (n, d, d), P (n, d, d), what the recovery of dl needs (Dp, W) and per node the number
    of active conditions, nullity = m - rank D_i (the size of D_i's null space)."""
    n, d, m = B.shape
    U, singular, Vt = np.linalg.svd(D)
    rank = np.sum(singular > RANK_TOLERANCE * d_scale[:, None], axis=1)
    Dp = np.zeros((n, m, m))
    P = np.broadcast_to(np.eye(d), (n, d, d)).copy()
    K = np.zeros((n, d, m))            # Q U_0^T: the constraints written in the directions Q
    W = np.zeros((n, m, d))            # V_0 R^-1 Q^T: b from the rows of u_i
    for r in np.unique(rank):
        idx = np.flatnonzero(rank == r)
        Ur, Vr = U[idx][:, :, :r], np.transpose(Vt[idx][:, :r, :], (0, 2, 1))
        Dp[idx] = Vr @ (Ur.transpose(0, 2, 1) / singular[idx][:, :r, None])
        if r == m:
            continue
        if m - r > d:
            raise np.linalg.LinAlgError(
                f"{m - r} active conditions on {d} displacement components at a contact node "
                "(singular Newton matrix)")
        U0 = U[idx][:, :, r:]
        V0 = np.transpose(Vt[idx][:, r:, :], (0, 2, 1))
        Q, R = np.linalg.qr(B[idx] @ V0)
        size = np.abs(np.diagonal(R, axis1=1, axis2=2))
        if np.any(size <= 1e-12 * np.max(np.abs(B[idx]), axis=(1, 2))[:, None] + 1e-300):
            raise np.linalg.LinAlgError(
                "a contact node has a multiplier that acts on no free displacement component "
                "(singular Newton matrix); use solver.linear_system = 'coupled' to see where")
        P[idx] -= Q @ Q.transpose(0, 2, 1)
        # Write the constraints as s_i (Q^T du_i - ...) = 0: with A = U_0^T C_i Q (square),
        # the rows are s_i Q A^-1 U_0^T (C_i du_i + G_i), whose block on the directions Q is
        # s_i I. Any invertible A^-1 gives the same solution, but this one keeps the diagonal
        # positive, which multigrid smoothers need.
        A = U0.transpose(0, 2, 1) @ C[idx] @ Q
        K[idx] = Q @ np.linalg.solve(A, U0.transpose(0, 2, 1))
        W[idx] = V0 @ np.linalg.solve(R, Q.transpose(0, 2, 1))
    E = B @ Dp
    s = scale[:, None, None]
    L = -P @ E @ C + s * (K @ C)
    F_red = np.einsum("nij,nj->ni", P, F - np.einsum("nij,nj->ni", E, G)) \
        + scale[:, None] * np.einsum("nij,nj->ni", K, G)
    return {"F_red": F_red, "L": L, "P": P, "Dp": Dp, "W": W, "nullity": m - rank,
            "E": E, "K": K, "scale": scale}


def condense_rhs(parts, F, G):
    """The condensed right-hand side of node rows F (n, d) and multiplier rows G (n, m), with
    the node blocks of `parts` (eliminate): P_i (F_i - E_i G_i) + s_i Q_i U_0^T G_i, the rows
    that eliminate gives F_red for the residual (F, G). J_red y = (this, elsewhere the u rows)
    solves the coupled system J y + B l = F, C y + D l = G for y."""
    P, E, K, scale = parts["P"], parts["E"], parts["K"], parts["scale"]
    return np.einsum("nij,nj->ni", P, F - np.einsum("nij,nj->ni", E, G)) \
        + scale[:, None] * np.einsum("nij,nj->ni", K, G)


def recover(parts, B, C, F, G, du, Jdu):
    """dl_i = a_i + W_i (-F_u,i - (J du)_i - B_i a_i), a_i = D_i^+ (-G_i - C_i du_i)."""
    a = np.einsum("nij,nj->ni", parts["Dp"], -G - np.einsum("nij,nj->ni", C, du))
    return a + np.einsum("nij,nj->ni", parts["W"], -F - Jdu - np.einsum("nij,nj->ni", B, a))


def replace_rows(A, rows, P, L):
    """Rows of node i of the assembled matrix A (rows[i]: its d global row indices, owned)
    become P_i (A's rows) + L_i on the node's own d x d block, for every node where
    P_i != I or L_i != 0; A is assembled afterwards.

    The new rows keep A's column pattern, so L_i needs the node's own columns rows[i] in the
    pattern of each of its rows (the diagonal block of an assembled stiffness matrix has
    them). Raises ValueError naming the row if one is missing, rather than writing L_i into
    other columns. Collective. The node rows are read once here (NodeRows); a caller that
    replaces the rows of one pattern again and again keeps a NodeRows instead."""
    node_rows = NodeRows(rows)
    try:
        node_rows.replace(A, P, L)
    finally:
        node_rows.destroy()


class NodeRows:
    """The rows of the contact nodes of matrices with one sparsity pattern (rows (n, d): each
    node's d global row indices, owned): read as one submatrix with all columns (its CSR
    arrays at once), and each node's d rows laid out on the union of their column patterns.
    The index sets, the submatrix and the layout are made at the first read and reused while
    the pattern stays (a matrix assembled again into its own pattern keeps it).

    Parameters
    ----------
    rows : numpy.ndarray
        (n, d) global row indices of the n nodes' rows, owned by this rank.
    """

    def __init__(self, rows):
        self.rows = np.asarray(rows)
        self.selection = None      # (rows, all columns) index sets of row_selection
        self.part = None           # the submatrix of the rows, reused
        self.layout = None         # (indptr, indices) of part and the union layout of them

    def read(self, A):
        """The submatrix of A's node rows (row k: rows.ravel()[k], A's global columns), its
        values taken from A now; the object owns it. Collective."""
        if self.part is None:
            self.selection = row_selection(A, self.rows)
            self.part = A.createSubMatrix(*self.selection)
        else:
            A.createSubMatrix(*self.selection, submat=self.part)
        return self.part

    def _tables(self, indptr, indices):
        """The union layout of the node rows' CSR pattern (found once per pattern):
        node (u,) and column (u,) of each union entry, sorted by node and column, and for
        each CSR entry its union entry and the node row it belongs to (0..d-1)."""
        if self.layout is not None and np.array_equal(self.layout[0], indptr) and \
                np.array_equal(self.layout[1], indices):
            return self.layout[2]
        d = self.rows.shape[1]
        row = np.repeat(np.arange(len(indptr) - 1), np.diff(indptr))
        width = int(indices.max(initial=0)) + 1
        union, position = np.unique(row // d * np.int64(width) + indices, return_inverse=True)
        tables = (union // width, union % width, position, row % d)
        self.layout = (indptr.copy(), indices.copy(), tables)
        return tables

    def replace(self, A, P, L, current=None):
        """Rows of node i of A become P_i (its rows) + L_i on the node's own d x d block, for
        every node where P_i != I or L_i != 0; A is assembled afterwards (replace_rows).
        `current`: the submatrix of A's node rows as `read` gives it, if the caller has just
        read it (its values must be A's); read here otherwise. Collective."""
        n, d = self.rows.shape
        changed = np.flatnonzero(np.any(np.abs(P - np.eye(d)) > 0, axis=(1, 2))
                                 | np.any(L != 0, axis=(1, 2)))
        part = current if current is not None else self.read(A)    # collective: every rank
        if changed.size:
            indptr, indices, values = part.getValuesCSR()
            node, columns, position, component = self._tables(indptr, indices)
            table = np.zeros((node.size, d))
            table[position, component] = values
            index = np.full(n, -1)
            index[changed] = np.arange(changed.size)
            keep = index[node] >= 0
            node, columns, table = index[node[keep]], columns[keep], table[keep]
            rows = self.rows[changed]
            own = rows[node]                                  # (u, d): the node's own columns
            new = np.einsum("ukj,uj->uk", P[changed][node], table)
            where, which = np.nonzero(own == columns[:, None])   # entry `where` = own column
            present = np.zeros((changed.size, d), dtype=bool)
            present[node[where], which] = True
            if not np.all(present):
                i, c = np.argwhere(~present)[0]
                raise ValueError(
                    f"rows {rows[i].tolist()} of the condensed matrix lack the node's own "
                    f"columns {[int(rows[i, c])]} in their sparsity pattern; the condensed "
                    "rows need the d x d diagonal block of each contact node")
            new[where] += L[changed][node[where], :, which]
            # CSR of the new rows: node i's d rows, each on the node's union of columns.
            width = np.bincount(node, minlength=changed.size)
            first = np.concatenate([[0], np.cumsum(width)])
            row_width = np.repeat(width, d)
            row_ptr = np.concatenate([[0], np.cumsum(row_width)]).astype(PETSc.IntType)
            entry_node = np.repeat(np.arange(changed.size), d * width)
            entry_row = np.repeat(np.tile(np.arange(d), changed.size), row_width)
            offset = np.arange(entry_node.size) - row_ptr[:-1][np.repeat(
                np.arange(changed.size * d), row_width)]
            entry = first[entry_node] + offset
            A.setValuesIJV(row_ptr, columns[entry].astype(PETSc.IntType),
                           new[entry, entry_row],
                           rowmap=rows.ravel().astype(PETSc.IntType))
        A.assemble()

    def destroy(self):
        """Free the submatrix and the index sets (idempotent)."""
        for obj in (self.part, *(self.selection or ())):
            if obj is not None:
                obj.destroy()
        self.part, self.selection = None, None


def node_blocks(block, rows, columns, name="a contact block"):
    """The node blocks of an assembled matrix: out[i] = block[rows[i], columns[i]], (n, r, c).

    rows (n, r): global indices of the node's rows, owned by this rank; columns (n, c): global
    indices of the node's columns. The node-wise elimination holds only if each of these rows
    couples the node's own unknowns alone (the vertex rule on Gamma_C): a non-zero entry of
    rows[i] in a column outside columns[i] raises ValueError on every rank, naming the block
    (`name`), the row and the column, rather than being dropped. Entries stored in the pattern
    with the value zero (a facet integral's pattern holds the whole cell) are allowed.
    Collective. The rows are read once here (NodeBlocks); a caller that reads the blocks of
    one pattern again and again keeps a NodeBlocks instead."""
    reader = NodeBlocks(rows, columns, name)
    try:
        return reader.read(block)
    finally:
        reader.destroy()


class NodeBlocks:
    """node_blocks for the matrices of one sparsity pattern: the node rows are taken out as
    one submatrix with all columns (NodeRows), whose local CSR arrays are read at once, and
    which entry of them is which node's (row, column), or outside the node's columns, is
    found at the first read and reused while the pattern stays.

    Parameters
    ----------
    rows : numpy.ndarray
        (n, r) global indices of each node's rows, owned by this rank.
    columns : numpy.ndarray
        (n, c) global indices of each node's columns.
    name : str, optional
        The block's name in the error for a row outside the vertex rule.
    """

    def __init__(self, rows, columns, name="a contact block"):
        self.rows, self.columns, self.name = np.asarray(rows), np.asarray(columns), name
        self.node_rows = NodeRows(rows)
        self.layout = None   # (indptr, indices, row of each entry, found, its column, stray)

    def _layout(self, indptr, indices):
        if self.layout is not None and np.array_equal(self.layout[0], indptr) and \
                np.array_equal(self.layout[1], indices):
            return self.layout[2:]
        r = self.rows.shape[1]
        row = np.repeat(np.arange(len(indptr) - 1), np.diff(indptr))  # flat (node, its row)
        match = indices[:, None] == self.columns[row // r]
        found = match.any(axis=1)
        self.layout = (indptr.copy(), indices.copy(), row, found, match[found].argmax(axis=1),
                       np.flatnonzero(~found))
        return self.layout[2:]

    def read(self, block):
        """out[i] = block[rows[i], columns[i]] (n, r, c); ValueError on every rank for a
        non-zero entry of a node row outside its node's columns. Collective."""
        n, r = self.rows.shape
        indptr, indices, values = self.node_rows.read(block).getValuesCSR()
        row, found, column, outside = self._layout(indptr, indices)
        stray = outside[values[outside] != 0]
        message = None
        if stray.size:
            k = stray[0]
            message = (
                f"{self.name}: row {int(self.rows.ravel()[row[k]])} of a contact node holds "
                f"{values[k]:.3g} in column {int(indices[k])}, outside the node's own "
                f"columns {self.columns[row[k] // r].tolist()}; the node-wise elimination "
                "needs contact rows that couple each node's own unknowns only (the vertex "
                "rule: discretization.contact_quadrature = 'nodal', degree 1)")
        # Every rank raises, so that no rank waits in the next collective call.
        messages = [m for m in block.getComm().tompi4py().allgather(message) if m]
        if messages:
            raise ValueError(messages[0])
        out = np.zeros((n * r, self.columns.shape[1]))
        out[row[found], column] = values[found]
        return out.reshape(n, r, self.columns.shape[1])

    def destroy(self):
        """Free the submatrix and the index sets (idempotent)."""
        self.node_rows.destroy()


def row_selection(A, rows):
    """Index sets that take the rows `rows` (owned, global indices) of A with all columns
    out of A as a submatrix (A.createSubMatrix(*row_selection(A, rows))), whose local row k
    is rows.ravel()[k] and whose columns keep A's global numbering."""
    comm = A.getComm()
    wanted = PETSc.IS().createGeneral(np.asarray(rows, dtype=PETSc.IntType).ravel(), comm=comm)
    first, last = A.getOwnershipRangeColumn()
    return wanted, PETSc.IS().createStride(last - first, first=first, step=1, comm=comm)


def node_indices(space, nodes):
    """Global indices (n, bs) of the components of the local nodes `nodes` of a P1 space."""
    bs = space.dofmap.index_map_bs
    start = space.dofmap.index_map.local_range[0]
    return ((start + nodes[:, None]) * bs + np.arange(bs)).astype(PETSc.IntType)


#: The kept cell part of J_uu (BulkPart) serves while the values of its Constants agree with
#: those it was assembled with to this relative tolerance: the steps t_n - t_(n-1) of a
#: uniform grid differ in their last bits (k = 0.1 takes 4 values in 10 steps), which changed
#: the memory's weight and made every such step a new bulk operator, with a new factorization
#: or AMG hierarchy. A Jacobian off by 1e-12 relative changes neither Newton's steps beyond
#: round-off nor its stopping test, which is on the exact residual. 0: exact equality.
CONSTANTS_RTOL = 1e-12


class BulkPart:
    """J_uu = J_cell + J_facet: the cell integrals (the bulk law A, the implicit memory term)
    assembled once and kept while the Constants they use keep their values, the facet
    integrals (Gamma_C, a few rows) assembled at every Jacobian and added to a copy of the
    kept matrix. Only where the cell integrals use no Function (a linear bulk law with
    Constant coefficients, the paper's): otherwise `split` is False and J_uu is assembled
    whole.

    Parameters
    ----------
    J_uu : ufl.Form
        dF_u/du.
    A : petsc4py.PETSc.Mat
        J_uu assembled: the kept matrix is a duplicate of it, with its sparsity pattern.
    """

    def __init__(self, J_uu, A):
        cells, facets = integrals_by_domain(J_uu)
        cell_form = ufl.Form(cells)
        self.split = bool(cells and facets) and not cell_form.coefficients()
        if not self.split:
            return
        self.cell, self.facet = fem.form(cell_form), fem.form(ufl.Form(facets))
        self.constants = cell_form.constants()
        self.values = None               # the Constants' values of the kept matrix
        self.assemblies = 0              # of the kept matrix: a new bulk operator each
        self.matrix = A.duplicate()
        # The owned rows the facet integrals reach (global indices): the only rows of J_uu
        # that differ between two iterates while the kept matrix stays. (An assembly puts
        # its entries, zeros too, in the pattern; create_matrix alone leaves it empty.)
        pattern = create_matrix(self.facet)
        compat.assemble_matrix(pattern, self.facet, [], diagonal=0.0)
        pattern.assemble()
        indptr = pattern.getValuesCSR()[0]
        pattern.destroy()
        first = A.getOwnershipRange()[0]
        self.rows = (first + np.flatnonzero(np.diff(indptr) > 0)).astype(PETSc.IntType)

    def assemble_into(self, A, bcs):
        """A = J_uu: the kept cell part (assembled again if a Constant changed by more than
        CONSTANTS_RTOL) plus the facet part; Dirichlet rows and columns zero with 1 on the
        diagonal."""
        values = [np.array(c.value, copy=True) for c in self.constants]
        if self.values is None or any(not np.allclose(a, b, rtol=CONSTANTS_RTOL, atol=0.0)
                                      for a, b in zip(values, self.values)):
            self.matrix.zeroEntries()
            # The diagonal of Dirichlet rows is 0 here and 1 from the facet part: 1 whether
            # DOLFINx inserts or adds it.
            compat.assemble_matrix(self.matrix, self.cell, bcs, diagonal=0.0)
            self.matrix.assemble()
            self.values = values
            self.assemblies += 1
        self.matrix.copy(A, structure=PETSc.Mat.Structure.SAME_NONZERO_PATTERN)
        compat.assemble_matrix(A, self.facet, bcs, diagonal=1.0)
        A.assemble()

    def destroy(self):
        compat.destroy_petsc_objects(self)


def coupling_blocks(J):
    """The blocks of the block Jacobian J (J[i][j] = dF_i/dw_j, w = (u, multipliers...))
    that the node blocks come from: every (i, j) but (0, 0) with a form, as
    {(i, j): (form, matrix)}; each matrix's pattern holds the integrals over Gamma_C only."""
    blocks = {}
    for i, row in enumerate(J):
        for j, a in enumerate(row):
            if (i, j) != (0, 0) and a is not None:
                form = fem.form(a)
                blocks[(i, j)] = (form, create_matrix(form))
    return blocks


def integrals_by_domain(F):
    """The integrals of the UFL form F: (those over cells, the others: Gamma_C)."""
    cells = [i for i in F.integrals() if i.integral_type() == "cell"]
    return cells, [i for i in F.integrals() if i.integral_type() != "cell"]


def forms_by_domain(F):
    """The form F as compiled forms whose sum is F: its cell integrals in one, its other
    integrals (Gamma_C) in another. An assembly packs every coefficient of its form for every
    cell or facet it visits; apart, the cells carry only the bulk's coefficients (u, the
    memory), not the contact fields (the multipliers, the normal)."""
    return [fem.form(ufl.Form(part)) for part in integrals_by_domain(F) if part]


def diagonal_scale(A, nodes, d):
    """s_i: the mean |diagonal| of A on the d rows of each local node in `nodes`; where it
    is zero, the mean over all nodes of all ranks (or 1). Collective."""
    scale = np.abs(A.getDiagonal().array.reshape(-1, d)).mean(axis=1)
    comm = A.getComm().tompi4py()
    typical = comm.allreduce(float(scale.mean()) if scale.size else 0.0, MPI.SUM) / comm.size
    return np.where(scale[nodes] > 0, scale[nodes], typical or 1.0)


class NodalCondensation:
    """Assembles the residual and Jacobian of the displacement-only Newton system of a
    Problem whose contact conditions hold node by node (degree 1, nodal contact quadrature)."""

    def __init__(self, problem):
        self.problem = problem
        self.V = V = problem.V
        self.d = d = V.dofmap.index_map_bs
        self.fields = list(problem.multipliers.values())
        self.bs = [f.function_space.dofmap.index_map_bs for f in self.fields]
        self.offsets = np.concatenate([[0], np.cumsum(self.bs)]).astype(int)
        self.m = int(self.offsets[-1])
        nodes = problem.contact.nodes
        self.own = nodes.nodes[nodes.owned]
        if V.dofmap.index_map.size_local != \
                self.fields[0].function_space.dofmap.index_map.size_local:
            raise RuntimeError("displacement and multiplier node ownership differ")
        self.bcs = problem.bcs_u
        self.F_u = forms_by_domain(problem.F[0])
        self.J_uu = fem.form(problem.J[0][0])
        self.G = [fem.form(problem.F[1 + a]) for a in range(len(self.fields))]
        self.G_vecs = [compat.form_vector(f) for f in self.G]
        # The blocks coupling u_i and lambda_i, read node by node (NodeBlocks); per unknown
        # (u, then each multiplier) the global indices of the owned contact nodes' components.
        self.couplings = coupling_blocks(problem.J)
        self.indices = [node_indices(space, self.own)
                        for space in [V] + [f.function_space for f in self.fields]]
        self.rows = self.indices[0]
        names = [problem.u.name] + [f.name for f in self.fields]
        self.readers = {(i, j): NodeBlocks(
            self.indices[i], self.indices[j],
            f"the Jacobian block (rows of {names[i]}, columns of {names[j]})")
            for i, j in self.couplings}

        self.free = np.concatenate([mask[self.own] for mask in problem.multiplier_free], axis=1)
        self.fixed_u = problem.u_fixed[self.own] > 0
        self.d_scale = nodes.weights[nodes.owned] / problem.constants["r"].value

        # One matrix of u's size: J is assembled into it and its contact rows are then
        # overwritten by the condensed ones (J_red); the original contact rows are kept in the
        # small matrix self.J_contact for the multiplier update.
        self.A = create_matrix(self.J_uu)
        self._bulk = None
        self._assemble_J()
        self._bulk = BulkPart(problem.J[0][0], self.A)
        self.scale = diagonal_scale(self.A, self.own, d)
        self.contact_rows = NodeRows(self.rows)
        self.J_contact = self.contact_rows.read(self.A)
        self._Jdu = self.J_contact.createVecLeft()
        self.J_red = self.A
        self.parts = None
        self.full_norm = 0.0
        #: Leave the node blocks and F_red of a residual to the next Jacobian
        #: (condense_residual); the residual's vector must then stay the one the linear
        #: solve reads, as SNES's function vector does.
        self.defer = False
        self._uncondensed = None
        self._gap = None

    #: The attributes whose PETSc objects belong to the problem, not to this system.
    BORROWED: tuple = ()

    def destroy(self):
        """Free the PETSc objects of the system (collective; idempotent)."""
        if self._bulk is not None:
            self._bulk.destroy()
        for reader in [*self.readers.values(), self.contact_rows]:
            reader.destroy()
        compat.destroy_petsc_objects(self, self.BORROWED)

    def _assemble_J(self):
        if self._bulk is not None and self._bulk.split:
            self._bulk.assemble_into(self.A, self.bcs)
            return
        self.A.zeroEntries()
        compat.assemble_matrix(self.A, self.J_uu, self.bcs, diagonal=1.0)
        self.A.assemble()

    def bulk_stamp(self):
        """A value that changes with the bulk operator (the cell integrals of J_uu): the
        count of its assemblies, or None where it depends on the iterate (not split off,
        BulkPart) and every Jacobian assembles it anew."""
        return self._bulk.assemblies if self._bulk is not None and self._bulk.split else None

    def varying_rows(self):
        """The owned rows (global indices, sorted) in which two Newton matrices J_red of the
        same bulk operator (equal bulk_stamp) can differ, the contact nodes' rows, which the
        condensation replaces, and the rows the facet integrals of J_uu reach, as the index
        sets that take them out of J_red with all columns (row_selection; the caller
        destroys them); None where the bulk operator is assembled with every Jacobian (no
        stamp)."""
        if self._bulk is None or not self._bulk.split:
            return None
        return row_selection(self.A, np.union1d(self.rows.ravel(), self._bulk.rows))

    def _node_values(self, vec, bs):
        vec.ghostUpdate(addv=_ADD, mode=_REVERSE)
        return vec.array.reshape(-1, bs)[self.own]

    def _assemble_vector(self, vec, form):
        with vec.localForm() as local:
            local.set(0.0)
        assemble_vector(vec, form)

    def local_blocks(self):
        """The node blocks at the current iterate (the Functions of the Problem):
        B (n, d, m) = dF_u,i/dlambda_i, C (n, m, d) = dG_i/du_i, D (n, m, m) = dG_i/dlambda_i
        at the n owned contact nodes, m multiplier components per node (lambda_nu first),
        read from the assembled coupling blocks of J (node_blocks, which checks that no row
        couples other unknowns). Rows and columns of prescribed components are decoupled:
        B, C zero there and D the identity (dl = 0)."""
        n, d = len(self.own), self.d
        start = np.concatenate([[0], d + self.offsets]).astype(int)    # of u, lambda_a
        K = np.zeros((n, d + self.m, d + self.m))      # [[., B], [C, D]] of each node
        for (i, j), (form, matrix) in self.couplings.items():
            matrix.zeroEntries()
            compat.assemble_matrix(matrix, form, [], diagonal=1.0)
            matrix.assemble()
            K[:, start[i]:start[i + 1], start[j]:start[j + 1]] = self.readers[i, j].read(matrix)
        B, C, D = K[:, :d, d:].copy(), K[:, d:, :d].copy(), K[:, d:, d:].copy()
        # Dirichlet rows of u carry no multiplier; fixed multipliers are decoupled (dl = 0).
        B[self.fixed_u] = 0.0
        B *= self.free[:, None, :]
        C *= self.free[:, :, None]
        D *= self.free[:, :, None] * self.free[:, None, :]
        idx_node, idx_comp = np.nonzero(~self.free)
        D[idx_node, idx_comp, idx_comp] = 1.0
        return B, C, D

    def residual(self, x, b):
        """The condensed residual at x (u's vector, ghosts updated) into b; also stores the
        node blocks for the Jacobian and the full residual norm of the coupled problem."""
        self.assemble_u_residual(x, b)
        self.condense_residual(b)

    def assemble_u_residual(self, x, b):
        """b = F_u(x) with the Dirichlet rows set to x - g: the lifting b += J_uu (g - x)
        applied only where x differs from g on a prescribed component (lifting_needed)."""
        with b.localForm() as local:
            local.set(0.0)
        for form in self.F_u:
            assemble_vector(b, form)
        if self.lifting_needed(x):
            compat.apply_lifting(b, [self.J_uu], bcs=[self.bcs], x0=[x], scale=-1.0)
        b.ghostUpdate(addv=_ADD, mode=_REVERSE)
        compat.set_bc(b, self.bcs, x, -1.0)

    def lifting_needed(self, x) -> bool:
        """Whether x misses the prescribed values g somewhere: max |g - x| over the
        Dirichlet components of all ranks above LIFTING_TOLERANCE |x|_inf. Below it the
        lifting J_uu (g - x) changes the residual by less than that fraction of J_uu x
        (round-off of the Newton update x - (x - g)), and is skipped: after the first Newton
        iteration of a step the iterate holds g. Collective."""
        if not self.bcs:
            return False
        if self._gap is None:
            self._gap = x.duplicate()
        gap = self._gap
        gap.set(0.0)
        compat.set_bc(gap, self.bcs, x, 1.0)
        return gap.norm(PETSc.NormType.INFINITY) > LIFTING_TOLERANCE * x.norm(
            PETSc.NormType.INFINITY)

    def condense_residual(self, b):
        """Eliminate the multipliers' residual G node by node from the u residual b (in
        place): the owned contact rows of b become F_red; the blocks are kept for the
        Jacobian, and the coupled residual's norm in `full_norm`. With `defer` set, only G
        and the norm are computed here: the node blocks and F_red wait for the Jacobian at
        the same iterate (finish_condensation), so that the last residual of a solve, which
        only tells Newton that it has converged, assembles no coupling block."""
        G = np.zeros((len(self.own), self.m))
        for a, (form, vec) in enumerate(zip(self.G, self.G_vecs)):
            self._assemble_vector(vec, form)
            G[:, self.offsets[a]:self.offsets[a + 1]] = self._node_values(vec, self.bs[a])
        G *= self.free
        comm = self.V.mesh.comm
        self.full_norm = float(np.sqrt(b.norm() ** 2 + comm.allreduce(float(np.sum(G * G)),
                                                                       MPI.SUM)))
        self._uncondensed = (b, G)
        if not self.defer:
            self.finish_condensation()

    def finish_condensation(self):
        """The node blocks at the iterate of the last residual and its owned contact rows
        replaced by F_red (condense_residual); nothing if that is done already."""
        if self._uncondensed is None:
            return
        b, G = self._uncondensed
        self._uncondensed = None
        B, C, D = self.local_blocks()
        array = b.array.reshape(-1, self.d)
        F = array[self.own].copy()
        parts = eliminate(B, C, D, F, G, self.scale, self.d_scale)
        array[self.own] = parts["F_red"]
        self.parts = dict(parts, B=B, C=C, D=D, F=F, G=G)

    def jacobian(self):
        """J_red = S J + L, in place: J is assembled, its contact rows saved, and the rows of
        every node where P_i != I or L_i != 0 replaced by P_i (J rows) + L_i; a deferred
        condensation of the last residual is done first (its vector then holds F_red)."""
        self.finish_condensation()
        self._assemble_J()
        self.contact_rows.read(self.A)                   # into J_contact
        self.contact_rows.replace(self.A, self.parts["P"], self.parts["L"],
                                  current=self.J_contact)

    def update_multipliers(self, du):
        """Add the node-wise dl for the displacement step du (a PETSc vector); returns dl
        (n, m) at the owned contact nodes."""
        Jdu = self._Jdu
        self.J_contact.mult(du, Jdu)
        p = self.parts
        dl = recover(p, p["B"], p["C"], p["F"], p["G"],
                     du.array.reshape(-1, self.d)[self.own],
                     Jdu.array.reshape(-1, self.d))
        self.add_to_multipliers(dl)
        return dl

    def add_to_multipliers(self, dl):
        """Add dl (n, m) at the owned contact nodes to the multiplier fields (ghosts
        updated)."""
        for a, f in enumerate(self.fields):
            f.x.array.reshape(-1, self.bs[a])[self.own] += dl[:, self.offsets[a]:self.offsets[a + 1]]
            compat.petsc_vector(f).ghostUpdate(addv=_INSERT, mode=_FORWARD)
