"""Checkpoints: after every accepted step the unknowns and the history state are gathered by
position (dof coordinates, and cell midpoints for the discontinuous history fields) into
checkpoint/state.npz with its meta (t, step, scene hash), written atomically by rank 0.
`contactvisco run ... --restart` continues from it on any partition (the partition of a mesh
is not reproducible between runs), and reaches the same answer as an uninterrupted run."""
from __future__ import annotations

import hashlib
import json
import os
import pathlib

import numpy as np

from .scene import SceneError


def scene_hash(scene: dict) -> str:
    from .output import jsonable
    return hashlib.sha1(json.dumps(jsonable(scene), sort_keys=True).encode()).hexdigest()[:16]


def _keys(space):
    """A position key per local dof block (owned first, then ghosts): its coordinates, and for
    a discontinuous space also the midpoint of its cell."""
    from dolfinx.mesh import compute_midpoints
    coords = space.tabulate_dof_coordinates()
    if space.ufl_element().family() not in ("Discontinuous Lagrange", "DG", "DQ"):
        return coords
    mesh = space.mesh
    tdim = mesh.topology.dim
    n_cells = mesh.topology.index_map(tdim).size_local + mesh.topology.index_map(tdim).num_ghosts
    cell_of = np.empty(len(coords), dtype=np.int32)
    dofs = space.dofmap.list.array.reshape(n_cells, -1)
    cell_of[dofs] = np.arange(n_cells, dtype=np.int32)[:, None]
    return np.hstack([coords, compute_midpoints(mesh, tdim, cell_of)])


def _cached_keys(problem, space):
    """_keys(space), computed once per problem (they never change during a run)."""
    cache = problem.__dict__.setdefault("_checkpoint_keys", {})
    if id(space) not in cache:
        cache[id(space)] = (space, _keys(space))   # the space is kept, so its id stays its own
    return cache[id(space)][1]


def _fields(problem):
    """(name, space, local array view) of everything a restart needs."""
    out = [(f"unknown{i}", f.function_space, f.x.array) for i, f in enumerate(problem.unknowns)]
    if problem.history is not None:
        out += [(f"history_{key}", problem.T, value)
                for key, value in problem.history.state().items()]
    return out


def save(folder, problem, comm, t: float, count: int, step: float | None):
    folder = pathlib.Path(folder) / "checkpoint"
    gathered = {}
    for name, space, array in _fields(problem):
        if name.startswith("history_times"):       # table kernel: the same on every rank
            gathered[name] = array
            continue
        n = space.dofmap.index_map.size_local
        bs = array.size // len(space.tabulate_dof_coordinates())
        parts = comm.gather((_cached_keys(problem, space)[:n], array.reshape(-1, bs)[:n]),
                            root=0)
        if comm.rank == 0:
            gathered[name + ".keys"] = np.concatenate([p[0] for p in parts])
            gathered[name] = np.concatenate([p[1] for p in parts])
    if comm.rank == 0:
        folder.mkdir(parents=True, exist_ok=True)
        meta = {"t": t, "count": count, "step": step, "ranks": comm.size,
                "scene": scene_hash(problem.scene)}
        tmp = folder / "state.tmp.npz"
        np.savez(tmp, meta=json.dumps(meta), **gathered)
        os.replace(tmp, folder / "state.npz")
    comm.barrier()


def load(folder, problem, comm) -> dict:
    """Restore the unknowns and the history; return the meta (t, count, step)."""
    path = pathlib.Path(folder) / "checkpoint" / "state.npz"
    if not path.exists():
        raise SceneError(f"--restart: no checkpoint in {pathlib.Path(folder)}")
    data = np.load(path)
    meta = json.loads(str(data["meta"]))
    if meta["scene"] != scene_hash(problem.scene):
        raise SceneError("--restart: the scene differs from the one of the checkpoint")
    scale = 1e-9 * problem.length_scale
    state = {}
    # The unknowns, then the history arrays the file holds (a fresh history has none yet).
    fields = [(name, space, array) for name, space, array in _fields(problem)
              if name.startswith("unknown")]
    fields += [(name, problem.T, None) for name in data.files
               if name.startswith("history_") and not name.endswith(".keys")]
    for name, space, array in fields:
        if name.startswith("history_times"):
            state[name[len("history_"):]] = data[name]
            continue
        lookup = {tuple(k): i for i, k in enumerate(np.round(data[name + ".keys"] / scale))}
        keys = np.round(_keys(space) / scale)
        rows = np.array([lookup[tuple(k)] for k in keys])
        values = data[name][rows].ravel()
        if name.startswith("unknown"):
            array[:] = values
        else:
            state[name[len("history_"):]] = values
    if problem.history is not None:
        problem.history.restore(state)
    return meta
