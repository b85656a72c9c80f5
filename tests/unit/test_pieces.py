"""The pieces of the displacement-only Newton system checked one by one on real scenes.

- options that would take the iterates away from the coupled Newton method are refused;
- the row replacement refuses a matrix without the node's own columns;
- the condensed step (J_red du = -F_red, dl recovered node by node) is the solution of the
  assembled coupled Newton system, at states where every null-space size of the node blocks
  occurs (2D bound + stick, 3D stick, 3D bound + stick);
- the memory acts on the part of the strain its kernel names (deviatoric: shear relaxes,
  dilatation does not);
- on 3 ranks the paper scene's contact nodes are split between ranks and the answer is the
  1-rank one.
"""
import numpy as np
import pytest
from mpi4py import MPI
from petsc4py import PETSc

from contactvisco.scene import loader as scene_module
from contactvisco.solver.condensed import replace_rows
from contactvisco.solver.time_loop import simulate
from contactvisco.errors import SceneError
from helpers import condensed_at, mumps_lu

SMALL = ["geometry.cells=[8, 8]", "time.T=0.2", "time.steps=2"]


def _paper(extra, system="auto"):
    scene = scene_module.load("paper", SMALL + extra + [f"solver.linear_system='{system}'"])
    scene["output"]["probes"] = []
    return scene


@pytest.mark.parametrize("option, value", [
    ("snes_lag_jacobian", "2"), ("snes_linesearch_type", "'bt'"),
    ("snes_linesearch_damping", "0.5"), ("snes_type", "'newtontr'")])
def test_options_that_leave_newton_are_refused(option, value):
    """The condensed system refuses, by scene key, every option under which its multiplier
    update would not follow the step SNES took."""
    scene = _paper([f"solver.petsc_options.{option}={value}"])
    with pytest.raises(SceneError, match=f"solver.petsc_options.{option} = .*full step.*"
                                         "linear_system = 'coupled'"):
        simulate(scene, comm=MPI.COMM_WORLD, progress=False)


def test_step_away_from_newton_is_caught(monkeypatch):
    """Without the option check, a lagged Jacobian is still caught at the first residual
    evaluated away from a full Newton step, and reported as a clear error, not as wrong
    iterates."""
    from contactvisco.solver.newton import CondensedSNES
    monkeypatch.setattr(CondensedSNES, "_check_options", lambda self: None)
    scene = _paper(["solver.petsc_options.snes_lag_jacobian=2"])
    with pytest.raises(SceneError, match="away from the full Newton step"):
        simulate(scene, comm=MPI.COMM_WORLD, progress=False)


def test_row_replacement_checks_the_pattern():
    """A row without the node's own columns is refused; with them, P rows + L are written."""
    comm = MPI.COMM_SELF
    A = PETSc.Mat().createAIJ((4, 4), nnz=2, comm=comm)
    A.setOption(PETSc.Mat.Option.NEW_NONZERO_ALLOCATION_ERR, False)
    for row, cols in ((0, [0, 1]), (1, [0, 1]), (2, [0, 3]), (3, [0, 3])):
        A.setValues([row], cols, [1.0 + row, 2.0])
    A.assemble()
    P = np.array([[[0.0, 0.0], [0.0, 1.0]]] * 2)
    L = np.array([[[5.0, 0.0], [0.0, 0.0]]] * 2)
    replace_rows(A, np.array([[0, 1]], dtype=PETSc.IntType), P[:1], L[:1])
    dense = A.getValues(range(4), range(4))
    assert np.allclose(dense[0], [5.0, 0.0, 0.0, 0.0]) and np.allclose(dense[1], [2.0, 2.0, 0, 0])
    with pytest.raises(ValueError, match=r"lack the node's own columns \[2\]"):
        replace_rows(A, np.array([[2, 3]], dtype=PETSc.IntType), P[1:], L[1:])


def _coupled_step(problem, comm):
    """The Newton step (du, dl) of the assembled coupled system at the current state, as
    arrays over the owned dofs of u and of each multiplier."""
    from contactvisco.solver.newton import BlockSNES
    block = BlockSNES(problem.F, problem.J, problem.unknowns, problem.bcs, comm)
    try:
        block._from_functions(block.x)
        block._residual(None, block.x, block.b)
        block._jacobian(None, block.x, block.A, block.A)
        step = block.b.duplicate()
        mumps_lu(block.A, comm).solve(block.b, step)
        step.scale(-1.0)
        out, offset = [], 0
        for f in problem.unknowns:
            n = f.function_space.dofmap.index_map.size_local * \
                f.function_space.dofmap.index_map_bs
            out.append(step.array[offset:offset + n].copy())
            offset += n
        return out
    finally:
        block.destroy()


def _condensed_step(problem, comm):
    """The step of the condensed system: J_red du = -F_red, dl recovered node by node.
    Returns du (owned dofs), dl (owned contact nodes, m columns) and the nodes' nullities."""
    from contactvisco.solver.condensed import recover
    system, x = condensed_at(problem)
    b = x.duplicate()
    system.residual(x, b)
    system.jacobian()
    du = b.duplicate()
    mumps_lu(system.J_red, comm).solve(b, du)
    du.scale(-1.0)
    Jdu = system.J_contact.createVecLeft()
    system.J_contact.mult(du, Jdu)
    p = system.parts
    d = system.d
    dl = recover(p, p["B"], p["C"], p["F"], p["G"], du.array.reshape(-1, d)[system.own],
                 Jdu.array.reshape(-1, d))
    return du.array.copy(), dl, system


def _block(cells, **contact):
    """The Coulomb sliding block in its stick regime (every contact node sticks), as a scene."""
    from contactvisco.studies import coulomb
    raw, _ = coulomb.block_scene("stick", cells=cells)
    raw["contact"].update(contact)
    return scene_module.resolve(raw)


BLOCK3D = ["geometry.parameters.h=0.25", "time.T=0.4", "time.steps=2"]

PIECE_SCENES = {     # the scene at whose final state the steps are compared; the nullities
    # (active conditions per node) that must occur there
    "2D bound + stick": (lambda: _block((8, 4)), {2}),
    # compliance (g never reached) and a large mu: lambda_nu's block is regular, lambda_tau's
    # has 2 nulls
    "3D stick": (lambda: scene_module.load("block3d", BLOCK3D + ["contact.g=1.0",
                                                                 "contact.mu=5.0"]), {2}),
    "3D bound + stick": (lambda: scene_module.load("block3d", BLOCK3D), {1, 3}),
}


@pytest.mark.mpi
@pytest.mark.parametrize("label", list(PIECE_SCENES))
def test_condensed_step_is_the_coupled_step(label):
    """At the end of a run, with u perturbed so that the residual is not small: the condensed
    displacement step and the recovered multiplier step equal the solution of the assembled
    coupled Newton system (the Schur complement of its multiplier block, taken node by node),
    to 1e-9 relative; each null-space size named occurs at some node. On more than one rank
    the contact nodes must be owned by more than one rank."""
    from contactvisco.fem import compat
    make, nullities = PIECE_SCENES[label]
    comm = MPI.COMM_WORLD
    scene = make()
    scene["output"]["probes"] = []
    problem = simulate(scene, comm=comm, progress=False).problem
    if comm.size > 1:       # the contact nodes lie on both sides of a partition boundary
        owners = comm.allgather(int(problem.contact.nodes.owned.sum()))
        assert sum(n > 0 for n in owners) >= 2, owners
    rng = np.random.default_rng(comm.rank)
    u = compat.petsc_vector(problem.u)
    u.array[:] += 1e-3 * np.max(np.abs(problem.u.x.array)) * rng.standard_normal(u.array.size)
    u.ghostUpdate(addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)
    coupled = _coupled_step(problem, comm)
    du, dl, system = _condensed_step(problem, comm)
    du_scale = comm.allreduce(np.max(np.abs(coupled[0])), MPI.MAX)
    assert comm.allreduce(np.max(np.abs(du - coupled[0])), MPI.MAX) <= 1e-9 * du_scale
    for a, f in enumerate(system.fields):
        bs = system.bs[a]
        expected = coupled[1 + a].reshape(-1, bs)[system.own]
        got = dl[:, system.offsets[a]:system.offsets[a + 1]]
        # Relative to the step, or to the multiplier itself where the step is round-off.
        scale = comm.allreduce(max(np.max(np.abs(expected), initial=0.0),
                                   np.max(np.abs(f.x.array), initial=0.0)), MPI.MAX)
        error = comm.allreduce(np.max(np.abs(got - expected), initial=0.0), MPI.MAX)
        assert error <= 1e-9 * scale, (f.name, error, scale)
    seen = set().union(*comm.allgather(set(system.parts["nullity"].tolist())))
    assert nullities <= seen, seen


RANKS_SCRIPT = """
import json, sys
import numpy as np
from mpi4py import MPI
from contactvisco.scene import loader as scene_module
from contactvisco.solver.time_loop import simulate
scene = scene_module.load("paper", SETS)
scene["output"]["probes"] = []
result = simulate(scene, comm=MPI.COMM_WORLD, progress=False, keep_tables=True)
owned = MPI.COMM_WORLD.allgather(int(result.problem.contact.nodes.owned.sum()))
table = result.tables[-1]
if MPI.COMM_WORLD.rank == 0:
    print(json.dumps({"owned": owned, "newton": [s["newton_iterations"] for s in result.steps],
                      **{key: table[key].tolist() for key in KEYS}}))
"""
RANK_KEYS = ("x", "u_nu", "u_tau", "lambda_nu", "reaction_tau", "status")
#: A wide, low mesh of the paper's body: any partition into 3 parts cuts the contact boundary.
RANK_SETS = ["geometry.cells=[48, 6]"]


@pytest.mark.processes
@pytest.mark.mpi
@pytest.mark.slow
@pytest.mark.skipif(MPI.COMM_WORLD.size > 1,
                    reason="starts its own 3 MPI processes; run on one rank")
def test_three_ranks_split_the_contact_nodes():
    """The paper scene on 3 ranks: its contact nodes are owned by more than one rank (so the
    node-wise condensation runs across a partition boundary), and the answer is the 1-rank
    one: Newton counts, contact status and values to 1e-10 relative."""
    import json
    import subprocess
    import sys

    from contactvisco.io.launcher import mpi_launcher
    from helpers import ENV, launcher
    if not mpi_launcher():
        pytest.skip("no MPI launcher found")
    script = f"KEYS = {RANK_KEYS!r}\nSETS = {RANK_SETS!r}\n" + RANKS_SCRIPT
    proc = subprocess.run([*launcher(3), sys.executable, "-c", script], env=ENV,
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    three = json.loads(proc.stdout.strip().splitlines()[-1])
    assert len(three["owned"]) == 3 and sum(n > 0 for n in three["owned"]) >= 2, three["owned"]
    scene = scene_module.load("paper", RANK_SETS)
    scene["output"]["probes"] = []
    one = simulate(scene, comm=MPI.COMM_SELF, progress=False, keep_tables=True)
    assert three["newton"] == [s["newton_iterations"] for s in one.steps]
    table = one.tables[-1]
    for key in RANK_KEYS:
        expected, got = np.asarray(table[key], float), np.asarray(three[key], float)
        scale = max(1e-300, np.max(np.abs(expected)))
        assert np.max(np.abs(got - expected)) <= 1e-10 * scale, key


def _homogeneous_run(displacement, part):
    """A unit square (plane strain) with u = displacement(x) on its whole boundary, under a
    softening Prony term on the given part of the strain; returns the mean stress
    (xx, xy, yx, yy) at t = 2, two relaxation times."""
    from dolfinx import fem
    raw = {"name": "homogeneous",
           "geometry": {"type": "box", "lower": [0.0, 0.0], "upper": [1.0, 1.0],
                        "cells": [2, 2]},
           "material": {"model": "plane_strain", "E": 100.0, "nu": 0.3},
           "memory": {"kernel": "prony",
                      "terms": [{"alpha": -30.0, "tau": 1.0, "part": part}]},
           "dirichlet": [{"boundary": side, "components": "all", "value": displacement}
                         for side in ("left", "right", "bottom", "top")],
           "time": {"T": 2.0, "steps": 4}, "output": {"probes": []}}
    problem = simulate(scene_module.resolve(raw), comm=MPI.COMM_WORLD, progress=False).problem
    sigma = fem.Function(problem.tensor_space)
    sigma.interpolate(problem.sigma_expression)
    values = sigma.x.array.reshape(-1, 4)
    comm = problem.V.mesh.comm
    return comm.allreduce(values.sum(axis=0), MPI.SUM) / comm.allreduce(len(values), MPI.SUM)


@pytest.mark.parametrize("part", ["deviatoric", "volumetric"])
def test_memory_acts_on_its_part_of_the_strain(part):
    """Under a pure shear (eps deviatoric) a deviatoric kernel changes the stress and a
    volumetric one does not; under a pure dilatation (eps = e I) the other way round. A swap
    of the two parts fails both."""
    from contactvisco.model.material import lame_constants
    lame_lambda, lame_mu = lame_constants("plane_strain", 100.0, 0.3)
    e = 0.01
    shear = _homogeneous_run([f"{e} * x[1]", f"{e} * x[0]"], part)
    dilatation = _homogeneous_run([f"{e} * x[0]", f"{e} * x[1]"], part)
    elastic_shear = 2 * lame_mu * e                      # sigma_xy
    elastic_dilatation = (2 * lame_lambda + 2 * lame_mu) * e   # sigma_xx = sigma_yy
    shear_change = abs(shear[1] - elastic_shear) / elastic_shear
    dilatation_change = abs(dilatation[0] - elastic_dilatation) / elastic_dilatation
    relaxed, kept = ((shear_change, dilatation_change) if part == "deviatoric"
                     else (dilatation_change, shear_change))
    assert relaxed > 0.05, (shear_change, dilatation_change)
    assert kept < 1e-10, (shear_change, dilatation_change)


@pytest.mark.mpi
def test_corner_values_are_the_forms_values():
    """At the corner of a contact boundary made of two faces (bottom, left), the forms use
    each face's normal: the contact table reports the law as the forms apply it there, the
    mean over the two faces, not the law at the mean normal. A block pressed by p and q onto
    compliant layers (stiffness c) has u = (-p/c, -q/c) at the corner: penetration
    (p + q) / (2c) and p_nu = (p + q) / 2, where the mean normal would give sqrt(2) times
    these."""
    q, p, c = 3.0, 1.0, 100.0
    raw = {"name": "corner",
           "geometry": {"lower": [0.0, 0.0], "upper": [1.0, 1.0], "cells": [5, 5]},
           "material": {"model": "plane_strain", "E": 50.0, "nu": 0.3},
           "traction": [{"boundary": "top", "value": [0.0, -q]},
                        {"boundary": "right", "value": [-p, 0.0]}],
           "contact": {"boundary": ["bottom", "left"], "stiffness": c, "g": 1.0, "mu": 0.0},
           "time": {"T": 1.0, "steps": 1}, "output": {"probes": []}}
    result = simulate(scene_module.resolve(raw), comm=MPI.COMM_WORLD, progress=False,
                      keep_tables=True)
    table = result.tables[-1]
    corner = np.flatnonzero(np.all(np.abs(table["x"]) < 1e-12, axis=1))
    assert corner.size == 1
    assert table["penetration"][corner[0]] == pytest.approx((p + q) / (2 * c), rel=1e-10)
    assert table["p_nu"][corner[0]] == pytest.approx((p + q) / 2, rel=1e-10)
    others = np.arange(len(table["x"])) != corner[0]     # one normal: the law at the node
    assert np.allclose(table["p_nu"][others], c * table["penetration"][others], rtol=1e-12)
