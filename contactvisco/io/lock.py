"""One run owns its output folder.

Rank 0 holds an exclusive fcntl.flock on DIR/contactvisco.io.lock for the whole run; the kernel
releases it when the process ends, however it ends (kill -9 included), so a stale lock file
never blocks a later run. The file names the holder (host, pids of the ranks, start time).

A new run into a folder that holds an earlier run's files is refused unless overwrite=True,
which removes exactly the files this package writes (never following a symlink out of the
folder); restart=True keeps them, after checking that none of them is a link or a special
file (unsafe_entries). A folder inside another run's folder (below a folder that holds a
lock file or a summary.json) is refused, and the removal never deletes a folder that holds
another run's files.
"""
from __future__ import annotations

import fcntl
import json
import os
import pathlib
import shutil
import socket
import time

from contactvisco.errors import SceneError
from contactvisco.io import files


class FolderError(SceneError):
    """The output folder cannot be taken (in use, or holding an earlier run's files)."""


LOCK = "contactvisco.io.lock"
#: Everything a run writes into its folder (files, and folders removed as a whole).
OWN_FILES = ("summary.json", "summary.json.tmp", "steps.jsonl", "steps.jsonl.tmp",
             "contact_nodes.csv", "contact_nodes.csv.tmp", "interface_nodes.csv",
             "interface_master.csv", "solution.xdmf",
             "solution.xdmf.tmp", "solution.h5", "obstacle.xdmf", "obstacle.xdmf.tmp", "snapshots.npz", "snapshots.tmp.npz",
             "deformed_mesh.png", "stress.png", "contact_reactions.png",
             "contact_displacements.png", "contact_status.png", "probes.png",
             "contact_radius.png")
OWN_FOLDERS = ("solution", "checkpoint")
OWN_PATTERNS = ("solution-restart*.xdmf", "solution-restart*.h5")


def earlier_files(folder: pathlib.Path) -> list[pathlib.Path]:
    """The files and folders of an earlier run in `folder`."""
    found = [folder / name for name in OWN_FILES + OWN_FOLDERS
             if os.path.lexists(folder / name)]
    for pattern in OWN_PATTERNS:
        found += sorted(folder.glob(pattern))
    return found


#: What marks a folder as a run's output folder.
MARKS = (LOCK, "summary.json", "steps.jsonl")


def unsafe_entries(folder: pathlib.Path) -> list[str]:
    """The entries of `folder` where the package reads or writes a regular file (its own
    files, their temporary names, the field and checkpoint files) or a folder ("solution",
    "checkpoint", "checkpoint/state-*") that are something else: a symbolic link, a FIFO, a
    device, a socket, a directory for a file; as 'name (what it is)'."""
    bad = []

    def check(path, directory=False):
        kind = files.what(path)
        wrong = kind not in (None, "") if not directory else kind not in (None, "a directory")
        if wrong:
            bad.append(f"{path.relative_to(folder)} ({kind or 'a regular file'})")
        return kind == "a directory"

    for name in OWN_FILES + (LOCK,):
        check(folder / name)
    for pattern in OWN_PATTERNS:
        for path in sorted(folder.glob(pattern)):
            check(path)
    if check(folder / "solution", directory=True):
        for path in sorted((folder / "solution").iterdir()):
            if path.name.startswith("step-"):
                check(path)
    if check(folder / "checkpoint", directory=True):
        for path in sorted((folder / "checkpoint").iterdir()):
            if path.name.startswith("state-"):
                if check(path, directory=True):
                    for part in sorted(path.iterdir()):
                        check(part)
            else:
                check(path)
    return bad


def enclosing_run(folder: pathlib.Path) -> pathlib.Path | None:
    """The nearest folder above `folder` (resolved) that is a run's output folder (holds a
    lock file or a summary.json), or None."""
    for parent in folder.resolve().parents:
        if any(files.what(parent / mark) is not None for mark in MARKS):
            return parent
    return None


def _other_runs_inside(path: pathlib.Path) -> list[pathlib.Path]:
    """The folders below `path` (links not followed) that are another run's output folder."""
    found = []
    for top, dirs, names in os.walk(path):
        if any(mark in names for mark in MARKS):
            found.append(pathlib.Path(top))
    return found


def clear(folder: pathlib.Path):
    """Remove the earlier run's files; a symlink is removed itself, never followed; a folder
    of the package's that holds another run's output folder is refused (FolderError), before
    anything is removed."""
    found = earlier_files(folder)
    for path in found:
        if path.is_dir() and not path.is_symlink():
            inside = _other_runs_inside(path)
            if inside:
                raise FolderError(f"output folder '{folder}': '{path.name}' holds another "
                                  f"run's output folder ({inside[0]}); it is not removed: "
                                  "move that run away or choose another --out")
    for path in found:
        if path.is_dir() and not path.is_symlink():
            shutil.rmtree(path)
        else:
            path.unlink()


class FolderLock:
    """The lock of one run on its output folder (held by rank 0, released by release() or by
    the end of the process)."""

    def __init__(self, folder, comm, restart=False, overwrite=False):
        """Take the folder (collective); raise FolderError on every rank when another run
        holds it, or when it holds an earlier run's files and neither restart nor overwrite
        is given."""
        self.folder = pathlib.Path(folder)
        self.fd = None
        error = None
        pids = comm.gather(os.getpid(), root=0)
        if comm.rank == 0:
            try:
                error = self._take(pids, restart, overwrite)
            except OSError as err:
                error = f"output folder '{folder}' is not writable: {err.strerror}"
        error = comm.bcast(error, root=0)
        if error:
            self.release()
            raise FolderError(error)

    def _take(self, pids, restart, overwrite) -> str | None:
        outer = enclosing_run(self.folder)
        if outer is not None:
            return (f"output folder '{self.folder}' lies inside the output folder of another "
                    f"run, '{outer}' (it holds {' or '.join(MARKS)}); its clean-up or "
                    "overwrite could remove this run's files: choose an --out outside it")
        self.folder.mkdir(parents=True, exist_ok=True)
        path = self.folder / LOCK
        created = files.what(path) is None
        try:
            fd = files.open_fd(path, "c")
        except files.UnsafeEntry as err:
            return str(err)
        error = self._check(fd, pids, restart, overwrite)
        if error and self.fd is not None:
            if created:            # a refused run leaves no mark of a run in the folder
                path.unlink(missing_ok=True)
            self.release()
        return error

    def _check(self, fd, pids, restart, overwrite) -> str | None:
        """With the lock file open as fd: take the lock, check the folder; None or why
        not."""
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = os.pread(fd, 4096, 0).decode(errors="replace").strip()
            os.close(fd)
            try:
                info = json.loads(holder)
                who = f"pid {info['pids'][0]} on {info['host']} (since {info['started']})"
            except (ValueError, KeyError, IndexError, TypeError):
                who = "another process"
            return (f"output folder '{self.folder}' is in use by another run: {who}; wait for "
                    "it to end or choose another --out")
        self.fd = fd
        if restart:
            bad = unsafe_entries(self.folder)
            if bad:
                return (f"output folder '{self.folder}': {', '.join(bad[:6])}"
                        f"{', ...' if len(bad) > 6 else ''}: where the run reads or writes "
                        "its files there are links or special files; nothing is written "
                        "through them: remove them, or start again with --overwrite")
        if not restart:
            found = earlier_files(self.folder)
            if found and not overwrite:
                names = ", ".join(sorted(p.name for p in found)[:6])
                return (f"output folder '{self.folder}' holds an earlier run's files ({names}"
                        f"{', ...' if len(found) > 6 else ''}); use --overwrite to replace "
                        "them, --restart to continue that run, or another --out")
            try:
                clear(self.folder)
            except FolderError as err:
                return str(err)
        info = {"host": socket.gethostname(), "pids": pids,
                "started": time.strftime("%Y-%m-%dT%H:%M:%S%z")}
        os.ftruncate(fd, 0)
        os.pwrite(fd, (json.dumps(info) + "\n").encode(), 0)
        return None

    def release(self):
        if self.fd is not None:
            os.close(self.fd)            # closing the descriptor releases the flock
            self.fd = None
