"""The stress of eq (19) on a mesh: sigma(u) = A eps(u) + H + the memory's implicit terms, A
linear or given by a strain energy, and for several bodies ([[body]] tables) each body's own
stress on its cells, with their memories seen as one."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from dolfinx import fem
from mpi4py import MPI

from contactvisco.errors import SceneError
from contactvisco.fem import compat
from contactvisco.fem.fields import scalar
from contactvisco.fem.geometry import Geometry
from contactvisco.fem.kinematics import kinematics
from contactvisco.fem.memory_part import build_memory, strain_part
from contactvisco.fem.tangent import TangentCheck
from contactvisco.model.material import (elasticity, energy_stress, hencky_energy,
                                         invariants, lame_constants)
from contactvisco.scene.expressions import Context


def material_stress(scene, mesh, u, context=None, updates=None, kin=None):
    """sigma(u) = A eps(u) + H + sum_part w_part P_part eps(u) (eq 19: the elastic stress,
    the history stress of the memory part and its implicit weights, none without memory),
    eps the strain of the kinematics `kin` (fem.kinematics; the scene's when None).
    Returns sigma, the Constants it uses by name (the Lame constants lame_lambda, lame_mu
    and the memory part's; with a nonlinear A also "tangent", its TangentCheck) and the
    MemoryPart (None without memory)."""
    kin = kin or kinematics(scene, mesh)
    strain = kin.strain
    mat = scene["material"]
    lame_lambda, lame_mu = lame_constants(mat["model"], mat["E"], mat["nu"])
    constants = {"lame_lambda": scalar(mesh, lame_lambda), "lame_mu": scalar(mesh, lame_mu)}
    if mat.get("law", "linear") == "linear":
        sigma = elasticity(strain(u), constants["lame_lambda"], constants["lame_mu"])
    else:
        energy = material_energy(mat, constants, context or Context(mesh))
        sigma, C = energy_stress(strain(u), energy)
        constants["tangent"] = TangentCheck(C, u, lame_mu)
    memory = build_memory(scene, mesh, u, context, updates, kin)
    if memory is not None:
        sigma = sigma + memory.H
        for constant, part in memory.implicit_terms:
            sigma = sigma + constant * strain_part(strain(u), part)
        constants.update(memory.constants)
    return sigma, constants, memory


def material_energy(mat: dict, constants: dict, context: Context):
    """The strain energy W of a nonlinear A (material.law "hencky" or "energy").

    Parameters
    ----------
    mat : dict
        The resolved [material] table.
    constants : dict
        The Constants lame_lambda and lame_mu (lambda* in plane stress).
    context : contactvisco.scene.expressions.Context
        The position and time symbols of material.energy.

    Returns
    -------
    callable
        eps -> W(eps), a UFL expression: hencky_energy, or material.energy in the
        invariants tr_eps, eps2, dev_eps2 with lmbda and mu_lame.
    """
    lmbda, mu = constants["lame_lambda"], constants["lame_mu"]
    if mat["law"] == "hencky":
        return lambda eps: hencky_energy(eps, lmbda, mu, mat["hencky_exponent"],
                                         mat["hencky_strain"])
    text = mat["energy"]
    return lambda eps: context.scalar(text, "material.energy",
                                      dict(invariants(eps), lmbda=lmbda, mu_lame=mu))


class BodyHistory:
    """The histories of eq (19) of several bodies seen as one by checkpoints and reports:
    state() holds each body's arrays under its key with the suffix _body<b>."""

    def __init__(self, histories: list):
        self.histories = histories
        self.direct = any(getattr(h, "direct", False) for h in histories)
        self.terms = [term for h in histories for term in getattr(h, "terms", [])]

    def state(self) -> dict:
        """Every body's history arrays (restore() takes them back)."""
        return {f"{key}_body{b}": value for b, history in enumerate(self.histories)
                for key, value in history.state().items()}

    def restore(self, state: dict):
        """Each body's arrays of state() back into its history."""
        for b, history in enumerate(self.histories):
            suffix = f"_body{b}"
            history.restore({key[:-len(suffix)]: value for key, value in state.items()
                             if key.endswith(suffix)})


@dataclass
class BodyMemory:
    """The memory parts of the bodies that have one ([[body]] tables): each a MemoryPart on
    the whole tensor space, of which the stress takes its body's cells only; H, the history
    stress of the output, is the body's H_b on each body's cells (combine())."""
    parts: list                                # MemoryPart of each body with memory
    masks: list                                # per part: 1.0 on its body's tensor dofs
    history: BodyHistory
    H: fem.Function
    tensor_space: fem.FunctionSpace
    bodies: list | None = None                 # per part: its [[body]] table

    def combine(self):
        """H = sum_b mask_b H_b."""
        self.H.x.array[:] = sum(mask * part.H.x.array for mask, part in zip(self.masks,
                                                                           self.parts))


def body_cells(scene: dict, geometry: Geometry) -> list[np.ndarray]:
    """The local cells (ghosts included) of each [[body]] table, checked: a cell tag name or
    region that names no cell, or a cell in no body or in two, is a SceneError naming the key.

    Parameters
    ----------
    scene : dict
        The resolved scene, with its list ``body`` of [[body]] tables.
    geometry : contactvisco.fem.geometry.Geometry
        The mesh with its cell tags and cell tag names.

    Returns
    -------
    list of numpy.ndarray
        Per body, the local cell indices c with tag(c) = the body's tag, or with r(x_c) > 0 for
        a region r in x, x_c the cell's midpoint.
    """
    from contactvisco.scene.expressions import value_at
    mesh = geometry.mesh
    tdim, d = mesh.topology.dim, mesh.geometry.dim
    cell_map = mesh.topology.index_map(tdim)
    local = cell_map.size_local + cell_map.num_ghosts
    names = geometry.cell_names or {}
    midpoints = None
    out = []
    for b, body in enumerate(scene["body"]):
        where, cells = f"body[{b}].cells", body["cells"]
        if cells in names:
            found = geometry.cell_tags.find(names[cells])
        else:
            try:
                value_at(cells, where, d, [0.0] * d, 0.0)
            except SceneError as err:
                raise SceneError(
                    f"{where} = {cells!r} is neither a cell tag of this mesh (it has "
                    f"{', '.join(sorted(names)) or 'none'}) nor a region in x: {err}",
                    key=where) from None
            if midpoints is None:
                nodes = compat.geometry_nodes(mesh)[:local]
                midpoints = mesh.geometry.x[nodes][:, :, :d].mean(axis=1)
            found = np.flatnonzero([value_at(cells, where, d, x, 0.0) > 0 for x in midpoints])
        found = np.asarray(found, dtype=np.int32)
        if mesh.comm.allreduce(found.size, MPI.SUM) == 0:
            raise SceneError(f"{where} = {cells!r} holds no cell of the mesh", key=where)
        out.append(found)
    count = np.zeros(local, dtype=int)
    for found in out:
        count[found] += 1
    owned = count[:cell_map.size_local]
    for what, bad in (("no", owned == 0), ("two", owned > 1)):
        if mesh.comm.allreduce(int(bad.sum()), MPI.SUM):
            raise SceneError(f"body: some cells of the mesh lie in {what} [[body]]; every "
                             "cell must lie in exactly one (body[i].cells)", key="body")
    return out


def _indicator(mesh, cells):
    """The DG0 field 1 on `cells` (local indices), 0 elsewhere."""
    chi = fem.Function(compat.scalar_space(mesh, "DG", 0))
    dofs = compat.cell_dofs(chi.function_space.dofmap)[cells].ravel()
    chi.x.array[dofs] = 1.0
    return chi


def _tensor_mask(space, cells):
    """1.0 on the dofs (all components) of `cells` in a blocked DG space, 0 elsewhere."""
    bs = space.dofmap.index_map_bs
    mask = np.zeros_like(fem.Function(space).x.array)
    nodes = compat.cell_dofs(space.dofmap)[cells].ravel()
    mask[(nodes[:, None] * bs + np.arange(bs)).ravel()] = 1.0
    return mask


def body_stress(scene: dict, geometry: Geometry, u, context=None, updates=None, kin=None):
    """The stress of several bodies, each with its own A and memory kernel:
    sigma = sum_b chi_b sigma_b(u), chi_b the DG0 indicator of body b's cells and sigma_b
    eq (19) with the body's [material] and [memory] (material_stress).

    Parameters
    ----------
    scene : dict
        The resolved scene with its [[body]] tables.
    geometry : contactvisco.fem.geometry.Geometry
        The mesh and its cell tags.
    u : dolfinx.fem.Function
        The displacement.
    context, updates
        The expressions' x and t, and the callables run at each new time.
    kin : Cartesian or Axisymmetric, optional
        The kinematics (fem.kinematics; the scene's when None).

    Returns
    -------
    tuple
        sigma (UFL), the Constants by name (``<body>.<name>``), and a BodyMemory (None if no
        body has memory).
    """
    if scene.get("viscoelastic") is not None:
        raise SceneError("viscoelastic: a scene with [[body]] tables gives each body its "
                         "material and memory in its own tables; leave out [viscoelastic]",
                         key="viscoelastic")
    mesh = geometry.mesh
    sigma, constants, parts, masks, owners = 0, {}, [], [], []
    for body, cells in zip(scene["body"], body_cells(scene, geometry)):
        own = dict(scene, material=body["material"], memory=body["memory"])
        sigma_b, constants_b, memory_b = material_stress(own, mesh, u, context, updates, kin)
        sigma = sigma + _indicator(mesh, cells) * sigma_b
        constants.update({f"{body['name']}.{name}": c for name, c in constants_b.items()})
        if memory_b is not None:
            parts.append(memory_b)
            masks.append(_tensor_mask(memory_b.tensor_space, cells))
            owners.append(body)
    if not parts:
        return sigma, constants, None
    space = parts[0].tensor_space
    memory = BodyMemory(parts=parts, masks=masks,
                        history=BodyHistory([part.history for part in parts]),
                        H=fem.Function(space, name="history_stress"), tensor_space=space,
                        bodies=owners)
    return sigma, constants, memory
