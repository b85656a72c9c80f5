"""Harness shared by the tests (tests/unit, tests/integration, tests/robustness) and the
benchmarks (benchmarks/performance, accuracy, robustness): the command line in a child
process (on 1 rank, or under this Python's MPI launcher), the environment those processes
get, the step records a run writes (steps.jsonl), the faults of a run (kill -9 of a rank,
signals, the end of a job within a time limit) and the checks of what a stopped run left in
its folder, and the discrete contact conditions (eqs 11-12) at the nodes of a contact table.

Why a module in tests/ and not contactvisco/testing.py: all of it drives or inspects this
source tree from outside (it starts `python -m contactvisco` with this checkout first on
PYTHONPATH, kills rank processes, reads the files a run leaves), so it belongs with the tests
and is not shipped by `pip install`, nor placed on a floor of the package's layers
(tests/unit/test_layers.py). pytest finds it through `pythonpath = ["tests"]` in
pyproject.toml; the benchmarks through benchmarks/common.py, which puts tests/ on sys.path.

It imports nothing but the standard library when loaded (benchmarks/accuracy/stacks.py runs
under any Python, with no FEniCSx); numpy and contactvisco are imported inside the functions
that need them. It does not import pytest: a failed check raises AssertionError, which a
benchmark records as a row and pytest reports as a failure.
"""
from __future__ import annotations

import csv
import json
import os
import pathlib
import signal
import subprocess
import sys
import time

#: The checkout: tests/ and benchmarks/ sit in it beside contactvisco/.
ROOT = pathlib.Path(__file__).resolve().parents[1]


def mpi_env(oversubscribe: bool = True, **extra) -> dict:
    """The environment of a child run: this checkout first on PYTHONPATH; Open MPI allowed
    to run as root (ignored by MPICH) and, with oversubscribe, to start more ranks than cores."""
    path = os.pathsep.join(p for p in (str(ROOT), os.environ.get("PYTHONPATH")) if p)
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
               PYTHONPATH=path, **extra)
    if oversubscribe:
        env["OMPI_MCA_rmaps_base_oversubscribe"] = "1"
    return env


ENV = mpi_env()


def launcher(ranks: int) -> list[str]:
    """The start of a command that runs on `ranks` ranks: nothing for 1, else this Python's
    MPI launcher (contactvisco.io.launcher.mpi_launcher) with -n."""
    if ranks == 1:
        return []
    from contactvisco.io.launcher import mpi_launcher
    found = mpi_launcher()
    if not found:
        raise RuntimeError("no MPI launcher (mpiexec or mpirun) found")
    return [*found, "-n", str(ranks)]


def cli_command(args, ranks: int = 1) -> list[str]:
    """`python -m contactvisco *args` with this Python, on `ranks` ranks."""
    return launcher(ranks) + [sys.executable, "-m", "contactvisco", *map(str, args)]


def layer_on_surface(distance: str, h: float = 0.25, h_bottom: float = 0.1,
                     steps: int = 1) -> dict:
    """The raw scene of a layer [0, 2] x [0, 1] (its top held, plane strain, E = 200,
    nu = 0.3) pressed by `steps` steps onto a surface obstacle of signed distance `distance`
    (*expr* in x) that rises by 1e-3: the case of the surface checks (tests/robustness,
    benchmarks/robustness/trust_round.py)."""
    return {"name": "layer_on_surface",
            "geometry": {"type": "gmsh", "script": "rectangle",
                         "parameters": {"length": 2.0, "height": 1.0, "h": h,
                                        "h_bottom": h_bottom}},
            "material": {"model": "plane_strain", "E": 200.0, "nu": 0.3},
            "dirichlet": [{"boundary": "top", "components": "all"}],
            "contact": {"boundary": "bottom", "g": 0.0, "mu": 0.0, "augmentation": 200.0},
            "obstacle": {"shape": "surface", "distance": distance,
                         "displacement": [0.0, "1e-3 * t"]},
            "time": {"T": 1.0, "steps": steps}, "output": {"probes": []}}


def axisymmetric_blocks(folder, a: float, size: float, divisions=(8, 16)) -> dict:
    """n -> the .msh file of an axisymmetric block of radius and height `size` whose mesh size
    is a/n under a contact of radius `a`, made on rank 0 in `folder` (the same on every rank)."""
    from mpi4py import MPI
    from contactvisco.fem import geometry
    comm = MPI.COMM_WORLD
    folder = pathlib.Path(comm.bcast(str(folder) if comm.rank == 0 else None, root=0))
    out = {}
    for n in divisions:
        path = folder / f"block{n}.msh"
        if comm.rank == 0:
            geometry._generate(
                {"script": "axisymmetric_block",
                 "parameters": {"radius": size, "height": size, "h_contact": a / n,
                                "h_far": size / 10, "refine": 1.5 * a, "growth": 0.4 / n}},
                path, 2)
        comm.barrier()
        out[n] = path
    return out


def run_cli(*args, ranks: int = 1, timeout: float = 300, cwd=None, env=None):
    """Run the command line to its end (killed after `timeout` s): the finished process, its
    output captured as text."""
    return subprocess.run(cli_command(args, ranks), env=ENV if env is None else env, cwd=cwd,
                          capture_output=True, text=True, timeout=timeout)


def read_steps(out) -> list[dict]:
    """The step records of a run folder (steps.jsonl), whole lines only."""
    text = (pathlib.Path(out) / "steps.jsonl").read_text()
    return [json.loads(line) for line in text.splitlines(keepends=True) if line.endswith("\n")]


def steps_done(out) -> int:
    """Whole lines in steps.jsonl (records of completed steps); 0 without the file."""
    try:
        return (pathlib.Path(out) / "steps.jsonl").read_bytes().count(b"\n")
    except OSError:
        return 0


# ---- faults: a run of the paper scene started, stopped and inspected ----

#: Every 2-rank failure must end the job within this many seconds.
EXIT_S = 30


def paper_command(ranks, out, steps=60, cells=16, *extra):
    """`contactvisco run paper` on a cells x cells mesh with `steps` steps, no figures."""
    return cli_command(["run", "paper", "--set", f"geometry.cells=[{cells}, {cells}]",
                        "--set", f"time.steps={steps}", "--set", "output.figures=false",
                        "--quiet", "--out", str(out), *extra], ranks)


def start_paper(ranks, out, steps=60, cells=16, *extra, log=None):
    """The paper run as a child process in a session of its own (stdout, stderr to files
    beside `out`: <log>.out, <log>.err)."""
    log = pathlib.Path(log or f"{out}.log")
    return subprocess.Popen(paper_command(ranks, out, steps, cells, *extra), env=ENV,
                            start_new_session=True, stdout=open(log.with_suffix(".out"), "w"),
                            stderr=open(log.with_suffix(".err"), "w"))


def run_paper(ranks, out, steps=60, cells=16, *extra, timeout=300):
    """The paper run to its end: the finished process, output captured as text."""
    return subprocess.run(paper_command(ranks, out, steps, cells, *extra), env=ENV,
                          capture_output=True, text=True, timeout=timeout)


def rank_pids(out, proc, ranks, timeout=120) -> list[int]:
    """The pids of the rank processes, from the lock file the run writes when it starts."""
    deadline = time.time() + timeout
    while time.time() < deadline and proc.poll() is None:
        try:
            pids = json.loads((pathlib.Path(out) / "contactvisco.io.lock").read_text())["pids"]
            if len(pids) == ranks:
                return pids
        except (OSError, ValueError, KeyError):
            pass
        time.sleep(0.02)
    raise RuntimeError(f"the run in {out} did not start (exit {proc.poll()})")


def alive(pid: int, wait_s: float = 5.0) -> bool:
    """Whether process pid still runs (a zombie awaiting its parent does not) after up to
    wait_s seconds."""
    deadline = time.time() + wait_s
    while True:
        try:
            state = pathlib.Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
        except OSError:
            return False
        if state in ("Z", "X"):
            return False
        if time.time() > deadline:
            return True
        time.sleep(0.05)


def wait_for(out, proc, steps, timeout=300) -> bool:
    deadline = time.time() + timeout
    while time.time() < deadline and proc.poll() is None:
        if steps_done(out) >= steps:
            return True
        time.sleep(0.005)
    return False


def end(proc, timeout=EXIT_S) -> tuple[int, float]:
    """Wait for the run to end: (exit code, seconds). Kills it (and fails) after timeout."""
    tick = time.time()
    try:
        code = proc.wait(timeout=timeout)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
        raise AssertionError(f"the run did not end within {timeout} s") from None
    return code, time.time() - tick




def kill_a_rank(out, proc, ranks, victim, at):
    """kill -9 of rank `victim` of a started run once `at` steps are done; the job must then
    end within EXIT_S with a non-zero code and no rank left running."""
    import os
    import signal
    pids = rank_pids(out, proc, ranks)
    assert wait_for(out, proc, at), "the run ended before the kill"
    os.kill(pids[victim], signal.SIGKILL)
    code, seconds = end(proc)
    assert code != 0 and seconds < EXIT_S
    assert not any(alive(pid) for pid in pids), "a rank runs on"

def mount_tmpfs(folder, size: str = "400k") -> bool:
    """A tmpfs of `size` mounted on the (empty) folder, to fill up: whether it could be
    mounted (root only)."""
    return subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size}", "tmpfs", str(folder)],
                          capture_output=True).returncode == 0


def grow_tmpfs(folder, size: str = "20m"):
    """Space freed on a full tmpfs: its size raised in place."""
    subprocess.run(["mount", "-o", f"remount,size={size}", str(folder)], check=True)


def unmount(folder, check: bool = False):
    subprocess.run(["umount", "-l", str(folder)], check=check)


def block_rank0_file(out):
    """A finished run's snapshots.npz overwritten by bytes that are no archive: only rank 0
    reads it on --restart, while the other ranks go on to a collective. (A folder in place
    of a file is refused by every rank before anything is read.)"""
    (pathlib.Path(out) / "snapshots.npz").write_bytes(b"PK\x03\x04 not an archive")

VTK_READ = """
import sys, vtk
reader = vtk.vtkXdmfReader()
reader.SetFileName(sys.argv[1])
reader.UpdateInformation()
times = reader.GetOutputInformation(0).Get(vtk.vtkStreamingDemandDrivenPipeline.TIME_STEPS())
reader.UpdateTimeStep(times[-1])
grid = reader.GetOutputDataObject(0)
print(len(times), times[-1], grid.GetNumberOfPoints(),
      grid.GetPointData().GetArray("u").GetNumberOfTuples())
"""


def vtk_read(path) -> tuple[int, float, int, int] | None:
    """What VTK's XDMF reader (the one ParaView offers) finds in `path`: number of times, the
    last time, points and u values at it; None without VTK. In a child process: VTK aborts in
    a process that has loaded DOLFINx."""
    proc = subprocess.run([sys.executable, "-c", VTK_READ, str(path)], capture_output=True,
                          text=True, timeout=120)
    if "No module named 'vtk'" in proc.stderr:
        return None
    n, t, points, values = proc.stdout.split()
    return int(n), float(t), int(points), int(values)


def check_folder(out, complete_steps=None, k=None) -> dict:
    """What a run (stopped at any moment) left in `out` is consistent and readable:
    every step record is whole and numbered 0..m-1; solution.xdmf lists each of them once,
    in order, at its time (and at most the one step after them), and every dataset it names
    reads back with its shape; contact_nodes.csv has whole rows of the same steps; the
    checkpoint is at most one step behind the records. With complete_steps, all of them must
    be there, at t = n k."""
    from contactvisco.io.h5read import check_xdmf
    from contactvisco.io.output import read_summary
    out = pathlib.Path(out)
    if not (out / "summary.json").exists():       # stopped during set-up: nothing written
        assert complete_steps is None and steps_done(out) == 0
        assert not (out / "checkpoint" / "meta.json").exists()
        return {"records": 0, "fields": 0, "csv_steps": 0, "checkpoint": None}
    records = read_summary(out)["steps"]
    m = len(records)
    assert [r["step"] for r in records] == list(range(m)), "step records out of order"
    series = check_xdmf(out / "solution.xdmf") if (out / "solution.xdmf").exists() else []
    times = [t for t, _ in series]
    assert len(times) in (m, m + 1), f"{len(times)} fields for {m} step records"
    assert times[:m] == [r["t"] for r in records], "XDMF times differ from the records"
    assert all(a < b for a, b in zip(times, times[1:])), "a step listed twice"
    for t, arrays in series:
        assert set(arrays) >= {"u", "sigma"}, f"t = {t}: fields {sorted(arrays)}"
    rows = []
    if (out / "contact_nodes.csv").exists():
        with open(out / "contact_nodes.csv", newline="") as f:
            rows = list(csv.DictReader(f))
    steps_in_csv = sorted({int(r["step"]) for r in rows})
    assert steps_in_csv[:m] == list(range(m)) and len(steps_in_csv) <= m + 1
    counts = {}
    for r in rows:
        counts[r["step"]] = counts.get(r["step"], 0) + 1
        assert None not in r.values() and r["status"] in ("separated", "compliance", "bound")
    assert len(set(counts.values())) <= 1, "a step with missing contact rows"
    checkpoint = None
    if (out / "checkpoint" / "meta.json").exists():
        checkpoint = json.loads((out / "checkpoint" / "meta.json").read_text())["count"]
        assert checkpoint in (m - 1, m), (checkpoint, m)
    if complete_steps is not None:
        assert m == complete_steps and len(times) == m
        assert max(abs(t - n * k) for n, t in enumerate(times)) < 1e-12
    return {"records": m, "fields": len(times), "csv_steps": len(steps_in_csv),
            "checkpoint": checkpoint}


# ---- linear algebra at a solved state ----

def mumps_lu(A, comm):
    """A KSP that solves with the matrix A by MUMPS's LU factorization alone."""
    from petsc4py import PETSc
    ksp = PETSc.KSP().create(comm)
    ksp.setOperators(A)
    ksp.setType("preonly")
    ksp.getPC().setType("lu")
    ksp.getPC().setFactorSolverType("mumps")
    return ksp


def condensed_at(problem):
    """The displacement-only Newton system at the problem's present state:
    (NodalCondensation, x), x the displacement as a PETSc vector with its ghost values."""
    from petsc4py import PETSc

    from contactvisco.fem import compat
    from contactvisco.solver.condensed import NodalCondensation
    system = NodalCondensation(problem)
    x = compat.petsc_vector(problem.u).copy()
    # copy() copies the owned values only: the lifting reads the ghosts too.
    x.ghostUpdate(addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)
    return system, x


# ---- the discrete contact conditions ----

def assert_contact_conditions(table, g, tol=1e-10, prescribed_tangential=None,
                              direction_tol=1e-8):
    """s <= g (s = u_nu - h the penetration); R = -lambda_nu >= 0 and (g - s) R = 0; the normal reaction is p_nu + R;
    |sigma_tau| <= radius (mu p_nu(u_nu), or mu (p_nu + R) for Coulomb's law), sigma_tau
    tangential; on sliding nodes sigma_tau = -radius slip / |slip| (slip: u_tau or its
    increment over the step). Returns the number of sliding nodes checked.

    prescribed_tangential: boolean mask of nodes whose tangential displacement is prescribed
    (their tangential reaction is carried by the Dirichlet condition).
    direction_tol: an error e in a node's friction equation turns sigma_tau by about
    e / (r |u_tau|), so the sliding direction gets a looser bound than the others."""
    import numpy as np
    u_nu, R = table["penetration"], -table["lambda_nu"]
    assert np.all(u_nu <= g + tol), np.max(u_nu - g)
    assert np.all(R >= -tol)
    if np.isfinite(g):
        assert np.max(np.abs((g - u_nu) * R)) < tol
    free = u_nu < g - 1e-6
    assert np.max(np.abs(R[free]), initial=0.0) < tol
    assert np.allclose(table["reaction_nu"], table["p_nu"] + R, atol=tol)

    # The slip the friction law acts on: u_tau, or the step's increment (slip = "increment").
    sig, ut, radius = table["sigma_tau_vector"], table["slip_vector"], table["radius"]
    assert np.all(np.linalg.norm(sig, axis=1) <= radius + tol)
    assert np.max(np.abs(np.einsum("ij,ij->i", sig, table["normal"]))) < tol
    sliding = (np.linalg.norm(ut, axis=1) > 1e-8) & (radius > 0)
    if prescribed_tangential is not None:
        sliding &= ~prescribed_tangential
    direction = ut[sliding] / np.linalg.norm(ut[sliding], axis=1)[:, None]
    expected = -radius[sliding, None] * direction
    assert np.max(np.abs(sig[sliding] - expected), initial=0.0) < direction_tol
    return int(sliding.sum())


# ---- steps that Newton cannot take within a limit: step cutting ----

#: Overrides of the ironing scene whose steps are hard for Newton: the moving load in 5 large
#: steps, ramped up from zero (t times the shipped load), so that the first state, which is
#: never cut, is u = 0 and takes no Newton iteration; each step starts from the last accepted
#: state (no predictor). The coupled Newton system, factorized at every iteration, gives the
#: same iterates in every run of a process: the condensed system solves with kept factors
#: inside FGMRES, whose iterates differ in their last digits from run to run on the PyPI route
#: (PETSc 3.25), and these steps' iteration counts move with such digits (docs/parallel.md,
#: Reproducibility).
HARD_IRONING = ["geometry.parameters.h=0.1", "time.steps=5", "output.probes=[]",
                "solver.predictor='none'", "solver.linear_system='coupled'",
                "traction.0.value=[0.0, '-60 * t * exp(-((x[0] - 0.4 - 2.2 * t) / 0.15)**2)']"]


def newton_limit(iterations) -> int:
    """One Newton iteration fewer than the most that a run without cuts took in a step. The
    same run with this limit (-snes_max_it) takes the same iterates up to the first step that
    needs more, so it must fail or cut that step, whatever the counts are on this stack."""
    iterations = list(iterations)
    limit = max(iterations) - 1
    assert limit >= 1 and iterations[0] == 0, f"no step to cut in {iterations}"
    return limit


# ---- a run stopped after a checkpoint ----

class StoppedAfterCheckpoint(Exception):
    """Raised by stop_after_checkpoint's wrapper of checkpoint.save."""


def run_stopped_after_checkpoint(monkeypatch, count, run):
    """run() with contactvisco.io.checkpoint.save wrapped so that the run stops (raises)
    right after the checkpoint of `count` accepted states; the original save is put back."""
    import pytest

    from contactvisco.io import checkpoint
    save = checkpoint.save

    def save_then_stop(folder, problem, comm, t, n, step, **records):
        save(folder, problem, comm, t, n, step, **records)
        if n == count:
            raise StoppedAfterCheckpoint

    monkeypatch.setattr(checkpoint, "save", save_then_stop)
    try:
        with pytest.raises(StoppedAfterCheckpoint):
            run()
    finally:
        monkeypatch.setattr(checkpoint, "save", save)


def diagonal_matrix(values):
    """A sequential PETSc AIJ matrix with `values` on its diagonal (for tests of the
    linear-solver pieces by themselves)."""
    from mpi4py import MPI
    from petsc4py import PETSc
    A = PETSc.Mat().createAIJ((len(values), len(values)), nnz=1, comm=MPI.COMM_SELF)
    for i, v in enumerate(values):
        A.setValue(i, i, v)
    A.assemble()
    return A
