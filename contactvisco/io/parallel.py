"""Stopping an MPI run together: an error on one rank, or a signal, ends every rank.

Two ways a run stops early, both ending every rank with one message and a non-zero exit:

- An error. The rank that raised it cannot know whether the others raised it too (a scene
  error, a Newton failure: collective) or are blocked in a collective waiting for it (a file
  only rank 0 writes, a full disk on one node). `fail_together` lets the failing ranks meet in
  a non-blocking barrier on a communicator of their own for a few seconds: if every rank
  arrives, the error was collective and rank 0 prints it once; if not, the failing rank prints
  its message and calls MPI_Abort, the only way to end a rank blocked in a collective. Clean-up
  that is itself collective (destroying the SNES) runs only when every rank failed
  (`together`): called by one rank alone, it would block like any collective.
- SIGINT (Ctrl-C) or SIGTERM (a batch system's wall-time limit, forwarded to the ranks by
  mpirun). The handler only sets a flag; after each step the ranks take the maximum of their
  flags (`stop_requested`, one small allreduce per step), so all stop after the same step, with
  its files and checkpoint written, and exit with 128 + the signal number.
"""
from __future__ import annotations

import contextlib
import os
import signal
import sys
import time

#: How long the ranks that raised an error wait for the others before aborting [s].
AGREE_S = 3.0
#: How long a rank that aborts the job waits after printing its message [s]: MPICH's
#: launcher drops the output it has not yet forwarded when it ends the job.
FORWARD_S = 1.0


class Stopped(Exception):
    """A signal asked the run to stop; raised on every rank after the same step."""

    def __init__(self, signum: int, step: int, t: float):
        self.signum, self.step, self.t = signum, step, t
        name = signal.Signals(signum).name
        super().__init__(f"stopped by {name} after step {step} (t = {t:g}); the files hold "
                         "every step up to it; continue with --restart")

    @property
    def exit_code(self) -> int:
        return 128 + self.signum


class Signalled(KeyboardInterrupt):
    """SIGINT or SIGTERM outside the time loop (start-up, figures), where there is no step to
    finish: the command ends at once with 128 + the signal number."""

    def __init__(self, signum: int):
        super().__init__(f"stopped by {signal.Signals(signum).name}")
        self.signum = signum
        self.reported = False            # True once a message has said what was stopped

    @property
    def exit_code(self) -> int:
        return 128 + self.signum


def _raise_signalled(signum, frame):
    raise Signalled(signum)


def stop_at_once() -> dict:
    """SIGINT and SIGTERM raise Signalled from here on (the time loop replaces this with its
    stop after a whole step, and restores it); returns the previous handlers. Main thread
    only."""
    import threading
    if threading.current_thread() is not threading.main_thread():
        return {}
    return {s: signal.signal(s, _raise_signalled) for s in (signal.SIGINT, signal.SIGTERM)}


def exit_at_once(signum, frame):
    """A handler for the command's first moments, before anything is written: one line
    (on the first rank) and exit 128 + signum at once, without the clean-up of half-started
    libraries (MPI, PETSc), which can crash when interrupted."""
    if first_rank():
        print(f"contactvisco: stopped by {signal.Signals(signum).name}", file=sys.stderr,
              flush=True)
    os._exit(128 + signum)


def command_line_start_up():
    """If this process runs the command line (`contactvisco ...` or `python -m contactvisco`),
    SIGINT and SIGTERM end it at once (exit_at_once) until `main` takes them over; a
    library import changes no handler. Main thread only."""
    import pathlib
    import threading
    argv = list(getattr(sys, "orig_argv", []))
    command = any(a == "-m" and b == "contactvisco" for a, b in zip(argv, argv[1:])) or (
        bool(sys.argv) and pathlib.Path(sys.argv[0]).name == "contactvisco")
    if command and threading.current_thread() is threading.main_thread():
        for s in (signal.SIGINT, signal.SIGTERM):
            signal.signal(s, exit_at_once)


@contextlib.contextmanager
def signals_deferred():
    """SIGINT and SIGTERM held back (blocked) inside the block and delivered when it ends:
    for the native start-up of PETSc and DOLFINx (MPI, the extension modules), which an
    exception raised in the middle of it can leave half made, so that the process crashes on
    its way out. Main thread only (elsewhere a no-op)."""
    import threading
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    held = {signal.SIGINT, signal.SIGTERM}
    previous = signal.pthread_sigmask(signal.SIG_BLOCK, held)
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, previous)


def interrupted_by(err: BaseException):
    """The KeyboardInterrupt (or Signalled) that caused `err`, if one did: Python wraps an
    interrupt raised inside some machinery (a class's __set_name__ while a module is
    imported) in a RuntimeError."""
    seen = set()
    while err is not None and id(err) not in seen:
        if isinstance(err, KeyboardInterrupt):
            return err
        seen.add(id(err))
        err = err.__cause__ or err.__context__
    return None


def first_rank() -> bool:
    """Whether this process is rank 0 of its launcher, read from the environment (usable
    before MPI starts: Open MPI, MPICH/Hydra and PMIx name the rank); True without one."""
    for name in ("OMPI_COMM_WORLD_RANK", "PMI_RANK", "PMIX_RANK", "MPI_LOCALRANKID"):
        if os.environ.get(name) not in (None, ""):
            return os.environ[name] == "0"
    return True


_requested = {"signum": 0}


def _handler(signum, frame):
    if _requested["signum"]:          # a second signal: stop now
        signal.signal(signum, signal.SIG_DFL)
        signal.raise_signal(signum)
    _requested["signum"] = signum


def catch_signals():
    """Turn SIGINT and SIGTERM into a stop request (returns the previous handlers). Only the
    main thread may set handlers: elsewhere the signals keep theirs."""
    import threading
    _requested["signum"] = 0
    if threading.current_thread() is not threading.main_thread():
        return {}
    return {s: signal.signal(s, _handler) for s in (signal.SIGINT, signal.SIGTERM)}


def restore_signals(previous: dict):
    for s, handler in previous.items():
        signal.signal(s, handler)


def stop_requested(comm) -> int:
    """The signal number any rank received (0 for none); collective."""
    from mpi4py import MPI
    return comm.allreduce(_requested["signum"], op=MPI.MAX)


def together(comm, err: BaseException, wait_s: float = AGREE_S) -> bool:
    """Whether every rank raised an error (then all may clean up collectively and report it
    once) or only some (the others are blocked elsewhere, e.g. in a collective: nothing
    collective may be called any more). Decided once per error: the answer is kept on it."""
    known = getattr(err, "_contactvisco_together", None)
    if known is not None:
        return known
    answer = True
    if comm.size > 1:
        # A communicator of its own: this barrier can never match a collective of the run.
        request = _agreement_comm(comm).Ibarrier()
        deadline = time.monotonic() + wait_s
        while not request.Test():
            if time.monotonic() > deadline:
                answer = False
                break
            time.sleep(0.01)
    try:
        err._contactvisco_together = answer
    except AttributeError:
        pass
    return answer


def fail_together(comm, code: int, message: str, err: BaseException) -> int:
    """Called by a rank that caught error `err`: print `message` once for the whole run and
    return `code`, or abort every rank with it when the other ranks did not fail too."""
    if comm.size == 1:
        _print(message)
        return code
    from mpi4py import MPI
    if not together(comm, err):
        _print(f"{message} [rank {comm.rank}; ending all {comm.size} ranks]")
        time.sleep(FORWARD_S)
        comm.Abort(code)
        os._exit(code)      # MPICH's MPI_Abort may return to the caller before the launcher
                            # ends the job: this rank must not go on (and print again)
    agree = _agreement_comm(comm)
    if comm.rank == 0:                 # every rank failed: rank 0's message, once
        _print(message)
    return agree.allreduce(code, op=MPI.MAX)


_comms = {}


def _agreement_comm(comm):
    """comm.Dup(), made once per communicator: call `prepare(comm)` before anything can fail,
    because Dup is itself collective."""
    key = comm.py2f()
    if key not in _comms:
        _comms[key] = comm.Dup()
    return _comms[key]


def prepare(comm):
    """Create the agreement communicator while every rank is still in step (collective)."""
    if comm.size > 1:
        _agreement_comm(comm)


#: How an error that only this rank raised is reported before every rank ends:
#: err -> (exit code, message). The command line sets its own (`describe_with`).
_describe = {"function": None}


def describe_with(function) -> None:
    """Report errors raised on one rank alone with `function(err) -> (code, message)`."""
    _describe["function"] = function


def _default_description(err: BaseException) -> tuple[int, str]:
    """Exit 2 for a scene error, 128 + N for a stop by signal N, else 1; the message names
    the error and the line that raised it (the caller's code for an on_step callback)."""
    import traceback

    from contactvisco.errors import SceneError
    if isinstance(err, SceneError):
        return 2, f"contactvisco: scene error: {err}"
    frames = traceback.extract_tb(err.__traceback__)
    where = f" ({frames[-1].filename}, line {frames[-1].lineno}, in {frames[-1].name})" \
        if frames else ""
    return getattr(err, "exit_code", 1), f"contactvisco: error: {type(err).__name__}: {err}{where}"


def end_if_alone(comm, err: BaseException) -> None:
    """Called by a rank that caught `err` inside a collective phase (the time loop, a user's
    on_step): if the other ranks did not raise too, they wait in a collective that will never
    complete, and raising `err` to the caller would leave them there for ever; every rank is
    then ended with one message (fail_together). Returns when the error is collective."""
    if comm.size == 1 or together(comm, err):
        return
    code, message = (_describe["function"] or _default_description)(err)
    fail_together(comm, code, message, err)


def same_scene(comm, scene) -> None:
    """Every rank runs the same scene (collective): a digest of the scene's canonical text is
    compared across the ranks before anything is built, since ranks that build different
    meshes or forms wait for each other for ever. Different scenes raise SceneError on every
    rank, naming the keys that differ from rank 0's."""
    if comm.size == 1:
        return
    import hashlib
    import json

    from contactvisco.errors import SceneError
    from contactvisco.scene.loader import differences, plain_copy
    plain = plain_copy(scene)
    text = json.dumps(plain, sort_keys=True, default=repr)
    digests = comm.allgather(hashlib.sha256(text.encode()).hexdigest())
    if len(set(digests)) == 1:
        return
    first = comm.bcast(plain if comm.rank == 0 else None, root=0)
    keys = sorted(differences(first, plain))
    named = comm.allgather(keys)
    ranks = [r for r, d in enumerate(digests) if d != digests[0]]
    keys = sorted({k for ks in named for k in ks})
    raise SceneError(f"the ranks were given different scenes: rank(s) "
                     f"{', '.join(map(str, ranks))} differ from rank 0 in "
                     f"{', '.join(keys[:5]) + (' ...' if len(keys) > 5 else '')}; start every "
                     "rank with the same scene file and --set values")


def _print(message: str):
    print(message, file=sys.stderr, flush=True)
