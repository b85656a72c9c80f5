"""The time loop of eqs (20)-(21): t_0 = 0 (no history yet), then n = 1..N with k = T/N."""
from __future__ import annotations

import math
import pathlib
import sys
import time as clock
from dataclasses import dataclass, field

from dolfinx import fem
from mpi4py import MPI

from . import checkpoint
from . import geometry as geometry_module
from . import output
from . import parallel
from . import scene as scene_module
from .lock import FolderLock
from .problem import Problem, build
from . import solver as solver_module
from .solver import NewtonFailure


@dataclass
class Result:
    problem: Problem
    steps: list = field(default_factory=list)        # the summary.json step records
    tables: list = field(default_factory=list)       # contact_table per step (every rank)
    linear_system: str = ""                           # condensed | coupled | displacement
    linear_solver: str = ""                           # KSP/PC, e.g. preonly/lu


def simulate(scene: dict, out=None, comm=MPI.COMM_WORLD, progress=True,
             keep_tables=False, restart=False, overwrite=True) -> Result:
    """Solve a resolved scene; write results into folder `out` when given, with a checkpoint
    after every step; restart=True continues from the checkpoint in `out`. The run holds the
    folder (contactvisco.lock); an earlier run's files in it are replaced when overwrite is
    true, else refused. SIGINT/SIGTERM stop every rank after the same step (parallel.Stopped).
    """
    started = clock.perf_counter()
    parallel.prepare(comm)          # collective: while every rank is still in step
    folder_lock = FolderLock(out, comm, restart, overwrite) if out else None
    snes, held = None, {}          # held: what must be closed however the run ends
    signals = parallel.catch_signals()
    try:
        geometry = geometry_module.build(scene, comm)
        problem = build(scene, geometry)
        snes = solver_module.create(problem, comm)
        result = _simulate(scene, out, comm, progress, keep_tables, restart, started,
                           problem, snes, held)
    except BaseException as err:
        # Destroying the SNES is collective: only when every rank failed.
        if not parallel.together(comm, err):
            snes = None
        raise
    finally:
        parallel.restore_signals(signals)
        if snes is not None:
            snes.destroy()
        if held.get("writer") is not None:
            held["writer"].close()
        if folder_lock is not None:
            folder_lock.release()
    return result


def _simulate(scene, out, comm, progress, keep_tables, restart, started, problem, snes,
              held) -> Result:
    geometry = problem.geometry
    setup_s = clock.perf_counter() - started
    opts = scene["output"]
    probes = output.Probes(geometry.mesh, opts["probes"]) if opts["probes"] else None
    sigma = fem.Function(problem.T, name="sigma")
    resumed = checkpoint.load(out, problem, comm) if restart else None
    writer = output.Writer(out, problem, comm, xdmf=opts["xdmf"],
                           restart_count=resumed and resumed["count"]) if out else None
    held["writer"] = writer
    T, N = scene["time"]["T"], scene["time"]["steps"]
    k = T / N
    figure_steps = {min(N, max(0, round(t / k))) for t in opts["figure_times"]} | {N}
    snapshots = []
    result = Result(problem, linear_system=snes.system_kind, linear_solver=snes.linear_solver())
    say = _printer(comm, progress)
    counts = problem.count_unknowns()
    contact_nodes = problem.count_contact_nodes()
    multipliers = ", ".join(name for name in counts if name != "u")
    say(f"contactvisco: scene '{scene['name']}', {comm.size} rank(s), {counts['u']} "
        f"displacement unknowns"
        + (f", {contact_nodes} contact nodes ({multipliers})" if contact_nodes else "")
        + f"; {snes.system_kind} system, {snes.linear_solver()}; set-up (incl. JIT) "
        f"{setup_s:.2f} s")

    if problem.history is not None and (problem.history.direct
                                        or hasattr(problem.history, "note")):
        note = getattr(problem.history, "note", None) or (
            "memory: a general (table) kernel has no recursion: eq (19) is summed "
            "directly, O(n) work and memory per step")
        say(note)
        if writer is not None:
            writer.note("notes", note)

    b = scene_module.stability_number(scene)
    if scene["time"]["rule"] == "paper" and b >= 1.0:
        warning = (f"warning: the paper's time rule is unstable here: k R(0) (1 + nu) / E = "
                   f"{b:.3g} >= 1; use more steps (time.steps > {math.ceil(N * b)}) or "
                   "time.rule = 'trapezoid'")
        if comm.rank == 0:
            print(f"contactvisco: {warning}", file=sys.stderr, flush=True)
        if writer is not None:
            writer.note("warnings", warning)

    figure_times = {round(i * k, 12) for i in figure_steps}
    # The figure snapshots gather the whole mesh on rank 0: skipped on large meshes.
    skip_snapshots = writer is not None and opts["figures"] and output.snapshot_skip_note(
        problem, opts["snapshot_max_nodes"], writer.xdmf is not None)
    if skip_snapshots:
        writer.note("notes", skip_snapshots)    # a restarted run keeps its earlier notes
        say(skip_snapshots)
    state = {"t": 0.0, "count": 0, "table": None}
    if resumed:
        state.update(t=resumed["t"], count=resumed["count"])
        if comm.rank == 0 and (pathlib.Path(out) / "snapshots.npz").exists():
            snapshots = output.read_snapshots(pathlib.Path(out) / "snapshots.npz", resumed["t"])
        say(f"restarting from the checkpoint at t = {resumed['t']:g} (step "
            f"{resumed['count'] - 1})")

    def accept(t, iterations, wall, cuts):
        """Record a converged state: tables, probes, files, figures, progress."""
        n = state["count"]
        table = output.contact_table(problem, comm)
        counts = output.status_counts(table)
        record = {"step": n, "t": t, "newton_iterations": iterations,
                  "residual": snes.residuals[-1] if snes.residuals else 0.0,
                  "residual_history": snes.residuals, "wall_s": wall, "cuts": cuts,
                  "krylov_iterations": snes.krylov_iterations,
                  "status_counts": counts,
                  "probes": probes.values(problem.u, comm) if probes else []}
        result.steps.append(record)
        if keep_tables:
            result.tables.append(table)
        if writer is not None:
            fields = []
            if writer.xdmf is not None:
                if "sigma" in opts["fields"]:
                    sigma.interpolate(problem.sigma_expression)
                available = {"u": problem.u, "sigma": sigma, "history_stress": problem.H,
                             "lambda_nu": problem.lambda_nu, "lambda_tau": problem.lambda_tau}
                fields = [available[name] for name in opts["fields"]
                          if available[name] is not None]
            writer.step(record, table, fields)
            if round(t, 12) in figure_times and opts["figures"] and not skip_snapshots:
                if writer.xdmf is None or "sigma" not in opts["fields"]:
                    sigma.interpolate(problem.sigma_expression)
                gathered = output.gather_mesh(problem, sigma, comm)
                if gathered is not None:
                    snapshots.append((t,) + gathered)
                    output.write_snapshots(pathlib.Path(out) / "snapshots.npz", snapshots)
        krylov = snes.krylov_iterations
        say(f"step {n:4d}  t = {t:.4g}/{T:g}  Newton {iterations:2d}  "
            + (f"Krylov {max(krylov):3d} max  " if krylov and max(krylov) > 1 else "")
            + f"|F| = {record['residual']:.2e}  "
            + " ".join(f"{key} {value}" for key, value in counts.items())
            + f"  {wall:.3f} s" + (f"  (cut x{2 ** cuts})" if cuts else ""))
        state.update(t=t, count=n + 1, table=table)

    def solve_to(t_new, cuts):
        """One step to t_new; on failure restore the unknowns and take it in two halves,
        at most solver.max_cuts times in a row."""
        tick = clock.perf_counter()
        step = t_new - state["t"]
        saved = [f.x.array.copy() for f in problem.unknowns]
        problem.set_time(t_new)
        if state["count"] > 0:
            problem.prepare(step)        # H from u_0 .. u_n (eq 19, any step sizes)
        try:
            iterations = snes.solve()
        except NewtonFailure as err:
            for f, values in zip(problem.unknowns, saved):
                f.x.array[:] = values
            if state["count"] == 0 or cuts >= scene["solver"]["max_cuts"]:
                # A body held by friction alone under too large a tangential load: say so.
                limit = output.friction_limit(problem, comm, state["table"])
                cut_note = f" after {cuts} cuts" if cuts else ""
                raise NewtonFailure(
                    f"step to t = {t_new:g} (from t = {state['t']:g}{cut_note}): "
                    + (f"{limit}; {err}" if limit else
                       f"{err}; {likely_cause(err, scene, state['count'])}"),
                    err.reason, err.residuals) from None
            say(f"step to t = {t_new:.4g} failed (SNES reason {err.reason}); "
                f"taking it in two halves")
            solve_to(state["t"] + 0.5 * step, cuts + 1)
            solve_to(t_new, cuts + 1)
            return
        problem.commit(None if state["count"] == 0 else step)
        accept(t_new, iterations, clock.perf_counter() - tick, cuts)
        if out and opts["checkpoint"]:
            checkpoint.save(out, problem, comm, t_new, state["count"], step)
        signum = parallel.stop_requested(comm)
        if signum:                        # every rank stops after this same step
            raise parallel.Stopped(signum, state["count"] - 1, t_new)

    for n in range(N + 1):
        if resumed and n * k <= state["t"] + 1e-12 * T:
            continue                      # done before the restart
        solve_to(n * k, 0)
    table = state["table"]

    if table is None and writer is not None and writer.last_record:
        counts = writer.last_record["status_counts"]     # nothing left after a restart
    else:
        counts = output.status_counts(table)
    final = {"t": T, "status_counts": counts,
             "wall_s": clock.perf_counter() - started, "setup_s": setup_s}
    if writer is not None:
        writer.finish(final)
        if comm.rank == 0 and opts["figures"]:
            from . import figures
            try:
                figures.draw_all(pathlib.Path(out))
            except Exception as err:   # the results are written; a figure must not lose them
                print(f"contactvisco: warning: figures failed ({type(err).__name__}: {err}); "
                      f"the results in {out} are complete; retry with 'contactvisco plot "
                      f"{out}'", file=sys.stderr, flush=True)
    say(f"done in {final['wall_s']:.2f} s; at t = {T:g}: "
        + ", ".join(f"{v} {key}" for key, v in final["status_counts"].items()))
    return result


def likely_cause(err: NewtonFailure, scene: dict, step: int) -> str:
    """A hint from the SNES reason and the scene."""
    if err.reason == -3:
        return ("likely cause: the linear solve failed; is the body held (Dirichlet conditions "
                "or a contact law with stiffness) against every rigid motion?")
    if err.reason == -4:
        return ("likely cause: the residual became NaN or Inf; check expressions for "
                "divisions by zero or overflow, and extreme parameter values")
    if err.reason == -5:
        hint = "likely cause: too large a step for the contact state to settle"
        if step > 0 and scene["time"]["rule"] == "paper" and \
                scene_module.stability_number(scene) >= 1:
            hint += " (the paper's time rule is unstable at this step: use 'trapezoid')"
        return hint + "; try more time steps or raise -snes_max_it"
    return "see the residual history"


def _printer(comm, enabled):
    def say(text):
        if enabled and comm.rank == 0:
            print(text, file=sys.stdout, flush=True)
    return say
