"""The MPI launcher of this Python: its vendor, the command that starts processes, the
syntax of its hostfile. For runs started from Python (tests, benchmarks, restarts on more
ranks)."""
from __future__ import annotations


def mpi_vendor() -> str:
    """'Open MPI', 'MPICH' or another name, from the MPI library this Python uses."""
    from mpi4py import MPI
    library = MPI.Get_library_version()
    for name in ("Open MPI", "MPICH"):
        if name in library:
            return name
    return library.split()[0] if library.strip() else "unknown"


def mpi_launcher() -> list[str]:
    """The command that starts processes of this Python's MPI: the mpiexec installed beside
    the interpreter (an MPI from PyPI lives in the virtual environment), else mpiexec or
    mpirun on PATH."""
    import pathlib
    import shutil
    import sys
    beside = pathlib.Path(sys.executable).parent / "mpiexec"
    if beside.exists():
        return [str(beside)]
    found = shutil.which("mpirun") or shutil.which("mpiexec")
    return [found] if found else []


def hostfile_line(host: str, slots: int) -> str:
    """One line of a hostfile in the launcher's syntax (Open MPI: 'host slots=N', MPICH's
    hydra: 'host:N')."""
    return f"{host} slots={slots}" if mpi_vendor() == "Open MPI" else f"{host}:{slots}"
