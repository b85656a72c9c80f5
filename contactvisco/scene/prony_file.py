"""A Prony table read from a CSV file, as fitting tools export it: a header row, then one row
per term, the relaxation time first and its modulus (or normalized fraction) second; and a
shift table (:func:`read_shift`): a header row, then temperature and log10 a_T per row.

Only data is read: the file the scene names (relative to the scene file's folder, or to the
working directory for a scene given as values), at most :data:`MAX_BYTES`, through the csv
module; every cell must be a finite number. An empty table, a row of the wrong length, a
value that is not a finite number, a relaxation time <= 0, a negative modulus, times that do
not increase (unsorted or duplicated rows) and more than :data:`MAX_TERMS` rows are refused,
naming the file and the row (its line in the file).

A column of sample times (:func:`read_times`, time.times_file) is read the same way; its path
must stay inside the scene file's folder (:func:`inside_path`): no absolute path, no '..',
no link that leads out.
"""
from __future__ import annotations

import csv
import io
import math
import pathlib

from contactvisco.errors import SceneError

#: Largest Prony file read (a table of terms is a few kilobytes).
MAX_BYTES = 1_000_000

#: Most terms of a Prony series: each keeps a history field of the size of the strain.
MAX_TERMS = 100

#: Most points of a shift table (log10 a_T against temperature).
MAX_SHIFT_ROWS = 1000


def resolve_path(name, base: pathlib.Path | None, key: str) -> pathlib.Path:
    """The path of a Prony file: `name` as given when absolute, else relative to `base` (the
    scene file's folder; None: the working directory).

    Parameters
    ----------
    name : str
        The file name the scene gives.
    base : pathlib.Path or None
        The scene file's folder.
    key : str
        The dotted key, for errors.

    Returns
    -------
    pathlib.Path
        The path (an existing regular file).
    """
    _need_name(name, key)
    path = pathlib.Path(name)
    if not path.is_absolute() and base is not None:
        path = base / path
    if not path.is_file():          # a device or a pipe could be read for ever
        raise SceneError(f"{key}: no Prony file '{path}' (a path relative to the scene file's "
                         "folder, or absolute)", key=key)
    return path


def _need_name(name, key: str) -> None:
    if not isinstance(name, str) or not name:
        raise SceneError(f"{key} must be the name of a CSV file, got {name!r}", key=key)


def inside_path(name, base: pathlib.Path | None, key: str) -> pathlib.Path:
    """The path of a data file named by a scene, inside the scene file's folder `base` (the
    working directory for a scene given as values): a relative name without '..', whose
    resolved path (links followed) stays inside that folder, naming an existing regular file.

    Parameters
    ----------
    name, key : str
        The file name as the scene gives it, and its dotted key (for errors).
    base : pathlib.Path or None
        The folder the name is relative to.

    Returns
    -------
    pathlib.Path
        The resolved path, inside the folder.
    """
    _need_name(name, key)
    given = pathlib.Path(name)
    if given.is_absolute() or ".." in given.parts:
        raise SceneError(f"{key} = {name!r}: give a path relative to the scene file's folder, "
                         "without '..' (scene input names files beside it, not elsewhere)",
                         key=key)
    folder = (base if base is not None else pathlib.Path.cwd()).resolve()
    path = (folder / given).resolve()
    if not path.is_relative_to(folder):
        raise SceneError(f"{key} = {name!r} leads out of the scene file's folder {folder} "
                         "(through a link)", key=key)
    if not path.is_file():          # a device or a pipe could be read for ever
        raise SceneError(f"{key}: no file '{folder / given}' (a path relative to the scene "
                         "file's folder)", key=key)
    return path


def read_times(path: pathlib.Path, key: str, column: str | None, most: int) -> list[float]:
    """The sample times of one column of a CSV file: a header row of column names, then one
    row per sample, the times finite, >= 0 and strictly increasing.

    Parameters
    ----------
    path, key, column : pathlib.Path, str, str or None
        The file (:func:`inside_path`), the dotted key naming it in errors, and the header
        name of its time column (None: the first column).
    most : int
        The most rows read (the scene's bound on the number of steps).

    Returns
    -------
    list of float
        The times, in the file's order.
    """
    fail = _failure(path, key, "time file")

    rows = _rows(path, fail, "a table of sample times")
    if len(rows) < 2:
        fail("needs a header row of column names and at least one row of times")
    number, header = rows[0]
    names = [cell.strip() for cell in header]
    if any(_number(cell) is not None for cell in names):
        fail(f"the first row must be a header of column names, got {header!r}", number)
    if column is not None and column not in names:
        fail(f"no column {column!r} in the header {names!r}", number)
    j = 0 if column is None else names.index(column)
    if len(rows) - 1 > most:
        fail(f"more than {most} rows of times (the most steps of a run)", rows[most + 1][0])
    out = []
    for number, row in rows[1:]:
        value = _number(row[j]) if j < len(row) else None
        if value is None:
            fail(f"the time (column {names[j]!r}) must be a finite number, got {row!r}",
                 number)
        if value < 0 or (out and value <= out[-1]):
            fail(f"the time {value!r} must be >= 0 and above the previous row's "
                 f"{out[-1] if out else 0!r}: the times must increase", number)
        out.append(value)
    return out


def read(path: pathlib.Path, key: str) -> tuple[list[float], list[float]]:
    """The relaxation times and moduli (or fractions) of a Prony CSV file.

    Parameters
    ----------
    path : pathlib.Path
        The file (see :func:`resolve_path`).
    key : str
        The dotted key that names it, for errors.

    Returns
    -------
    tuple of list of float
        (taus, values): the first and second column of every row after the header, taus
        increasing.
    """
    fail = _failure(path, key, "Prony file")

    taus, values, lines = _columns(
        path, fail, "a Prony table", "the relaxation time, then the modulus", "tau, modulus",
        ("tau = ", "relaxation time", "each time once"), 1, MAX_TERMS, "terms")
    for tau, value, line in zip(taus, values, lines):
        if tau <= 0:
            fail(f"the relaxation time must be > 0, got {tau!r}", line)
        if value < 0:
            fail(f"the modulus must be >= 0, got {value!r}", line)
    return taus, values


def read_shift(path: pathlib.Path, key: str) -> tuple[list[float], list[float]]:
    """The points of a shift table: a CSV file of a header row, then one row per temperature,
    the temperature first and log10 a_T second (read as data only, like a Prony file).

    Parameters
    ----------
    path : pathlib.Path
        The file (see :func:`resolve_path`).
    key : str
        The dotted key that names it, for errors.

    Returns
    -------
    tuple of list of float
        (theta_j, log10 a_T(theta_j)), theta_j strictly increasing, at most
        :data:`MAX_SHIFT_ROWS` rows, |log10 a_T| <= 300 (a_T positive and finite).
    """
    fail = _failure(path, key, "shift file")

    temps, logs, lines = _columns(
        path, fail, "a shift table", "the temperature, then log10 a_T", "temperature, log10 a_T",
        ("temperature ", "temperature", "each temperature once"), 2, MAX_SHIFT_ROWS, "points")
    for value, line in zip(logs, lines):
        if abs(value) > 300.0:
            fail(f"|log10 a_T| = {abs(value)!r} is above 300 (a_T would be 0 or infinite)",
                 line)
    return temps, logs


def _failure(path: pathlib.Path, key: str, what: str):
    """fail(message, line=None): raise the SceneError of `key` naming the file and row."""
    def fail(message, line=None):
        where = f"{path}, row {line}" if line is not None else f"{path}"
        raise SceneError(f"{key}: {what} {where}: {message}", key=key)
    return fail


def _columns(path, fail, what, header_words, row_words, first, at_least, at_most, items):
    """The two columns of a CSV table of a header row and then one row of two finite numbers
    per entry, the first column strictly increasing: (first, second, line numbers). `fail`
    raises the error naming the file; `first` = (the first value's label, its quantity, what
    a repeat means) words its messages."""
    label, quantity, once = first
    rows = _rows(path, fail, what)
    if not rows:
        fail(f"empty (a header row, then one row of {row_words} per {items[:-1]})")
    number, header = rows[0]
    if len(header) != 2 or any(_number(cell) is not None for cell in header):
        fail(f"the first row must be a header of two column names ({header_words}), got "
             f"{header!r}", number)
    rows = rows[1:]
    if not rows and at_least == 1:
        fail(f"has a header but no {items}")
    if len(rows) < at_least:
        fail(f"needs at least two {items} after the header, got {len(rows)}")
    if len(rows) > at_most:
        fail(f"more than {at_most} {items}", rows[at_most][0])
    firsts, seconds, lines = [], [], []
    for number, row in rows:
        if len(row) != 2:
            fail(f"needs 2 values ({row_words}), got {len(row)}: {row!r}", number)
        x, value = (_number(cell) for cell in row)
        if x is None or value is None:
            fail(f"values must be finite numbers, got {row!r}", number)
        if firsts and x <= firsts[-1]:
            repeat = "duplicates" if x == firsts[-1] else "is below"
            fail(f"{label}{x!r} {repeat} the previous row's {firsts[-1]!r}: the rows must be "
                 f"sorted by increasing {quantity}, {once}", number)
        firsts.append(x)
        seconds.append(value)
        lines.append(number)
    return firsts, seconds, lines


def _rows(path: pathlib.Path, fail, what: str) -> list:
    """The non-blank rows of a CSV file, (line number, cells), read as data (at most
    MAX_BYTES, UTF-8); `fail` raises the error naming the file."""
    try:
        with open(path, "rb") as f:
            data = f.read(MAX_BYTES + 1)
    except OSError as err:
        fail(f"cannot be read ({err.strerror})")
    if len(data) > MAX_BYTES:
        fail(f"larger than {MAX_BYTES} bytes: not {what}")
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError:
        fail("not a UTF-8 text file")
    return [(number, row) for number, row in enumerate(csv.reader(io.StringIO(text)), start=1)
            if any(cell.strip() for cell in row)]


def _number(cell: str) -> float | None:
    """The finite number a cell holds, else None (nan, inf and text are not numbers)."""
    try:
        value = float(cell.strip())
    except ValueError:
        return None
    return value if math.isfinite(value) else None
