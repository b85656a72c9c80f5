"""Files of an output folder opened without following links, and only if they are regular.

Every file the package writes or reads in an output folder goes through `open_file` (or
`replace`, `read_bytes`): the last component of the path is opened with O_NOFOLLOW (a symbolic
link planted under one of the package's file names, temporary names included, is refused, not
written through) and O_NONBLOCK (a FIFO or device where a file belongs is refused at once,
not waited on), and the opened descriptor must be a regular file. A refusal is an
`UnsafeEntry` (exit 2 on the command line) naming the path and what it is.

The HDF5 and XDMF files that DOLFINx's XDMFFile writes, and that the HDF5 library reads back
(contactvisco.io.h5read), are opened by those libraries from a path: there `require_regular`
checks, just before, that the path is absent or a regular file.
"""
from __future__ import annotations

import errno
import os
import pathlib
import stat

from contactvisco.errors import SceneError


class UnsafeEntry(SceneError):
    """A path of an output folder that is a symbolic link, or not a regular file (directory),
    where the package reads or writes one."""


class Damaged(SceneError):
    """A checkpoint or record file of an output folder that fails a check on --restart."""


def what(path) -> str | None:
    """What `path` is, without following a link: None if absent, "" for a regular file, else
    words for the user ("a symbolic link to /x", "a FIFO", "a directory", ...)."""
    try:
        mode = os.lstat(path).st_mode
    except FileNotFoundError:
        return None
    if stat.S_ISREG(mode):
        return ""
    if stat.S_ISLNK(mode):
        try:
            return f"a symbolic link to {os.readlink(path)}"
        except OSError:
            return "a symbolic link"
    for test, words in ((stat.S_ISDIR, "a directory"), (stat.S_ISFIFO, "a FIFO"),
                        (stat.S_ISSOCK, "a socket"), (stat.S_ISCHR, "a character device"),
                        (stat.S_ISBLK, "a block device")):
        if test(mode):
            return words
    return "not a regular file"


def refusal(path, kind: str, wanted: str = "a regular file of the run's") -> UnsafeEntry:
    """The error for `path` found to be `kind` where `wanted` belongs."""
    return UnsafeEntry(f"'{path}' is {kind}, where {wanted} belongs; nothing is read or "
                       "written through links or special files: remove it or choose "
                       "another folder")


def require_regular(path) -> None:
    """Raise UnsafeEntry unless `path` is absent or a regular file (used just before a
    library that opens paths itself, DOLFINx's XDMFFile or the HDF5 library, opens it)."""
    kind = what(path)
    if kind:
        raise refusal(path, kind)


_FLAGS = {"r": os.O_RDONLY, "w": os.O_WRONLY | os.O_CREAT | os.O_TRUNC,
          "a": os.O_WRONLY | os.O_CREAT | os.O_APPEND, "r+": os.O_RDWR,
          "c": os.O_RDWR | os.O_CREAT, "x": os.O_WRONLY | os.O_CREAT | os.O_EXCL}


def open_fd(path, mode: str = "r", permissions: int = 0o644) -> int:
    """A descriptor of the regular file `path` opened as `mode` ("r", "w", "a", "r+", or
    "c": read and write, created if absent, not truncated; "w", "a" and "c" create it), never through a symbolic link and never waiting on a FIFO."""
    flags = _FLAGS[mode] | os.O_NOFOLLOW | os.O_NONBLOCK | os.O_CLOEXEC
    try:
        fd = os.open(path, flags, permissions)
    except OSError as err:
        kind = what(path)
        if kind or err.errno in (errno.ELOOP, errno.ENXIO, errno.EISDIR):
            raise refusal(path, kind or "not a regular file") from None
        raise
    status = os.fstat(fd)
    if not stat.S_ISREG(status.st_mode):
        os.close(fd)
        raise refusal(path, what(path) or "not a regular file")
    if mode != "r" and status.st_nlink > 1:
        os.close(fd)
        raise refusal(path, f"a regular file with {status.st_nlink} names (hard links)")
    os.set_blocking(fd, True)
    return fd


def open_file(path, mode: str = "r", **options):
    """open(path, mode) through `open_fd`: mode is "r", "w", "a" or "r+", with "b" for
    bytes; `options` go to os.fdopen (newline, encoding)."""
    fd = open_fd(path, mode.replace("b", "").replace("t", ""))
    try:
        return os.fdopen(fd, mode, **options)
    except BaseException:
        os.close(fd)
        raise


def read_bytes(path, limit: int | None = None) -> bytes:
    """The content of the regular file `path`; with `limit`, a file larger than `limit`
    bytes is refused (UnsafeEntry naming it) before it is read."""
    with open_file(path, "rb") as f:
        size = os.fstat(f.fileno()).st_size
        if limit is not None and size > limit:
            raise UnsafeEntry(f"'{path}' has {size} bytes, more than the {limit} such a file "
                              "can have: not a file of this package")
        return f.read()


def replace(path, data: bytes | str, tmp=None, durable: bool = True) -> None:
    """Replace the content of `path` by `data` atomically: `replace_with`."""
    if isinstance(data, str):
        data = data.encode()
    replace_with(path, lambda f: f.write(data), tmp, durable)


def replace_with(path, write, tmp=None, durable: bool = True) -> None:
    """Replace the content of `path` atomically (a stop leaves the old or the new file):
    write(f) writes into a new file `tmp` (default path + ".tmp"; whatever had that name,
    a link included, is removed first, never followed; a directory there is refused), which
    is then renamed onto `path` (a rename replaces a link at `path` itself, never its
    target). durable: the new file is synced to the disk before the rename (a power loss
    then leaves the old or the new content); without it the content reaches the operating
    system only, which is all the death of the process needs, and saves the disk's sync
    (milliseconds per file)."""
    path = pathlib.Path(path)
    tmp = path.with_name(path.name + ".tmp") if tmp is None else pathlib.Path(tmp)
    kind = what(tmp)
    if kind == "a directory":
        raise refusal(tmp, kind)
    if kind is not None:
        os.unlink(tmp)
    if what(path) == "a directory":
        raise refusal(path, "a directory")
    with os.fdopen(open_fd(tmp, "x"), "wb") as f:
        write(f)
        f.flush()
        if durable:
            os.fsync(f.fileno())
    os.replace(tmp, path)
