"""The time loop of eqs (20)-(21): t_0 = 0 (no history yet), then the step times t_1 .. t_N
of the scene's grid (contactvisco.model.time_grid: uniform, logarithmic, piecewise or given
times), each step of its own size k_n = t_n - t_{n-1}.

The loop is plain: `advance` solves one step and yields the accepted states (more than one
when the step had to be cut), and every accepted state goes to the observers in turn: the
result, the output writer, the figure snapshots, the progress line and the caller's
`on_step`; then the checkpoint. The records and contact rows are written for every accepted
state; the XDMF fields and the checkpoint on the schedule of [output] (FieldSchedule,
contactvisco.io.checkpoint.Schedule), both counted in accepted states and always at the
final one.
"""
from __future__ import annotations

import math
import pathlib
import time as clock
from dataclasses import dataclass, field

import numpy as np
from dolfinx import fem
from mpi4py import MPI

from contactvisco.errors import SceneError
from contactvisco.fem import contact_state
from contactvisco.fem import geometry as geometry_module
from contactvisco.fem.probes import Probes
from contactvisco.fem.problem import Problem, build
from contactvisco.io import checkpoint, output, parallel
from contactvisco.io.lock import FolderLock
from contactvisco.model import time_grid
from contactvisco.solver import coarse_start, diagnosis, predictor, report, step_control
from contactvisco.solver.field_schedule import FieldSchedule
from contactvisco.solver import newton as solver_module
from contactvisco.solver.newton import NewtonFailure, SlidingLimit


@dataclass
class Result:
    """What a run gives back (``solve`` makes it).

    Parameters
    ----------
    problem : contactvisco.fem.problem.Problem
        The solved problem; its fields hold the state at the last accepted step.
    steps : list of dict, optional
        The step records of steps.jsonl, one per accepted state (t = 0 included).
    tables : list of dict, optional
        The contact table of each step when kept (see ``contact``).
    linear_system : str, optional
        ``"condensed"``, ``"coupled"`` or ``"displacement"``.
    linear_solver : str, optional
        The Krylov method and preconditioner, e.g. ``"preonly/lu"``; where
        ``linear_solver = "auto"`` takes another one for the states after the first
        (``newton.AUTO_DIRECT_LATER``), both: ``"gmres/hypre; after the first state
        preonly/lu"``.
    final : dict, optional
        The summary's final record: ``t``, ``status_counts``, timings.
    """
    problem: Problem
    steps: list = field(default_factory=list)        # the summary.json step records
    tables: list = field(default_factory=list)       # contact_table per step (every rank)
    linear_system: str = ""                           # condensed | coupled | displacement
    linear_solver: str = ""                           # KSP/PC, e.g. preonly/lu
    final: dict = field(default_factory=dict)

    @property
    def u(self):
        """The displacement (a ``dolfinx.fem.Function``, P1 or P2) at the last accepted
        step."""
        return self.problem.u

    @property
    def contact(self) -> list:
        """The contact table of each accepted step: a dict of numpy arrays per step, one
        entry per contact node of the whole mesh (on every rank), sorted by position: ``x``,
        ``u_nu``, ``u_tau``, ``p_nu``, ``lambda_nu``, ``reaction_nu``, ``reaction_tau``,
        ``status`` (0 separated, 1 compliance, 2 bound), ... (see
        ``contactvisco.fem.contact_state.contact_table``); None entries when the scene has no
        contact."""
        return self.tables


@dataclass
class Accepted:
    """A converged state at time t, reached by a step of size k (None: the first state)."""
    t: float
    k: float | None
    iterations: int
    wall_s: float
    cuts: int


class StepFailed(Exception):
    """Newton failed on a step that may not be cut further."""

    def __init__(self, t_from, t_to, cuts, failure: NewtonFailure):
        super().__init__(str(failure))
        self.t_from, self.t_to, self.cuts, self.failure = t_from, t_to, cuts, failure


def simulate(scene: dict, out=None, comm=MPI.COMM_WORLD, progress=True,
             keep_tables=False, restart=False, overwrite=True, geometry=None,
             on_step=None) -> Result:
    """Solve a resolved scene; write results into folder `out` when given, with a checkpoint
    on the schedule of its [output] table (every step by default); restart=True continues
    from the checkpoint in `out`. The run holds the folder (contactvisco.io.lock); an earlier
    run's files in it are replaced when overwrite is true, else refused. SIGINT/SIGTERM stop
    every rank after the same step (parallel.Stopped). `geometry` replaces the scene's own
    mesh; on_step(record) is called after every accepted step.
    """
    started = clock.perf_counter()
    parallel.prepare(comm)          # collective: while every rank is still in step
    parallel.same_scene(comm, scene)
    folder_lock = FolderLock(out, comm, restart, overwrite) if out else None
    snes, problem, run, held = None, None, None, {}  # held: closed however the run ends
    signals = parallel.catch_signals()
    try:
        geometry = geometry or geometry_module.build(scene, comm)
        problem = build(scene, geometry)
        from contactvisco.solver.check import initial_penetration, output_limit
        initial_penetration(problem, comm)
        estimate = None
        if out:                           # before a step, and before the solver's set-up
            estimate = output_limit(scene, problem, out)
        snes = solver_module.create(problem, comm, later=restart)
        run = Run(scene, out, comm, problem, snes, progress, restart, started)
        run.output_estimate = estimate
        held["writer"] = run.writer
        held["coarse"] = getattr(run.predictor, "release", None)
        result = run.loop(keep_tables, on_step)
    except BaseException as err:
        # Destroying the SNES is collective: only when every rank failed.
        if not parallel.together(comm, err):
            snes = problem = None              # nothing collective on the way out
            if isinstance(err, Exception):     # the others wait in a collective: end them
                parallel.end_if_alone(comm, err)
        raise
    finally:
        parallel.restore_signals(signals)
        if snes is not None:
            snes = run.snes if run is not None else snes   # the later states' solver
            snes.destroy()
            if held.get("coarse") is not None:     # collective too
                held["coarse"]()
        if held.get("writer") is not None:
            held["writer"].close()
        if folder_lock is not None:
            folder_lock.release()
        if problem is not None:
            snes = run = held = None           # the solver's PETSc objects become garbage
            problem.release_garbage()
    return result


class Run:
    """One run's fixed parts: the scene, the problem and solver, the output writer, the
    printer; `loop` takes the steps."""

    def __init__(self, scene, out, comm, problem, snes, progress, restart, started):
        self.scene, self.out, self.comm = scene, out, comm
        self.problem, self.snes, self.started = problem, snes, started
        self.setup_s = clock.perf_counter() - started
        self.say = report.printer(comm, progress)
        points = scene["output"]["probes"]
        self.probes = Probes(problem.geometry.mesh, points) if points else None
        self.resumed = checkpoint.load(out, problem, comm) if restart else None
        self.predictor = predictor.create(scene, problem)
        if not self.resumed:                  # a restart has no coarse history
            self.predictor = coarse_start.create(scene, problem, comm, self.predictor,
                                                 self.say)
        opts = scene["output"]
        self.writer = output.Writer(out, problem, comm, xdmf=opts["xdmf"],
                                    restart_count=self.resumed and self.resumed["count"],
                                    records=self.resumed and self.resumed.get("records")
                                    ) if out else None

    def loop(self, keep_tables, on_step) -> Result:
        """Steps n = 0..N (those after a restart point only); every accepted state goes to
        the observers."""
        scene, problem, snes, comm = self.scene, self.problem, self.snes, self.comm
        t_end, grid = scene["time"]["T"], time_grid.times(scene["time"])
        report.announce(scene, problem, snes, comm, self.setup_s, self.say, self.writer,
                        getattr(self, "output_estimate", None))
        result = Result(problem, linear_system=snes.system_kind,
                        linear_solver=snes.linear_solver())
        observers = [recorder(result, keep_tables), *self._file_observers(),
                     lambda record, table: self.say(report.progress_line(record, t_end))]
        opts = scene["output"]
        self.checkpoints = checkpoint.Schedule(comm, opts["checkpoint_every"],
                                               opts["checkpoint_seconds"])
        if on_step is not None:
            observers.append(lambda record, table: on_step(record))
        t, count, table = 0.0, 0, None
        self.tangent_warned = False
        if self.resumed:
            t, count = self.resumed["t"], self.resumed["count"]
            self.say(f"restarting from the checkpoint at t = {t:g} (step {count - 1})")
        last = len(grid) - 1
        self.control = None
        if time_grid.adaptive(scene["time"]):     # the times come as the states are accepted
            self.control = step_control.Controller(
                scene["time"], problem, comm, self.resumed and self.writer.last_record)
            grid, last = self.control.times(), None
        for n, t_n in enumerate(grid):
            t_n = float(t_n)
            if self.resumed and t_n <= t + 1e-12 * t_end:
                continue                      # done before the restart
            try:
                for state in advance(problem, snes, t_n, scene["solver"]["max_cuts"],
                                     self.say, predict=self.predictor):
                    check_sliding(problem, state.t, count)
                    table = contact_state.contact_table(problem, comm)
                    record = self._record(count, state, table)
                    self.tangent_warned = report.tangent_warning(
                        record, problem, comm, self.writer, self.tangent_warned)
                    for observe in observers:
                        observe(record, table)
                    t, count = state.t, count + 1
                    self._checkpoint(state, count, final=state.t == t_n and (
                        n == last or (last is None and t_n == t_end)))
            except StepFailed as failed:
                raise diagnosis.step_failure(problem, comm, failed.t_from, failed.t_to,
                                             failed.cuts, failed.failure, table,
                                             count) from None
            snes = self._later_solver(snes, result)
        result.final = self._finish(table, t_end)
        return result

    def _later_solver(self, snes, result):
        """The solver of the states after the first (newton.for_later_states), announced and
        added to the result's linear_solver where it is another one."""
        later = solver_module.for_later_states(self.problem, self.comm, snes)
        if later is snes:
            return snes
        self.snes = later
        if later.auto_direct:
            result.linear_solver += f"; after the first state {later.linear_solver()}"
            self.say(f"  the states after the first: {later.describe_linear_solver()}")
        else:
            result.linear_solver += f"; after {snes.solves} solves {later.linear_solver()}"
            self.say(f"  back to {later.describe_linear_solver()}: the direct solver "
                     f"factorized {snes.all_setups} times in {snes.solves} solves")
        return later

    def _record(self, n, state: Accepted, table) -> dict:
        """The step record of steps.jsonl."""
        snes, probes = self.snes, self.probes
        control = getattr(self, "control", None)
        # adaptive grid: the relative estimate of the step's memory error (step_control)
        error = {} if control is None else {"error": control.accepted(state.t, state.k)}
        # k: the step actually taken (a cut step's halves have their own), None at t_0
        return {"step": n, "t": state.t, "k": state.k, "newton_iterations": state.iterations,
                "residual": snes.residuals[-1] if snes.residuals else 0.0,
                "residual_history": snes.residuals, "wall_s": state.wall_s, "cuts": state.cuts,
                "krylov_iterations": snes.krylov_iterations,
                "preconditioner_setups": snes.setups,
                "status_counts": contact_state.status_counts(table),
                "probes": probes.values(self.problem.u, self.comm) if probes else [],
                **thermal_record(self.problem, self.comm),
                **obstacle_record(self.problem, table),
                **contact_radius_record(self.problem, table), **error}

    def _file_observers(self) -> list:
        """The writer (steps.jsonl, contact files, XDMF fields) and the figure snapshots."""
        if self.writer is None:
            return []
        opts = self.scene["output"]
        sigma = fem.Function(self.problem.tensor_space, name="sigma")
        time = self.scene["time"]
        writer = FieldWriter(self.writer, self.problem, sigma, opts["fields"],
                             FieldSchedule(opts["field_every"], opts["field_times"], time))
        snapshots = Snapshots(self.out, self.problem, writer, self.comm, opts, time,
                              self.writer, self.say, self.resumed)
        return [writer, snapshots]

    def _checkpoint(self, state: Accepted, count, final=False):
        """The checkpoint of the accepted state when the schedule (or a stop) asks for it;
        then every rank stops here on a signal, its last state checkpointed: a restart loses
        no step."""
        signum = parallel.stop_requested(self.comm)
        if self.out and self.scene["output"]["checkpoint"] and (
                signum or self.checkpoints.due(count - 1, final)):
            checkpoint.save(self.out, self.problem, self.comm, state.t, count, state.k,
                            records=self.writer and self.writer.record_state(),
                            durable=final or bool(signum))
            self.checkpoints.written()
        if signum:                        # every rank stops after this same step
            raise parallel.Stopped(signum, count - 1, state.t)

    def _finish(self, table, t_end) -> dict:
        """The final record; the summary when writing."""
        writer = self.writer
        if table is None and writer is not None and writer.last_record:
            counts = writer.last_record["status_counts"]     # nothing left after a restart
        else:
            counts = contact_state.status_counts(table)
        final = {"t": t_end, "status_counts": counts,
                 "wall_s": clock.perf_counter() - self.started, "setup_s": self.setup_s}
        if writer is not None:
            writer.finish(final)
        self.say(report.closing_line(final, t_end))
        return final


def check_sliding(problem, t: float, completed: int) -> None:
    """Stop the run when a slave node of two bodies in contact has slid past its pairing's
    small-sliding limit (fem.body_contact.BodyContact.sliding); collective.

    Parameters
    ----------
    problem : contactvisco.fem.problem.Problem
        The problem at the converged state of time t.
    t : float
        The state's time.
    completed : int
        The steps recorded before it (kept in the output folder).

    Raises
    ------
    SlidingLimit
        |u_rel,tau,i| > l_i at some slave node i (a NewtonFailure: exit 3).
    """
    obstacle = problem.contact and problem.contact.obstacle
    sliding = getattr(obstacle, "sliding", None)
    found = sliding(problem.u) if sliding is not None else None
    if found is None:
        return
    position, slip, limit = found
    where = ", ".join(f"{c:.6g}" for c in position)
    raise SlidingLimit(
        f"at t = {t:g} the slave node at ({where}) has slid {slip:.4g} along the master, "
        f"past the small-sliding limit {limit:.4g} (contact.sliding_limit = "
        f"{obstacle.sliding_limit:g} of its master facet: obstacle.shape = "
        "'body' pairs the boundaries once in the reference configuration); stopped, the "
        f"{completed} step(s) before are kept", position, slip, limit, t)


def thermal_record(problem, comm) -> dict:
    """With a temperature ([viscoelastic] temperature): the range over the points of the
    temperature theta and of the reduced time xi = int dt / a_T(theta) at the committed state,
    as ``temperature`` and ``reduced_time`` [min, max] (collective); else nothing."""
    history = problem.memory and problem.memory.history
    if getattr(history, "reduced_time", None) is None:
        return {}
    out = {}
    for name, values in (("temperature", history.temperature),
                         ("reduced_time", history.reduced_time)):
        mine = values[:history.owned]
        lo = comm.allreduce(float(mine.min()) if mine.size else math.inf, op=MPI.MIN)
        hi = comm.allreduce(float(mine.max()) if mine.size else -math.inf, op=MPI.MAX)
        out[name] = [lo, hi]
    return out


def contact_radius_record(problem, table) -> dict:
    """An axisymmetric body's contact radius as ``contact_radius``: ``node`` (the outermost
    node in contact) and ``interpolated`` (the edge between it and the first open node:
    fem.contact_state.contact_radius); {} for other bodies or without contact."""
    if table is None or not getattr(problem.kinematics, "axisymmetric", False):
        return {}
    return {"contact_radius": contact_state.contact_radius(table)}


def obstacle_record(problem, table) -> dict:
    """The obstacle's entry of a step record ({} without an obstacle): its displacement d and
    the resultant contact force it exerts on the body, sum_i w_i (-(reaction_nu) nu +
    sigma_tau) over the contact nodes (the force obstacle.force prescribes under force
    control); for an axisymmetric body w_i is the node's ring area, so the force is the total
    over the full circle, and its radial component is zero. Another body of the mesh as the obstacle (fem.body_contact) has no position of
    its own: its entry says so and gives each body's resultant contact force
    (BodyContact.record)."""
    obstacle = problem.contact and problem.contact.obstacle
    if obstacle is None or table is None:
        return {}
    if hasattr(obstacle, "record"):
        return {"obstacle": obstacle.record()}
    weight = table["weight"][:, None]
    force = np.sum(weight * (table["sigma_tau_vector"]
                             - table["reaction_nu"][:, None] * table["normal"]), axis=0)
    if getattr(problem.kinematics, "axisymmetric", False):
        force[0] = 0.0      # the radial ring forces of a body of revolution cancel
    return {"obstacle": {"displacement": obstacle.displacement().tolist(),
                         "force": force.tolist()}}


def recorder(result: Result, keep_tables):
    """Observer: the record (and the table) into the Result."""
    def record_into_result(record, table):
        result.steps.append(record)
        if keep_tables:
            result.tables.append(table)
    return record_into_result


def advance(problem, snes, t_to, max_cuts, say, cuts=0, predict=None):
    """Yield the accepted states that take the problem from its committed time to t_to: one,
    or, when Newton fails, those of the two halves (at most max_cuts halvings in a row; none
    on the first state, which has no earlier state to fall back on). Each state is committed
    (the history of eq 19 takes the exact step sizes) before it is yielded; a failure that
    may not be cut raises StepFailed with the unknowns restored. `predict`
    (contactvisco.solver.predictor.Extrapolation, optional) gives Newton's first iterate."""
    tick = clock.perf_counter()
    t_from = problem.time.committed           # None: the first state, t_0
    first = t_from is None
    saved = [f.x.array.copy() for f in problem.unknowns]
    problem.time.stage(t_to)                  # H from u_0 .. u_n (eq 19, any step sizes)
    try:
        iterations = _solve(problem, snes, saved, predict, t_to)
    except NewtonFailure as err:
        _restore(problem, saved)
        if first or cuts >= max_cuts:
            raise StepFailed(t_to if first else t_from, t_to, cuts, err) from None
        say(f"step to t = {t_to:.4g} failed (SNES reason {err.reason}); taking it in two "
            "halves")
        middle = t_from + 0.5 * (t_to - t_from)
        yield from advance(problem, snes, middle, max_cuts, say, cuts + 1, predict)
        yield from advance(problem, snes, t_to, max_cuts, say, cuts + 1, predict)
        return
    problem.time.commit()
    if predict is not None:
        predict.record(t_to)
    k = None if first else t_to - t_from
    yield Accepted(t_to, k, iterations, clock.perf_counter() - tick, cuts)


def _solve(problem, snes, saved, predict, t_to) -> int:
    """Newton from the predicted first iterate, and from the last accepted state (`saved`)
    when that fails or there is no prediction; returns the iterations of both attempts.
    Under force control the prediction moves u but holds the obstacle at its last
    equilibrium, which can part them (a creeping body, large steps): the obstacle's
    out-of-contact error (key obstacle.force) from a prediction is such a failure too."""
    if predict is None or not predict.apply(t_to):
        return snes.solve()
    try:
        return snes.solve()
    except NewtonFailure as err:
        spent = max(len(err.residuals) - 1, 0)
    except SceneError as err:
        if err.key != "obstacle.force":
            raise
        spent = 0
    _restore(problem, saved)
    return spent + snes.solve()


def _restore(problem, saved):
    for f, values in zip(problem.unknowns, saved):
        f.x.array[:] = values


class FieldWriter:
    """Observer: the step record and the contact table into the writer at every accepted
    state, the XDMF fields at those of the schedule."""

    def __init__(self, writer, problem, sigma, names, schedule: FieldSchedule | None = None):
        self.writer, self.problem, self.sigma, self.names = writer, problem, sigma, names
        self.derived = {}                     # the Functions of output.derived_fields
        self.schedule = schedule or FieldSchedule(1, (), {"T": 1.0, "steps": 1})
        self.sigma_step = None       # the step at which sigma was last interpolated
        self.body = output.body_field(problem) if writer.xdmf is not None else None

    def __call__(self, record, table):
        fields = []
        if self.writer.xdmf is not None and self.schedule.due(record["step"], record["t"]):
            problem = self.problem
            if any(name in output.STRESS_FIELDS for name in self.names):
                self.sigma.interpolate(problem.sigma_expression)
                self.sigma_step = record["step"]
            available = {"u": problem.u, "sigma": self.sigma,
                         "history_stress": problem.memory and problem.memory.H,
                         **problem.multipliers}
            derived = output.derived_fields(self.names, problem, self.sigma, table, self.derived)
            fields = [available[name] for name in self.names if available.get(name) is not None]
            fields += [f for name in self.names for f in derived.get(name, [])]
            if self.body is not None:             # the bodies' cells, at every field step
                fields.append(self.body)
        self.writer.step(record, table, fields)


class Snapshots:
    """Observer: the whole mesh gathered on rank 0 at the figure times (snapshots.npz), unless
    the mesh is too large for that (a note then says so)."""

    def __init__(self, out, problem, fields: FieldWriter, comm, opts, time, writer, say,
                 resumed):
        self.path = pathlib.Path(out) / "snapshots.npz"
        self.problem, self.comm, self.writer = problem, comm, writer
        self.fields, self.sigma = fields, fields.sigma     # sigma: shared with the XDMF output
        grid = time_grid.times(time)
        figure_steps = set(time_grid.nearest(time, opts["figure_times"])) | {len(grid) - 1}
        self.times = {round(float(grid[i]), 12) for i in figure_steps}
        skip = opts["figures"] and output.snapshot_skip_note(
            problem, opts["snapshot_max_nodes"], writer.xdmf is not None)
        if skip:
            writer.note("notes", skip)    # a restarted run keeps its earlier notes
            say(skip)
        self.enabled = opts["figures"] and not skip
        self.taken = []
        if resumed and comm.rank == 0 and self.path.exists():
            self.taken = output.read_snapshots(self.path, resumed["t"])

    def __call__(self, record, table):
        t = record["t"]
        if not self.enabled or round(t, 12) not in self.times:
            return
        if self.fields.sigma_step != record["step"]:      # not interpolated for the XDMF
            self.sigma.interpolate(self.problem.sigma_expression)
        gathered = output.gather_mesh(self.problem, self.sigma, self.comm)
        if gathered is not None:
            self.taken.append((t,) + gathered)
            output.write_snapshots(self.path, self.taken)
