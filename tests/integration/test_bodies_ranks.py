"""Two bodies on 1, 2 and 3 ranks: the block dragged over the block with Coulomb friction
(meshes/two_blocks.py, non-matching interface nodes), its interface split between the ranks,
gives the same slave contact state and the same master displacement at the interface
whatever the partition. The 2- and 3-rank runs are children under this MPI's launcher,
started from a 1-rank test (skipped on more ranks)."""
import json
import pathlib
import subprocess
import sys

import numpy as np
import pytest
from mpi4py import MPI

pytestmark = [pytest.mark.processes,
              pytest.mark.skipif(MPI.COMM_WORLD.size > 1,
                                 reason="starts its own MPI processes; run on one rank")]

MU, PRESSURE = 0.3, 0.01


def sliding_scene(pairing: str) -> dict:
    """The upper block (slave, 16 interface segments) pressed by p onto the lower one
    (master, 12 segments, clamped at its bottom) and dragged by its top (u_x = 0.05 t):
    Signorini contact with Coulomb friction mu = 0.3, partly stuck at t = 0.5, sliding at
    t = 1."""
    return {
        "name": "sliding_blocks",
        "geometry": {"type": "gmsh", "script": "two_blocks",
                     "parameters": {"h_slave": 1 / 16, "h_master": 1 / 12}},
        "material": {"model": "plane_strain", "E": 1.0, "nu": 0.3},
        "dirichlet": [{"boundary": "bottom", "components": "all"},
                      {"boundary": "top", "components": [0], "value": "0.05 * t"}],
        "traction": [{"boundary": "top", "value": [0.0, -PRESSURE]}],
        "contact": {"boundary": "slave", "stiffness": 0.0, "g": 0.0, "mu": MU,
                    "friction_law": "coulomb", "pairing": pairing},
        "obstacle": {"shape": "body", "boundary": "master"},
        "time": {"T": 1.0, "steps": 2},
        "solver": {"petsc_options": {"snes_rtol": 1e-13, "snes_atol": 1e-16}},
        "output": {"probes": []},
    }


def interface_state(pairing: str, comm=MPI.COMM_WORLD) -> dict:
    """Solve the sliding blocks on comm (t = 0, 0.5, 1) and gather, keyed by the node's place
    rounded to 1e-12 (and "s"/"m" for the slave or master side of the interface y = 0): the
    slave's nodal contact forces and displacements, the master's interface displacements;
    also Newton's iterations per step and how many slave nodes each rank owns."""
    from contactvisco.fem import geometry as geometry_module
    from contactvisco.fem.problem import build
    from contactvisco.scene import loader
    from contactvisco.solver.newton import create
    scene = loader.resolve(sliding_scene(pairing))
    problem = build(scene, geometry_module.build(scene, comm))
    snes = create(problem, comm)
    iterations = []
    for t in (0.0, 0.5, 1.0):
        problem.time.stage(t)
        iterations.append(int(snes.solve()))
        problem.time.commit()
    c = snes.system.contact_forces().array.reshape(-1, 2)
    u = problem.u.x.array.reshape(-1, 2)
    owned = problem.V.dofmap.index_map.size_local
    x = problem.V.tabulate_dof_coordinates()[:owned, :2]
    nodes = problem.contact.nodes
    slave = set(int(i) for i in nodes.nodes[nodes.owned])
    mine = {}
    for i in np.flatnonzero(np.abs(x[:, 1]) < 1e-12):
        side = "s" if int(i) in slave else "m"
        key = f"{side} {round(float(x[i, 0]), 12) + 0.0:.12f}"         # no "-0.000..."
        mine[key] = ([*u[i], *c[i]] if side == "s" else [*u[i]])
    state = {}
    for part in comm.allgather(mine):
        assert not set(part) & set(state)
        state.update(part)
    return {"state": state, "iterations": iterations,
            "owned": comm.allgather(len(slave))}


PAIRINGS = ("mortar", "node_to_segment")

CHILD = """
import json, sys
sys.path.insert(0, {here!r})
from mpi4py import MPI
from test_bodies_ranks import PAIRINGS, interface_state
out = {{pairing: interface_state(pairing) for pairing in PAIRINGS}}
if MPI.COMM_WORLD.rank == 0:
    print(json.dumps(out))
"""


def _on_ranks(ranks: int) -> dict:
    """interface_state of both pairings computed by a child on `ranks` ranks."""
    from helpers import ENV, launcher
    script = CHILD.format(here=str(pathlib.Path(__file__).parent))
    proc = subprocess.run([*launcher(ranks), sys.executable, "-c", script], env=ENV,
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    return json.loads(proc.stdout.strip().splitlines()[-1])


@pytest.mark.mpi
@pytest.mark.slow
def test_one_two_and_three_ranks_agree():
    """The sliding blocks on 2 and 3 ranks, the slave nodes owned by at least two ranks,
    for both pairings: the same Newton iterations, and the slave's contact forces and
    displacements and the master's interface displacements those of 1 rank to 1e-12 of
    their largest value (measured: at most 6e-14); at t = 1 the slave slides
    (|c_tau| = mu |c_nu| at its pressed nodes)."""
    from contactvisco.io.launcher import mpi_launcher
    if not mpi_launcher():
        pytest.skip("no MPI launcher found")
    alone = {pairing: interface_state(pairing, MPI.COMM_SELF) for pairing in PAIRINGS}
    for one in alone.values():
        values = np.array([one["state"][k][2:] for k in sorted(one["state"]) if k[0] == "s"])
        pressed = np.abs(values[:, 1]) > 1e-12 * PRESSURE
        assert pressed.sum() >= 12
        assert np.allclose(np.abs(values[pressed, 0]), MU * np.abs(values[pressed, 1]),
                           rtol=1e-10, atol=0.0)
    for ranks in (2, 3):
        children = _on_ranks(ranks)
        for pairing, one in alone.items():
            many = children[pairing]
            assert sum(n > 0 for n in many["owned"]) >= 2, many["owned"]
            assert many["iterations"] == one["iterations"]
            assert set(many["state"]) == set(one["state"])
            for side, columns, name in (("s", slice(0, 2), "slave u"),
                                        ("s", slice(2, 4), "c"),
                                        ("m", slice(0, 2), "master u")):
                keys = sorted(k for k in one["state"] if k[0] == side)
                a = np.array([one["state"][k][columns] for k in keys])
                b = np.array([many["state"][k][columns] for k in keys])
                difference = np.abs(a - b).max() / np.abs(a).max()
                print(f"{pairing}, {ranks} ranks (slave nodes owned {many['owned']}), "
                      f"{name}: largest difference / largest value {difference:.1e}, "
                      f"Newton iterations {one['iterations']}")
                assert difference <= 1e-12, (pairing, ranks, name)
