"""Newton on the displacement for two deformable bodies in contact (contactvisco.fem.body_contact):
the slave's contact forces c act on u_rel = T u, T = I - P, P = Pi (x) I_d, and the master
receives -Pi^T c:

    F = F_el + T^T c(T u),        J = J_el + T^T K_c T,        K_c = dc/du_rel.

The problem's forms give F_el + c and J_el + K_c at D = P u held fixed (the slave rows as for a
rigid obstacle at the displacement D); the master's share is added with PETSc's sparse
products: F - P^T c, and J + (T^T K_c T - K_c) (MatPtAP), whose rows and columns of
prescribed components are zeroed so that those rows stay the identity's. The matrix has the
pattern of J_el and of T^T K_c T (the slave-master couplings through Pi): it is found at the
first assembly and kept.
"""
from __future__ import annotations

import dataclasses

import numpy as np
from dolfinx import fem
from dolfinx.fem.petsc import assemble_vector, create_matrix
from petsc4py import PETSc

from contactvisco.fem import compat, interface
from contactvisco.solver.condensed import NodalCondensation
from contactvisco.solver.newton_base import NewtonSolver, _weak, near_nullspace

_INSERT, _ADD = PETSc.InsertMode.INSERT, PETSc.InsertMode.ADD
_FORWARD, _REVERSE = PETSc.ScatterMode.FORWARD, PETSc.ScatterMode.REVERSE
_DIFFERENT = PETSc.Mat.Structure.DIFFERENT_NONZERO_PATTERN
_SAME = PETSc.Mat.Structure.SAME_NONZERO_PATTERN


def transfer(P: PETSc.Mat) -> PETSc.Mat:
    """T = I - P for a square P.

    Parameters
    ----------
    P : petsc4py.PETSc.Mat
        Pi (x) I_d on the dofs of u (slave rows, master columns).

    Returns
    -------
    petsc4py.PETSc.Mat
        T, with (T u)_i = u_i - sum_k Pi_ik u_k at the slave dofs and u elsewhere.
    """
    start, end = P.getOwnershipRange()
    n = end - start
    identity = PETSc.Mat().createAIJ(
        (P.getSizes()[0], P.getSizes()[1]),
        csr=(np.arange(n + 1, dtype=PETSc.IntType),
             np.arange(start, end, dtype=PETSc.IntType), np.ones(n)), comm=P.getComm())
    identity.assemble()
    identity.axpy(-1.0, P, _DIFFERENT)
    return identity


class InterfaceSNES(NewtonSolver):
    """SNES over u alone for a problem whose contact boundary meets another body of the mesh
    (module description).

    Parameters
    ----------
    problem : contactvisco.fem.problem.Problem
        The problem; ``problem.contact.obstacle`` is a fem.body_contact.BodyContact.
    comm : mpi4py.MPI.Comm
        The communicator.
    scene_options, defaults : dict, optional
        PETSc options (NewtonSolver).
    reuse : bool, optional
        Keep the factorization of an unchanged matrix.
    """

    system_kind = "displacement"

    def __init__(self, problem, comm, scene_options=None, defaults=None, reuse=False):
        super().__init__(comm, [problem.u], scene_options, defaults, reuse)
        self.problem = problem
        self.link = problem.contact.obstacle
        u = problem.u
        self.F = fem.form(problem.F[0])
        self.J_form = fem.form(problem.J[0][0])
        contact = self.link.contact_form
        self.F_c = fem.form(contact)
        self.J_c = fem.form(ufl_derivative(contact, u))
        self.bcs = problem.bcs_u
        self.A_fe = create_matrix(self.J_form)
        self.K_c = create_matrix(self.J_c)
        self.c = compat.form_vector(self.F_c)
        u_vector = compat.petsc_vector(u)
        self.b, self.x, self.share = u_vector.copy(), u_vector.copy(), u_vector.copy()
        self._moved = u_vector.copy()
        d = problem.V.dofmap.index_map_bs
        owned = problem.V.dofmap.index_map.size_local * d
        fixed = np.flatnonzero(problem.u_fixed.reshape(-1)[:owned] > 0)
        self.fixed_local = fixed
        self.fixed_global = (fixed + self.b.getOwnershipRange()[0]).astype(PETSc.IntType)
        self.T = transfer(self.link.P)
        self.A = None
        self._assemble_jacobian()
        self.operator = self.A.duplicate(copy=True) if reuse else self.A
        self.snes.setFunction(_weak(self._residual), self.b)
        self.snes.setJacobian(_weak(self._jacobian), self.operator)
        self.operator.setNearNullSpace(near_nullspace(problem))
        self._finish_setup()

    def destroy(self):
        for name in ("A_fe", "K_c", "c", "share", "T", "_moved"):
            obj = self.__dict__.get(name)
            if obj is not None:
                obj.destroy()
        super().destroy()

    def _residual(self, snes, x, b):
        """F = (F_el + c) - P^T c at x, with D = P u; rows of prescribed components x - g."""
        x.ghostUpdate(addv=_INSERT, mode=_FORWARD)
        self._to_functions(x)
        self.link.follow(self.problem.u)
        with b.localForm() as local:
            local.set(0.0)
        assemble_vector(b, self.F)
        compat.apply_lifting(b, [self.J_form], bcs=[self.bcs], x0=[x], scale=-1.0)
        b.ghostUpdate(addv=_ADD, mode=_REVERSE)
        compat.set_bc(b, self.bcs, x, -1.0)
        b.axpy(-1.0, self.master_share())
        self._lift_correction(b)

    def _lift_correction(self, b):
        """b += C (g - x) on the free rows, C = T^T K_c T - K_c the master's share of the
        Jacobian (the lifting of its columns of prescribed components, which the Jacobian
        zeroes): with x off its prescribed values g (a held slave node moved to a new value),
        the first Newton step is then the exact linear one, as the forms' own lifting makes
        it for J_el + K_c. Nothing is done while x holds its prescribed values."""
        moved = self._moved
        moved.set(0.0)
        moved.array[self.fixed_local] = -b.array[self.fixed_local]     # g - x
        if moved.norm(PETSc.NormType.NORM_INFINITY) == 0.0:
            return
        self.K_c.zeroEntries()
        compat.assemble_matrix(self.K_c, self.J_c, [], diagonal=0.0)
        self.K_c.assemble()
        relative, force = self.K_c.createVecs()
        self.T.mult(moved, relative)                  # T v
        self.K_c.mult(relative, force)                # K_c T v
        self.T.multTranspose(force, self.share)       # T^T K_c T v
        self.K_c.mult(moved, force)
        self.share.axpy(-1.0, force)                  # - K_c v
        self.share.array[self.fixed_local] = 0.0
        b.axpy(1.0, self.share)
        for vec in (relative, force):
            vec.destroy()

    def master_share(self) -> PETSc.Vec:
        """P^T c at the current D: the slave's contact forces carried to the master's dofs
        (zero on prescribed components); -P^T c is what the master receives.

        Returns
        -------
        petsc4py.PETSc.Vec
            P^T c (a vector of u's layout, owned by this solver).
        """
        with self.c.localForm() as local:
            local.set(0.0)
        assemble_vector(self.c, self.F_c)
        self.c.ghostUpdate(addv=_ADD, mode=_REVERSE)
        self.link.P.multTranspose(self.c, self.share)
        self.share.array[self.fixed_local] = 0.0
        return self.share

    def contact_forces(self) -> PETSc.Vec:
        """c, the slave's nodal contact forces at the last residual (u's layout).

        Returns
        -------
        petsc4py.PETSc.Vec
            The assembled contact terms of F_u (non-zero at the slave dofs only).
        """
        return self.c

    def _assemble_jacobian(self):
        """J = (J_el + K_c) + (T^T K_c T - K_c), prescribed rows and columns kept the
        identity's."""
        self.link.follow(self.problem.u)
        self.A_fe.zeroEntries()
        compat.assemble_matrix(self.A_fe, self.J_form, self.bcs, diagonal=1.0)
        self.A_fe.assemble()
        self.K_c.zeroEntries()
        compat.assemble_matrix(self.K_c, self.J_c, [], diagonal=0.0)
        self.K_c.assemble()
        correction = self.K_c.PtAP(self.T)
        correction.axpy(-1.0, self.K_c, _DIFFERENT)
        correction.zeroRowsColumns(self.fixed_global, diag=0.0)
        total = self.A_fe.duplicate(copy=True)
        total.axpy(1.0, correction, _DIFFERENT)
        correction.destroy()
        if self.A is None:
            self.A = total
            return
        total.copy(self.A, structure=_SAME)
        total.destroy()

    def _jacobian(self, snes, x, A, P):
        self._assemble_jacobian()
        self._to_operator(self.A)


def ufl_derivative(form, u):
    """dF/du of a linear form F in the direction of u's trial function (UFL)."""
    import ufl
    return ufl.algorithms.expand_derivatives(
        ufl.derivative(form, u, ufl.TrialFunction(u.function_space)))


#: Entries of Pi below this couple no master component (InterfaceCondensation: a multiplier
#: whose slave components and coupled master components are all prescribed is left out).
COUPLING = 1e-12


class InterfaceCondensation(NodalCondensation):
    """The condensed Newton system (contactvisco.solver.condensed) of two bodies in contact
    whose law has nodal multipliers (a bound g, friction).

    In the unknowns w = S^-1 u, S = I + P (w_i = u_i - (Pi u)_i at the slave dofs, w = u
    elsewhere), the contact terms act on the slave rows and columns alone, as for a rigid
    obstacle:

        R_w = S^T F' + c,          J_w = S^T J' S + K_c,

    so the node-wise elimination of the multipliers applies to the slave rows of J_w
    unchanged. The system handed to Newton is that one written back in u,

        F = S^-T R_w,red,          J = S^-T J_w,red S^-1 = T^T J_w,red T,   T = S^-1 = I - P,

    (P P = 0: slave and master dofs differ); the multipliers are recovered from dw = T du.

    Prescribed components. The residual and matrices are evaluated with u = g on every
    prescribed component, and the rows of prescribed components away from the contact nodes
    are x - g, their columns zero, as usual. A prescribed component u_ih of a slave contact
    node keeps its coupling: its contact force acts on w_i = u_i - (Pi u)_i whatever holds
    u_i, the master receives -Pi^T c, and the slave's share goes to the support. The
    support's force is then an unknown of its own, z_ih = x_ih - g_ih (SNES's value in the
    slot of u_ih, which stays g_ih in the Functions): F'_ih = z_ih in place of the elastic
    row, so that R_w,ih = z_ih + c_ih, and the column of the slot in J is dF/dz,

        (P_i e_h at the rows of node i,   Pi_ik (I - P_i) e_h at the rows of master node k),

    P_i the node's projection of the elimination (the identity where no condition of the
    node is active). Where the node's condition is active in a held direction, this is the
    master's constraint (the held node pins the master's surface) with its reaction. A
    multiplier is left out (held at zero) only where both sides are held: the slave
    components it acts on and every master component of the row of Pi.

    Parameters
    ----------
    problem : contactvisco.fem.problem.Problem
        The problem; ``problem.contact.obstacle`` is a fem.body_contact.BodyContact.
    """

    #: Pi (x) I_d belongs to the interface of the problem, _u is u's own vector.
    BORROWED = ("P", "_u")

    def __init__(self, problem):
        self.link = problem.contact.obstacle
        V = problem.V
        d = V.dofmap.index_map_bs
        owned = V.dofmap.index_map.size_local * d
        fixed = np.flatnonzero(problem.u_fixed.reshape(-1)[:owned] > 0)
        start = V.dofmap.index_map.local_range[0] * d
        self.fixed_local = fixed
        self.fixed_global = (fixed + start).astype(PETSc.IntType)
        nodes = problem.contact.nodes
        own = nodes.nodes[nodes.owned]
        at_node = np.zeros(owned // d, dtype=bool)
        at_node[own] = True
        held = at_node[fixed // d]
        self.z_local = fixed[held]                       # held slave contact components
        self.z_global = self.fixed_global[held]
        self.plain_local = fixed[~held]                  # every other prescribed component
        self.plain_global = self.fixed_global[~held]
        self.P = self.link.P
        self.T = transfer(self.P)
        S = self.T.duplicate(copy=True)
        S.scale(-1.0)
        S.shift(2.0)                                     # S = 2 I - T = I + P
        self.S = S
        contact = self.link.contact_form
        self.F_c = None if contact is None else fem.form(contact)
        self.J_c = None if contact is None else fem.form(ufl_derivative(contact, problem.u))
        self.K_c = None if self.J_c is None else create_matrix(self.J_c)
        self._patterned = False
        self._u = compat.petsc_vector(problem.u)
        super().__init__(problem)
        self.fixed_u = np.zeros_like(self.fixed_u)       # held slave rows carry z and lambda
        self.free = self._free_multipliers(problem)
        self.c = self._u.copy()
        self._el, self._share = self.c.copy(), self.c.copy()
        self._dw, self._x = self.c.copy(), self.c.copy()
        self._columns_kept = self.c.copy()
        with self._columns_kept.localForm() as local:
            local.set(1.0)
        self._columns_kept.array[self.z_local] = 0.0
        self.J_red = self.A.PtAP(self.T)
        self.J_red.setOption(PETSc.Mat.Option.KEEP_NONZERO_PATTERN, True)
        self._write_back()

    def _free_multipliers(self, problem):
        """The multiplier components kept: all but those whose slave components (u_nu: the
        components nu involves; u_tau: its own) and every master component they couple to
        through Pi are prescribed."""
        d = self.d
        marks = self._u.copy()
        marks.set(1.0)
        marks.array[self.fixed_local] = 0.0
        pairing = self.link.pairing
        sizes = interface.index_sizes(self.V)
        # an entry of Pi below COUPLING is round-off of an exact zero (a mortar row at a
        # corner: the dual basis is orthogonal to the master's function that vanishes there)
        weights = np.where(np.abs(pairing.values) > COUPLING, np.abs(pairing.values), 0.0)
        spread = dataclasses.replace(pairing, values=weights).matrix(
            self.V.mesh.comm, sizes, sizes, d)
        reached = marks.copy()
        spread.mult(marks, reached)                      # > 0: a free master component
        spread.destroy()
        master_free = reached.array.reshape(-1, d)[self.own] > 0
        slave_free = self.problem.u_fixed[self.own] == 0
        loose = master_free | slave_free                 # (n, d): one side at least is free
        marks.destroy()
        reached.destroy()
        involved = np.abs(self.problem.contact.nodes.normals[
            self.problem.contact.nodes.owned]) > 1e-8
        masks = []
        for a, field in enumerate(self.fields):
            if self.bs[a] == 1:                          # lambda_nu
                masks.append(np.any(involved & loose, axis=1)[:, None])
            else:                                        # lambda_tau, per component
                masks.append(loose)
        return np.concatenate(masks, axis=1)

    def _evaluation_point(self):
        """u = g on every prescribed component (ghosts updated) and D = P u."""
        compat.set_bc(self._u, self.bcs, None, 1.0)
        self._u.ghostUpdate(addv=_INSERT, mode=_FORWARD)
        self.link.follow(self.problem.u)

    def _assemble_J(self):
        """A = J_w = S^T (J_full - K_c0) S + K_c: J_full the assembled J_el + K_c at D = P u
        with Dirichlet rows and columns (and zero rows at the held slave components, whose
        row is z), K_c0 the contact part it holds (no prescribed row or column)."""
        self._evaluation_point()
        full = create_matrix(self.J_uu) if not self._patterned else self._full
        full.zeroEntries()
        compat.assemble_matrix(full, self.J_uu, self.bcs, diagonal=1.0)
        full.assemble()
        diagonal = full.getDiagonal()                    # collective: on every rank
        diagonal.array[self.z_local] = 0.0
        full.setDiagonal(diagonal)
        diagonal.destroy()
        total = full.PtAP(self.S)
        if self.K_c is not None:
            self.K_c.zeroEntries()
            compat.assemble_matrix(self.K_c, self.J_c, [], diagonal=0.0)
            self.K_c.assemble()
            inside = self.K_c.duplicate(copy=True)
            # as J_full's: no entry in the rows and columns of prescribed components (the
            # pattern of K_c, from Gamma_C alone, has no diagonal for a Dirichlet row)
            inside.zeroRowsColumns(self.fixed_global, diag=0.0)
            moved = inside.PtAP(self.S)
            total.axpy(-1.0, moved, _DIFFERENT)
            total.axpy(1.0, self.K_c, _DIFFERENT)
            moved.destroy()
            inside.destroy()
        if not self._patterned:
            self.A.destroy()
            self.A, self._full, self._patterned = total, full, True
            return
        total.copy(self.A, structure=_SAME)
        total.destroy()

    def residual(self, x, b):
        """F = S^-T R_w,red at x (class description); the coupled residual's norm in w."""
        self._evaluation_point()
        self._u.copy(self._x)                            # x with u = g where prescribed
        self._x.ghostUpdate(addv=_INSERT, mode=_FORWARD)  # (the lifting reads the ghosts)
        self.assemble_u_residual(self._x, b)
        with self.c.localForm() as local:
            local.set(0.0)
        if self.F_c is not None:
            assemble_vector(self.c, self.F_c)
            self.c.ghostUpdate(addv=_ADD, mode=_REVERSE)
        b.copy(self._el)
        self._el.axpy(-1.0, self.c)                      # F_el
        self._el.array[self.plain_local] = 0.0
        given = x.getArray(readonly=True)
        self._el.array[self.z_local] = given[self.z_local] - self._x.array[self.z_local]
        self.P.multTranspose(self._el, self._share)
        self._el.axpy(1.0, self._share)
        self._el.axpy(1.0, self.c)
        self._el.copy(b)                                 # R_w = S^T F' + c
        b.array[self.plain_local] = given[self.plain_local] - self._x.array[self.plain_local]
        self.condense_residual(b)
        self.P.multTranspose(b, self._share)
        b.axpy(-1.0, self._share)                        # S^-T R_w,red
        b.array[self.plain_local] = given[self.plain_local] - self._x.array[self.plain_local]

    def jacobian(self):
        """J = T^T J_w,red T: J_w assembled, its slave rows saved and condensed, written
        back in u; then the columns of z and the Dirichlet rows and columns."""
        super().jacobian()
        self.A.PtAP(self.T, result=self.J_red)
        self._write_back()

    def _write_back(self):
        """In J_red: the columns of the held slave components become dF/dz (class
        description), the other prescribed rows and columns the identity's."""
        J, d = self.J_red, self.d
        J.diagonalScale(None, self._columns_kept)
        if self.parts is None:                           # the pattern's first assembly
            diagonal = J.getDiagonal()
            diagonal.array[self.z_local] = 1.0
            J.setDiagonal(diagonal, addv=_INSERT)
            diagonal.destroy()
        elif self.z_local.size:
            node_of = {int(n): j for j, n in enumerate(self.own)}
            projection = self.parts["P"]
            first = self.V.dofmap.index_map.local_range[0]
            pairing = self.link.pairing
            for dof in self.z_local:
                node, h = divmod(int(dof), d)
                j = node_of[node]
                column = int(self.z_global[np.flatnonzero(self.z_local == dof)[0]])
                own_rows = ((first + node) * d + np.arange(d)).astype(PETSc.IntType)
                J.setValues(own_rows, [column], projection[j][:, h].reshape(d, 1),
                            addv=_ADD)
                rest = np.eye(d)[:, h] - projection[j][:, h]
                if not np.any(rest):
                    continue
                for k, value in zip(pairing.cols[pairing.rows == first + node],
                                    pairing.values[pairing.rows == first + node]):
                    rows = (int(k) * d + np.arange(d)).astype(PETSc.IntType)
                    J.setValues(rows, [column], (value * rest).reshape(d, 1), addv=_ADD)
        J.assemble()
        J.zeroRowsColumns(self.plain_global, diag=1.0)

    def update_multipliers(self, du):
        """The multipliers' step for dw = T du (NodalCondensation.update_multipliers), du
        without its prescribed components (the linearization was at u = g there); the step
        dz of a held slave component joins that component's row."""
        du.copy(self._dw)
        step = self._dw.array
        dz = step[self.z_local].copy()
        step[self.z_local] = 0.0
        step[self.plain_local] = 0.0
        self._dw.copy(self._x)
        self.T.mult(self._x, self._dw)
        if self.z_local.size:
            node_of = {int(n): j for j, n in enumerate(self.own)}
            for dof, value in zip(self.z_local, dz):
                node, h = divmod(int(dof), self.d)
                self.parts["F"][node_of[node], h] += value
        return super().update_multipliers(self._dw)

    def contact_forces(self) -> PETSc.Vec:
        """c, the slave's nodal contact forces at the current Functions (u's layout).

        Returns
        -------
        petsc4py.PETSc.Vec
            The assembled contact terms of F_u (non-zero at the slave dofs only).
        """
        with self.c.localForm() as local:
            local.set(0.0)
        if self.F_c is not None:
            assemble_vector(self.c, self.F_c)
            self.c.ghostUpdate(addv=_ADD, mode=_REVERSE)
        return self.c

    def master_share(self) -> PETSc.Vec:
        """P^T c: the slave's contact forces carried to the master's dofs; -P^T c is what
        the master receives.

        Returns
        -------
        petsc4py.PETSc.Vec
            P^T c (u's layout).
        """
        self.P.multTranspose(self.contact_forces(), self._share)
        return self._share

    def finish(self):
        """After a solve: u = g on every prescribed component (SNES's slots of the held
        slave components hold z), D = P u."""
        self._evaluation_point()
