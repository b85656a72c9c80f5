"""What a run prints: the start-up announcement (unknown counts, the converted (A, R) of a
[viscoelastic] material, the memory note, the warning of an unstable time rule), one progress
line per accepted state and the closing line. Lines
go to stdout on rank 0; the warning goes to stderr, and notes and warnings also to the output
folder's summary.json when a writer is given.
"""
from __future__ import annotations

import math
import sys
import weakref

from contactvisco.model.stability import worst_body
from contactvisco.scene.viscoelastic_table import describe

#: The memory note of a kernel whose history has no recursion (and no note of its own).
DIRECT_SUM_NOTE = ("memory: a general (table) kernel has no recursion: eq (19) is summed "
                   "directly, O(n) work and memory per step")


def printer(comm, enabled):
    """say(text): print a line on rank 0 when enabled (True, or "verbose": then the run also
    prints the residual of every Newton iteration; say.verbose tells)."""
    def say(text):
        if enabled and comm.rank == 0:
            print(text, file=sys.stdout, flush=True)
    say.verbose = enabled == "verbose"
    return say


def announce(scene, problem, snes, comm, setup_s, say, writer=None, output=None):
    """The output folder, the header line (ending with `output`, the estimate of what the run
    writes, when given), the memory note and the time-rule warning; with a verbose `say`, a
    line per Newton iteration from then on."""
    if writer is not None:
        say(f"writing to {writer.folder}")
    if getattr(say, "verbose", False):
        follow_iterations(snes, say)
    counts = problem.count_unknowns()
    contact_nodes = problem.count_contact_nodes()
    multipliers = ", ".join(name for name in counts if name != "u")
    say(f"contactvisco: scene '{scene['name']}', {comm.size} rank(s), {counts['u']} "
        f"displacement unknowns"
        + (f", {contact_nodes} contact nodes ({multipliers})" if contact_nodes else "")
        + f"; {snes.system_kind} system, {snes.describe_linear_solver()}; set-up (incl. JIT) "
        f"{setup_s:.2f} s" + (f"; {output}" if output else ""))
    converted = describe(scene)
    if converted:
        say(converted)
        if writer is not None:
            writer.note("notes", converted)
    note = memory_note(problem)
    if note:
        say(note)
        if writer is not None:
            writer.note("notes", note)
    warning = time_rule_warning(scene)
    if warning:
        if comm.rank == 0:
            print(f"contactvisco: {warning}", file=sys.stderr, flush=True)
        if writer is not None:
            writer.note("warnings", warning)


def follow_iterations(snes, say):
    """Print the residual of every Newton iteration of `snes` (a NewtonSolver): the norm its
    own monitor recorded (for the condensed system the norm of the full residual). The
    solver is held weakly: the SNES keeps the callback."""
    solver = weakref.ref(snes)

    def iteration(_, it, norm):
        newton = solver()
        if newton is not None and newton.residuals:
            say(f"  Newton {it:2d}  |F| = {newton.residuals[-1]:.3e}")
    snes.snes.setMonitor(iteration)


def memory_note(problem) -> str | None:
    """The history's own note (a fitted kernel's), or the note of a direct sum; None for a
    recursion without a note or no memory."""
    history = problem.memory and problem.memory.history
    if history is None or not (history.direct or hasattr(history, "note")):
        return None
    return getattr(history, "note", None) or DIRECT_SUM_NOTE


def time_rule_warning(scene) -> str | None:
    """The warning of the paper's time rule at k R(0) (1 + nu) / E >= 1, else None."""
    b, body = worst_body(scene)
    if scene["time"]["rule"] != "paper" or b < 1.0:
        return None
    steps = scene["time"]["steps"]
    where = "" if body is None else f" in body {body!r}"
    more = (f"time.steps > {math.ceil(steps * b)}" if scene["time"]["grid"] == "uniform" else
            "smaller steps where the grid's are largest")
    return (f"warning: the paper's time rule is unstable here{where}: k R(0) (1 + nu) / E "
            f"= {b:.3g} >= 1; use more steps ({more}) or time.rule = 'trapezoid'")


def progress_line(record: dict, t_end: float) -> str:
    """The line of an accepted state: step, time, iterations, residual, node states, wall
    time and the step cut that reached it."""
    krylov = record["krylov_iterations"]
    cuts = record["cuts"]
    return (f"step {record['step']:4d}  t = {record['t']:.4g}/{t_end:g}  Newton "
            f"{record['newton_iterations']:2d}  "
            + (f"Krylov {max(krylov):3d} max  " if krylov and max(krylov) > 1 else "")
            + f"|F| = {record['residual']:.2e}  "
            + " ".join(f"{key} {value}" for key, value in record["status_counts"].items())
            + f"  {record['wall_s']:.3f} s" + (f"  (cut x{2 ** cuts})" if cuts else ""))


def closing_line(final: dict, t_end: float) -> str:
    """The last line: the run's wall time and the node states at T."""
    return (f"done in {final['wall_s']:.2f} s; at t = {t_end:g}: "
            + ", ".join(f"{v} {key}" for key, v in final["status_counts"].items()))


def tangent_warning(record: dict, problem, comm, writer, warned: bool) -> bool:
    """With a nonlinear A, the smallest eigenvalue of its tangent at the accepted state into
    the step record (``tangent_min``, over 2 mu; contactvisco.fem.tangent) and, the first
    time it is <= 0, a warning naming the point and the time (stderr on rank 0 and the output
    folder's warnings). Returns whether the warning has been given."""
    if problem.tangent is None:
        return warned
    check = problem.tangent.smallest(comm)
    record["tangent_min"] = check["ratio"]
    if check["ratio"] > 0 or warned:
        return warned
    x = ", ".join(f"{c:.4g}" for c in check["x"][:problem.V.mesh.geometry.dim])
    warning = (f"warning: material.law: the tangent of A = dW/deps is not positive definite "
               f"at x = ({x}) at t = {record['t']:g} (smallest eigenvalue {check['ratio']:.3g} "
               "x 2 mu): W is not convex there, the solution may not be unique")
    if comm.rank == 0:
        print(f"contactvisco: {warning}", file=sys.stderr, flush=True)
    if writer is not None:
        writer.note("warnings", warning)
    return True

