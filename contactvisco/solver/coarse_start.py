"""Newton's first iterate of the first steps from the same scene on a coarser mesh.

The first loaded step has no earlier states to extrapolate from (contactvisco.solver.predictor),
so Newton starts it from the unloaded state, where every contact node is in the wrong branch of
the law; the semi-smooth Newton method then spends its iterations moving the contact state
node by node towards the converged one (docs/scaling.md). Mesh sequencing gives a start whose
contact state is close to the converged one: the same scene on a mesh `factor` times coarser
(`solver.coarse_factor`) takes the same steps, and each fine step's first iterate is the coarse
solution at that time, carried to the fine nodes:

    w_fine(x) = sum_j omega_j(x) w_coarse(x_j) / sum_j omega_j(x),  omega_j = 1 / |x - x_j|,

over the d + 1 nearest coarse nodes x_j of u (d for the multipliers, among the coarse contact
nodes only), and w_fine(x) = w_coarse(x_j) where a fine node lies on a coarse one. Only the
start of Newton changes: the converged state is fixed by the fine residual, and a step whose
Newton fails from this start is solved again from the last accepted state
(contactvisco.solver.time_loop._solve).

The coarse run follows the fine one for the states the extrapolation cannot predict (the first
two; a state the coarse run reaches without a Newton iteration keeps the fine run's last state
too) and is then released; a cut step, a restart or a failure of the coarse run ends it early,
and the fine run goes on as without it.
"""
from __future__ import annotations

import copy

import numpy as np

from contactvisco.errors import SceneError
from contactvisco.solver.newton_base import NewtonFailure
from contactvisco.scene.tables import MESH_SIZES, coarse_start_refused


def coarse_scene(scene: dict, factor: int) -> dict:
    """The scene with a mesh `factor` times coarser: a box's cell counts divided by `factor`
    (at least 2 per direction), a gmsh script's mesh sizes (scene.tables.MESH_SIZES)
    multiplied by it (the scene's checks allow "coarse" only for these two)."""
    coarse = copy.deepcopy(scene)
    geo = coarse["geometry"]
    if geo["type"] == "box":
        geo["cells"] = [max(2, int(n) // factor) for n in geo["cells"]]
    else:
        geo["parameters"] = {name: float(value) * factor if name in MESH_SIZES else value
                             for name, value in geo["parameters"].items()}
    coarse["output"]["probes"] = []
    coarse["solver"]["first_iterate"] = "previous"
    return coarse


def _gathered(comm, coordinates: np.ndarray, values: np.ndarray):
    """Every rank's (coordinates, values) rows, on every rank."""
    xs, vs = comm.allgather(coordinates), comm.allgather(values)
    return np.vstack(xs), np.vstack(vs)


def carry(source_x, source_values, target_x, k: int) -> np.ndarray:
    """Inverse-distance weights over the k nearest source points: the values at target_x
    (exactly the source value where a target point lies on a source point).

    Parameters
    ----------
    source_x, target_x : numpy.ndarray
        (n, d) and (m, d) point coordinates.
    source_values : numpy.ndarray
        (n, b) values at the source points.
    k : int
        How many nearest source points weigh in.

    Returns
    -------
    numpy.ndarray
        (m, b) values at the target points.
    """
    from scipy.spatial import cKDTree
    k = min(k, len(source_x))
    distance, index = cKDTree(source_x).query(target_x, k=k)
    distance, index = distance.reshape(len(target_x), k), index.reshape(len(target_x), k)
    scale = max(float(np.ptp(source_x, axis=0).max()), 1e-300)
    on_node = distance[:, 0] <= 1e-10 * scale
    weights = 1.0 / np.maximum(distance, 1e-300)
    weights[on_node] = 0.0
    weights[on_node, 0] = 1.0
    weights /= weights.sum(axis=1, keepdims=True)
    return np.einsum("mk,mkb->mb", weights, source_values[index])


class CoarseStart:
    """The coarse run beside a fine one and the first iterates it gives.

    Parameters
    ----------
    scene : dict
        The fine run's resolved scene.
    problem : contactvisco.fem.problem.Problem
        The fine problem (its unknowns receive the first iterates).
    comm : mpi4py.MPI.Comm
        The fine run's communicator (the coarse run is distributed over it too).
    then : contactvisco.solver.predictor.Extrapolation or None
        The predictor of the later steps.
    say : callable, optional
        say(text): the run's progress output (why a coarse run ended early).
    """

    #: The fine states after which the coarse run is released (the extrapolation predicts
    #: from two).
    STATES = 2

    def __init__(self, scene, problem, comm, then=None, say=None):
        self.fine, self.comm, self.then = problem, comm, then
        self.say = say or (lambda text: None)
        self.scene = coarse_scene(scene, int(scene["solver"]["coarse_factor"]))
        self.problem = self.snes = None  # built at the first coarse state, in its step's time
        self.released = False
        self.recorded = 0              # fine states accepted
        self.used = 0                  # first iterates given
        self.last_iterations = None    # Newton iterations of the coarse run's last state

    def apply(self, t: float) -> bool:
        """Set the fine unknowns to the first iterate at time t: the extrapolation's where it
        has one, else the coarse solution at t (the coarse run advanced to t), unless the
        coarse run took no Newton iteration to reach t (its last state solves t already: an
        unloaded start, a load that did not change), where the fine run's last state is kept.

        Returns
        -------
        bool
            Whether a first iterate was set (False: Newton starts from the last state).
        """
        if self.then is not None and self.then.apply(t):
            return True
        if self.released or not self._advance(t):
            return False
        if self.last_iterations == 0:        # the coarse state did not move: nor will the fine
            return False
        self._carry()
        self.used += 1
        return True

    def record(self, t: float):
        """A fine state accepted at t: kept by the extrapolation; the coarse run released
        once the extrapolation can predict."""
        if self.then is not None:
            self.then.record(t)
        self.recorded += 1
        if self.recorded >= self.STATES:
            self.release()

    def release(self):
        """Destroy the coarse run's solver (collective)."""
        self.released = True
        if self.snes is not None:
            self.snes.destroy()
            self.snes = None
            self.problem.release_garbage()    # (the coarse problem's own communicators)
            self.problem = None

    def _advance(self, t: float) -> bool:
        """The coarse run at time t; False (and the coarse run released) where it cannot be:
        t before its last state (a cut fine step), or its Newton failed."""
        if self.problem is None:
            from contactvisco.fem import geometry as geometry_module
            from contactvisco.fem.problem import build
            from contactvisco.solver import newton
            try:    # e.g. a coarse mesh with fewer cells than ranks
                self.problem = build(self.scene, geometry_module.build(self.scene, self.comm))
                self.snes = newton.create(self.problem, self.comm)
            except SceneError as err:
                self.say(f"no coarse first iterate ({err}); Newton starts from the last "
                         "state")
                self.problem = None
                self.release()
                return False
        committed = self.problem.time.committed
        if committed is not None and t <= committed:
            self.release()
            return False
        # One step of eqs (20)-(21) from the coarse run's last state, uncut: the history of
        # eq (19) staged for t, Newton, the state committed.
        self.problem.time.stage(t)
        try:
            self.last_iterations = self.snes.solve()
        except NewtonFailure as err:
            self.say(f"the coarse run failed at t = {t:g} ({err}); Newton starts from the "
                     "last state")
            self.release()
            return False
        self.problem.time.commit()
        return True

    def _carry(self):
        """The coarse unknowns at the fine nodes: u at every dof from the d + 1 nearest coarse
        dofs, the multipliers at the contact nodes from the d nearest coarse contact nodes."""
        coarse, fine = self.problem, self.fine
        d = fine.V.mesh.geometry.dim
        for fc, ff in zip(coarse.unknowns, fine.unknowns):
            if ff is fine.u:
                owned = fc.function_space.dofmap.index_map.size_local
                source, target, k = np.arange(owned), slice(None), d + 1
            else:
                nodes = coarse.contact.nodes
                source, target, k = nodes.nodes[nodes.owned], fine.contact.nodes.nodes, d
            self._carry_rows(fc, ff, source, target, k)
            ff.x.scatter_forward()

    def _carry_rows(self, fc, ff, source, target, k: int):
        """ff's rows `target` (nodes, each of block size b) from fc's owned rows `source`,
        gathered from every rank."""
        d = self.fine.V.mesh.geometry.dim
        b = fc.function_space.dofmap.index_map_bs
        xs = fc.function_space.tabulate_dof_coordinates()[source, :d]
        x_all, v_all = _gathered(self.comm, xs, fc.x.array.reshape(-1, b)[source])
        if len(x_all) == 0:
            return
        values = ff.x.array.reshape(-1, b)
        xf = ff.function_space.tabulate_dof_coordinates()[target, :d]
        values[target] = carry(x_all, v_all, xf, k)


#: solver.first_iterate = "auto" starts from the coarse run from this many displacement
#: unknowns on (2D, 3D): where the first loaded step was measured cheaper with it than
#: without, the coarse run's set-up included (docs/scaling.md).
AUTO_UNKNOWNS = {2: 100_000, 3: 20_000}


def wanted(scene: dict, problem) -> bool:
    """Whether the scene's first iterates come from a coarse run: solver.first_iterate =
    "coarse", or "auto" on a scene that allows it (scene.tables.coarse_start_refused) with at
    least AUTO_UNKNOWNS displacement unknowns."""
    choice = scene["solver"]["first_iterate"]
    if choice == "previous" or coarse_start_refused(scene) is not None:
        return False
    if choice == "coarse":
        return True
    d = problem.V.mesh.geometry.dim
    return problem.count_unknowns()["u"] >= AUTO_UNKNOWNS.get(d, AUTO_UNKNOWNS[3])


def create(scene: dict, problem, comm, then, say=None):
    """The first-iterate rule of solver.first_iterate: CoarseStart around the predictor
    `then` where `wanted`, else `then` itself."""
    return CoarseStart(scene, problem, comm, then, say) if wanted(scene, problem) else then
