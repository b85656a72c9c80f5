"""What a run leaves behind: summary.json + steps.jsonl, contact_nodes.csv and XDMF (the
contact table itself is computed in contactvisco.fem.contact_state).

Everything is gathered by owned dofs and coordinates, so the output does not depend on the rank
count (dof numbering does). Files are written step by step: a run that stops early leaves
readable output for the steps it finished.

Who writes what, per step: every rank writes its own part of solution/step-<n>.h5 (DOLFINx
XDMFFile, MPI-IO HDF5); rank 0 appends to solution.xdmf, steps.jsonl and contact_nodes.csv,
O(contact nodes + probes) per step, from tables that were allgathered (O(contact nodes) per
rank). Only the figure
snapshots (gather_mesh, at output.figure_times and T) copy the whole mesh to rank 0, and they
are skipped above output.snapshot_max_nodes.
"""
from __future__ import annotations

import csv
import io as io_module
import json
import math
import os
import pathlib

import numpy as np
from dolfinx import fem, io

from contactvisco.fem import compat
from contactvisco.fem.contact_state import STATUSES, STICK_SLIP_STATES, status_at_nodes

class Writer:
    """summary.json, steps.jsonl, contact_nodes.csv and solution.xdmf in one output folder.

    Every file is consistent after a hard stop (kill -9) at any moment: the per-step records
    are appended and flushed (a cut last line is ignored by read_summary), the fields of step
    n go to solution/step-n.h5 (closed before the step is listed), and solution.xdmf lists a
    step only once its file is complete (xdmf_index). Per step the work is O(1) in the number of
    steps: nothing already written is rewritten.

    One class for the four files because their consistency is one guarantee: a restart cuts
    all of them back to the same step (restart_count), which a writer per file could not do
    without sharing that state."""

    def __init__(self, folder, problem, comm, xdmf=True, restart_count=None):
        """restart_count: continue the files of an earlier run after its first
        restart_count steps (what a later stop may have written beyond them is dropped)."""
        self.folder = pathlib.Path(folder)
        self.comm = comm
        self.rank = comm.rank
        self.mesh = problem.geometry.mesh
        if self.rank == 0:
            self.folder.mkdir(parents=True, exist_ok=True)
        comm.barrier()
        self.summary = {"scene": problem.scene, "unknowns": problem.count_unknowns(),
                        "ranks": comm.size, "steps_file": STEPS_FILE, "final": None}
        self.steps_written = 0
        self.last_record = None
        kept_steps = []
        if restart_count is not None:
            earlier = read_summary(self.folder)
            kept_steps = earlier["steps"][:restart_count]
            self.summary["restarts"] = earlier.get("restarts", []) + [
                {"from_step": restart_count}]
            for key in ("notes", "warnings"):
                if key in earlier:
                    self.summary[key] = earlier[key]
            self.last_record = kept_steps[-1] if kept_steps else None
        self.steps_written = len(kept_steps)
        self.csv = self.steps_file = self.index = None
        if self.rank == 0:
            # Restart: the records are cut to the checkpoint once (O(N) once per restart).
            path = self.folder / STEPS_FILE
            _rewrite(path, "".join(json.dumps(jsonable(record), allow_nan=False) + "\n"
                                   for record in kept_steps))
            self.steps_file = open(path, "a")
            self._write_summary()
        if self.rank == 0 and problem.contact is not None:
            self._start_csv(problem.geometry.mesh.geometry.dim, restart_count)
        self.xdmf = None
        if xdmf:
            self.xdmf = self.folder / SOLUTION_DIR
            if self.rank == 0:
                self.xdmf.mkdir(exist_ok=True)
                if restart_count is not None:
                    self._drop_fields_from(restart_count)
                self.index = XdmfIndex(self.folder / "solution.xdmf", self.xdmf,
                                       restart_count or 0)
            comm.barrier()
        self._writable = {}                # P1/DG0 copies of higher-degree fields (xdmf_field)

    def _drop_fields_from(self, count: int):
        """Rank 0, on a restart: remove the field files of steps >= count, written after the
        checkpoint by the stopped run. The restart writes those steps again where its
        schedule asks for them; a file it does not write would otherwise stay, unlisted, and
        be listed by a later restart (XdmfIndex takes every file before its count)."""
        for path in self.xdmf.glob("step-*.*"):
            number = path.name[len("step-"):].split(".", 1)[0]
            if number.isdigit() and int(number) >= count and path.suffix in (".xdmf", ".h5"):
                path.unlink(missing_ok=True)

    def _start_csv(self, d: int, restart_count: int | None):
        """Rank 0: contact_nodes.csv with its header and, on a restart, the rows of the
        first restart_count steps (a row cut by a stop is dropped), opened for appending."""
        header = ["step", "t"] + ["xyz"[i] for i in range(d)] + [
            "u_nu", "gap", "u_tau", "reaction_nu", "reaction_tau", "friction_bound",
            "status", "friction"]
        path = self.folder / "contact_nodes.csv"
        kept = []
        if restart_count is not None and path.exists():
            with open(path, newline="") as f:
                kept = [row for row in list(csv.reader(f))[1:]
                        if len(row) == len(header) and int(row[0]) < restart_count]
        text = io_module.StringIO()
        writer = csv.writer(text)
        writer.writerow(header)
        writer.writerows(kept)
        _rewrite(path, text.getvalue())
        self.csv_file = open(path, "a", newline="")
        self.csv = csv.writer(self.csv_file)

    def step(self, record: dict, table, fields=()):
        """Write step record["step"]: its fields (none: the step has no XDMF entry; the
        caller's schedule decides), contact-node rows, then its record."""
        n = record["step"]
        if self.xdmf is not None and fields:
            # A file per step, closed before the index lists it: a stop while it is being
            # written never touches the steps before it.
            name = self.xdmf / f"step-{n:06d}.xdmf"
            with io.XDMFFile(self.comm, str(name), "w") as f:
                f.write_mesh(self.mesh)
                for field in fields:
                    f.write_function(xdmf_field(field, self._writable), record["t"])
        self.steps_written = n + 1
        self.last_record = record
        if self.rank != 0:
            return
        if self.csv is not None and table is not None:
            for i in range(len(table["u_nu"])):
                self.csv.writerow([n, repr(record["t"])]
                                  + [repr(float(c)) for c in table["x"][i]]
                                  + [repr(float(table[key][i])) for key in
                                     ("u_nu", "gap", "u_tau", "reaction_nu", "reaction_tau",
                                      "radius")]
                                  + [STATUSES[table["status"][i]],
                                     STICK_SLIP_STATES[table["friction"][i]]])
            self.csv_file.flush()
        if self.index is not None and fields:
            self.index.append(n, record["t"])
        # One line, written whole and flushed: a stop leaves whole lines (and at most a cut
        # last one, which read_summary drops).
        self.steps_file.write(json.dumps(jsonable(record), allow_nan=False) + "\n")
        self.steps_file.flush()

    def note(self, key: str, text: str):
        """Add a note or warning to summary.json (rewritten: it is small)."""
        items = self.summary.setdefault(key, [])
        if text not in items:
            items.append(text)
        if self.rank == 0:
            self._write_summary()

    def finish(self, final: dict):
        self.summary["final"] = final
        self.close()
        if self.rank == 0:
            self._write_summary()

    def close(self):
        """Close the files (idempotent); what was written stays valid."""
        if self.rank != 0:
            return
        if self.index is not None:
            self.index.close()
        for f in (self.csv is not None and self.csv_file, self.steps_file):
            if f and not f.closed:
                f.flush()
                os.fsync(f.fileno())
                f.close()

    def _write_summary(self):
        _rewrite(self.folder / "summary.json",
                 json.dumps(jsonable(self.summary), indent=1, allow_nan=False))


STEPS_FILE = "steps.jsonl"
SOLUTION_DIR = "solution"


def _rewrite(path: pathlib.Path, text: str):
    """Replace a file's content atomically (a stop leaves the old or the new file)."""
    tmp = path.with_name(path.name + ".tmp")
    with open(tmp, "w") as f:
        f.write(text)
        f.flush()
        os.fsync(f.fileno())
    os.replace(tmp, path)


def read_summary(folder) -> dict:
    """summary.json with "steps": the step records of steps.jsonl (a cut last line, left by
    a hard stop, is dropped). An earlier layout with the steps inside summary.json reads
    as it is."""
    folder = pathlib.Path(folder)
    summary = json.loads((folder / "summary.json").read_text())
    path = folder / summary.get("steps_file", STEPS_FILE)
    if "steps" not in summary:
        steps = []
        if path.exists():
            for line in path.read_text().split("\n"):
                try:
                    steps.append(json.loads(line))
                except ValueError:
                    break            # the last, cut line of a stopped run (or the end)
        summary["steps"] = steps
    return summary


class XdmfIndex:
    """solution.xdmf: one temporal collection whose step n is the mesh and fields of
    solution/step-n.xdmf. Appending a step overwrites only the closing tags at the end of the
    file with the new grid and the closing tags, in one write: O(1) per step, and the file is
    a complete XDMF document before and after that write."""

    HEAD = ('<?xml version="1.0"?>\n<Xdmf Version="3.0" '
            'xmlns:xi="http://www.w3.org/2001/XInclude">\n  <Domain>\n'
            '    <Grid Name="solution" GridType="Collection" CollectionType="Temporal">\n')
    TAIL = "    </Grid>\n  </Domain>\n</Xdmf>\n"

    def __init__(self, path: pathlib.Path, steps: pathlib.Path, keep: int):
        """Start the index with the first `keep` steps of the files in `steps`."""
        self.path, self.steps = path, steps
        body = "".join(self.entry(n) for n in range(keep)
                       if (steps / f"step-{n:06d}.xdmf").exists())
        _rewrite(path, self.HEAD + body + self.TAIL)
        self.fd = os.open(path, os.O_WRONLY)
        self.end = os.path.getsize(path) - len(self.TAIL)

    def entry(self, n: int, t=None) -> str:
        """The grid of step n, taken from solution/step-n.xdmf, its data paths made relative
        to solution.xdmf."""
        import xml.etree.ElementTree as ET
        name = f"step-{n:06d}"
        root = ET.parse(self.steps / f"{name}.xdmf").getroot()
        domain = root.find("Domain")
        mesh = domain.find("Grid[@GridType='Uniform']")
        grid = ET.Element("Grid", Name=f"step {n}", GridType="Uniform")
        for part in mesh:
            if part.tag in ("Topology", "Geometry"):
                grid.append(part)
        time_value = None
        for collection in domain.findall("Grid[@GridType='Collection']"):
            for uniform in collection.findall("Grid"):
                time_value = uniform.find("Time").get("Value")
                for attribute in uniform.findall("Attribute"):
                    grid.append(attribute)
        grid.insert(0, ET.Element("Time", Value=time_value if t is None else repr(t)))
        for item in grid.iter("DataItem"):
            item.text = f"{self.steps.name}/{item.text.strip()}"
        ET.indent(grid, space="  ", level=3)
        return "      " + ET.tostring(grid, encoding="unicode").rstrip() + "\n"

    def append(self, n: int, t: float):
        data = (self.entry(n, t) + self.TAIL).encode()
        written = os.pwrite(self.fd, data, self.end)
        if written != len(data):       # a full disk: put the old end back and fail
            os.pwrite(self.fd, self.TAIL.encode(), self.end)
            os.ftruncate(self.fd, self.end + len(self.TAIL))
            raise OSError(28, f"short write to {self.path}")
        self.end += len(data) - len(self.TAIL)

    def close(self):
        if getattr(self, "fd", None) is not None:
            os.fsync(self.fd)
            os.close(self.fd)
            self.fd = None

    def __del__(self):
        try:
            self.close()
        except OSError:
            pass


def jsonable(value):
    """value with non-finite floats as the strings "inf", "-inf", "nan" (strict JSON has
    none) and numpy scalars as Python numbers."""
    if isinstance(value, dict):
        return {k: jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [jsonable(v) for v in value]
    if isinstance(value, (np.integer, np.floating)):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return str(value)
    return value


#: The stress components written by output.fields = "stress_components", (i, j) of sigma.
COMPONENTS = {2: (("xx", 0, 0), ("yy", 1, 1), ("xy", 0, 1)),
              3: (("xx", 0, 0), ("yy", 1, 1), ("zz", 2, 2), ("xy", 0, 1), ("yz", 1, 2),
                  ("xz", 0, 2))}
#: The output.fields computed from sigma.
STRESS_FIELDS = ("sigma", "stress_components", "von_mises")


def derived_fields(names, problem, sigma, table, cache: dict) -> dict:
    """The fields of output.fields that are not unknowns of the problem, by field name, each a
    list of Functions named as ParaView shows them:
    "stress_components": sigma_xx, sigma_yy, sigma_xy (3D: and sigma_zz, sigma_yz, sigma_xz),
    scalar fields of sigma's (discontinuous) space; "von_mises": sqrt(3/2 s:s) at the same
    points (in 2D of the in-plane stress, sigma_zz taken as 0, as the figures);
    "contact_status": a P1 scalar on the vertices, the contact table's status (0 separated,
    1 compliance, 2 bound) on Gamma_C and 0 elsewhere (none without contact).
    `sigma` must hold the stress of the step when a stress field is asked for; `cache`
    keeps the Functions between steps."""
    d = problem.geometry.mesh.geometry.dim
    fields = {}
    if "stress_components" in names or "von_mises" in names:
        tensor_space = sigma.function_space
        values = sigma.x.array.reshape(-1, d, d)
        wanted = ([(f"sigma_{name}", values[:, i, j]) for name, i, j in COMPONENTS[d]]
                  if "stress_components" in names else [])
        if "von_mises" in names:
            wanted.append(("von_mises", von_mises(values)))
        if wanted and "stress space" not in cache:
            cache["stress space"] = compat.scalar_space(tensor_space.mesh, "DG",
                                                        compat.element_degree(tensor_space))
        for name, value in wanted:
            target = _cached(cache, name, lambda: cache["stress space"])
            # The same element, so the same nodes cell by cell: copied through the cell dofs.
            target.x.array[compat.cell_dofs(target.function_space.dofmap)] = \
                value[compat.cell_dofs(tensor_space.dofmap)]
        fields["stress_components"] = [cache[f"sigma_{name}"] for name, _, _ in COMPONENTS[d]
                                       if f"sigma_{name}" in cache]
        fields["von_mises"] = [cache["von_mises"]] if "von_mises" in cache else []
    if "contact_status" in names and problem.contact is not None and table is not None:
        target = _cached(cache, "contact_status", lambda: problem.contact.gap.function_space)
        own, status = status_at_nodes(problem, table)
        target.x.array[:] = 0.0
        target.x.array[own] = status
        target.x.scatter_forward()
        fields["contact_status"] = [target]
    return fields


def _cached(cache: dict, name: str, space):
    """The Function `name` of cache, made on space() the first time."""
    if name not in cache:
        cache[name] = fem.Function(space(), name=name)
    return cache[name]


def snapshot_skip_note(problem, limit, xdmf: bool) -> str | None:
    """None if the figure snapshots may be taken; else the note that says why not: gather_mesh
    copies the whole mesh and its fields to rank 0, which must stay O(boundary) on a large
    mesh (output.snapshot_max_nodes)."""
    nodes = problem.V.dofmap.index_map.size_global
    if nodes <= limit:
        return None
    return (f"figures: no snapshots (snapshots.npz, deformed_mesh.png, stress.png): {nodes} "
            f"nodes > output.snapshot_max_nodes = {limit}"
            + ("; the fields are in the XDMF output" if xdmf else ""))


def xdmf_field(function, cache: dict, convert: bool = None):
    """What XDMFFile can write of a Function: the Function itself where XDMFFile writes any
    degree (DOLFINx 0.5), else (0.6 on: only the mesh's degree) its interpolation into the P1
    or DG0 space of the same shape, under the same name. convert=True always interpolates.
    `cache` keeps the interpolation targets between steps."""
    space = function.function_space
    discontinuous = compat.is_discontinuous(space)
    if convert is None:
        convert = not compat.xdmf_writes_any_degree()
    if not convert or compat.element_degree(space) == (0 if discontinuous else 1):
        return function
    if function.name not in cache:
        family, degree = ("DG", 0) if discontinuous else ("CG", 1)
        make = {0: compat.scalar_space, 1: compat.vector_space,
                2: compat.tensor_space}[len(function.ufl_shape)]
        cache[function.name] = fem.Function(make(space.mesh, family, degree),
                                            name=function.name)
    target = cache[function.name]
    target.interpolate(function)
    return target


def gather_mesh(problem, sigma, comm):
    """(points (n, d), cells (m, d+1), displacement (n, d), von Mises stress per cell (m,))
    of the mesh's vertices on rank 0 (None elsewhere), in a numbering independent of the rank
    count. In 2D the von Mises stress is that of the in-plane stress (sigma_zz taken as 0)."""
    V = problem.V
    d = problem.geometry.mesh.geometry.dim
    imap = V.dofmap.index_map
    n_own = imap.size_local
    x = V.tabulate_dof_coordinates()[:n_own, :d]
    u = problem.u.x.array.reshape(-1, d)[:n_own]
    global_index = imap.local_range[0] + np.arange(n_own)
    n_cells = problem.geometry.mesh.topology.index_map(d).size_local
    cell_dofs = compat.cell_dofs(V.dofmap)[:n_cells, :d + 1]
    cells = imap.local_to_global(cell_dofs.ravel()).reshape(-1, d + 1)
    stress_dofs = compat.cell_dofs(sigma.function_space.dofmap)[:n_cells]
    stress = sigma.x.array.reshape(-1, d, d)[stress_dofs].mean(axis=1)   # cell averages
    parts = comm.gather((global_index, x, u, cells, von_mises(stress)), root=0)
    if comm.rank != 0:
        return None
    size = imap.size_global
    points, disp = np.zeros((size, d)), np.zeros((size, d))
    for gi, xi, ui, _, _ in parts:
        points[gi], disp[gi] = xi, ui
    return (points, np.concatenate([p[3] for p in parts]), disp,
            np.concatenate([p[4] for p in parts]))


def von_mises(stress: np.ndarray) -> np.ndarray:
    """sqrt(3/2 s:s), s the deviator of the (3 x 3, zero-padded in 2D) stress tensors."""
    full = np.zeros((len(stress), 3, 3))
    d = stress.shape[1]
    full[:, :d, :d] = stress
    dev = full - np.einsum("cii->c", full)[:, None, None] / 3 * np.eye(3)
    return np.sqrt(1.5 * np.einsum("cij,cij->c", dev, dev))


def read_snapshots(path, t_max):
    """The snapshots of snapshots.npz up to time t_max, as write_snapshots takes them."""
    data = np.load(path)
    return [(t, data["points"], data["cells"], disp, mises)
            for t, disp, mises in zip(data["times"], data["displacements"], data["von_mises"])
            if t <= t_max + 1e-12]


def write_snapshots(path, snapshots):
    """snapshots.npz: the mesh once, then per figure time its displacement and stress."""
    times, points, cells, disp, mises = zip(*snapshots)
    tmp = path.with_suffix(".tmp.npz")
    np.savez_compressed(tmp, times=np.array(times), points=points[0], cells=cells[0],
                        displacements=np.array(disp), von_mises=np.array(mises))
    os.replace(tmp, path)
