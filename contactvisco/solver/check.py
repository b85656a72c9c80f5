"""A scene built as a run builds it, with every check that needs the mesh, and nothing solved.

:func:`check` makes the mesh, the forms and the solver of a scene, so that every error a run
would meet before its first Newton iteration (a boundary the mesh lacks, a probe outside the
body, a free rigid motion, a PETSc option the solver refuses, an unstable time rule) is met
here, and reports what the run will cost: its unknowns, the storage of its memory and the size
of its output.
"""
from __future__ import annotations

import numpy as np
from mpi4py import MPI

from contactvisco.fem import geometry as geometry_module
from contactvisco.fem.problem import build
from contactvisco.model.material import lame_constants
from contactvisco.model import time_grid
from contactvisco.model.memory import History
from contactvisco.model.stability import amplifies, worst_body
from contactvisco.solver import newton
from contactvisco.solver.field_schedule import FieldSchedule

#: Bytes of one float64 value.
FLOAT = 8
#: Bytes of one number in contact_nodes.csv (text, with its separator).
CSV_NUMBER = 10
#: Bytes of one step's line in steps.jsonl; of its XDMF text and the HDF5 file's own
#: structure (measured: 9.1 kB at 8 x 8 cells, 8.5 kB at 32 x 32 on the paper scene).
STEP_RECORD = 600
XDMF_STEP = 9600
#: Bytes per step of each field beyond u and sigma (the XDMF text of both files and the
#: HDF5 dataset's own structure; measured: 2.0 kB at 8 x 8 cells on the paper scene).
XDMF_FIELD = 2000


def _global_dofs(space) -> int:
    index_map = space.dofmap.index_map
    return index_map.size_global * space.dofmap.index_map_bs


def history_values(history, steps: int) -> int:
    """How many strain-sized arrays the history of eq (19) holds after `steps` steps: one per
    exponential term (and the last strain) for the recursions, every step's strain for the
    direct sums (table kernels, fractional kernels summed directly)."""
    if history is None:
        return 0
    if history.direct:
        return steps + 1
    history = getattr(history, "history", history)      # a reduced-time history wraps it
    rates = getattr(getattr(history, "fit", None), "rates", None)
    terms = len(rates) if rates is not None else len(history.terms)
    return terms + 1


def output_bytes(scene: dict, problem, counts: dict[str, int], tensor_dofs: int) -> int:
    """An estimate of what a run writes into its folder, figures and the checkpoint (replaced,
    not added up) left out: at every step a row of contact_nodes.csv per contact node and a
    line of steps.jsonl; at the steps of the field schedule an HDF5 file with the mesh and the
    fields (vectors padded to 3 and tensors to 9 components, as XDMF wants them)."""
    mesh = problem.geometry.mesh
    d = mesh.geometry.dim
    tdim = mesh.topology.dim
    opts = scene["output"]
    steps = len(time_grid.steps(scene["time"]))
    records = (steps + 1) * (STEP_RECORD + problem.count_contact_nodes() * CSV_NUMBER * (d + 11))
    body = problem.contact and problem.contact.obstacle
    if getattr(body, "master_nodes", None) is not None:    # two bodies: the interface tables
        records += (steps + 1) * CSV_NUMBER * (problem.count_contact_nodes() * (2 * d + 10)
                                               + len(body.master_nodes) * (2 * d + 2))
    if not opts["xdmf"]:
        return records
    cells = mesh.topology.index_map(tdim).size_global
    vertices = mesh.topology.index_map(0).size_global
    written = {"u": counts["u"] // d * 3, "sigma": tensor_dofs // d ** 2 * 9,
               "history_stress": tensor_dofs // d ** 2 * 9 if problem.memory else 0,
               "lambda_nu": counts.get("lambda_nu", 0),
               "lambda_tau": counts.get("lambda_tau", 0) // d * 3,
               "stress_components": tensor_dofs // d ** 2 * (3 if d == 2 else 6),
               "von_mises": tensor_dofs // d ** 2,
               "contact_status": vertices if problem.contact is not None else 0,
               "contact": 7 * vertices if problem.contact is not None else 0}
    values = cells * (tdim + 1) + vertices * d + sum(written[name] for name in opts["fields"])
    two = (scene.get("obstacle") or {}).get("shape") == "body"
    values += cells if scene.get("body") or two else 0    # the cell field "body"
    grid = time_grid.times(scene["time"])
    schedule = FieldSchedule(opts["field_every"], opts["field_times"], scene["time"])
    field_steps = sum(schedule.due(n, float(t)) for n, t in enumerate(grid))
    # The Functions each output.fields entry writes (the stress components: 3 in 2D).
    functions = {"contact": 7 if problem.contact is not None else 0,
                 "stress_components": 3 if d == 2 else 6}
    extra = sum(functions.get(name, 1) for name in opts["fields"]
                if name not in ("u", "sigma") and written[name])
    return records + field_steps * (FLOAT * values + XDMF_STEP + XDMF_FIELD * extra)


#: A rigid obstacle may start inside the body by what the contact law allows (the layer
#: contact.g) plus this fraction of the body's size L: an interference the first state
#: pushes out. Deeper, it is refused (as two bodies' overlap beyond their search distance,
#: by default the same fraction of L).
INITIAL_PENETRATION = 0.1

#: The key that places each shape of rigid obstacle.
_POSITION_KEY = {"plane": "obstacle.point", "cylinder": "obstacle.centre",
                 "sphere": "obstacle.centre", "surface": "obstacle.distance"}


def initial_penetration(problem, comm) -> None:
    """Refuse a rigid obstacle that starts inside the body deeper than the contact law allows
    plus INITIAL_PENETRATION times the body's size L: the depth is -h, h the gap at the contact
    nodes at the obstacle's first position d(t_0) (h < 0: the node lies inside the obstacle).
    The message names the key that places the obstacle, the deepest node, its depth, how many
    nodes are that deep and the limit. Collective (the same on every rank).

    Raises
    ------
    SceneError
        Naming obstacle.point, obstacle.centre or obstacle.distance.
    """
    from contactvisco.errors import SceneError
    from contactvisco.fem.obstacle import ObstaclePart
    contact = problem.contact
    obstacle = contact and contact.obstacle
    if not isinstance(obstacle, ObstaclePart):
        return
    scene = problem.scene
    law = float(scene["contact"]["g"] or 0.0)
    size = problem.length_scale
    limit = law + INITIAL_PENETRATION * size
    nodes = contact.nodes
    own = nodes.nodes[nodes.owned]
    depth = -obstacle.gap.x.array[own]
    deep = np.flatnonzero(depth > limit)
    found = None
    if len(deep):
        k = deep[np.argmax(depth[deep])]
        x = contact.Q_coordinates[own[k], :obstacle.dim]
        x = np.where(np.abs(x) < 1e-12 * size, 0.0, x)      # a mesh's round-off shown as 0
        found = (-float(depth[k]), ", ".join(f"{v:.6g}" for v in x))
    count = comm.allreduce(len(deep), MPI.SUM)
    if not count:
        return
    deepest, where = min(f for f in comm.allgather(found) if f is not None)
    shape = scene["obstacle"]["shape"]
    key = _POSITION_KEY[shape]
    moved = np.asarray(obstacle.reference.value, float)
    placed = (f" moved by obstacle.displacement to d = {np.round(moved, 12).tolist()}"
              if np.any(moved) else "")
    raise SceneError(
        f"{key}: the {shape} obstacle{placed} starts inside the body at t = "
        f"{float(obstacle.t.value):g}: {count} contact node(s) lie inside it by more than "
        f"{limit:.6g} (contact.g = {law:g} that the contact law allows, plus "
        f"{INITIAL_PENETRATION:g} of the body's size {size:.6g}), the deepest by {-deepest:.6g} "
        f"at ({where}); place the obstacle outside the body (a gap >= 0 at its first point)",
        key=key)


def output_limit(scene: dict, problem, out) -> str:
    """The estimated size of the run's output (`output_bytes`), refused above
    output.max_bytes (a SceneError on every rank: the estimate is the same on all), with a
    warning when it exceeds the free space of the output folder's disk.

    Parameters
    ----------
    scene : dict
        The scene.
    problem : contactvisco.fem.problem.Problem
        The built problem (its mesh, contact nodes and spaces give the sizes).
    out : path-like
        The output folder.

    Returns
    -------
    str
        The line that says the estimate (and warns when the disk has less free space).
    """
    import shutil

    from contactvisco.errors import SceneError
    estimate = output_bytes(scene, problem, problem.count_unknowns(),
                            _global_dofs(problem.tensor_space))
    limit = scene["output"]["max_bytes"]
    if estimate > limit:
        raise SceneError(
            f"output.max_bytes: the run would write about {size_text(estimate)} into {out} "
            f"(time.steps = {scene['time']['steps']}, output.fields = "
            f"{scene['output']['fields']}, output.field_every = "
            f"{scene['output']['field_every']}), more than output.max_bytes = "
            f"{size_text(limit)}; write fields less often (output.field_every, "
            "output.field_times, output.xdmf = false), or allow it with --allow-large-output "
            "(output.max_bytes = inf)", key="output.max_bytes")
    line = f"output about {size_text(estimate)} (estimate, figures left out)"
    try:
        free = shutil.disk_usage(out).free
    except OSError:
        free = None
    if free is not None and estimate > free:
        line += f"; warning: more than the {size_text(free)} free on the disk of {out}"
    return line


def size_text(n: float) -> str:
    """A number of bytes in B, kB, MB, GB or TB (powers of 1000)."""
    for unit in ("B", "kB", "MB", "GB"):
        if n < 1000:
            return f"{n:.0f} {unit}" if unit == "B" else f"{n:.1f} {unit}"
        n /= 1000
    return f"{n:.1f} TB" if n < 1e15 else f"{n:.3g} TB"


def unconditionally_stable(scene: dict, history) -> bool:
    """Whether the step's stiffness stays positive for every step: time.rule = 'exponential'
    with a kernel whose terms all relax (finite tau_i; a Prony history, the power kernel's sum
    of exponentials), where A + sum_i alpha_i w1_i >= the long-term modulus for every k
    (model/memory.py: alpha_i w1_i = -G_i (1 - phi1(k/tau_i)))."""
    if hasattr(history, "histories"):                   # [[body]] tables: every body's
        return all(unconditionally_stable(scene, h) for h in history.histories)
    inner = getattr(history, "history", history)       # a reduced-time history wraps it
    return (scene["time"]["rule"] == "exponential" and type(inner) is History
            and all(tau < float("inf") for _, tau, _ in inner.terms))


def implicit_stiffness(scene: dict, problem, comm=MPI.COMM_WORLD) -> dict[str, float]:
    """The smallest stiffness of a step of the implicit rules, per mode of A that the memory
    acts on: A + w P with w the implicit weight of P eps_{n+1} (k/2 R(0) for the trapezoid
    rule, sum_i alpha_i w1_i for the exponential rule, alpha k^(1-beta) / Gamma(3 - beta) for
    the fractional kernel), on the deviatoric strains 2 mu + w_full + w_deviatoric and on the
    volumetric ones d lambda + 2 mu + w_full + w_volumetric (A I = (d lambda + 2 mu) I). The
    step is well posed while these stay > 0. In reduced time w is taken at dxi = k / a_T per
    point at every step time t_n = n k (the temperature moved there; nothing solved), the
    smallest over the points and times. Collective.

    Parameters
    ----------
    scene : dict
        The scene.
    problem : contactvisco.fem.problem.Problem
        The built problem (its memory's history gives w).
    comm : MPI.Comm
        The communicator.

    Returns
    -------
    dict
        ``deviatoric`` and/or ``volumetric`` (the modes the memory acts on), each
        (smallest stiffness, the elastic stiffness 2 mu or d lambda + 2 mu); empty for the
        paper's rule or without memory.
    """
    memory = problem.memory
    if memory is None or scene["time"]["rule"] == "paper":
        return {}
    if getattr(memory, "bodies", None):            # [[body]] tables: the least of the bodies
        out = {}
        for body, part in zip(memory.bodies, memory.parts):
            own = dict(scene, material=body["material"], memory=body["memory"])
            for mode, value in _stiffness(own, problem, part.history, comm).items():
                if mode not in out or value[0] < out[mode][0]:
                    out[mode] = value
        return out
    return _stiffness(scene, problem, memory.history, comm)


def _stiffness(scene: dict, problem, history, comm) -> dict[str, tuple[float, float]]:
    """implicit_stiffness of one material and history."""
    import numpy as np
    grid = time_grid.times(scene["time"])
    steps = time_grid.steps(scene["time"])
    if getattr(history, "staged", False) is False:            # isothermal: numbers
        # the weights are monotone in k: the least stiffness is at one end of the steps
        samples = [history.implicit(float(steps.min())), history.implicit(float(steps.max()))]
    else:                                                     # reduced time: fields
        samples = []
        for t, k in zip(grid, [steps[0], *steps]):
            problem.time.move_to(float(t))
            samples.append(history.history.implicit(k * history.staged[:history.owned]))
        problem.time.move_to(0.0)
    d = problem.geometry.mesh.geometry.dim
    lam, mu = lame_constants(scene["material"]["model"], scene["material"]["E"],
                             scene["material"]["nu"])
    elastic = {"deviatoric": 2.0 * mu, "volumetric": d * lam + 2.0 * mu}
    acts = {"full": ("deviatoric", "volumetric"), "deviatoric": ("deviatoric",),
            "volumetric": ("volumetric",)}
    modes = sorted({mode for part in samples[0] for mode in acts[part]})
    out = {}
    for mode in modes:
        least = np.inf
        for weights in samples:
            total = sum(np.asarray(w, float) for part, w in weights.items()
                        if mode in acts[part])
            if np.size(total):
                least = min(least, float(np.min(total)))
        least = comm.allreduce(least, op=MPI.MIN)
        out[mode] = (elastic[mode] + least, elastic[mode])
    return out


def check(scene: dict, geometry=None, comm=MPI.COMM_WORLD) -> dict:
    """Build a scene's mesh, problem and solver, run every check a run makes before solving,
    and report the size of the run. Collective.

    Parameters
    ----------
    scene : dict
        A scene from ``load_scene``.
    geometry : Geometry, optional
        A mesh with its boundary tags (``contactvisco.fem.user_mesh.from_mesh``); default: the
        scene's own.
    comm : MPI.Comm
        The communicator.

    Returns
    -------
    dict
        ``steps``, ``smallest_step`` and ``largest_step`` (the time grid), ``cells``,
        ``vertices``, ``unknowns`` (by field), ``contact_nodes``,
        ``linear_system``, ``linear_solver``, ``stability_number`` (b, the worst [[body]]'s
        with bodies), ``stability_body`` (that body's name, or None) and ``unstable`` (the
        paper's rule at b >= 1), ``implicit_stiffness`` (the trapezoid and exponential rules:
        :func:`implicit_stiffness`) and ``unconditionally_stable`` (:func:`unconditionally_stable`),
        ``history_bytes`` (all ranks, at the last step) and ``output_bytes`` (an estimate for
        the whole run).

    Raises
    ------
    SceneError
        What a run would refuse before its first step.
    """
    from contactvisco.io import parallel
    parallel.same_scene(comm, scene)
    geometry = geometry or geometry_module.build(scene, comm)
    mesh = geometry.mesh
    geometry_module.check_probes(mesh, scene["output"]["probes"])
    problem = build(scene, geometry)
    initial_penetration(problem, comm)
    snes = newton.create(problem, comm)
    try:
        system, solver = snes.system_kind, snes.linear_solver()
        if newton.solver_kinds(problem, system) == ("iterative", "direct"):
            solver += (f"; after the first state preonly/lu ({solver} again past "
                       f"{newton.LATER_FACTORIZATIONS:g} factorization(s) per step)")
    finally:
        snes.destroy()
    tdim = mesh.topology.dim
    mesh.topology.create_connectivity(0, tdim)
    counts = problem.count_unknowns()
    tensor = _global_dofs(problem.tensor_space)
    history = problem.memory.history if problem.memory is not None else None
    b, body = worst_body(scene)
    steps, least, largest = time_grid.summary(scene["time"])
    report = {
        "steps": steps, "smallest_step": least, "largest_step": largest,
        "cells": mesh.topology.index_map(tdim).size_global,
        "vertices": mesh.topology.index_map(0).size_global,
        "unknowns": counts, "contact_nodes": problem.count_contact_nodes(),
        "linear_system": system, "linear_solver": solver,
        "stability_number": b, "stability_body": body,
        "unstable": scene["time"]["rule"] == "paper" and amplifies(b, steps),
        "implicit_stiffness": implicit_stiffness(scene, problem, comm),
        "unconditionally_stable": unconditionally_stable(scene, history),
        "history_bytes": FLOAT * tensor * history_values(history, steps),
        "output_bytes": output_bytes(scene, problem, counts, tensor),
    }
    snes = None                        # its PETSc objects become garbage
    problem.release_garbage()
    return report
