"""The zone at the bound on Gamma_C: which of its nodes lie inside it and which on its edge.

A contact node is inside the zone at the bound when it is at the bound and so is every node
it shares a facet of Gamma_C with. Found by assembly, so that every rank sees the same
answer for a node it holds, ghosts included: with o the P1 field that is 1 at the nodes off
the bound and 0 at the others,

    reach_i = int_{Gamma_C} o phi_i ds    (Gauss points inside the facets),

is 0 exactly where every facet through node i has all its vertices at the bound (o = 0 on
them) and positive where one of them has a vertex off it (o > 0 and phi_i > 0 inside that
facet).
"""
from __future__ import annotations

import numpy as np
import ufl
from dolfinx import fem

from contactvisco.fem.fields import assembled_values


class BoundZone:
    """The test above for the P1 space Q of the multipliers.

    Parameters
    ----------
    Q : dolfinx.fem.FunctionSpace
        The scalar P1 space of lambda_nu.
    dsc : ufl.Measure
        The contact measure (Gamma_C); its quadrature is replaced by a Gauss rule of degree
        2, whose points lie inside the facets (the vertex rule would see node i alone).
    """

    def __init__(self, Q, dsc):
        self.off = fem.Function(Q)
        measure = dsc.reconstruct(metadata={"quadrature_degree": 2})
        self.form = fem.form(self.off * ufl.TestFunction(Q) * measure)

    def interior(self, bound: np.ndarray) -> np.ndarray:
        """The nodes inside the zone (collective).

        Parameters
        ----------
        bound : numpy.ndarray of bool
            At the bound, per local dof of Q (ghosts included, the same on every rank that
            holds a node).

        Returns
        -------
        numpy.ndarray of bool
            At the bound and every neighbour on Gamma_C at the bound, per local dof.
        """
        self.off.x.array[:] = np.where(bound, 0.0, 1.0)
        return bound & (assembled_values(self.form) == 0.0)
