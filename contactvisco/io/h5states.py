"""The state codes of a step's XDMF fields as integers: DOLFINx writes every Function as
float64 (and DOLFINx 0.5 writes a P1 Function through vertex values, with round-off), so the
fields that hold codes (contact_state, friction_state, contact_status) are rewritten after the
step's file is closed as 32-bit integer datasets, and the step's XDMF says so
(NumberType="Int" Precision="4"): ParaView and meshio then read integer arrays.

Done by one process with the HDF5 library DOLFINx links (through ctypes, as h5read reads):
it reads the code fields of the step (O(vertices) on that process, once per written step) and
writes them back as integers; the float datasets are unlinked (HDF5 does not give their space
back: the file keeps about 8 bytes per vertex and field more than it needs).
"""
from __future__ import annotations

import ctypes
import pathlib
import xml.etree.ElementTree as ET

import numpy as np

from contactvisco.io import files
from contactvisco.io.h5read import _hdf5, read_dataset

#: The fields whose values are codes (output.CONTACT_FIELDS, contact_status): written as
#: integers.
CODE_FIELDS = ("contact_state", "friction_state", "contact_status")
#: How far from an integer a code may be read before it is refused (DOLFINx 0.5's vertex
#: values carry round-off of about 1e-15).
ROUND_OFF = 1e-6


def integer_codes(step_xdmf: pathlib.Path, names=CODE_FIELDS) -> list[str]:
    """Rewrite the datasets of the attributes `names` of the XDMF file `step_xdmf` (one
    step, written by DOLFINx's XDMFFile and closed) as 32-bit integers, the nearest
    integer to each value, and mark their DataItems NumberType="Int" Precision="4".

    Parameters
    ----------
    step_xdmf : pathlib.Path
        The step's XDMF file; its HDF5 file is named in the DataItems.
    names : iterable of str
        The attribute names to convert (those absent are skipped).

    Returns
    -------
    list of str
        The attributes converted.

    Raises
    ------
    OSError
        A dataset that cannot be read or written, or a value farther than ROUND_OFF from an
        integer (a field that does not hold codes), named with its file and dataset.
    """
    step_xdmf = pathlib.Path(step_xdmf)
    tree = ET.ElementTree(ET.fromstring(files.read_bytes(step_xdmf)))
    done = []
    for attribute in tree.getroot().iter("Attribute"):
        if attribute.get("Name") not in names:
            continue
        item = attribute.find("DataItem")
        if item is None or item.get("Format") != "HDF" or item.get("NumberType") == "Int":
            continue
        file, _, dataset = item.text.strip().partition(":")
        h5 = step_xdmf.parent / file
        values = read_dataset(h5, dataset)
        codes = np.rint(values)
        if values.size and np.abs(values - codes).max() > ROUND_OFF:
            raise OSError(f"{h5}:{dataset}: values {np.abs(values - codes).max():.3g} from "
                          "an integer, not codes")
        _write_int32(h5, dataset, codes.astype(np.int32))
        item.set("NumberType", "Int")
        item.set("Precision", "4")
        done.append(attribute.get("Name"))
    if done:
        ET.register_namespace("xi", "http://www.w3.org/2001/XInclude")
        text = b'<?xml version="1.0"?>\n' + ET.tostring(tree.getroot())
        files.replace(step_xdmf, text.decode())
    return done


def _write_int32(file: pathlib.Path, path: str, values: np.ndarray) -> None:
    """Replace dataset `path` of HDF5 file `file` by `values` as little-endian int32."""
    files.require_regular(file)
    lib = _hdf5()
    for name in ("H5Fopen", "H5Screate_simple", "H5Dcreate2"):
        getattr(lib, name).restype = ctypes.c_int64
    hid = ctypes.c_int64
    f = lib.H5Fopen(str(file).encode(), 1, hid(0))            # H5F_ACC_RDWR
    if f < 0:
        raise OSError(f"{file}: not a writable HDF5 file")
    try:
        if lib.H5Ldelete(hid(f), path.encode(), hid(0)) < 0:
            raise OSError(f"{file}: no dataset {path} to replace")
        dims = (ctypes.c_uint64 * values.ndim)(*values.shape)
        space = lib.H5Screate_simple(ctypes.c_int(values.ndim), dims, None)
        stored = ctypes.c_int64.in_dll(lib, "H5T_STD_I32LE_g")
        native = ctypes.c_int64.in_dll(lib, "H5T_NATIVE_INT_g")
        d = lib.H5Dcreate2(hid(f), path.encode(), stored, hid(space), hid(0), hid(0), hid(0))
        try:
            if d < 0:
                raise OSError(f"{file}: dataset {path} cannot be created")
            data = np.ascontiguousarray(values, dtype=np.intc)
            if lib.H5Dwrite(hid(d), native, hid(0), hid(0), hid(0),
                            data.ctypes.data_as(ctypes.c_void_p)) < 0:
                raise OSError(f"{file}: dataset {path} cannot be written")
        finally:
            if d >= 0:
                lib.H5Dclose(hid(d))
            lib.H5Sclose(hid(space))
    finally:
        lib.H5Fclose(hid(f))
