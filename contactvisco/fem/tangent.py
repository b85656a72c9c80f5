"""The tangent of a nonlinear elasticity operator A = dW/deps where the solution takes it:
positive definite (W convex there) or not, and where not.

The tangent C = d^2W/deps^2 is written in an orthonormal basis E_a of the symmetric strains
(Mandel's notation: E_a = e_i (x) e_i, and (e_i (x) e_j + e_j (x) e_i) / sqrt 2 for i < j),
C_ab = E_a : C : E_b, a symmetric n x n matrix (n = 3 in 2D, 6 in 3D), interpolated into a
DG space of the strain's degree (P1: one value per cell, the strain there). Its smallest
eigenvalue over the mesh, over 2 mu (the small-strain shear stiffness), says how far A is
from losing its monotonicity; <= 0 means W is not convex at that state (the incremental
problem may lose uniqueness and Newton its quadratic rate).
"""
from __future__ import annotations

import numpy as np
import ufl
from dolfinx import fem
from mpi4py import MPI
from petsc4py import PETSc

from contactvisco.fem import compat
from contactvisco.model.material import strain_basis


class TangentCheck:
    """The smallest eigenvalue of the tangent C_ab = E_a : C : E_b over the mesh.

    Parameters
    ----------
    C : UFL expression
        The fourth-order tangent d^2W/deps^2 at eps(u).
    u : dolfinx.fem.Function
        The displacement.
    mu : float
        The small-strain shear modulus, the scale 2 mu of the eigenvalues.
    """

    def __init__(self, C, u, mu):
        mesh = u.function_space.mesh
        d = mesh.geometry.dim
        degree = max(compat.element_degree(u.function_space) - 1, 0)
        basis = strain_basis(d)
        n = len(basis)
        i, j, k, l = ufl.indices(4)
        # A zero Constant times x keeps the mesh in a tangent that is constant (an energy
        # written with numbers, quadratic in eps): fem.Expression needs one.
        zero = fem.Constant(mesh, PETSc.ScalarType(0.0)) * ufl.SpatialCoordinate(mesh)[0]
        entries = []
        for A in basis:
            for B in basis:
                Ea, Eb = ufl.as_matrix(A.tolist()), ufl.as_matrix(B.tolist())
                entries.append(Ea[i, j] * C[i, j, k, l] * Eb[k, l] + zero)
        self.n, self.mu = n, mu
        self.space = compat.blocked_space(mesh, "DG", degree, n * n)
        self.values = fem.Function(self.space)
        self.expression = compat.expression(ufl.as_vector(entries), self.space)

    def smallest(self, comm=MPI.COMM_WORLD) -> dict:
        """The smallest eigenvalue of the tangent over the mesh (collective).

        Parameters
        ----------
        comm : mpi4py.MPI.Comm, optional
            The mesh's communicator.

        Returns
        -------
        dict
            ``ratio``: the smallest eigenvalue over 2 mu; ``x``: the point where it is
            taken (a DG node); ``eigenvalue``: its value.
        """
        self.values.interpolate(self.expression)
        owned = self.space.dofmap.index_map.size_local
        C = self.values.x.array.reshape(-1, self.n, self.n)[:owned]
        if len(C):
            eigenvalues = np.linalg.eigvalsh(0.5 * (C + C.transpose(0, 2, 1)))[:, 0]
            worst = int(np.argmin(eigenvalues))
            local = (float(eigenvalues[worst]),
                     self.space.tabulate_dof_coordinates()[worst].tolist())
        else:
            local = (np.inf, None)
        value, x = min(comm.allgather(local), key=lambda item: item[0])
        scale = 2.0 * float(self.mu)
        return {"ratio": value / scale, "eigenvalue": value, "x": x}
