"""The external loads and the Dirichlet conditions of a scene: the linear form (f, v) +
(f_N, v)_Gamma_N and the prescribed displacements, values in x and t that follow the time."""
from __future__ import annotations

import numpy as np
import ufl
from dolfinx import fem
from petsc4py import PETSc

from contactvisco.fem import compat
from contactvisco.fem.fields import interpolator


def external_loads(scene, geometry, context, v, ds, kin):
    """(f, v) + sum (f_N, v)_Gamma_N: the linear form of the external loads, None without
    (integrals weighted as the kinematics `kin` weighs them: 2 pi r in axisymmetry)."""
    d = geometry.mesh.geometry.dim
    loads = []
    body = scene["body_force"]["value"]
    if body is not None:
        loads.append(kin.integral(ufl.dot(context.vector(body, "body_force.value", d), v),
                                  ufl.dx))
    for i, traction in enumerate(scene["traction"]):
        geometry.facets(traction["boundary"], f"traction[{i}].boundary")   # checks the name
        fN = context.vector(traction["value"], f"traction[{i}].value", d)
        loads.append(kin.integral(ufl.dot(fN, v), ds(geometry.names[traction["boundary"]])))
    return sum(loads[1:], loads[0]) if loads else None


def dirichlet_conditions(scene, geometry, V, context, updates, kin=None):
    """Dirichlet conditions and, per displacement dof, whether it is prescribed (0/1 array,
    consistent over ranks, ghosts included). Values may depend on x and t. An axisymmetric
    body (kin) also gets u_r = 0 at its nodes on the axis (kin.axis_dofs)."""
    mesh = geometry.mesh
    d = mesh.geometry.dim
    fdim = d - 1
    bcs = []
    fixed = fem.Function(V)
    for i, item in enumerate(scene["dirichlet"]):
        where = f"dirichlet[{i}]"          # keys and values checked by tables.Dirichlet
        facets = geometry.facets(item["boundary"], f"{where}.boundary")
        comps = item.get("components", "all")
        value = item.get("value", 0.0)
        if comps == "all":
            vals = value if isinstance(value, (list, tuple)) else [value] * d
            dofs = fem.locate_dofs_topological(V, fdim, facets)
            vector = context.vector(vals, f"{where}.value", d)
            if isinstance(vector, fem.Constant):
                bcs.append(fem.dirichletbc(vector.value, dofs, V))
            else:
                g = fem.Function(V)
                update = interpolator(g, vector, V)
                update()
                if context.depends_on_time(vals):
                    updates.append(update)
                bcs.append(fem.dirichletbc(g, dofs))
            fixed.x.array[(dofs[:, None] * d + np.arange(d)).ravel()] = 1.0
            continue
        bcs += _component_bcs(item, where, comps, facets, V, context, updates, fixed)
    axis = None if kin is None else kin.axis_dofs(V)
    if axis is not None:
        bcs.append(fem.dirichletbc(PETSc.ScalarType(0.0), axis, V.sub(0)))
        fixed.x.array[axis] = 1.0
    # A rank may hold a prescribed node as a ghost without the facet that prescribes it.
    fixed_vector = compat.petsc_vector(fixed)
    fixed_vector.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
    fixed_vector.ghostUpdate(addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)
    return bcs, fixed.x.array.reshape(-1, V.dofmap.index_map_bs)


def _component_bcs(item, where, comps, facets, V, context, updates, fixed):
    """The conditions of one dirichlet entry on the listed components; marks their dofs in
    the Function `fixed`."""
    d = V.mesh.geometry.dim
    value = item.get("value", 0.0)
    vals = value if isinstance(value, (list, tuple)) else [value] * len(comps)
    bcs = []
    for comp, val in zip(comps, vals):
        scalar = context.scalar(val, f"{where}.value")
        if isinstance(scalar, fem.Constant):
            dofs = fem.locate_dofs_topological(V.sub(comp), d - 1, facets)
            bcs.append(fem.dirichletbc(scalar.value, dofs, V.sub(comp)))
        else:
            Vc, _ = V.sub(comp).collapse()
            g = fem.Function(Vc)
            update = interpolator(g, scalar, Vc)
            update()
            if context.depends_on_time(val):
                updates.append(update)
            pair = fem.locate_dofs_topological((V.sub(comp), Vc), d - 1, facets)
            bcs.append(fem.dirichletbc(g, pair, V.sub(comp)))
            dofs = pair[0]
        fixed.x.array[dofs] = 1.0
    return bcs
