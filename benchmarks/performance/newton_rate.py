"""Newton's rate at a fixed contact state: iterations per step of block3d and the paper scene,
and, for the first loaded step (block3d's t_1, the paper scene's t_0), per Newton iterate:
|F| of the coupled residual, |u - u*|_inf (u* the step's converged displacement), the
number of contact nodes whose branch of the law (separated; compliance or bound; stick or
slip) differs from the previous iterate's, and the largest error of the slip direction
|t - t*| with t = z / |z|, z = lambda_tau,tau - r slip (the direction the friction disc's
projection (radius / |z|) (I - t t^T) is linearized about).

With an exact Jacobian, Newton converges quadratically once the branches stop changing and
the iterate is close enough for its linearization: for the disc that means the slip
directions, whose error enters the projection as |t - t*| and which turn by up to 60 degrees
between iterates in block3d's first loaded step (the pressure and the slip both start at 0).
The ratio e_{k+1} / e_k^2 of the displacement errors shows the rate
(tests/integration/test_jacobian.py checks the matrices against central differences).

    python benchmarks/performance/newton_rate.py [--paper 64 128 256]
        [--block 0.125 0.0833 0.0625 0.04] [--augmentation R ...]

--augmentation runs block3d again with contact.augmentation = R (r in z, the augmented-
Lagrangian parameter of eq 20; the converged answer does not depend on it).
"""
import argparse
import pathlib
import sys

import numpy as np
from mpi4py import MPI

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1]))  # benchmarks/: common.py
from common import first_loaded_step, write_results  # noqa: E402

from contactvisco.model import contact_law as law  # noqa: E402


def node_state(problem):
    """(branch codes, slip directions t = z / |z|) at the owned contact nodes: code 0
    separated, 1 compliance stick, 2 compliance slip, 4 bound stick, 5 bound slip."""
    c = problem.contact
    d = problem.V.mesh.geometry.dim
    nodes = c.nodes.nodes[c.nodes.owned]
    normals = c.nodes.normals[c.nodes.owned]
    constants = {k: float(np.max(v.x.array)) if hasattr(v, "x") else float(v.value)
                 for k, v in c.constants.items() if v is not None}
    constants.setdefault("g", None)
    u = problem.u.x.array.reshape(-1, d)[nodes]
    lam_nu = None if c.lambda_nu is None else c.lambda_nu.x.array[nodes]
    lam_tau = c.lambda_tau.x.array.reshape(-1, d)[nodes]
    previous = None if c.u_previous is None else c.u_previous.x.array.reshape(-1, d)[nodes]
    terms = law.law_terms(law.NUMPY, u, normals, c.gap.x.array[nodes], lam_nu, lam_tau,
                          previous, constants, problem.scene["contact"]["friction_law"])
    z = law.tangential_part(lam_tau, normals, law.NUMPY) - constants["r"] * terms["slip"]
    norm = np.linalg.norm(z, axis=1)
    s = terms["s_nu"]
    bound = 0 if constants["g"] is None else 3 * (s >= constants["g"])
    code = np.where(s < 0, 0, np.where(norm <= terms["radius"], 1, 2) + bound)
    return code, z / np.maximum(norm, 1e-300)[:, None]


def run(name, sets, comm):
    """(result, the first loaded step's iterates [(|F|, u, branch codes, directions)])."""
    def state(snes):
        problem = snes.system.problem
        return (problem.u.x.array.copy(), *node_state(problem))
    result, history, loaded = first_loaded_step(name, sets, comm, state)
    return result, [(norm, *rest) for norm, rest in history], loaded

def iterates(history, comm):
    """Per iterate: |F|, |u - u*|_inf, branch changes, largest |t - t*| (all ranks)."""
    final_u, final_t = history[-1][1], history[-1][3]
    rows, previous = [], None
    for norm, u, code, direction in history:
        error = comm.allreduce(float(np.max(np.abs(u - final_u), initial=0.0)), MPI.MAX)
        changed = None if previous is None else comm.allreduce(int(np.sum(code != previous)))
        turn = comm.allreduce(float(np.max(np.linalg.norm(direction - final_t, axis=1),
                                           initial=0.0)), MPI.MAX)
        rows.append(dict(norm=norm, error=error, changed=changed, direction_error=turn))
        previous = code
    return rows


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--paper", type=int, nargs="*", default=[64, 128, 256])
    parser.add_argument("--block", type=float, nargs="*", default=[0.125, 0.0833, 0.0625, 0.04])
    parser.add_argument("--augmentation", type=float, nargs="*", default=[])
    parser.add_argument("--name", default=None)
    args = parser.parse_args()
    comm = MPI.COMM_WORLD
    cases = [("paper", [f"geometry.cells=[{n}, {n}]"], f"{n}^2") for n in args.paper]
    cases += [("block3d", [f"geometry.parameters={{lx=1.0, ly=1.0, lz=0.5, h={h}}}"],
               f"h = {h}") for h in args.block]
    cases += [("block3d", [f"geometry.parameters={{lx=1.0, ly=1.0, lz=0.5, h={h}}}",
                           f"contact.augmentation={r}"], f"h = {h}, r = {r:g}")
              for r in args.augmentation for h in args.block]
    rows, contact = [], {}
    for name, sets, size in cases:
        result, history, step = run(name, sets, comm)
        rows.append(dict(scene=name, size=size, unknowns=result.problem.count_unknowns()["u"],
                         solver=result.linear_solver,
                         iterations=[s["newton_iterations"] for s in result.steps],
                         first_loaded_step=step, iterates=iterates(history, comm)))
        # Another r: the largest difference of the contact values from the default r's run.
        key = (name, sets[0])
        if key in contact:
            rows[-1]["contact_gap"] = max(
                float(np.max(np.abs(np.asarray(a[k]) - np.asarray(b[k])), initial=0.0))
                for a, b in zip(contact[key], result.contact)
                for k in ("u_nu", "u_tau", "lambda_nu", "reaction_nu", "reaction_tau"))
        else:
            contact[key] = result.contact
    load = open("/proc/loadavg").read().split()[:3]
    lines = [f"Load average at the end: {' '.join(load)}; {comm.size} rank(s). Per iterate of "
             "the first loaded step: |F|, |u - u*|_inf, e_k / e_(k-1)^2, nodes whose branch "
             "changed, largest slip-direction error |t - t*|.", "",
             "| scene | size | u unknowns | linear solver | Newton per step (t_0 first) | "
             "total | first loaded step: per iterate |F|, e, e_k/e_(k-1)^2, changed, |t - t*| |",
             "|---|---|---|---|---|---|---|"]
    for r in rows:
        parts, last = [], None
        for it in r["iterates"]:
            ratio = ("-" if last is None or last == 0 or it["error"] == 0
                     else f"{it['error'] / last ** 2:.1e}")
            parts.append(f"{it['norm']:.1e}, {it['error']:.1e}, {ratio}, {it['changed']}, "
                         f"{it['direction_error']:.1e}")
            last = it["error"]
        lines.append(f"| {r['scene']} | {r['size']} | {r['unknowns']} | {r['solver']} | "
                     f"{r['iterations']} | {sum(r['iterations'])}"
                     + (f" (contact values within {r['contact_gap']:.1e} of the default r's)"
                        if "contact_gap" in r else "") + " | "
                     f"step {r['first_loaded_step']}: {'; '.join(parts)} |")
    if comm.rank == 0:
        write_results(args.name or f"newton_rate_np{comm.size}", rows, lines)


if __name__ == "__main__":
    main()
