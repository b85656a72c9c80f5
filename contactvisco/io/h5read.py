"""Reading back what solution.xdmf references, with the HDF5 library DOLFINx itself links
(through ctypes: no h5py needed), to check that every listed step is complete.

    check_xdmf(path) -> [(t, {attribute name: array}), ...]

raises OSError naming the file and dataset that cannot be read.
"""
from __future__ import annotations

import contextlib
import ctypes
import ctypes.util
import pathlib
import xml.etree.ElementTree as ET

import numpy as np

_lib = None


def _hdf5():
    global _lib
    if _lib is None:
        for name in ("libhdf5_openmpi.so.103", ctypes.util.find_library("hdf5_openmpi"),
                     ctypes.util.find_library("hdf5")):
            if name:
                try:
                    _lib = ctypes.CDLL(name)
                    break
                except OSError:
                    continue
        else:
            raise OSError("no HDF5 library found")
        _lib.H5open()
        _lib.H5Eset_auto2(ctypes.c_int64(0), None, None)       # no error stack printing
        for f in ("H5Fopen", "H5Dopen2", "H5Dget_space"):
            getattr(_lib, f).restype = ctypes.c_int64
    return _lib


@contextlib.contextmanager
def _dataset(file: pathlib.Path, path: str):
    """The HDF5 library and the open dataset `path` of file `file` (a regular file: the
    library opens the path itself), both closed on leaving."""
    from contactvisco.io import files
    files.require_regular(file)
    lib = _hdf5()
    f = lib.H5Fopen(str(file).encode(), 0, ctypes.c_int64(0))
    if f < 0:
        raise OSError(f"{file}: not a readable HDF5 file")
    try:
        d = lib.H5Dopen2(ctypes.c_int64(f), path.encode(), ctypes.c_int64(0))
        if d < 0:
            raise OSError(f"{file}: no dataset {path}")
        try:
            yield lib, ctypes.c_int64(d)
        finally:
            lib.H5Dclose(ctypes.c_int64(d))
    finally:
        lib.H5Fclose(ctypes.c_int64(f))


def read_dataset(file: pathlib.Path, path: str) -> np.ndarray:
    """The dataset `path` of HDF5 file `file`, as float64."""
    with _dataset(file, path) as (lib, d):
        space = lib.H5Dget_space(d)
        rank = lib.H5Sget_simple_extent_ndims(ctypes.c_int64(space))
        dims = (ctypes.c_uint64 * max(rank, 1))()
        lib.H5Sget_simple_extent_dims(ctypes.c_int64(space), dims, None)
        lib.H5Sclose(ctypes.c_int64(space))
        out = np.empty([dims[i] for i in range(rank)], dtype=np.float64)
        double = ctypes.c_int64.in_dll(lib, "H5T_NATIVE_DOUBLE_g")
        status = lib.H5Dread(d, double, ctypes.c_int64(0), ctypes.c_int64(0),
                             ctypes.c_int64(0), out.ctypes.data_as(ctypes.c_void_p))
        if status < 0:
            raise OSError(f"{file}: dataset {path} cannot be read")
        return out


def stored_type(file: pathlib.Path, path: str) -> np.dtype:
    """The type dataset `path` of HDF5 file `file` is stored as: an integer or float numpy
    dtype of the same size and sign (byte order left out)."""
    with _dataset(file, path) as (lib, d):
        lib.H5Dget_type.restype = ctypes.c_int64
        t = lib.H5Dget_type(d)
        kind = lib.H5Tget_class(ctypes.c_int64(t))      # 0 integer, 1 float
        size = lib.H5Tget_size(ctypes.c_int64(t))
        signed = lib.H5Tget_sign(ctypes.c_int64(t)) == 1 if kind == 0 else True
        lib.H5Tclose(ctypes.c_int64(t))
    if kind not in (0, 1):
        raise OSError(f"{file}: dataset {path} is neither integer nor float")
    return np.dtype(("i" if signed else "u") + str(size) if kind == 0 else f"f{size}")


def check_xdmf(path) -> list[tuple[float, dict]]:
    """Every time step of an XDMF file with every dataset it references read back; each
    array's shape must be the Dimensions the XDMF gives and its values finite."""
    path = pathlib.Path(path)
    root = ET.parse(path).getroot()
    steps = []
    for grid in root.iter("Grid"):
        if grid.get("GridType") != "Uniform" or grid.find("Time") is None:
            continue
        arrays = {}
        for item in grid.iter("DataItem"):
            name, _, dataset = item.text.strip().partition(":")
            data = read_dataset(path.parent / name, dataset)
            shape = tuple(int(n) for n in item.get("Dimensions").split())
            if data.shape != shape or not np.all(np.isfinite(data)):
                raise OSError(f"{path.parent / name}:{dataset} has shape {data.shape}, "
                              f"the XDMF says {shape}, or non-finite values")
            owner = next((a.get("Name") for a in grid.findall("Attribute")
                          if item in list(a.iter("DataItem"))), None)
            arrays[owner or dataset.rsplit("/", 1)[-1]] = data
        steps.append((float(grid.find("Time").get("Value")), arrays))
    return steps
