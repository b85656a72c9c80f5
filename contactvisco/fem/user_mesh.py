"""A caller's own DOLFINx mesh, its facet tags and {boundary name: tag}, checked against the
scene that will run on it (the `mesh=` route of contactvisco.solve)."""
from __future__ import annotations

import numbers

from mpi4py import MPI

from contactvisco.errors import SceneError
from contactvisco.fem.geometry import Geometry, check_cells, check_probes
from contactvisco.model.material import dimension


def scene_boundaries(scene: dict) -> dict[str, str]:
    """The boundary names a scene uses: name -> the first key that names it."""
    used = {}
    for key in ("dirichlet", "traction"):
        for i, item in enumerate(scene[key]):
            used.setdefault(item["boundary"], f"{key}[{i}].boundary")
    contact = scene["contact"]
    if contact is not None:
        names = contact["boundary"]
        for name in [names] if isinstance(names, str) else names:
            used.setdefault(name, "contact.boundary")
    return used


def from_mesh(scene: dict, mesh, facet_tags, boundaries) -> Geometry:
    """A Geometry from a caller's mesh, facet meshtags and {name: tag}, checked against the
    scene: dimension, facet dimension, every boundary name the scene uses, every tag present
    on some rank, probes inside the mesh."""
    if mesh is None or facet_tags is None or boundaries is None:
        raise SceneError("solve: a mesh needs all three of mesh, facet_tags and boundaries "
                         "(a dict {boundary name: facet tag value})")
    d = dimension(scene)
    if mesh.geometry.dim != d or mesh.topology.dim != d:
        raise SceneError(f"solve: material.model = '{scene['material']['model']}' needs a "
                         f"{d}D mesh; this mesh has topological dimension "
                         f"{mesh.topology.dim} in {mesh.geometry.dim}D")
    if facet_tags.dim != d - 1:
        raise SceneError(f"solve: facet_tags must tag facets (dimension {d - 1}); these tag "
                         f"entities of dimension {facet_tags.dim}")
    if not isinstance(boundaries, dict) or not all(
            isinstance(k, str) and isinstance(v, numbers.Integral) and not isinstance(v, bool)
            for k, v in boundaries.items()):
        raise SceneError(f"solve: boundaries must map names to integer tag values, got "
                         f"{boundaries!r}")
    missing = {name: key for name, key in scene_boundaries(scene).items()
               if name not in boundaries}
    if missing:
        name, key = next(iter(missing.items()))
        raise SceneError(f"{key}: no boundary named '{name}' in solve(boundaries=...); it "
                         f"has {', '.join(sorted(boundaries)) or 'none'}", key=key)
    present = set(int(v) for v in facet_tags.values)
    for name, tag in sorted(boundaries.items()):
        if not mesh.comm.allreduce(int(tag) in present, MPI.LOR):
            raise SceneError(f"solve: boundaries['{name}'] = {tag} tags no facet of the mesh "
                             f"(the tag values are "
                             f"{sorted(set().union(*mesh.comm.allgather(present)))})")
    check_cells(mesh, "solve(mesh=...)")
    geometry = Geometry(mesh, facet_tags,
                        {name: int(tag) for name, tag in boundaries.items()})
    check_probes(mesh, scene["output"]["probes"])
    return geometry
