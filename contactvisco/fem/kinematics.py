"""The body's kinematics in one place: the strain eps(u), the weight of the volume and surface
integrals, the dimension of the strain tensor and its spaces, which every form of the problem
(the elasticity, the memory, the loads, the contact terms) takes from here.

Two implementations, chosen by material.model:

- :class:`Cartesian` (plane_strain, plane_stress, 3d): eps(u) = (grad u + grad u^T) / 2, a
  d x d tensor, and unweighted integrals, int_Omega f dx.
- :class:`Axisymmetric` (axisymmetric): a body of revolution about the z axis, meshed in its
  meridian half-plane (r, z) = (x[0], x[1]), r >= 0, with a displacement (u_r, u_z) that does not
  depend on the angle theta. The strain is the 3 x 3 tensor in the (r, z, theta) frame

      eps(u) = [[du_r/dr,                       (du_r/dz + du_z/dr) / 2,  0      ],
                [(du_r/dz + du_z/dr) / 2,       du_z/dz,                  0      ],
                [0,                             0,                        u_r / r]],

  the hoop strain u_r / r in the third diagonal entry, and every integral over the body of
  revolution is the meridian integral weighted by 2 pi r: int_Omega3 f dV = int_Omega f 2 pi r dx,
  int_Gamma3 f dS = int_Gamma f 2 pi r ds. Forces are therefore totals over the full circle. On
  the axis r = 0 the radial displacement vanishes (u_r = 0, a consequence of the symmetry,
  prescribed on the axis nodes by :meth:`Axisymmetric.axis_dofs`), and the hoop strain takes
  its limit du_r/dr there.
"""
from __future__ import annotations

import math

import numpy as np
import ufl
from mpi4py import MPI

from contactvisco.errors import SceneError
from contactvisco.fem import compat

#: material.model of the axisymmetric body.
AXISYMMETRIC = "axisymmetric"

#: A node with r below this fraction of the mesh's size lies on the axis; a node with r below
#: minus it makes the mesh refused (round-off of a mesh generator is far smaller).
AXIS_TOLERANCE = 1e-10


class Cartesian:
    """The kinematics of plane strain, plane stress and 3D: eps(u) = sym grad u, d x d, and
    unweighted integrals. :class:`Axisymmetric` changes the strain, the weight, the tensor
    shape, the contact nodes' weights and the axis.

    Parameters
    ----------
    mesh : dolfinx.mesh.Mesh
        The body's mesh (its geometric dimension d).
    """

    axisymmetric = False
    #: The weight of every integral (None: none; 2 pi r in axisymmetry).
    weight = None
    #: The shape of the strain and stress tensors (None: d x d).
    tensor_shape = None

    def __init__(self, mesh):
        self.mesh = mesh
        #: The dimension of the strain and stress tensors.
        self.tensor_dim = mesh.geometry.dim

    def strain(self, u):
        """eps(u) = (grad u + grad u^T) / 2.

        Parameters
        ----------
        u : UFL vector
            A displacement (or test or trial function).

        Returns
        -------
        UFL expression
            The strain, tensor_dim x tensor_dim.
        """
        return ufl.sym(ufl.grad(u))

    def gradient(self, u):
        """The gradient of u in the body, grad u (tensor_dim x tensor_dim); its symmetric
        part is strain(u).

        Parameters
        ----------
        u : UFL vector
            A displacement.

        Returns
        -------
        UFL expression
            grad u, the integrand |grad u|^2 of the body's H1 seminorm.
        """
        return ufl.grad(u)

    def history_degree(self, degree: int) -> int:
        """The degree of the DG space that holds the memory's strain history (and the stress
        output with memory): degree - 1, where eps(u) of a P_k field lies exactly.

        Parameters
        ----------
        degree : int
            The displacement's Lagrange degree k.

        Returns
        -------
        int
            k - 1.
        """
        return degree - 1

    def integral(self, integrand, measure):
        """The integral over the body (dx) or a part of its boundary (ds): integrand * measure,
        times the weight when there is one.

        Parameters
        ----------
        integrand : UFL expression
            The scalar integrand f.
        measure : ufl.Measure
            dx or ds (restricted, with metadata, as the caller needs).

        Returns
        -------
        UFL form
            int f dx (the form itself without a weight), or int f 2 pi r dx.
        """
        if self.weight is None:
            return integrand * measure
        return self.weight * integrand * measure

    def tensor_space(self, family: str, degree: int):
        """The space of the strain and stress tensors.

        Parameters
        ----------
        family : str
            "CG" or "DG".
        degree : int
            The degree.

        Returns
        -------
        dolfinx.fem.FunctionSpace
            Tensors of tensor_shape (d x d without one).
        """
        return compat.tensor_space(self.mesh, family, degree, shape=self.tensor_shape)

    def contact_weight(self, Q, dsc, shares):
        """The weight omega of the contact terms (a P1 field) and each node's weight, the
        area its force acts on; here none and the nodes' shares of Gamma_C.

        Parameters
        ----------
        Q : dolfinx.fem.FunctionSpace
            The scalar P1 space of the contact nodes.
        dsc : ufl.Measure
            The contact measure.
        shares : numpy.ndarray
            Each local P1 node's share of Gamma_C (the vertex rule's lumped weight, 0 off it).

        Returns
        -------
        tuple
            (omega or None, the node weights at every local P1 node).
        """
        return None, shares

    def axis_dofs(self, V):
        """The dofs of u_r on the axis, where symmetry makes it vanish (None: no axis).

        Parameters
        ----------
        V : dolfinx.fem.FunctionSpace
            The displacement space.

        Returns
        -------
        numpy.ndarray or None
            Local dof indices of V.sub(0) (unrolled), ghosts included.
        """
        return None


class Axisymmetric(Cartesian):
    """The kinematics of a body of revolution meshed in (r, z) (module description): the 3 x 3
    strain with the hoop component u_r / r, integrals weighted by 2 pi r, the contact nodes
    weighted by their ring areas, u_r = 0 on the axis.

    Parameters
    ----------
    mesh : dolfinx.mesh.Mesh
        A 2D mesh of the meridian half-plane, r = x[0] >= 0 (checked: a SceneError names
        material.model and the least r found otherwise).
    """

    axisymmetric = True
    tensor_shape = (3, 3)

    def __init__(self, mesh):
        super().__init__(mesh)
        if mesh.geometry.dim != 2:
            raise SceneError(f"material.model = '{AXISYMMETRIC}' needs a 2D mesh of the "
                             f"meridian half-plane (r, z), got a {mesh.geometry.dim}D mesh",
                             key="material.model")
        x = mesh.geometry.x[:, :2]
        comm = mesh.comm
        least = comm.allreduce(float(x[:, 0].min()) if len(x) else math.inf, op=MPI.MIN)
        extent = max(comm.allreduce(float(np.ptp(x[:, j])) if len(x) else 0.0, op=MPI.MAX)
                     for j in range(2))
        self.scale = extent
        if least < -AXIS_TOLERANCE * extent:
            raise SceneError(
                f"material.model = '{AXISYMMETRIC}': the mesh lies in the half-plane "
                f"(r, z) = (x[0], x[1]) with r >= 0 (the z axis is r = 0), but it reaches "
                f"r = {least:.6g}; move or cut the mesh to r >= 0", key="material.model")
        self.tensor_dim = 3
        self.r = ufl.SpatialCoordinate(mesh)[0]
        self.weight = 2.0 * math.pi * self.r

    def strain(self, u):
        """The 3 x 3 strain of (u_r, u_z) in (r, z, theta) (module description), the hoop
        strain u_r / r taking its limit du_r/dr on the axis, so that points on the axis give
        finite values."""
        e = ufl.sym(ufl.grad(u))
        hoop = ufl.conditional(ufl.gt(self.r, 0.0), u[0] / self.r, u[0].dx(0))
        return ufl.as_matrix([[e[0, 0], e[0, 1], 0.0],
                              [e[1, 0], e[1, 1], 0.0],
                              [0.0, 0.0, hoop]])

    def history_degree(self, degree: int) -> int:
        """k - 1 for P1 and k from P2 on: the hoop strain u_r / r of a P_k field is no
        polynomial, and its interpolation into DG_{k-1} is a consistency error of O(h^k)
        in the memory term, which takes P2's L2 order from 3 to 2 (measured 2.14 at
        h = 1/32 on the manufactured solution with memory; DG_k keeps it at
        O(h^(k+1))). For P1 the midpoint value of DG0 keeps the L2 order 2."""
        return degree if degree > 1 else 0

    def gradient(self, u):
        """The gradient of (u_r, u_z) in (r, z, theta): [[du_r/dr, du_r/dz, 0],
        [du_z/dr, du_z/dz, 0], [0, 0, u_r / r]] (the hoop entry as in strain, its limit
        du_r/dr on the axis)."""
        g = ufl.grad(u)
        hoop = ufl.conditional(ufl.gt(self.r, 0.0), u[0] / self.r, u[0].dx(0))
        return ufl.as_matrix([[g[0, 0], g[0, 1], 0.0],
                              [g[1, 0], g[1, 1], 0.0],
                              [0.0, 0.0, hoop]])

    def contact_weight(self, Q, dsc, shares):
        """Cartesian.contact_weight with the ring areas: the conditions hold node by node (the
        vertex rule), and a node's force is its pressure times w_i = int_Gamma_C 2 pi r phi_i ds
        (exact: the consistent lumping), also on the axis, where 2 pi r itself is zero.
        omega_i = w_i / m_i, m_i the node's share, so that the vertex rule of omega f gives
        sum_i w_i f(x_i)."""
        from dolfinx import fem
        from contactvisco.fem.fields import assembled_values
        exact = dsc.reconstruct(metadata={"quadrature_degree": 2})
        areas = assembled_values(fem.form(self.weight * ufl.TestFunction(Q) * exact))
        omega = fem.Function(Q, name="ring_weight")
        on = shares > 0
        omega.x.array[on] = areas[on] / shares[on]
        return omega, areas

    def axis_dofs(self, V):
        """The u_r dofs at the nodes with |r| <= AXIS_TOLERANCE times the mesh's size."""
        blocks = np.flatnonzero(np.abs(V.tabulate_dof_coordinates()[:, 0])
                                <= AXIS_TOLERANCE * self.scale)
        return (blocks * V.dofmap.index_map_bs).astype(np.int32)


def kinematics(scene: dict, mesh):
    """The kinematics of a scene's material.model on its mesh.

    Parameters
    ----------
    scene : dict
        The resolved scene.
    mesh : dolfinx.mesh.Mesh
        Its mesh.

    Returns
    -------
    Cartesian or Axisymmetric
        Axisymmetric for material.model = "axisymmetric", else Cartesian.
    """
    if scene["material"]["model"] == AXISYMMETRIC:
        return Axisymmetric(mesh)
    return Cartesian(mesh)
