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
_FREE_FORM = {("geometry", "parameters"), ("solver", "petsc_options")}


def load_scene(name_or_path, preset: str | None = None, sets=(), **overrides) -> dict:
    """The scene `name_or_path` (a built-in name, see `builtin_scenes()`, or a TOML file) with
    its defaults filled in and `overrides` applied, checked as a whole.

    Overrides are Python values nested by table, as in the TOML file:
    ``load_scene("paper", contact={"mu": 0.4}, time={"steps": 20})``; a table given as a dict
    changes only the keys it names. `preset` ("fast", "balanced", "accurate") scales the mesh
    and the steps. Raises SceneError (what, where it came from, what is allowed) for an
    unknown key or a value out of range, exactly as ``contactvisco run --set`` does.
    `sets` takes ``"key=value"`` texts (TOML values) as the command line's --set, applied
    before the keyword overrides.
    """
    given = list(sets) + list(_assignments(overrides, []))
    if preset is not None:
        given.insert(0, scene_module.Override(["preset"], preset))
    return scene_module.load(str(name_or_path), given)


def _assignments(values: dict, path: list):
    """One Override per leaf of the nested dict (lists and free-form tables are leaves)."""
    for key, value in values.items():
        where = path + [str(key)]
        if isinstance(value, dict) and value and tuple(where) not in _FREE_FORM:
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
    """The built-in scenes: name -> description."""
    return {name: scene_module.load(name)["description"]
            for name in scene_module.builtin_names()}


def solve(scene: dict, out=None, mesh=None, facet_tags=None, boundaries=None, on_step=None,
          comm=None, progress=False, restart=False, overwrite=True, keep_contact=True):
    """Solve `scene` (from load_scene) and return a Result.

    mesh, facet_tags, boundaries: a DOLFINx mesh, its facet meshtags and a dict
        {boundary name: tag value}; they replace the scene's geometry table. Every boundary
        the scene names (dirichlet, traction, contact) must be in `boundaries`, and each tag
        must mark facets of the mesh's boundary (SceneError otherwise).
    out: a folder for the files of `contactvisco run` (steps.jsonl, summary.json, XDMF,
        checkpoints, figures); None writes nothing. restart=True continues the run in `out`
        from its checkpoint; overwrite=False refuses a folder holding an earlier run.
    on_step(record): called on every rank after every accepted step with its record.
    comm: the MPI communicator (default: the mesh's, else COMM_WORLD). Collective.
    progress: print a line per step (rank 0).
    keep_contact: keep the contact table of every step in result.contact (False for long
        runs that write them to `out` anyway).

    Raises SceneError (bad scene or mesh), NewtonFailure (a step that does not converge even
    when cut), contactvisco.io.parallel.Stopped (SIGINT/SIGTERM, after a completed step).
    """
    from mpi4py import MPI

    from contactvisco.fem.user_mesh import from_mesh
    from contactvisco.solver.time_loop import simulate
    if comm is None:
        comm = mesh.comm if mesh is not None else MPI.COMM_WORLD
    try:
        geometry = None
        if mesh is not None or facet_tags is not None or boundaries is not None:
            geometry = from_mesh(scene, mesh, facet_tags, boundaries)
        result = simulate(scene, out, comm=comm, progress=progress, keep_tables=keep_contact,
                          restart=restart, overwrite=overwrite, geometry=geometry,
                          on_step=on_step)
    except SceneError as err:          # errors found while building name their origin too
        raise _located(scene, err) from None
    if out is not None and comm.rank == 0 and scene["output"]["figures"]:
        _draw_figures(out)
    return result


def _located(scene, err: SceneError) -> SceneError:
    """A build-time error with the origin of its key (file line, override) appended."""
    return scene.locate(err) if hasattr(scene, "locate") else err


def _draw_figures(out) -> None:
    """The figures of a finished run's folder; a failing figure only warns, since the results
    are already written."""
    import pathlib
    import sys

    from contactvisco.post import figures
    try:
        figures.draw_all(pathlib.Path(out))
    except Exception as err:
        print(f"contactvisco: warning: figures failed ({type(err).__name__}: {err}); the "
              f"results in {out} are complete; retry with 'contactvisco plot {out}'",
              file=sys.stderr, flush=True)


def pyvista_grid(u):
    """This rank's part of a P1 vector field `u` (e.g. result.u) as a pyvista
    UnstructuredGrid, with point data "u" (3 components, zero-padded in 2D) made the active
    vectors, ready for ``grid.warp_by_vector("u")``."""
    import numpy as np
    import pyvista

    from contactvisco.fem import compat
    grid = pyvista.UnstructuredGrid(*compat.vtk_mesh(u.function_space))
    d = u.function_space.mesh.geometry.dim
    values = np.zeros((grid.n_points, 3))
    values[:, :d] = u.x.array.reshape(-1, d)[:grid.n_points]
    grid.point_data["u"] = values
    grid.set_active_vectors("u")
    return grid


def read_results(folder) -> dict:
    """The summary.json of a run's output folder with "steps": the step records."""
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
        ``cells``, ``vertices``, ``unknowns`` (by field), ``contact_nodes``,
        ``linear_system``, ``linear_solver``, ``stability_number``, ``unstable``,
        ``history_bytes`` (the memory's storage at the last step, all ranks) and
        ``output_bytes`` (an estimate of what ``solve(scene, out=...)`` writes, figures left
        out).

    Raises
    ------
    SceneError
        Whatever a run would refuse before its first step, naming the key and its origin.
    """
    from mpi4py import MPI

    from contactvisco.fem.user_mesh import from_mesh
    from contactvisco.solver.check import check as check_scene
    if comm is None:
        comm = mesh.comm if mesh is not None else MPI.COMM_WORLD
    try:
        geometry = None
        if mesh is not None or facet_tags is not None or boundaries is not None:
            geometry = from_mesh(scene, mesh, facet_tags, boundaries)
        return check_scene(scene, geometry, comm)
    except SceneError as err:
        raise _located(scene, err) from None


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
