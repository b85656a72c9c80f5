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

import numpy as np
from dolfinx import fem
from dolfinx.fem.petsc import assemble_vector, create_matrix
from petsc4py import PETSc

from contactvisco.fem import compat
from contactvisco.solver.condensed import NodalCondensation
from contactvisco.solver.newton import NewtonSolver, _weak, rigid_body_modes

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
        self.operator.setNearNullSpace(rigid_body_modes(problem.V))
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


class InterfaceCondensation(NodalCondensation):
    """The condensed Newton system (contactvisco.solver.condensed) of two bodies in contact
    whose law has nodal multipliers (a bound g, friction).

    In the unknowns w = S^-1 u, S = I + P0 (w_i = u_i - (Pi u)_i at the slave dofs, w = u
    elsewhere; P0 is P without the rows and columns of prescribed components), the contact
    terms act on the slave rows and columns alone, as for a rigid obstacle:

        R_w = S^T F_el + c,        J_w = S^T J_el S + K_c,

    so the node-wise elimination of the multipliers applies to the slave rows of J_w
    unchanged. The system handed to Newton is that one written back in u,

        F = S^-T R_w,red,          J = S^-T J_w,red S^-1 = T^T J_w,red T,   T = S^-1 = I - P0,

    whose solution is du = S dw (P0 P0 = 0: slave and master dofs differ). The multipliers are
    recovered from dw = T du.

    Parameters
    ----------
    problem : contactvisco.fem.problem.Problem
        The problem; ``problem.contact.obstacle`` is a fem.body_contact.BodyContact.
    """

    def __init__(self, problem):
        self.link = problem.contact.obstacle
        V = problem.V
        d = V.dofmap.index_map_bs
        owned = V.dofmap.index_map.size_local * d
        fixed = np.flatnonzero(problem.u_fixed.reshape(-1)[:owned] > 0)
        start = V.dofmap.index_map.local_range[0] * d
        self.fixed_global = (fixed + start).astype(PETSc.IntType)
        self.P0 = self.link.P.duplicate(copy=True)
        self.P0.zeroRowsColumns(self.fixed_global, diag=0.0)
        self.T0 = transfer(self.P0)
        contact = self.link.contact_form
        self.F_c = None if contact is None else fem.form(contact)
        self.J_c = None if contact is None else fem.form(ufl_derivative(contact, problem.u))
        self.K_c = None if self.J_c is None else create_matrix(self.J_c)
        self._patterned = False
        super().__init__(problem)
        self.c = compat.petsc_vector(problem.u).copy()
        self._el, self._share = self.c.copy(), self.c.copy()
        self._dw = self.c.copy()
        self.J_red = self.A.PtAP(self.T0)

    def _assemble_J(self):
        """A = J_w = S^T (J_full - K_c) S + K_c, J_full the assembled J_el + K_c at D = P0 u."""
        target = compat.petsc_vector(self.link.D)
        self.P0.mult(compat.petsc_vector(self.problem.u), target)
        target.ghostUpdate(addv=_INSERT, mode=_FORWARD)
        full = create_matrix(self.J_uu) if not self._patterned else self._full
        full.zeroEntries()
        compat.assemble_matrix(full, self.J_uu, self.bcs, diagonal=1.0)
        full.assemble()
        S = self.T0.duplicate(copy=True)
        S.scale(-1.0)
        S.shift(2.0)                         # S = 2 I - T = I + P0
        total = full.PtAP(S)
        if self.K_c is not None:
            self.K_c.zeroEntries()
            compat.assemble_matrix(self.K_c, self.J_c, [], diagonal=0.0)
            self.K_c.assemble()
            # as J_full's: no entry in the rows and columns of prescribed components (the
            # pattern of K_c, from Gamma_C alone, has no diagonal for a Dirichlet row)
            self.K_c.zeroRowsColumns(self.fixed_global, diag=0.0)
            moved = self.K_c.PtAP(S)
            total.axpy(-1.0, moved, _DIFFERENT)
            total.axpy(1.0, self.K_c, _DIFFERENT)
            moved.destroy()
        S.destroy()
        if not self._patterned:
            self.A.destroy()
            self.A, self._full, self._patterned = total, full, True
            return
        total.copy(self.A, structure=_SAME)
        total.destroy()

    def residual(self, x, b):
        """F = S^-T R_w,red at x (module description); the coupled residual's norm in w."""
        target = compat.petsc_vector(self.link.D)
        self.P0.mult(compat.petsc_vector(self.problem.u), target)
        target.ghostUpdate(addv=_INSERT, mode=_FORWARD)
        self.assemble_u_residual(x, b)
        with self.c.localForm() as local:
            local.set(0.0)
        if self.F_c is not None:
            assemble_vector(self.c, self.F_c)
            self.c.ghostUpdate(addv=_ADD, mode=_REVERSE)
        b.copy(self._el)
        self._el.axpy(-1.0, self.c)                  # F_el (slave rows are what P0^T reads)
        self.P0.multTranspose(self._el, self._share)
        b.axpy(1.0, self._share)                     # R_w = S^T F_el + c
        self.condense_residual(b)
        self.P0.multTranspose(b, self._share)
        b.axpy(-1.0, self._share)                    # S^-T R_w,red

    def jacobian(self):
        """J = T^T J_w,red T: J_w assembled, its slave rows saved and condensed, then
        written back in u."""
        super().jacobian()
        self.A.PtAP(self.T0, result=self.J_red)

    def update_multipliers(self, du):
        """The multipliers' step for dw = T du (NodalCondensation.update_multipliers)."""
        self.T0.mult(du, self._dw)
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
        """P0^T c: the slave's contact forces carried to the master's dofs; -P0^T c is what
        the master receives.

        Returns
        -------
        petsc4py.PETSc.Vec
            P0^T c (u's layout).
        """
        self.P0.multTranspose(self.contact_forces(), self._share)
        return self._share
