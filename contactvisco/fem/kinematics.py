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
    unweighted integrals.

    Parameters
    ----------
    mesh : dolfinx.mesh.Mesh
        The body's mesh (its geometric dimension d).
    """

    axisymmetric = False

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
            The d x d strain.
        """
        return ufl.sym(ufl.grad(u))

    def integral(self, integrand, measure):
        """integrand * measure: the integral over the body (dx) or a part of its boundary (ds).

        Parameters
        ----------
        integrand : UFL expression
            The scalar integrand.
        measure : ufl.Measure
            dx or ds (restricted, with metadata, as the caller needs).

        Returns
        -------
        UFL form
            int f dx, the form itself with no weight.
        """
        return integrand * measure

    def tensor_space(self, family: str, degree: int):
        """The space of the strain and stress tensors (tensor_dim x tensor_dim).

        Parameters
        ----------
        family : str
            "CG" or "DG".
        degree : int
            The degree.

        Returns
        -------
        dolfinx.fem.FunctionSpace
            The d x d tensor space.
        """
        return compat.tensor_space(self.mesh, family, degree)

    def contact_weight(self, Q, dsc, shares):
        """The weight of the contact terms at the contact nodes (none here).

        Parameters
        ----------
        Q : dolfinx.fem.FunctionSpace
            The scalar P1 space of the contact nodes.
        dsc : ufl.Measure
            The contact measure.
        shares : numpy.ndarray
            Each local P1 node's share of Gamma_C (the vertex rule's lumped weight).

        Returns
        -------
        tuple
            (None, shares): no weight, and the node weights unchanged.
        """
        return None, shares

    def axis_dofs(self, V):
        """The displacement dofs held by the axis (none here).

        Parameters
        ----------
        V : dolfinx.fem.FunctionSpace
            The displacement space.

        Returns
        -------
        None
            No axis.
        """
        return None


class Axisymmetric(Cartesian):
    """The kinematics of a body of revolution meshed in (r, z) (module description): the 3 x 3
    strain with the hoop component u_r / r, integrals weighted by 2 pi r.

    Parameters
    ----------
    mesh : dolfinx.mesh.Mesh
        A 2D mesh of the meridian half-plane, r = x[0] >= 0 (checked: a SceneError names
        material.model and the least r found otherwise).
    """

    axisymmetric = True

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

    def strain(self, u):
        """The 3 x 3 strain in (r, z, theta), hoop strain u_r / r (du_r/dr on the axis, its
        limit, so that points on the axis give finite values).

        Parameters
        ----------
        u : UFL vector
            (u_r, u_z).

        Returns
        -------
        UFL expression
            eps(u), 3 x 3 (module description).
        """
        e = ufl.sym(ufl.grad(u))
        hoop = ufl.conditional(ufl.gt(self.r, 0.0), u[0] / self.r, u[0].dx(0))
        return ufl.as_matrix([[e[0, 0], e[0, 1], 0.0],
                              [e[1, 0], e[1, 1], 0.0],
                              [0.0, 0.0, hoop]])

    def integral(self, integrand, measure):
        """int f 2 pi r dx (or ds): the integral over the body of revolution.

        Parameters
        ----------
        integrand : UFL expression
            The scalar integrand.
        measure : ufl.Measure
            dx or ds of the meridian mesh.

        Returns
        -------
        UFL form
            integrand * 2 pi r * measure.
        """
        return 2.0 * math.pi * self.r * integrand * measure

    def tensor_space(self, family: str, degree: int):
        """The 3 x 3 tensor space on the meridian mesh (the hoop component included).

        Parameters
        ----------
        family : str
            "CG" or "DG".
        degree : int
            The degree.

        Returns
        -------
        dolfinx.fem.FunctionSpace
            Tensors of shape (3, 3).
        """
        return compat.tensor_space(self.mesh, family, degree, shape=(3, 3))

    def contact_weight(self, Q, dsc, shares):
        """The contact terms' weight omega, a P1 field with the vertex rule: the contact
        conditions hold node by node, and a node's force is its pressure times its ring area
        w_i = int_Gamma_C 2 pi r phi_i ds (exact: the consistent lumping), also on the axis,
        where 2 pi r itself is zero. omega_i = w_i / m_i, m_i the node's share of Gamma_C
        (the vertex rule's sum_f |f| / 2), so that the vertex rule of omega f gives
        sum_i w_i f(x_i).

        Parameters
        ----------
        Q : dolfinx.fem.FunctionSpace
            The scalar P1 space of the contact nodes.
        dsc : ufl.Measure
            The contact measure.
        shares : numpy.ndarray
            m_i at every local P1 node (0 off Gamma_C).

        Returns
        -------
        tuple
            (omega, w): the P1 Function omega and the ring areas w at every local node.
        """
        from dolfinx import fem
        from contactvisco.fem.problem import assembled_values
        exact = dsc.reconstruct(metadata={"quadrature_degree": 2})
        areas = assembled_values(fem.form(2.0 * math.pi * self.r * ufl.TestFunction(Q)
                                          * exact))
        omega = fem.Function(Q, name="ring_weight")
        on = shares > 0
        omega.x.array[on] = areas[on] / shares[on]
        return omega, areas

    def axis_dofs(self, V):
        """The dofs of u_r at the nodes on the axis r = 0, where symmetry makes u_r vanish.

        Parameters
        ----------
        V : dolfinx.fem.FunctionSpace
            The displacement space.

        Returns
        -------
        numpy.ndarray
            Local dof indices of V.sub(0) (unrolled), ghosts included.
        """
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
