"""One run owns its output folder.

Rank 0 holds an exclusive fcntl.flock on DIR/contactvisco.io.lock for the whole run; the kernel
releases it when the process ends, however it ends (kill -9 included), so a stale lock file
never blocks a later run. The file names the holder (host, pids of the ranks, start time).

A new run into a folder that holds an earlier run's files is refused unless overwrite=True,
which removes exactly the files this package writes (never following a symlink out of the
folder); restart=True keeps them.
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


class FolderError(SceneError):
    """The output folder cannot be taken (in use, or holding an earlier run's files)."""


LOCK = "contactvisco.io.lock"
#: Everything a run writes into its folder (files, and folders removed as a whole).
OWN_FILES = ("summary.json", "summary.json.tmp", "steps.jsonl", "steps.jsonl.tmp",
             "contact_nodes.csv", "contact_nodes.csv.tmp", "solution.xdmf",
             "solution.xdmf.tmp", "solution.h5", "snapshots.npz", "snapshots.tmp.npz",
             "deformed_mesh.png", "stress.png", "contact_reactions.png",
             "contact_displacements.png", "contact_status.png", "probes.png")
OWN_FOLDERS = ("solution", "checkpoint")
OWN_PATTERNS = ("solution-restart*.xdmf", "solution-restart*.h5")


def earlier_files(folder: pathlib.Path) -> list[pathlib.Path]:
    """The files and folders of an earlier run in `folder`."""
    found = [folder / name for name in OWN_FILES + OWN_FOLDERS
             if os.path.lexists(folder / name)]
    for pattern in OWN_PATTERNS:
        found += sorted(folder.glob(pattern))
    return found


def clear(folder: pathlib.Path):
    """Remove the earlier run's files; a symlink is removed itself, never followed."""
    for path in earlier_files(folder):
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
        self.folder.mkdir(parents=True, exist_ok=True)
        path = self.folder / LOCK
        fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW, 0o644)
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
        if not restart:
            found = earlier_files(self.folder)
            if found and not overwrite:
                names = ", ".join(sorted(p.name for p in found)[:6])
                return (f"output folder '{self.folder}' holds an earlier run's files ({names}"
                        f"{', ...' if len(found) > 6 else ''}); use --overwrite to replace "
                        "them, --restart to continue that run, or another --out")
            clear(self.folder)
        info = {"host": socket.gethostname(), "pids": pids,
                "started": time.strftime("%Y-%m-%dT%H:%M:%S%z")}
        os.ftruncate(fd, 0)
        os.pwrite(fd, (json.dumps(info) + "\n").encode(), 0)
        return None

    def release(self):
        if self.fd is not None:
            os.close(self.fd)            # closing the descriptor releases the flock
            self.fd = None
