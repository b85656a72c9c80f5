"""Checkpoints: after an accepted step (every one by default; see Schedule) each rank writes
the unknowns and the history state of its own dofs, keyed by position (dof coordinates, and
cell midpoints for the discontinuous history fields), to
checkpoint/state-<step>/part-<rank>.npz; rank 0 then writes checkpoint/meta.json (t, step,
scene hash, the parts and the bounding box of each part's positions) atomically and removes
the previous checkpoint's folder. No rank gathers the state of the whole mesh: every rank
writes O(dofs / ranks).

`contactvisco run ... --restart` continues from it on any partition and any rank count (the
partition of a mesh is not reproducible between runs): each rank reads only the parts whose
bounding box meets its own positions, and reaches the same answer as an uninterrupted run.
A checkpoint of the earlier single-file layout (checkpoint/state.npz) is read as one part.

A restart trusts nothing it reads: meta.json carries a SHA-256 of its own content and of every
part; each part repeats t and the step count; the arrays' shapes are checked against the
fields and each other. Anything that does not match stops the restart (SceneError, exit 2)
naming the file and what is wrong. The scene must equal the checkpoint's except in its
[output] table; a refused restart lists the keys that differ. The mesh must be the
checkpoint's (mesh_signature), a caller's mesh given to the Python interface included.
meta.json also keeps the length and SHA-256 of each record file at that step (the output
writer's record_state), which the restart checks (contactvisco.io.output.check_records).

With an [obstacle], each part also holds the obstacle's committed displacement d and the
position d_ref at which its normals and gaps were last evaluated (the same on every rank, like
the step times of a table kernel); the restart puts the obstacle back there, so a run under
force control, whose d is an unknown, continues from its own position. A checkpoint written
without them restarts a displacement-controlled obstacle (d follows from t) but not a
force-controlled one."""
from __future__ import annotations

import hashlib
import io
import json
import pathlib
import shutil
import time

import numpy as np

from contactvisco.fem import compat
from contactvisco.errors import SceneError
from contactvisco.io import files
from contactvisco.io.files import Damaged  # noqa: F401 - raised here, named by the CLI

META = "meta.json"
LEGACY = "state.npz"


def scene_hash(scene: dict) -> str:
    from contactvisco.io.output import jsonable
    return hashlib.sha1(json.dumps(jsonable(scene), sort_keys=True).encode()).hexdigest()[:16]


#: Scene tables a restart may change: they decide what is written, not what is solved.
FREE = ("output",)


def scene_values(scene: dict) -> dict:
    """The scene as flat {"table.key": value} (JSON values), without the FREE tables; with
    time.times_file, a digest of the grid its times make."""
    from contactvisco.io.output import jsonable
    flat = {}

    def walk(prefix, value):
        if isinstance(value, dict) and value:
            for key, item in value.items():
                walk(f"{prefix}.{key}" if prefix else str(key), item)
        else:
            flat[prefix] = value
    walk("", jsonable({k: v for k, v in scene.items() if k not in FREE}))
    time = scene.get("time")
    if isinstance(time, dict) and time.get("times_file") is not None:
        # the file's times make the grid: a restart steps on the same grid or is refused
        from contactvisco.model import time_grid
        grid = np.asarray(time_grid.times(time), dtype="<f8").tobytes()
        flat["time.times_file (its times)"] = _digest(grid)[:16]
    return json.loads(json.dumps(flat))         # tuples as lists, as read back from JSON


def _items_flat(values: dict) -> dict:
    """{"table.key": value} with the lists of tables ([[body]], [[dirichlet]]) written out
    item by item ("body.0.material.E"), so that a difference names the key inside an item."""
    flat = {}

    def walk(prefix, value):
        if isinstance(value, dict) and value:
            for key, item in value.items():
                walk(f"{prefix}.{key}", item)
        elif isinstance(value, list) and value and all(isinstance(v, dict) for v in value):
            for j, item in enumerate(value):
                walk(f"{prefix}.{j}", item)
        else:
            flat[prefix] = value
    for key, value in values.items():
        walk(key, value)
    return flat


def scene_difference(saved: dict, scene: dict) -> list[str]:
    """The keys whose values differ, 'key: saved -> now' (inside the items of a list of
    tables: body.0.material.E)."""
    saved, now = _items_flat(saved), _items_flat(scene_values(scene))
    return [f"{key}: {saved.get(key, '(absent)')!r} -> {now.get(key, '(absent)')!r}"
            for key in sorted(set(saved) | set(now)) if saved.get(key) != now.get(key)]


def _digest(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def _meta_digest(meta: dict) -> str:
    """SHA-256 of meta.json's content without its own checksum."""
    body = {k: v for k, v in meta.items() if k != "sha256"}
    return _digest(json.dumps(body, sort_keys=True).encode())


def _keys(space):
    """A position key per local dof block (owned first, then ghosts): its coordinates, and for
    a discontinuous space also the midpoint of its cell."""
    from dolfinx.mesh import compute_midpoints
    coords = space.tabulate_dof_coordinates()
    if not compat.is_discontinuous(space):
        return coords
    mesh = space.mesh
    tdim = mesh.topology.dim
    n_cells = mesh.topology.index_map(tdim).size_local + mesh.topology.index_map(tdim).num_ghosts
    cell_of = np.empty(len(coords), dtype=np.int32)
    dofs = compat.cell_dofs(space.dofmap)
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
    u_previous = problem.contact and problem.contact.u_previous   # the slip's origin
    if u_previous is not None:
        out.append(("u_previous", problem.V, u_previous.x.array))
    if problem.memory is not None:
        out += [(f"history_{key}", problem.tensor_space, value)
                for key, value in problem.memory.history.state().items()]
    obstacle = problem.contact and problem.contact.obstacle
    if obstacle is not None:
        out += [(name, None, value) for name, value in obstacle_state(obstacle).items()]
    return out


def obstacle_state(obstacle) -> dict:
    """The obstacle's arrays of a checkpoint: ``obstacle_displacement``, its displacement d
    at the committed state, and ``obstacle_reference``, the position d_ref at which its normal
    and gap were evaluated (shape (dim,) each; the same on every rank).

    Parameters
    ----------
    obstacle : contactvisco.fem.obstacle.ObstaclePart
        The problem's obstacle.

    Returns
    -------
    dict
        name -> numpy.ndarray: d and d_ref, the state ``restore_obstacle`` puts back;
        empty for another body of the mesh as the obstacle (obstacle.shape = "body"), whose
        displacement D = Pi u follows from the restored unknowns.
    """
    if not obstacle.rigid:
        return {}
    return {"obstacle_displacement": obstacle.displacement(),
            "obstacle_reference": np.asarray(obstacle.reference.value, float).copy()}


def _global(name: str) -> bool:
    """Arrays that are the same on every rank (the table kernel's step times, the obstacle's
    position), not per dof."""
    return name.startswith(("history_times", "obstacle_"))


def _box(coordinates: np.ndarray):
    """[lower, upper] of a set of points, or None for none."""
    if len(coordinates) == 0:
        return None
    return [coordinates.min(axis=0).tolist(), coordinates.max(axis=0).tolist()]


class Schedule:
    """When a run writes its checkpoint ([output] checkpoint_every, checkpoint_seconds): after
    the steps whose number (the record's "step": accepted states, the halves of a cut step
    included) is a multiple of `every`; or, when `seconds` > 0 (then `every` is not used),
    after the first step that ends at least `seconds` of wall time after the last checkpoint
    (or after the start of the time loop); and always after the final state. The wall-time
    decision is rank 0's, broadcast: every rank writes the same checkpoints (save is
    collective)."""

    def __init__(self, comm, every: int = 1, seconds: float = 0.0, clock=time.monotonic):
        self.comm, self.every, self.seconds, self.clock = comm, every, seconds, clock
        self.last = clock()

    def due(self, step: int, final: bool = False) -> bool:
        """Whether the state after record `step` gets a checkpoint (collective when
        `seconds` > 0 and not final)."""
        if final:
            return True
        if self.seconds > 0:
            late = self.clock() - self.last >= self.seconds
            return bool(self.comm.bcast(late, root=0)) if self.comm.size > 1 else late
        return step % self.every == 0

    def written(self):
        """A checkpoint was written now: the wall-time interval starts again."""
        self.last = self.clock()


def mesh_signature(problem, comm) -> dict:
    """What identifies the mesh whatever its partition (collective): the global numbers of
    cells and of displacement nodes, and per coordinate the sum and the sum of squares of
    the nodes' positions (equal up to rounding on any rank count)."""
    from mpi4py import MPI
    mesh = problem.geometry.mesh
    tdim = mesh.topology.dim
    imap = problem.V.dofmap.index_map
    x = problem.V.tabulate_dof_coordinates()[:imap.size_local]
    sums = comm.allreduce(np.concatenate([x.sum(axis=0), (x * x).sum(axis=0)]), op=MPI.SUM)
    return {"cells": int(mesh.topology.index_map(tdim).size_global),
            "nodes": int(imap.size_global), "moments": [float(v) for v in sums]}


def _check_mesh(saved: dict | None, now: dict):
    """Refuse a restart onto a mesh other than the checkpoint's (any rank count)."""
    if not saved:
        return                          # a checkpoint written before meshes were recorded
    differ = [f"{key}: {saved.get(key)} -> {now[key]}" for key in ("cells", "nodes")
              if saved.get(key) != now[key]]
    moments = np.asarray(saved.get("moments", []), dtype=float)
    scale = max(1.0, float(np.max(np.abs(now["moments"]))))
    if not differ and (moments.shape != (len(now["moments"]),) or np.max(
            np.abs(moments - now["moments"])) > 1e-9 * scale):
        differ.append("node positions (their sums and sums of squares) differ")
    if differ:
        raise SceneError("--restart: the mesh differs from the one of the checkpoint (a "
                         "restart continues the same mesh, on any rank count): "
                         + "; ".join(differ))


def save(folder, problem, comm, t: float, count: int, step: float | None,
         records: dict | None = None, durable: bool = True):
    """Write the state after `count` accepted steps (collective: every rank calls it).
    `records` (rank 0): the output writer's record_state(), kept in meta.json for the
    restart's check of the record files (contactvisco.io.output.check_records). durable:
    the files are synced to the disk (files.replace_with); the time loop syncs the last
    checkpoint of a run and the one of a stop only, like its record files (a kill of the
    process loses no step either way; only a power loss could take the unsynced ones)."""
    root = pathlib.Path(folder) / "checkpoint"
    folder_name = f"state-{count:06d}"
    here = root / folder_name
    if comm.rank == 0:
        if files.what(here) == "a directory":   # left by a run killed before its meta
            shutil.rmtree(here)
        elif files.what(here) is not None:       # a link or file planted there: removed
            here.unlink()
        here.mkdir(parents=True)
    comm.barrier()
    here.mkdir(parents=True, exist_ok=True)   # no reliance on another node's directory cache
    part, points, names = {}, [], []
    for field, space, array in _fields(problem):
        names.append(field)
        if _global(field):
            part[field] = array
            continue
        n = space.dofmap.index_map.size_local
        keys = _cached_keys(problem, space)
        bs = array.size // len(keys)
        part[field + ".keys"] = keys[:n]
        part[field] = array.reshape(-1, bs)[:n]
        points.append(keys[:n, :3])
    part["t"], part["count"] = np.float64(t), np.int64(count)
    buffer = io.BytesIO()
    np.savez(buffer, **part)
    data = buffer.getvalue()
    if files.what(here) != "a directory":     # made a link by someone else meanwhile
        raise files.refusal(here, files.what(here) or "absent", "the checkpoint folder (a directory)")
    files.replace(here / f"part-{comm.rank}.npz", data, tmp=here / f"part-{comm.rank}.tmp.npz",
                  durable=durable)
    cache = problem.__dict__.setdefault("_checkpoint_keys", {})
    if "box" not in cache:             # the positions never change during a run
        cache["box"] = _box(np.concatenate(points)) if points else None
        cache["scene"] = scene_values(problem.scene)
        cache["mesh"] = mesh_signature(problem, comm)
    parts = comm.gather((cache["box"], _digest(data), len(data)), root=0)
    if comm.rank == 0:                 # every part is complete once rank 0 has every box
        meta = {"t": t, "count": count, "step": step, "ranks": comm.size,
                "scene_values": cache["scene"], "mesh": cache["mesh"], "fields": names,
                "parts": [{"file": f"{folder_name}/part-{rank}.npz", "box": box,
                           "sha256": digest, "bytes": size}
                          for rank, (box, digest, size) in enumerate(parts)]}
        if records is not None:
            meta["records"] = records
        meta["sha256"] = _meta_digest(meta)
        # The checkpoint of step `count` is the one once meta.json is replaced.
        files.replace(root / META, json.dumps(meta), tmp=root / "meta.tmp.json",
                      durable=durable)
        for old in root.iterdir():
            if old.name != folder_name and old.name.startswith("state-") and \
                    files.what(old) == "a directory":      # a link is not followed
                shutil.rmtree(old, ignore_errors=True)
        (root / LEGACY).unlink(missing_ok=True)
    comm.barrier()


def _read_meta(root: pathlib.Path) -> dict:
    if files.what(root / META) is not None:
        return _checked_meta(root / META)
    if files.what(root / LEGACY) is not None:   # one file holding every dof, from rank 0
        data = np.load(io.BytesIO(files.read_bytes(root / LEGACY)))
        meta = json.loads(str(data["meta"]))
        meta["fields"] = [f for f in data.files if f != "meta" and not f.endswith(".keys")]
        meta["parts"] = [{"file": LEGACY, "box": None}]
        return meta
    raise SceneError(f"--restart: no checkpoint in {root.parent}")


def _checked_meta(path: pathlib.Path) -> dict:
    """meta.json, its checksum and structure verified."""
    def bad(what):
        return Damaged(f"--restart: checkpoint {path}: {what}")
    try:
        meta = json.loads(files.read_bytes(path, 64 * 2**20))
    except (ValueError, UnicodeDecodeError, RecursionError) as err:
        raise bad(f"not valid JSON ({type(err).__name__})") from None
    if not isinstance(meta, dict):
        raise bad("not a JSON object")
    # A checkpoint without its checksum cannot be told from an edited one: refused alike.
    if not isinstance(meta.get("sha256"), str):
        raise bad("no checksum ('sha256'): the file was edited or damaged, or written without "
                  "one; restart from another checkpoint or run again without --restart")
    if meta["sha256"] != _meta_digest(meta):
        raise bad("checksum mismatch: the file was edited or damaged")
    types = {"t": (int, float), "count": int, "ranks": int, "fields": list, "parts": list}
    for key, kind in types.items():
        if not isinstance(meta.get(key), kind) or isinstance(meta.get(key), bool):
            raise bad(f"'{key}' is missing or not a {getattr(kind, '__name__', 'number')}")
    if meta["count"] < 1 or not np.isfinite(meta["t"]) or meta["t"] < 0:
        raise bad(f"impossible t = {meta['t']} or count = {meta['count']}")
    if len(meta["parts"]) != meta["ranks"]:
        raise bad(f"{len(meta['parts'])} parts for {meta['ranks']} ranks")
    records = meta.get("records")
    if records is not None and not (isinstance(records, dict) and all(
            name in ("steps.jsonl", "contact_nodes.csv", "solution.xdmf",
                     "interface_nodes.csv", "interface_master.csv")
            and isinstance(entry, dict) and isinstance(entry.get("bytes"), int)
            and entry["bytes"] >= 0 and isinstance(entry.get("sha256"), str)
            for name, entry in records.items())):
        raise bad("'records' is not the record files' lengths and checksums")
    return meta


def _checked_part(root: pathlib.Path, entry: dict, meta: dict):
    """One part (npz), verified against its checksum, meta's t and count, and the fields."""
    path = root / entry["file"]
    if pathlib.Path(entry["file"]).is_absolute() or ".." in pathlib.Path(entry["file"]).parts:
        raise Damaged(f"--restart: checkpoint {root / META}: part path '{entry['file']}' "
                      "leaves the checkpoint folder")

    def bad(what):
        return Damaged(f"--restart: checkpoint {path}: {what}")
    try:
        data = files.read_bytes(path)
    except OSError as err:
        raise bad(f"cannot be read ({err.strerror})") from None
    if not isinstance(entry.get("sha256"), str):
        raise bad("no checksum in meta.json for this part: the checkpoint was edited or "
                  "damaged, or written without one")
    if _digest(data) != entry["sha256"]:
        raise bad(f"checksum mismatch ({len(data)} bytes, {entry.get('bytes')} written): "
                  "the file was edited or damaged")
    try:
        npz = np.load(io.BytesIO(data))
        arrays = {name: npz[name] for name in npz.files}
    except Exception as err:          # any failure to parse is a damaged file
        raise bad(f"not a readable .npz ({type(err).__name__})") from None
    if "t" in arrays and (float(arrays["t"]) != meta["t"] or
                          int(arrays["count"]) != meta["count"]):
        raise bad(f"written at t = {float(arrays['t']):g}, step count {int(arrays['count'])}; "
                  f"meta.json says t = {meta['t']:g}, count {meta['count']}")
    for name in meta["fields"]:
        if name not in arrays:
            raise bad(f"no array '{name}' (meta.json lists it)")
        if _global(name):
            continue
        keys, values = arrays.get(name + ".keys"), arrays[name]
        if keys is None or keys.ndim != 2 or len(keys) != len(values) or \
                not np.all(np.isfinite(values)):
            raise bad(f"array '{name}' has shape {values.shape} for "
                      f"{None if keys is None else keys.shape} positions, or non-finite "
                      "values")
    return arrays


def _match(want: np.ndarray, have: np.ndarray) -> np.ndarray:
    """For each row of `want`, the index of the equal row of `have`, or -1 (rows are integer
    position keys; sorted search, O((n + m) log m))."""
    if len(have) == 0:
        return np.full(len(want), -1)
    row = np.dtype([(f"c{i}", np.int64) for i in range(have.shape[1])])
    have_rows = np.ascontiguousarray(have).view(row).ravel()
    want_rows = np.ascontiguousarray(want).view(row).ravel()
    order = np.argsort(have_rows)
    ordered = have_rows[order]
    at = np.minimum(np.searchsorted(ordered, want_rows), len(ordered) - 1)
    return np.where(ordered[at] == want_rows, order[at], -1)


def load(folder, problem, comm) -> dict:
    """Restore the unknowns, the history and the committed time; return the meta (t, count,
    step). Collective: a check that fails on one rank stops every rank with the same error."""
    root = pathlib.Path(folder) / "checkpoint"
    meta = _read_meta(root)
    _check_scene(meta, problem.scene)
    _check_mesh(meta.get("mesh"), mesh_signature(problem, comm))
    scale = 1e-9 * problem.length_scale
    # The unknowns, then the history arrays the checkpoint holds (a fresh history has none).
    fields = [(name, space, array) for name, space, array in _fields(problem)
              if name.startswith("unknown") or name == "u_previous"]
    fields += [(name, problem.tensor_space, None) for name in meta["fields"]
               if name.startswith("history_")]
    mine = {name: _keys(space) for name, space, _ in fields if not _global(name)}
    parts = _parts_near(meta["parts"], mine, scale)
    data, first = _read_parts(root, parts, meta, comm)
    state = _restore(fields, mine, data, first, scale, comm)
    if problem.memory is not None:
        problem.memory.history.restore(state)
    restore_obstacle(problem, meta, first)
    problem.time.committed = meta["t"]
    return meta


def restore_obstacle(problem, meta: dict, first) -> None:
    """Put the obstacle back where the checkpoint left it: its normal and gap evaluated at
    d_ref, its displacement d, and d as the committed position (the next step's first
    guess of a force-controlled component and the origin of its slip). A checkpoint without
    the obstacle's arrays (written before they were kept) restores nothing: right for a
    displacement-controlled obstacle, whose d follows from t; refused for a force-controlled
    one (SceneError naming obstacle.force_components).

    Parameters
    ----------
    problem : contactvisco.fem.problem.Problem
        The problem being restarted.
    meta : dict
        The checkpoint's meta.json (its ``fields``).
    first : mapping
        The arrays of the checkpoint's first part (the obstacle's are the same in every part).
    """
    obstacle = problem.contact and problem.contact.obstacle
    if obstacle is None:
        return
    if not obstacle.rigid:                                # the master body: D = Pi u
        obstacle.follow(problem.u)
        return
    names = ("obstacle_displacement", "obstacle_reference")
    if not all(name in meta["fields"] for name in names):
        if obstacle.controlled:
            raise SceneError("obstacle.force_components: the checkpoint holds no position of "
                             "the obstacle (it was written before checkpoints kept one), and "
                             "under force control the position is an unknown; run it from "
                             "t = 0", key="obstacle.force_components")
        return
    d, reference = (np.asarray(first[name], float) for name in names)
    if d.shape != (obstacle.dim,) or reference.shape != (obstacle.dim,) or \
            not np.all(np.isfinite(d)) or not np.all(np.isfinite(reference)):
        raise Damaged(f"--restart: checkpoint {meta['parts'][0]['file']}: the obstacle's "
                      f"position has shape {d.shape} and {reference.shape} (want "
                      f"({obstacle.dim},)) or non-finite values")
    obstacle.place(reference)
    obstacle.set_displacement(d)
    obstacle.committed = d.copy()


def _check_scene(meta: dict, scene: dict):
    """Refuse a restart whose scene differs from the checkpoint's outside [output], listing
    the keys that differ (a checkpoint with only a scene hash: that the hashes differ)."""
    if "scene_values" in meta:
        differ = scene_difference(meta["scene_values"], scene)
        if differ:
            raise SceneError("--restart: the scene differs from the one of the checkpoint "
                             "(only [output] may change): " + "; ".join(differ))
    elif meta.get("scene") != scene_hash(scene):
        raise SceneError("--restart: the scene differs from the one of the checkpoint")


def _parts_near(entries: list[dict], mine: dict, scale: float) -> list[dict]:
    """The entries of meta["parts"] whose box meets, within 2 `scale`, the box of this
    rank's positions `mine`: only they can hold this rank's values."""
    box = _box(np.concatenate([k[:, :3] for k in mine.values()])) if mine else None
    tol = 2 * scale
    return [p for p in entries if p["box"] is None or (
        box is not None and np.all(np.array(p["box"][0]) <= np.array(box[1]) + tol)
        and np.all(np.array(box[0]) <= np.array(p["box"][1]) + tol))]


def _read_parts(root: pathlib.Path, parts: list[dict], meta: dict, comm):
    """The arrays of the parts this rank reads, and of the first part (it holds the arrays
    that are the same on every rank). Each rank checks the parts it reads; a damaged one
    stops every rank (collective)."""
    def read(entry):
        return (_checked_part(root, entry, meta) if entry["file"] != LEGACY
                else np.load(io.BytesIO(files.read_bytes(root / LEGACY))))
    error = data = first = None
    try:
        data = [read(p) for p in parts]
        first = data[0] if parts and parts[0] is meta["parts"][0] else read(meta["parts"][0])
    except SceneError as err:          # Damaged, or files.UnsafeEntry (a link, a FIFO)
        error = str(err)
    error = next((e for e in comm.allgather(error) if e is not None), None)
    if error is not None:
        raise Damaged(error)
    return data, first


def _restore(fields: list, mine: dict, data: list, first, scale: float, comm) -> dict:
    """Copy into each field the values at its positions, matched to the positions of the
    parts read rounded to `scale`; return the history state. A position no part holds stops
    every rank (collective)."""
    def integer_key(positions):
        return np.round(positions / scale).astype(np.int64)

    state, missing = {}, None
    for name, space, array in fields:
        if _global(name):
            state[name[len("history_"):]] = first[name]
            continue
        want = mine[name]
        have_keys = [part[name + ".keys"] for part in data] or [np.zeros((0, want.shape[1]))]
        have_values = [part[name] for part in data] or [np.zeros(0)]
        rows = _match(integer_key(want), integer_key(np.concatenate(have_keys)))
        if np.any(rows < 0):
            missing = missing or (name, want[np.argmin(rows)][:3].tolist())
            continue
        values = np.concatenate(have_values)[rows].ravel()
        if array is not None:
            array[:] = values
        else:
            state[name[len("history_"):]] = values
    missing = next((m for m in comm.allgather(missing) if m is not None), None)
    if missing is not None:      # on every rank, so that none waits for the others
        raise SceneError(f"--restart: the checkpoint has no value of '{missing[0]}' at "
                         f"{missing[1]}: was it written for another mesh?")
    return state
