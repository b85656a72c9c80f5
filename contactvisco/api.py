"""The Python interface: load a scene with Python overrides, solve it (on its own mesh or on a
DOLFINx mesh of the caller's), read the result. The command line is a layer over these.

    scene = load_scene("paper", contact={"mu": 0.4}, time={"steps": 20})
    result = solve(scene, mesh=mesh, facet_tags=tags, boundaries={"bottom": 1, ...})
    result.u, result.steps[-1]["status_counts"], result.contact[-1]["p_nu"]

DOLFINx and PETSc are imported when `solve` is first called, not on import.
"""
from __future__ import annotations

import numbers

from contactvisco.scene import loader as scene_module
from contactvisco.errors import SceneError

#: Scene tables whose keys are free (a nested dict is one value, not more overrides).
def load_scene(name_or_path, preset: str | None = None, sets=(), **overrides) -> dict:
    """A scene with its defaults filled in and overrides applied, checked as a whole.

    Parameters
    ----------
    name_or_path : str or path-like
        A built-in scene name (see ``builtin_scenes()``) or the path of a TOML scene file.
    preset : str, optional
        ``"fast"``, ``"balanced"`` or ``"accurate"``: scales the mesh and the steps.
    sets : sequence of str, optional
        ``"key=value"`` texts with TOML values, as the command line's ``--set``; applied
        before the keyword overrides.
    **overrides
        Python values nested by table, as in the TOML file:
        ``load_scene("paper", contact={"mu": 0.4}, time={"steps": 20})``. A table given as a
        dict changes only the keys it names, except a free-form table (a relaxation function such
        as ``viscoelastic={"shear": {...}}``, ``geometry.parameters``,
        ``solver.petsc_options``), which replaces the scene's whole; numpy scalars and arrays
        are accepted.

    Returns
    -------
    dict
        The resolved scene: every table with every key, ready for ``solve``.

    Raises
    ------
    SceneError
        For an unknown key (with a suggestion) or a value out of range: what, where it came
        from and what is allowed, exactly as ``contactvisco run --set`` reports it.

    Examples
    --------
    >>> scene = load_scene("paper", contact={"mu": 0.4}, time={"steps": 20})
    >>> scene["contact"]["mu"]
    0.4
    """
    given = list(sets) + list(_assignments(overrides, []))
    if preset is not None:
        given.insert(0, scene_module.Override(["preset"], preset))
    return scene_module.load(str(name_or_path), given)


def _assignments(values: dict, path: list):
    """One Override per leaf of the nested dict (lists and free-form tables are leaves)."""
    for key, value in values.items():
        where = path + [str(key)]
        if isinstance(value, dict) and value and ".".join(where) not in scene_module.FREE_FORM:
            yield from _assignments(value, where)
        else:
            yield scene_module.Override(where, _plain(value))


def _plain(value):
    """numpy scalars and tuples as the TOML reader would give them (float, int, list)."""
    if isinstance(value, bool) or value is None or isinstance(value, str):
        return value
    if isinstance(value, numbers.Integral):
        return int(value)
    if isinstance(value, numbers.Real):
        return float(value)
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)) or hasattr(value, "tolist"):
        return [_plain(v) for v in (value.tolist() if hasattr(value, "tolist") else value)]
    return value


def builtin_scenes() -> dict[str, str]:
    """The built-in scenes.

    Returns
    -------
    dict of str to str
        Scene name -> its one-line description (``block3d``, ``creep``, ``hertz``,
        ``ironing``, ``paper``).
    """
    return {name: scene_module.load(name)["description"]
            for name in scene_module.builtin_names()}


def solve(scene: dict, out=None, mesh=None, facet_tags=None, boundaries=None, on_step=None,
          comm=None, progress=False, restart=False, overwrite=True, keep_contact=True):
    """Solve a scene over its time interval. Collective over `comm`.

    Parameters
    ----------
    scene : dict
        A resolved scene, from ``load_scene``.
    out : path-like, optional
        A folder for the files of ``contactvisco run`` (steps.jsonl, summary.json, XDMF,
        checkpoints, figures); None writes nothing.
    mesh : dolfinx.mesh.Mesh, optional
        A mesh of the caller's; it replaces the scene's geometry table, together with
        `facet_tags` and `boundaries` (all three or none).
    facet_tags : dolfinx.mesh.MeshTags, optional
        Tags of the mesh's boundary facets.
    boundaries : dict of str to int, optional
        ``{boundary name: tag value}``. Every boundary the scene names (dirichlet, traction,
        contact) must be in it, and each tag must mark facets of the mesh.
    on_step : callable, optional
        ``on_step(record)``, called on every rank after every accepted step with its record
        (the step's line of steps.jsonl, as a dict).
    comm : mpi4py.MPI.Comm, optional
        The communicator; default: the mesh's, else ``COMM_WORLD``.
    progress : bool or "verbose", optional
        Print the output folder and a line per step (rank 0); "verbose": also a line per
        Newton iteration with its residual norm.
    restart : bool, optional
        Continue the run in `out` from its checkpoint.
    overwrite : bool, optional
        Replace an earlier run's files in `out`; False refuses such a folder.
    keep_contact : bool, optional
        Keep the contact table of every step in ``Result.contact`` (False for long runs that
        write them to `out` anyway).

    Returns
    -------
    Result
        The step records, the final record, the contact tables and the solved fields.

    Raises
    ------
    SceneError
        For a scene or mesh that cannot be used, or an output folder that is held, refused or
        holds a damaged checkpoint.
    NewtonFailure
        For a step that does not converge even when cut (with the step, the residuals and a
        likely cause in the message).
    contactvisco.io.parallel.Stopped
        On SIGINT or SIGTERM, after the step every rank has completed.
    """
    from mpi4py import MPI

    from contactvisco.solver.time_loop import simulate
    if comm is None:
        comm = mesh.comm if mesh is not None else MPI.COMM_WORLD
    scene = scene_module.check_given(scene)       # as changed since load_scene, if it was
    try:
        geometry = _own_geometry(scene, mesh, facet_tags, boundaries)
        result = simulate(scene, out, comm=comm, progress=progress, keep_tables=keep_contact,
                          restart=restart, overwrite=overwrite, geometry=geometry,
                          on_step=on_step)
    except SceneError as err:          # errors found while building name their origin too
        raise _located(scene, err) from None
    if out is not None and comm.rank == 0 and scene["output"]["figures"]:
        _draw_figures(out)
    return result


def _own_geometry(scene, mesh, facet_tags, boundaries):
    """The Geometry of a caller's mesh checked against the scene, or None for the scene's
    own (when none of the three is given)."""
    if mesh is None and facet_tags is None and boundaries is None:
        return None
    from contactvisco.fem.user_mesh import from_mesh
    return from_mesh(scene, mesh, facet_tags, boundaries)


def _located(scene, err: SceneError) -> SceneError:
    """A build-time error with the origin of its key (file line, override) appended."""
    return scene.locate(err) if hasattr(scene, "locate") else err


def _draw_figures(out) -> None:
    """The figures of a finished run's folder; a failing figure only warns, since the results
    are already written."""
    import pathlib
    import sys

    from contactvisco.io import parallel
    try:
        from contactvisco.post import figures
        figures.draw_all(pathlib.Path(out))
    except BaseException as err:
        interrupt = parallel.interrupted_by(err)     # SIGINT, or SIGTERM under the CLI
        if interrupt is not None:
            name = "SIGTERM" if getattr(interrupt, "signum", 2) == 15 else "SIGINT"
            print(f"contactvisco: figures stopped by {name}; the results in {out} are "
                  f"complete; draw them with 'contactvisco plot {out}'", file=sys.stderr,
                  flush=True)
            interrupt.reported = True
            raise interrupt from None
        if not isinstance(err, Exception):
            raise
        print(f"contactvisco: warning: figures failed ({type(err).__name__}: {err}); the "
              f"results in {out} are complete; retry with 'contactvisco plot {out}'",
              file=sys.stderr, flush=True)


def pyvista_grid(u, gather=False):
    """A P1 vector field as a pyvista grid: this rank's part, or the whole mesh on rank 0.

    Parameters
    ----------
    u : dolfinx.fem.Function
        A P1 vector field, e.g. ``result.u``.
    gather : bool
        False: this rank's part (the cells it owns). True: the whole mesh on rank 0
        (its points in the global numbering of the field's nodes, each cell once) and None on
        the other ranks; collective then (call it on every rank of the mesh's
        communicator).

    Returns
    -------
    pyvista.UnstructuredGrid or None
        The grid with point data ``"u"`` (3 components, zero-padded in 2D) made the active
        vectors, ready for ``grid.warp_by_vector("u")``.
    """
    import numpy as np
    import pyvista

    from contactvisco.fem import compat
    topology, cell_types, points = compat.vtk_mesh(u.function_space)
    d = u.function_space.mesh.geometry.dim
    values = np.zeros((len(points), 3))
    values[:, :d] = u.x.array.reshape(-1, d)[:len(points)]
    if gather:
        topology, cell_types, points, values = _gathered(u.function_space, topology,
                                                         cell_types, points, values)
        if points is None:
            return None
    grid = pyvista.UnstructuredGrid(topology, cell_types, points)
    grid.point_data["u"] = values
    grid.set_active_vectors("u")
    return grid


def _gathered(space, topology, cell_types, points, values):
    """The VTK arrays of every rank's owned cells and nodes on rank 0, the nodes in the
    space's global numbering (Nones elsewhere). P1: VTK's points are the space's nodes."""
    import numpy as np

    mesh = space.mesh
    comm = mesh.comm
    imap = space.dofmap.index_map
    own = imap.size_local
    cells = mesh.topology.index_map(mesh.topology.dim).size_local   # owned cells first
    rows = np.asarray(topology, dtype=np.int64).reshape(len(cell_types), -1)[:cells]
    rows[:, 1:] = imap.local_to_global(rows[:, 1:].ravel().astype(np.int32)).reshape(-1, rows.shape[1] - 1)
    parts = comm.gather((imap.local_range[0], points[:own], values[:own], rows,
                         np.asarray(cell_types)[:cells]), root=0)
    if comm.rank != 0:
        return None, None, None, None
    size = imap.size_global
    all_points, all_values = np.zeros((size, 3)), np.zeros((size, 3))
    for start, x, v, _, _ in parts:
        all_points[start:start + len(x)], all_values[start:start + len(x)] = x, v
    return (np.concatenate([p[3] for p in parts]).ravel(),
            np.concatenate([p[4] for p in parts]), all_points, all_values)


def read_results(folder) -> dict:
    """The results of a run from its output folder alone.

    Parameters
    ----------
    folder : path-like
        The output folder of ``contactvisco run`` or of ``solve(..., out=folder)``.

    Returns
    -------
    dict
        The content of summary.json (the resolved scene, unknown counts, notes and warnings,
        ``restarts``, ``final``) with ``"steps"``: the step records of steps.jsonl.
    """
    from contactvisco.io.output import read_summary
    return read_summary(folder)


def check(scene: dict, mesh=None, facet_tags=None, boundaries=None, comm=None) -> dict:
    """Build `scene` as `solve` would and make every check that needs the mesh, without
    solving: boundaries, probes, free rigid motions, the solver's PETSc options, the stability
    of the time rule; report the size of the run. Collective.

    Parameters
    ----------
    scene : dict
        A scene from `load_scene`.
    mesh, facet_tags, boundaries : optional
        A caller's DOLFINx mesh, its facet meshtags and ``{boundary name: tag}``, as for
        `solve`.
    comm : MPI.Comm, optional
        Default: the mesh's communicator, else COMM_WORLD.

    Returns
    -------
    dict
        ``steps``, ``smallest_step`` and ``largest_step`` (the time grid), ``cells``,
        ``vertices``, ``unknowns`` (by field), ``contact_nodes``,
        ``linear_system``, ``linear_solver``, ``stability_number``, ``unstable``,
        ``implicit_stiffness`` (per mode, the smallest stiffness of a step A + w P of the
        trapezoid and exponential rules, and the elastic one), ``unconditionally_stable``,
        ``history_bytes`` (the memory's storage at the last step, all ranks) and
        ``output_bytes`` (an estimate of what ``solve(scene, out=...)`` writes, figures left
        out).

    Raises
    ------
    SceneError
        Whatever a run would refuse before its first step, naming the key and its origin.
    """
    from mpi4py import MPI

    from contactvisco.solver.check import check as check_scene
    if comm is None:
        comm = mesh.comm if mesh is not None else MPI.COMM_WORLD
    scene = scene_module.check_given(scene)
    try:
        return check_scene(scene, _own_geometry(scene, mesh, facet_tags, boundaries), comm)
    except SceneError as err:
        raise _located(scene, err) from None


def fit(description, out=None, comm=None, progress=False) -> dict:
    """Identify material parameters from indentation curves by weighted least squares with
    the contact solver in the loop (docs/identification.md): minimize
    1/2 sum_e sum_j (w_e (d_e(t_j; theta) - d_ej))^2 over the parameters theta of a fit
    description, within their bounds.

    Parameters
    ----------
    description : path-like
        A fit description (TOML): its experiments (scene and CSV data) and parameters.
    out : path-like, optional
        A folder for ``fit.json``, ``curves.csv`` and the figures (``fit.png``,
        ``fit_moduli.png``, ``fit_correlation.png``); None writes nothing.
    comm : mpi4py.MPI.Comm, optional
        The communicator of the forward runs (default COMM_WORLD); rank 0 writes.
    progress : bool, optional
        Print a line per Prony term dropped by fit.reduction and per round.

    Returns
    -------
    dict
        Per parameter its estimate, standard error and whether the data determines it; the
        correlations, the singular values of J, the cost, the residual variance, the number of
        forward runs, the wall time, the optimizer's status, warnings and the fitted curves.

    Raises
    ------
    SceneError
        For a fit description, data file or parameter key that cannot be used (the key named).
    """
    from mpi4py import MPI

    from contactvisco.studies import identification
    comm = comm or MPI.COMM_WORLD
    report = identification.fit(description, comm=comm, progress=progress)
    if out is not None and comm.rank == 0:
        identification.write(report, out)
    return report


def scene_toml(scene: dict, every_value: bool = False) -> str:
    """A scene as TOML text that ``contactvisco run`` and `load_scene` read back to the same
    scene.

    Parameters
    ----------
    scene : dict
        A scene from `load_scene`.
    every_value : bool
        True: every key with its value, defaults included. False (default): what the scene
        sets, i.e. the values that differ from the defaults.

    Returns
    -------
    str
        The TOML text (None values, which TOML cannot hold, are left out: they are the
        defaults of optional keys).
    """
    from contactvisco.scene.toml_text import scene_text
    return scene_text(scene, every_value)
