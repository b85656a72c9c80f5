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
import errno
import hashlib
import io as io_module
import json
import math
import os
import pathlib
import shutil

import numpy as np
from dolfinx import fem, io

from contactvisco.fem import compat
from contactvisco.errors import SceneError
from contactvisco.fem.contact_state import (STATUSES, STICK_SLIP_STATES, rows_at_nodes,
                                            status_at_nodes)
from contactvisco.io import files, h5states
from contactvisco.io.obstacle_file import DRAWN, OBSTACLE_FILE, ObstacleFile, surface

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

    def __init__(self, folder, problem, comm, xdmf=True, restart_count=None, records=None):
        """restart_count: continue the files of an earlier run after its first
        restart_count steps (what a later stop may have written beyond them is dropped).
        records: the checkpoint's record_state(); the record files are then checked against
        it first (check_records: cut back exactly to it, or refused)."""
        self.folder = pathlib.Path(folder)
        self.comm = comm
        self.rank = comm.rank
        self.mesh = problem.geometry.mesh
        if self.rank == 0:
            self.folder.mkdir(parents=True, exist_ok=True)
        comm.barrier()
        if records is not None and restart_count is not None:
            error = None
            if self.rank == 0:
                try:
                    check_records(self.folder, records, restart_count)
                except SceneError as err:
                    error = err
            message = comm.bcast(error and str(error), root=0)
            if message is not None:
                from contactvisco.io.files import Damaged
                raise error if error is not None else Damaged(message)
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
            if records is not None and [s.get("step") for s in kept_steps] != list(
                    range(restart_count)):
                from contactvisco.io.files import Damaged
                raise Damaged(f"--restart: {self.folder / STEPS_FILE} holds "
                              f"{len(kept_steps)} step records, not the steps 0.."
                              f"{restart_count - 1} of the checkpoint")
        self.steps_written = len(kept_steps)
        self.csv = self.steps_file = self.index = None
        verified = {name for name in (records or {}) if restart_count is not None}
        if self.rank == 0:
            # Restart: the records are cut to the checkpoint once (O(N) once per restart).
            path = self.folder / STEPS_FILE
            if STEPS_FILE not in verified:
                files.replace(path, "".join(json.dumps(jsonable(record), allow_nan=False)
                                            + "\n" for record in kept_steps))
            self.steps_file = AppendedRecord(path)
            self._write_summary()
        if self.rank == 0 and problem.contact is not None:
            self._start_csv(problem.geometry.mesh.geometry.dim, restart_count,
                            CSV_FILE in verified)
        self.interface = {}                  # two bodies: the interface tables
        if self.rank == 0 and hasattr(problem.contact and problem.contact.obstacle,
                                      "interface_values"):
            d = problem.geometry.mesh.geometry.dim
            for name, header in interface_headers(d).items():
                self.interface[name] = self._start_table(name, header, restart_count,
                                                         name in verified)
        self.xdmf = None
        if xdmf:
            self.xdmf = self.folder / SOLUTION_DIR
            if self.rank == 0:
                self.xdmf.mkdir(exist_ok=True)
                if restart_count is not None:
                    self._drop_fields_from(restart_count)
                self.index = XdmfIndex(self.folder / "solution.xdmf", self.xdmf,
                                       restart_count or 0, "solution.xdmf" in verified)
            comm.barrier()
        self._writable = {}                # P1/DG0 copies of higher-degree fields (xdmf_field)
        self.last_field_bytes = 0          # rank 0: the last step's field files (_check_room)
        self.obstacle = None               # obstacle.xdmf: a rigid obstacle's surface
        drawing = xdmf and obstacle_drawing(problem, comm)
        if drawing and self.rank == 0:
            self.obstacle = ObstacleFile(self.folder / OBSTACLE_FILE, drawing, kept_steps)

    def _drop_fields_from(self, count: int):
        """Rank 0, on a restart: remove the field files of steps >= count, written after the
        checkpoint by the stopped run. The restart writes those steps again where its
        schedule asks for them; a file it does not write would otherwise stay, unlisted, and
        be listed by a later restart (XdmfIndex takes every file before its count)."""
        for path in self.xdmf.glob("step-*.*"):
            number = path.name[len("step-"):].split(".", 1)[0]
            if number.isdigit() and int(number) >= count and path.suffix in (".xdmf", ".h5"):
                path.unlink(missing_ok=True)

    def _start_csv(self, d: int, restart_count: int | None, verified: bool = False):
        """Rank 0: contact_nodes.csv with its header and, on a restart, the rows of the
        first restart_count steps (a row cut by a stop is dropped), opened for appending.
        verified: the file was already cut back to the checkpoint (check_records)."""
        header = ["step", "t"] + ["xyz"[i] for i in range(d)] + [
            "u_nu", "gap", "contact_pressure", "u_tau", "reaction_nu", "reaction_tau",
            "friction_bound", "status", "friction"]
        self.csv = self._start_table(CSV_FILE, header, restart_count, verified)

    def _start_table(self, name: str, header: list, restart_count: int | None,
                     verified: bool = False) -> "AppendedRecord":
        """Rank 0: the CSV table `name` with its header and, on a restart, the rows of the
        first restart_count steps (a row cut by a stop is dropped), opened for appending.
        verified: the file was already cut back to the checkpoint (check_records)."""
        path = self.folder / name
        if not (verified and files.what(path) == ""):
            kept = []
            if restart_count is not None and files.what(path) is not None:
                with files.open_file(path, "r", newline="") as f:
                    kept = [row for row in list(csv.reader(f))[1:]
                            if len(row) == len(header) and row[0].isdigit()
                            and int(row[0]) < restart_count]
            text = io_module.StringIO()
            writer = csv.writer(text)
            writer.writerow(header)
            writer.writerows(kept)
            files.replace(path, text.getvalue())
        return AppendedRecord(path)

    def step(self, record: dict, table, fields=()):
        """Write step record["step"]: its fields (none: the step has no XDMF entry; the
        caller's schedule decides), contact-node rows, then its record."""
        n = record["step"]
        if self.xdmf is not None and fields:
            # A file per step, closed before the index lists it: a stop while it is being
            # written never touches the steps before it.
            name = self.xdmf / f"step-{n:06d}.xdmf"
            self._check_room(name)
            if self.rank == 0:          # DOLFINx opens these paths itself: checked before
                files.require_regular(name)
                files.require_regular(name.with_suffix(".h5"))
            with io.XDMFFile(self.comm, str(name), "w") as f:
                f.write_mesh(self.mesh)
                for field in fields:
                    f.write_function(xdmf_field(field, self._writable), record["t"])
            self._integer_codes(name, fields)
            if self.rank == 0:
                self.last_field_bytes = sum(os.stat(path).st_size
                                            for path in (name, name.with_suffix(".h5")))
        self.steps_written = n + 1
        self.last_record = record
        if self.rank != 0:
            return
        if self.csv is not None and table is not None:
            text = io_module.StringIO()
            rows = csv.writer(text)
            for i in range(len(table["u_nu"])):
                rows.writerow([n, repr(record["t"])]
                              + [repr(float(c)) for c in table["x"][i]]
                              + [repr(float(table[key][i])) for key in
                                 ("u_nu", "gap", "contact_pressure", "u_tau",
                                  "reaction_nu", "reaction_tau", "radius")]
                              + [STATUSES[table["status"][i]],
                                 STICK_SLIP_STATES[table["friction"][i]]])
            self.csv.append(text.getvalue())
        if self.interface and table is not None:
            for name, text in interface_rows(n, record["t"], table).items():
                self.interface[name].append(text)
        if self.index is not None and fields:
            self.index.append(n, record["t"])
        if self.obstacle is not None:
            self.obstacle.append(record)
        # One line, written whole and flushed: a stop leaves whole lines (and at most a cut
        # last one, which read_summary drops).
        self.steps_file.append(json.dumps(jsonable(record), allow_nan=False) + "\n")

    def _integer_codes(self, name: pathlib.Path, fields):
        """The state codes of the step file `name` rewritten as integers (h5states), by rank
        0 once every rank has closed the file; a failure is raised on every rank."""
        if not any(f.name in h5states.CODE_FIELDS for f in fields):
            return
        error = None
        self.comm.barrier()
        if self.rank == 0:
            try:
                h5states.integer_codes(name)
            except OSError as err:
                error = str(err)
        error = self.comm.bcast(error, root=0)
        if error is not None:
            raise OSError(f"the state codes of {name} cannot be written as integers: {error}")

    def _check_room(self, name: pathlib.Path):
        """Stop (OSError ENOSPC on every rank) before the fields of a step are written when
        the disk has less free space than twice the last step's field files: HDF5 failing
        to write a file at its close leaves DOLFINx's file object in a state that crashes
        the process when it is destroyed, so a step's fields are begun only with room for
        them."""
        need = 0
        if self.rank == 0 and self.last_field_bytes:
            free = shutil.disk_usage(name.parent).free
            need = 2 * self.last_field_bytes if free < 2 * self.last_field_bytes else 0
        need = self.comm.bcast(need, root=0)
        if need:
            raise OSError(errno.ENOSPC, f"{os.strerror(errno.ENOSPC)} (the fields of a step "
                          f"need about {need // 2} bytes)", str(name.parent))

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
        for f in (self.csv, self.steps_file, self.obstacle, *self.interface.values()):
            if f is not None:
                f.close()

    def record_state(self) -> dict | None:
        """Rank 0: {file name: {"bytes": length, "sha256": digest}} of the record files as
        they are now (steps.jsonl, contact_nodes.csv, solution.xdmf without its closing
        tags), kept by a checkpoint so that a restart can check them; None elsewhere. O(1):
        the digests are kept up to date as the files grow."""
        if self.rank != 0:
            return None
        state = {}
        for name, f in ((STEPS_FILE, self.steps_file), (CSV_FILE, self.csv),
                        ("solution.xdmf", self.index), *self.interface.items()):
            if f is not None:
                state[name] = {"bytes": f.size, "sha256": f.digest.hexdigest()}
        return state

    def _write_summary(self):
        files.replace(self.folder / "summary.json",
                      json.dumps(jsonable(self.summary), indent=1, allow_nan=False))


STEPS_FILE = "steps.jsonl"
CSV_FILE = "contact_nodes.csv"
#: Two bodies in contact: the slave nodes' and the master boundary nodes' tables.
INTERFACE_FILE = "interface_nodes.csv"
MASTER_FILE = "interface_master.csv"


def interface_headers(d: int) -> dict:
    """The columns of the interface tables of dimension d, by file name: the slave nodes'
    (position, the master facet of the closest point, s, u_tau, p_nu, R_nu, sigma_tau, the
    node's contact force, status, friction) and the master boundary nodes' (position and
    contact force)."""
    xyz = ["xyz"[i] for i in range(d)]
    force = [f"f_{c}" for c in xyz]
    return {INTERFACE_FILE: ["step", "t"] + xyz + ["facet", "s", "u_tau", "p_nu", "R_nu",
                                                   "sigma_tau"] + force
            + ["status", "friction"],
            MASTER_FILE: ["step", "t"] + xyz + force}


def interface_rows(n: int, t: float, table: dict) -> dict:
    """The CSV rows of step n at time t of the interface tables, by file name, from a contact
    table of two bodies (contact_state.contact_table: its facet, force and master entries);
    R_nu = -lambda_nu, sigma_tau the table's reaction_tau."""
    out = {}
    text = io_module.StringIO()
    rows = csv.writer(text)
    for i in range(len(table["u_nu"])):
        rows.writerow([n, repr(t)] + [repr(float(c)) for c in table["x"][i]]
                      + [int(table["facet"][i])]
                      + [repr(float(v)) for v in (
                          table["penetration"][i], table["u_tau"][i], table["p_nu"][i],
                          -table["lambda_nu"][i], table["reaction_tau"][i])]
                      + [repr(float(c)) for c in table["force"][i]]
                      + [STATUSES[table["status"][i]],
                         STICK_SLIP_STATES[table["friction"][i]]])
    out[INTERFACE_FILE] = text.getvalue()
    text = io_module.StringIO()
    rows = csv.writer(text)
    master = table["master"]
    for x, f in zip(master["x"], master["force"]):
        rows.writerow([n, repr(t)] + [repr(float(c)) for c in x] + [repr(float(c)) for c in f])
    out[MASTER_FILE] = text.getvalue()
    return out
SOLUTION_DIR = "solution"
#: The largest summary.json and JSON line read back (a run's scene and notes: far less).
JSON_MAX_BYTES = 64 * 2**20


class AppendedRecord:
    """A record file that only grows (steps.jsonl, contact_nodes.csv): opened for appending
    as files.open_file opens, each append written whole and flushed; its length and the
    SHA-256 of its content are kept as it grows (what a checkpoint records)."""

    def __init__(self, path: pathlib.Path):
        self.path = path
        self.file = files.open_file(path, "ab")
        self.digest = hashlib.sha256()
        with files.open_file(path, "rb") as f:      # O(N) once per run (a restart's part)
            for chunk in iter(lambda: f.read(1 << 20), b""):
                self.digest.update(chunk)
        self.size = os.fstat(self.file.fileno()).st_size

    def append(self, text: str):
        data = text.encode()
        self.file.write(data)
        self.file.flush()
        self.digest.update(data)
        self.size += len(data)

    def close(self):
        if not self.file.closed:
            self.file.flush()
            os.fsync(self.file.fileno())
            self.file.close()


def check_records(folder, records: dict, count: int) -> None:
    """Check the record files of `folder` against a checkpoint's record_state() after
    `count` steps: a file longer than then (steps written after the checkpoint) is cut back
    to exactly its length at the checkpoint; a file that is missing, shorter, or whose first
    bytes differ from what the checkpoint recorded stops the restart (SceneError naming the
    file): the steps it held would be lost. Every HDF5 file the XDMF index lists up to the
    checkpoint must be there. Nothing is changed unless every file passes."""
    from contactvisco.io.files import Damaged
    folder = pathlib.Path(folder)
    for name, entry in records.items():
        path = folder / name
        if files.what(path) is None:
            raise Damaged(f"--restart: the record file '{path}' is missing; the checkpoint "
                          f"(after {count} steps) expects {entry['bytes']} bytes: its steps "
                          "would be lost")
        with files.open_file(path, "rb") as f:
            size = os.fstat(f.fileno()).st_size
            if size < entry["bytes"]:
                raise Damaged(f"--restart: the record file '{path}' has {size} bytes, fewer "
                              f"than the {entry['bytes']} it had at the checkpoint (after "
                              f"{count} steps): records were cut or removed")
            digest, left, head = hashlib.sha256(), entry["bytes"], []
            while left:
                chunk = f.read(min(left, 1 << 20))
                if not chunk:
                    break
                digest.update(chunk)
                if name == "solution.xdmf":
                    head.append(chunk)
                left -= len(chunk)
        if digest.hexdigest() != entry["sha256"]:
            raise Damaged(f"--restart: the record file '{path}' differs from what it held at "
                          f"the checkpoint (after {count} steps; SHA-256 of its first "
                          f"{entry['bytes']} bytes): it was edited or damaged")
        if name == "solution.xdmf":
            _check_listed_fields(path, b"".join(head) + XdmfIndex.TAIL.encode())
    for name, entry in records.items():       # all checked: cut back to the checkpoint
        with files.open_file(folder / name, "r+b") as f:
            f.truncate(entry["bytes"])
            if name == "solution.xdmf":
                f.seek(entry["bytes"])
                f.write(XdmfIndex.TAIL.encode())
            f.flush()
            os.fsync(f.fileno())


def _check_listed_fields(path: pathlib.Path, text: bytes):
    """Every HDF5 file the XDMF index `text` (of file `path`) points to is a regular file."""
    import xml.etree.ElementTree as ET

    from contactvisco.io.files import Damaged
    try:
        root = ET.fromstring(text)
    except ET.ParseError as err:
        raise Damaged(f"--restart: '{path}' is not XML ({err})") from None
    for item in root.iter("DataItem"):
        name = (item.text or "").strip().split(":", 1)[0]
        target = path.parent / name
        kind = files.what(target)
        if kind is None or pathlib.Path(name).is_absolute() or ".." in pathlib.Path(name).parts:
            raise Damaged(f"--restart: '{target}', listed in {path} before the checkpoint, "
                          "is missing: the fields of that step would be lost")
        if kind:
            raise files.refusal(target, kind)


def read_summary(folder) -> dict:
    """summary.json with "steps": the step records of steps.jsonl (a cut last line, left by
    a hard stop, is dropped). An earlier layout with the steps inside summary.json reads
    as it is. A file that is a link, not a regular file, not a JSON object, or nested
    too deeply stops with a SceneError naming it (files.UnsafeEntry, DamagedFile)."""
    folder = pathlib.Path(folder)
    summary = read_json(folder / "summary.json")
    name = summary.get("steps_file", STEPS_FILE)
    if not isinstance(name, str) or pathlib.PurePath(name).name != name:
        raise DamagedFile(folder / "summary.json", f"steps_file {name!r} is not a file name "
                          "in its folder")
    path = folder / name
    if "steps" not in summary:
        steps = []
        if files.what(path) is not None:
            lines = files.read_bytes(path).split(b"\n")
            for number, line in enumerate(lines, 1):
                try:
                    record = json.loads(line)
                except (ValueError, RecursionError):
                    if number < len(lines):     # a whole line: not the last, cut one
                        raise DamagedFile(path, f"line {number} is not a JSON record") from None
                    break            # the last, cut line of a stopped run (or the end)
                if not isinstance(record, dict):
                    raise DamagedFile(path, f"line {number} is not a JSON object")
                steps.append(record)
        summary["steps"] = steps
    if not isinstance(summary["steps"], list) or not all(
            isinstance(s, dict) for s in summary["steps"]):
        raise DamagedFile(folder / "summary.json", "'steps' is not a list of objects")
    return summary


class DamagedFile(SceneError):
    """A file of an output folder that cannot be what the package wrote (cut elsewhere than
    at its end, not the JSON object it must be, nested too deeply, too large)."""

    def __init__(self, path, what: str):
        super().__init__(f"'{path}': {what}")
        self.path, self.what = path, what

    def __reduce__(self):
        return DamagedFile, (self.path, self.what)


def read_json(path, limit: int = JSON_MAX_BYTES) -> dict:
    """The JSON object in file `path` (regular, at most `limit` bytes), else DamagedFile or
    files.UnsafeEntry naming it."""
    try:
        value = json.loads(files.read_bytes(path, limit))
    except RecursionError:
        raise DamagedFile(path, "JSON nested too deeply") from None
    except (ValueError, UnicodeDecodeError) as err:
        raise DamagedFile(path, f"not valid JSON ({type(err).__name__}: {err})") from None
    if not isinstance(value, dict):
        raise DamagedFile(path, f"not a JSON object (a {type(value).__name__})")
    return value


class XdmfIndex:
    """solution.xdmf: one temporal collection whose step n is the mesh and fields of
    solution/step-n.xdmf. Appending a step overwrites only the closing tags at the end of the
    file with the new grid and the closing tags, in one write: O(1) per step, and the file is
    a complete XDMF document before and after that write."""

    HEAD = ('<?xml version="1.0"?>\n<Xdmf Version="3.0" '
            'xmlns:xi="http://www.w3.org/2001/XInclude">\n  <Domain>\n'
            '    <Grid Name="solution" GridType="Collection" CollectionType="Temporal">\n')
    TAIL = "    </Grid>\n  </Domain>\n</Xdmf>\n"

    def __init__(self, path: pathlib.Path, steps: pathlib.Path, keep: int,
                 verified: bool = False):
        """Start the index with the first `keep` steps of the files in `steps`; verified:
        `path` already lists exactly them (check_records cut it back to the checkpoint)."""
        self.path, self.steps = path, steps
        if not verified:
            body = "".join(self.entry(n) for n in range(keep)
                           if files.what(steps / f"step-{n:06d}.xdmf") is not None)
            files.replace(path, self.HEAD + body + self.TAIL)
        self.fd = files.open_fd(path, "r+")
        self.end = os.fstat(self.fd).st_size - len(self.TAIL)
        self.digest = hashlib.sha256(os.pread(self.fd, self.end, 0))

    @property
    def size(self) -> int:
        """The length of the index without its closing tags (what only grows)."""
        return self.end

    def entry(self, n: int, t=None) -> str:
        """The grid of step n, taken from solution/step-n.xdmf, its data paths made relative
        to solution.xdmf."""
        import xml.etree.ElementTree as ET
        name = f"step-{n:06d}"
        root = ET.fromstring(files.read_bytes(self.steps / f"{name}.xdmf"))
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
        self.digest.update(data[:len(data) - len(self.TAIL)])
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


#: The stress components written by output.fields = "stress_components", (i, j) of sigma;
#: an axisymmetric body's in (r, z, theta), tt the hoop stress sigma_theta.
COMPONENTS = {2: (("xx", 0, 0), ("yy", 1, 1), ("xy", 0, 1)),
              3: (("xx", 0, 0), ("yy", 1, 1), ("zz", 2, 2), ("xy", 0, 1), ("yz", 1, 2),
                  ("xz", 0, 2)),
              "axisymmetric": (("rr", 0, 0), ("zz", 1, 1), ("rz", 0, 1), ("tt", 2, 2))}
#: The output.fields computed from sigma.
STRESS_FIELDS = ("sigma", "stress_components", "von_mises")
#: output.fields = "contact": the P1 scalar fields on the vertices it writes, their value at
#: a vertex of the contact boundary (off it: 0, and -1 for the two states).
CONTACT_FIELDS = {
    "contact_pressure": "-sigma_nu, positive in compression (contact table: contact_pressure)",
    "gap": "h - u_nu, the distance left to the foundation or obstacle (negative: into the "
           "layer)",
    "normal_traction": "sigma_nu = -contact_pressure, negative in compression",
    "tangential_traction": "sigma_tau (2D: along t = (-nu_y, nu_x); 3D: its magnitude)",
    "slip": "the slip (u_tau, or its increment over the step with contact.slip = "
            "'increment'; 2D: along t; 3D: its magnitude)",
    "contact_state": "0 separated, 1 normal compliance, 2 at the bound; -1 off the contact "
                     "boundary",
    "friction_state": "0 no friction, 1 stick, 2 slip; -1 off the contact boundary",
}


def derived_fields(names, problem, sigma, table, cache: dict) -> dict:
    """The fields of output.fields that are not unknowns of the problem, by field name, each a
    list of Functions named as ParaView shows them:
    "stress_components": sigma_xx, sigma_yy, sigma_xy (3D: and sigma_zz, sigma_yz, sigma_xz;
    axisymmetric: sigma_rr, sigma_zz, sigma_rz and the hoop stress sigma_tt), scalar fields of sigma's (discontinuous) space; "von_mises": sqrt(3/2 s:s) at the same
    points (in 2D of the in-plane stress, sigma_zz taken as 0, as the figures);
    "contact_status": a P1 scalar on the vertices, the contact table's status (0 separated,
    1 compliance, 2 bound) on Gamma_C and 0 elsewhere (none without contact).
    `sigma` must hold the stress of the step when a stress field is asked for; `cache`
    keeps the Functions between steps."""
    d = sigma.ufl_shape[0]                  # of the stress: 3 for an axisymmetric body
    kin = getattr(problem, "kinematics", None)
    components = COMPONENTS["axisymmetric" if getattr(kin, "axisymmetric", False) else d]
    fields = {}
    if "stress_components" in names or "von_mises" in names:
        tensor_space = sigma.function_space
        values = sigma.x.array.reshape(-1, d, d)
        wanted = ([(f"sigma_{name}", values[:, i, j]) for name, i, j in components]
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
        fields["stress_components"] = [cache[f"sigma_{name}"] for name, _, _ in components
                                       if f"sigma_{name}" in cache]
        fields["von_mises"] = [cache["von_mises"]] if "von_mises" in cache else []
    if "contact" in names and problem.contact is not None and table is not None:
        fields["contact"] = contact_fields(problem, table, cache)
    if "contact_status" in names and problem.contact is not None and table is not None:
        target = _cached(cache, "contact_status", lambda: problem.contact.gap.function_space)
        own, status = status_at_nodes(problem, table)
        target.x.array[:] = 0.0
        target.x.array[own] = status
        target.x.scatter_forward()
        fields["contact_status"] = [target]
    return fields


def contact_fields(problem, table, cache: dict) -> list:
    """The fields of CONTACT_FIELDS as P1 scalars on the vertices (the space of the gap),
    from the gathered contact table: its values at the contact nodes, 0 elsewhere (and -1
    for the two states, so that ParaView's Threshold at >= 0 keeps the contact boundary).

    Parameters
    ----------
    problem : contactvisco.fem.problem.Problem
        The problem with contact.
    table : dict
        The contact table of the step (contact_state.contact_table).
    cache : dict
        Keeps the Functions between steps.

    Returns
    -------
    list of dolfinx.fem.Function
        One Function per name of CONTACT_FIELDS, named so.
    """
    own, rows = rows_at_nodes(problem, table)
    d = table["x"].shape[1]
    slip = np.asarray(table["slip_vector"])[rows]
    normal = np.asarray(table["normal"])[rows]
    if d == 2:                     # signed along t = (-nu_y, nu_x), as u_tau in the table
        slip = slip[:, 0] * -normal[:, 1] + slip[:, 1] * normal[:, 0]
    else:
        slip = np.linalg.norm(slip - np.sum(slip * normal, axis=1)[:, None] * normal, axis=1)
    values = {"contact_pressure": table["contact_pressure"][rows],
              "gap": -np.asarray(table["penetration"])[rows],
              "normal_traction": -table["contact_pressure"][rows],
              "tangential_traction": table["reaction_tau"][rows],
              "slip": slip,
              "contact_state": table["status"][rows],
              "friction_state": table["friction"][rows]}
    out = []
    for name, value in values.items():
        target = _cached(cache, name, lambda: problem.contact.gap.function_space)
        target.x.array[:] = -1.0 if name.endswith("_state") else 0.0
        target.x.array[own] = value
        target.x.scatter_forward()
        out.append(target)
    return out


def obstacle_drawing(problem, comm):
    """The surface of the scene's rigid obstacle in its reference position, drawn to cover
    the body (obstacle_file.surface), on every rank (the body's bounding box is reduced over
    the ranks); None without an obstacle that has a drawing.

    Parameters
    ----------
    problem : contactvisco.fem.problem.Problem
        The problem (its scene and mesh).
    comm : mpi4py.MPI.Comm
        The communicator of the mesh.

    Returns
    -------
    tuple or None
        (points, cells, XDMF topology type).
    """
    from mpi4py import MPI
    obstacle = problem.scene.get("obstacle") or {}
    if obstacle.get("shape") not in DRAWN or problem.contact is None:
        return None
    d = problem.geometry.mesh.geometry.dim
    x = problem.geometry.mesh.geometry.x[:, :d]
    lower = x.min(axis=0) if len(x) else np.full(d, np.inf)
    upper = x.max(axis=0) if len(x) else np.full(d, -np.inf)
    comm.Allreduce(MPI.IN_PLACE, lower, op=MPI.MIN)
    comm.Allreduce(MPI.IN_PLACE, upper, op=MPI.MAX)
    return surface(obstacle, lower, upper)


def body_field(problem):
    """The DG0 cell field "body": on each cell the index b of the [[body]] table it lies in
    (0, 1, ...), so that a viewer can tell the bodies apart (ParaView: Threshold on "body");
    two bodies in contact without [[body]] tables: 0 on the slave's part of the mesh, 1 on
    the master's (fem.rigid.interface_parts); None for a scene with neither.

    Parameters
    ----------
    problem : contactvisco.fem.problem.Problem
        The problem (its scene and mesh).

    Returns
    -------
    dolfinx.fem.Function or None
        b on the cells of body b (ghost cells included).
    """
    from contactvisco.fem.stress import body_cells
    obstacle = problem.contact and problem.contact.obstacle
    two = hasattr(obstacle, "pairing")
    if not problem.scene.get("body") and not two:
        return None
    mesh = problem.geometry.mesh
    field = fem.Function(compat.scalar_space(mesh, "DG", 0), name="body")
    dofs = compat.cell_dofs(field.function_space.dofmap)
    if problem.scene.get("body"):
        for b, cells in enumerate(body_cells(problem.scene, problem.geometry)):
            field.x.array[dofs[cells].ravel()] = float(b)
        return field
    from contactvisco.fem.rigid import interface_parts
    parts = interface_parts(problem)
    cells = compat.cell_dofs(problem.V.dofmap)
    field.x.array[dofs[:, 0]] = parts[cells[:, 0]]
    return field


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
    `cache` keeps the interpolation targets between steps. A Function of the mesh's degree
    is written as it is, without asking what XDMFFile can write (a probe file written once per
    process: compat.xdmf_writes_any_degree)."""
    space = function.function_space
    discontinuous = compat.is_discontinuous(space)
    if compat.element_degree(space) == (0 if discontinuous else 1):
        return function
    if convert is None:
        convert = not compat.xdmf_writes_any_degree()
    if not convert:
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
    t = sigma.ufl_shape[0]                  # 3 x 3 for an axisymmetric body
    stress = sigma.x.array.reshape(-1, t, t)[stress_dofs].mean(axis=1)   # cell averages
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


#: The most that snapshots.npz may hold once decompressed (its arrays as declared).
SNAPSHOT_MAX_BYTES = 2 * 2**30


def load_npz(path, limit: int = SNAPSHOT_MAX_BYTES) -> dict:
    """The arrays of the regular file `path` (an .npz archive), after checking what its
    members declare: each member's declared size and its array header (shape x item size)
    must add up to at most `limit` bytes, so that a damaged or forged archive is refused
    (DamagedFile naming it) before anything is allocated."""
    import zipfile
    from numpy.lib import format as npy_format
    with files.open_file(path, "rb") as f:
        try:
            archive = zipfile.ZipFile(f)
            total = 0
            for member in archive.infolist():
                with archive.open(member) as item:
                    version = npy_format.read_magic(item)
                    header = {(1, 0): npy_format.read_array_header_1_0,
                              (2, 0): npy_format.read_array_header_2_0}.get(version)
                    if header is None:
                        raise ValueError(f"npy format version {version}")
                    shape, _, dtype = header(item)
                total += max(member.file_size,
                             int(np.prod(shape, dtype=object)) * dtype.itemsize)
                if total > limit:
                    raise DamagedFile(path, f"declares more than {limit} bytes of arrays "
                                      "(at most that is read)")
            f.seek(0)
            data = np.load(f, allow_pickle=False)
            return {name: data[name] for name in data.files}
        except DamagedFile:
            raise
        except (ValueError, OSError, EOFError, KeyError, TypeError, zipfile.BadZipFile,
                NotImplementedError) as err:
            raise DamagedFile(path, f"not a readable .npz archive ({type(err).__name__}: "
                              f"{err})") from None


def read_snapshots(path, t_max):
    """The snapshots of snapshots.npz up to time t_max, as write_snapshots takes them."""
    data = load_npz(path)
    return [(t, data["points"], data["cells"], disp, mises)
            for t, disp, mises in zip(data["times"], data["displacements"], data["von_mises"])
            if t <= t_max + 1e-12]


def write_snapshots(path, snapshots):
    """snapshots.npz: the mesh once, then per figure time its displacement and stress."""
    times, points, cells, disp, mises = zip(*snapshots)
    files.replace_with(path, lambda f: np.savez_compressed(
        f, times=np.array(times), points=points[0], cells=cells[0],
        displacements=np.array(disp), von_mises=np.array(mises)),
        tmp=path.with_suffix(".tmp.npz"))
