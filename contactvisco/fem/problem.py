"""The discrete problem (20)-(21) of a scene: spaces, unknowns, UFL residual and Jacobian.

Only the terms a scene needs are built: no lambda_tau without friction, no lambda_nu without a
finite bound g, no compliance term when g = 0 (pure Signorini), no history without memory, no
previous-step displacement unless friction acts on the slip per step.

Residual, with sigma_n = A eps(u_n) + H_n (H_n the history stress of eq 19) and
R_nu = (lambda_nu - r (u_nu - g))_-, sigma_tau = P_B(lambda_tau - r u_tau), B of radius
mu p_nu(u_nu) (contact.friction_law = "compliance", the paper's) or mu (p_nu(u_nu) + R_nu)
("coulomb": the total normal pressure); with contact.slip = "increment", u_tau is replaced by
the slip of the step, u_tau - u_tau(t_{n-1}):

    F_u   = (sigma_n, eps(v)) - (f, v) + int_C (p_nu(u_nu) + R_nu) v_nu - int_C sigma_tau . v_tau
    F_nu  = -1/r int_C (lambda_nu + R_nu) gamma_nu
    F_tau = -1/r int_C (lambda_tau - sigma_tau) . gamma_tau

Here u_nu = u . nu - h, the penetration past the initial gap h, and nu is the averaged nodal normal
(a P1 field); with an [obstacle] (contactvisco.fem.obstacle) nu and h are the obstacle's normal
and distance at the nodes (P1 fields) and u is replaced by u - d, d the obstacle's
displacement. lambda_nu and lambda_tau are P1 fields whose dofs off Gamma_C are fixed to zero,
because DOLFINx 0.5 has no boundary-only spaces. With the vertex quadrature on Gamma_C the
conditions hold node by node, on curved boundaries too. F_tau uses the full vector gamma_tau,
which also forces lambda_tau . nu = 0.

The parts are built in their own modules, which build() assembles: the stress and the memory
of eq (19) (fem.stress, fem.memory_part, with a temperature fem.temperature), the loads and
the Dirichlet conditions (fem.loads), the contact terms and their unknowns (fem.contact_terms,
fem.contact_unknowns), what a time step stages and commits (fem.time_state), and small tools
of fields and forms (fem.fields).
"""
from __future__ import annotations

import gc
from dataclasses import dataclass

import numpy as np
import ufl
from dolfinx import fem
from mpi4py import MPI

from contactvisco.fem import compat
from contactvisco.fem import geometry as geometry_module
from contactvisco.fem import rigid
from contactvisco.fem.contact_terms import (ContactNodes, ContactPart, build_contact,
                                            contact_laws, corner_values,
                                            multiplier_conditions)
from contactvisco.fem.contact_unknowns import has_friction
from contactvisco.fem.fields import assembled_values, length_scale, nodal_rule
from contactvisco.fem.geometry import Geometry
from contactvisco.fem.kinematics import kinematics
from contactvisco.fem.loads import dirichlet_conditions, external_loads
from contactvisco.fem.memory_part import MemoryPart
from contactvisco.fem.stress import (BodyHistory, BodyMemory, body_cells, body_stress,
                                     material_energy, material_stress)
from contactvisco.fem.time_state import TimeState
from contactvisco.scene.expressions import Context

#: The names that other modules have imported from here, each defined in its part's module.
__all__ = ["Problem", "build", "TimeState", "MemoryPart", "ContactNodes", "ContactPart",
           "BodyHistory", "BodyMemory", "body_cells", "body_stress", "material_energy",
           "assembled_values", "corner_values", "contact_laws", "has_friction", "nodal_rule"]


@dataclass
class Problem:
    """The discrete problem, complete when built (build()); afterwards only the values of
    its Functions and Constants change (time, history, iterates), through `time` between
    steps and the solver within them."""
    scene: dict
    geometry: Geometry
    V: fem.FunctionSpace                      # displacement
    u: fem.Function
    F: list
    J: list
    bcs: list                                 # on every unknown
    bcs_u: list                               # on u only
    u_fixed: np.ndarray                       # (nodes, d) 1 where u's component is prescribed
    multiplier_free: list                     # per multiplier: (nodes, bs) bool
    constants: dict                           # every Constant of the forms, by name
    context: Context                          # x and t of the scene's expressions
    time: TimeState                           # staged and committed between steps
    loads: object                             # the linear form of the external loads (UFL)
    tensor_space: fem.FunctionSpace           # the stress output's tensor space
    sigma_expression: fem.Expression
    length_scale: float
    kinematics: object = None                 # fem.kinematics: eps(u), weights, tensor size
    memory: MemoryPart | None = None
    contact: ContactPart | None = None
    tangent: object | None = None              # fem.tangent.TangentCheck (nonlinear A)

    def load_resultant(self) -> np.ndarray:
        """The resultant of the external loads at the current time, int f + int_N f_N
        (collective; compiles its forms on first use)."""
        d = self.V.mesh.geometry.dim
        if self.loads is None:
            return np.zeros(d)
        if "_resultant" not in self.__dict__:
            units = [fem.Function(self.V) for _ in range(d)]
            for j, e in enumerate(units):
                e.x.array.reshape(-1, d)[:, j] = 1.0
            self._resultant = [fem.form(ufl.action(self.loads, e)) for e in units]
        comm = self.V.mesh.comm
        return np.array([comm.allreduce(fem.assemble_scalar(f), MPI.SUM)
                         for f in self._resultant])

    @property
    def multipliers(self) -> dict[str, fem.Function]:
        """The multipliers the scene needs, by name, in the order lambda_nu, lambda_tau."""
        contact = self.contact
        if contact is None:
            return {}
        return {name: f for name, f in (("lambda_nu", contact.lambda_nu),
                                        ("lambda_tau", contact.lambda_tau)) if f is not None}

    @property
    def unknowns(self) -> list[fem.Function]:
        return [self.u, *self.multipliers.values()]

    def spaces(self) -> list:
        """Every function space of the problem's forms (unknowns, multipliers, coefficients:
        history, obstacle, normals, gap) and its stress output space."""
        spaces = {id(self.V): self.V, id(self.tensor_space): self.tensor_space}
        forms = list(self.F) + [a for row in self.J for a in row if a is not None]
        for form in forms:
            for term in (*form.coefficients(), *form.arguments()):
                space = getattr(term, "function_space", None)
                if space is not None and hasattr(space, "dofmap"):
                    spaces.setdefault(id(space), space)
        return list(spaces.values())

    def release_garbage(self) -> None:
        """Destroy the PETSc objects that Python dropped on this problem's communicators
        (collective; fem.compat.release_petsc_garbage), the solver's included once the
        caller holds it no more. Called when a run ends; a caller that builds problems and
        solvers itself calls it after dropping the solver, before dropping the problem."""
        if self.V.mesh.comm.size == 1:
            return                     # petsc4py destroys the objects of one rank at once
        gc.collect()                   # objects in reference cycles become garbage now
        compat.release_petsc_garbage(self.spaces())

    def count_unknowns(self) -> dict:
        """Global dof counts per unknown."""
        out = {}
        for name, f in (("u", self.u), *self.multipliers.items()):
            imap = f.function_space.dofmap.index_map
            out[name] = imap.size_global * f.function_space.dofmap.index_map_bs
        return out

    def count_contact_nodes(self) -> int:
        """Global number of contact nodes (0 without contact)."""
        if self.contact is None:
            return 0
        return self.V.mesh.comm.allreduce(int(self.contact.nodes.owned.sum()))


def _block_jacobian(F, unknowns, spaces):
    """J[i][j] = dF_i/dw_j, None where the block is empty."""
    J = []
    for Fi in F:
        row = []
        for unknown, space in zip(unknowns, spaces):
            a = ufl.algorithms.expand_derivatives(
                ufl.derivative(Fi, unknown, ufl.TrialFunction(space)))
            row.append(None if a.empty() else a)
        J.append(row)
    return J


def build(scene: dict, geometry: Geometry) -> Problem:
    """The Problem of a scene on a geometry, built complete in one call: elasticity with the
    memory part (eq 19), the external loads, the Dirichlet conditions, and the contact part
    (eqs 20-21) with its multipliers, residual blocks F and Jacobian blocks J."""
    mesh = geometry.mesh
    geometry_module.check_ranks(mesh)
    compat.settle_coordinate_element(mesh)
    d = mesh.geometry.dim
    degree = scene["discretization"]["degree"]
    context = Context(mesh)
    updates = []                               # run at each new time
    kin = kinematics(scene, mesh)

    V = compat.vector_space(mesh, "CG", degree)
    u, v = fem.Function(V, name="u"), ufl.TestFunction(V)
    if scene.get("body"):
        sigma, constants, memory = body_stress(scene, geometry, u, context, updates, kin)
    else:
        sigma, constants, memory = material_stress(scene, mesh, u, context, updates, kin)
    constants["t"] = context.t

    ds = ufl.Measure("ds", domain=mesh, subdomain_data=geometry.facet_tags)
    loads = external_loads(scene, geometry, context, v, ds, kin)
    F_u = kin.integral(ufl.inner(sigma, kin.strain(v)), ufl.dx)
    if loads is not None:
        F_u -= loads
    bcs, fixed_components = dirichlet_conditions(scene, geometry, V, context, updates, kin)

    unknowns, spaces, F_extra = [u], [V], []
    contact = None
    if scene["contact"] is not None:
        contact, contact_terms, multipliers = build_contact(scene, geometry, u, v, ds, context,
                                                     updates, kin)
        constants.update(contact.constants)
        if contact_terms is not None:
            F_u += contact_terms
        for function, residual in multipliers:
            unknowns.append(function)
            spaces.append(function.function_space)
            F_extra.append(residual)
    multiplier_bcs, multiplier_free = multiplier_conditions(
        contact and contact.nodes, contact and contact.lambda_nu,
        contact and contact.lambda_tau, fixed_components, d)

    F = [F_u] + F_extra
    tensor_space = memory.tensor_space if memory else kin.tensor_space("DG", degree - 1)
    problem = Problem(
        scene=scene, geometry=geometry, V=V, u=u, F=F, J=_block_jacobian(F, unknowns, spaces),
        bcs=bcs + multiplier_bcs, bcs_u=list(bcs), u_fixed=fixed_components,
        multiplier_free=multiplier_free, constants=constants, context=context,
        time=TimeState(context.t, updates, u, memory, contact and contact.u_previous,
                       obstacle=contact and contact.obstacle),
        loads=loads, tensor_space=tensor_space,
        sigma_expression=compat.expression(sigma, tensor_space),
        length_scale=length_scale(mesh), kinematics=kin, memory=memory, contact=contact,
        tangent=constants.pop("tangent", None))
    rigid.check(problem)
    return problem
