"""The paper scene's Newton time against an independent semismooth Newton solver on the same
discrete problem, side by side in one process: contactvisco (DOLFINx, PETSc SNES) and a
solver written here in GetFEM's Python interface (python3-getfem).

The peer solves the discrete problem of contactvisco.fem.problem (eqs 19-21 of Ouafik 2024)
with its own assembly, unknowns and Newton loop:

- the same triangles (taken from contactvisco's DOLFINx mesh), P1 displacement, plane stress
  A eps = lambda* tr(eps) I + 2 mu eps with lambda* = E nu / (1 - nu^2);
- the Dirichlet conditions by elimination: u lives on the P1 dofs that are not prescribed
  (a reduced GetFEM MeshFem), so the clamp and the roller add no unknowns;
- the memory of eq (19) for R = alpha I with the paper's rule: the history stress of step
  n + 1 is alpha eps(U_n), U_n = P_n + k u_n with the trapezoid sum of displacements
  P_n = P_{n-1} + k/2 (u_{n-1} + u_n), P_0 = 0 (eps is linear, so summing displacements is
  summing the P1 strains);
- the contact on the bottom edge, normal nu = (0, -1), tangent tau = (1, 0), integrated with
  the vertex (Newton-Cotes) rule so that it holds node by node, written in GetFEM's weak form
  language with the node-wise complementarity functions of eqs 20-21: s = u . nu,
  p_nu = c (min(s, g))_+, R_nu = (r (s - g) - lambda_nu)_+, and the friction force
  sigma_tau = clamp(lambda_tau - r u . tau, -mu p_nu, mu p_nu) (the projection on the 1-D
  ball of radius mu p_nu);

      F_u   = int A eps(u):eps(v) + alpha eps(U_n):eps(v) - f.v - int_top f_N.v
              + int_C (p_nu + R_nu) v.nu - sigma_tau v.tau
      F_nu  = -1/r int_C (lambda_nu + R_nu) gamma_nu
      F_tau = -1/r int_C (lambda_tau - sigma_tau) gamma_tau

  with scalar P1 multipliers on the contact nodes only (lambda_tau a scalar along tau; a
  multiplier is left out at a node where the displacement it acts on is prescribed);
- GetFEM assembles the residual and its generalized (semismooth) Jacobian, derived by GetFEM
  from the expressions; each Newton iteration solves the full system with MUMPS
  (getfem.linsolve_mumps), from the previous step's converged state, until the residual's
  2-norm is at most 1e-10 times that of the step's first iterate (or 1e-10), the test of
  contactvisco's SNES (snes_rtol = snes_atol = 1e-10).

Before any time is compared, the contact values of both solvers at every contact node and
every step (u_nu, the normal reaction p_nu + R_nu and the tangential reaction sigma_tau) must
agree to AGREEMENT relative to the largest value; otherwise the script stops with an error.

Newton time: the sum of the steps' wall_s over the 10 steps after t_0 (contactvisco's step
records, outputs off) and, for the peer, the wall time of each step's history update and Newton
loop; best of 2 runs each, in one process. t_0 (the first state, from u = 0) is shown apart.

    python benchmarks/performance/peer.py [--sizes 32 64 128] [--superlu]

(about 3 minutes on an idle machine, 6 with --superlu; results/peer.md and docs/scaling.md)
"""
import argparse
import os
import pathlib
import sys
import time

import numpy as np

try:
    import getfem as gf
except ImportError:
    sys.exit("peer.py needs GetFEM's Python interface: apt-get install -y python3-getfem "
             "(Debian's package; the Debian route's .venv sees it through its system "
             "site packages)")

from mpi4py import MPI

import contactvisco as cv

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1]))  # benchmarks/: common.py
from common import write  # noqa: E402

#: Largest contact-value difference allowed, relative to the largest value of the quantity.
AGREEMENT = 1e-8
RTOL = ATOL = 1e-10
MAX_IT = 50
BOTTOM, TOP, LEFT, RIGHT = 1, 2, 3, 4


def dolfinx_triangles(result):
    """Vertex coordinates (n, 2) and triangles (m, 3) of the mesh contactvisco solved on."""
    mesh = result.problem.V.mesh
    dofmap = mesh.geometry.dofmap
    cells = np.asarray(dofmap) if isinstance(dofmap, np.ndarray) else \
        np.asarray(dofmap.array).reshape(-1, 3)
    return mesh.geometry.x[:, :2].copy(), cells


class GetfemPeer:
    """The paper scene's discrete problem in GetFEM (module description), on given triangles.

    Parameters
    ----------
    scene : dict
        The resolved paper scene (its material, memory, loads and contact values are read).
    points : numpy.ndarray
        (n, 2) vertex coordinates.
    cells : numpy.ndarray
        (m, 3) vertex indices of the triangles.
    linear : str, optional
        The linear solver of each Newton step: "mumps" (GetFEM's) or "superlu" (SciPy's).
    """

    def __init__(self, scene, points, cells, linear="mumps"):
        self._check(scene)
        self.linear = linear
        self.clock = {"assembly": 0.0, "linear": 0.0}
        mat, contact, time_table = scene["material"], scene["contact"], scene["time"]
        E, nu = mat["E"], mat["nu"]
        self.alpha = scene["memory"]["alpha"]
        self.k = time_table["T"] / time_table["steps"]
        self.steps = time_table["steps"]
        gf.util_trace_level(0)
        gf.util_warning_level(0)
        m = gf.Mesh("empty", 2)
        m.add_convex(gf.GeoTrans("GT_PK(2,1)"), np.ascontiguousarray(
            points[cells].transpose(2, 1, 0)))
        for region, direction in ((BOTTOM, [0, -1]), (TOP, [0, 1]), (LEFT, [-1, 0]),
                                  (RIGHT, [1, 0])):
            m.set_region(region, m.outer_faces_with_direction(direction, 0.01))
        mfu = gf.MeshFem(m, 2)
        mfu.set_classical_fem(1)
        mfs = gf.MeshFem(m, 1)
        mfs.set_classical_fem(1)
        # Prescribed dofs: both components on the left (clamp), x on the right (roller).
        left = mfu.basic_dof_on_region(LEFT)
        right = mfu.basic_dof_on_region(RIGHT)
        nodes_u = mfu.basic_dof_nodes()
        component = np.arange(mfu.nbdof()) % 2
        assert np.allclose(nodes_u[:, 0::2], nodes_u[:, 1::2]), "dofs not grouped by node"
        fixed = np.zeros(mfu.nbdof(), bool)
        fixed[left] = True
        fixed[right[component[right] == 0]] = True
        # A "partial" MeshFem keeps the listed basic dofs, in increasing order.
        self.u_free = np.flatnonzero(~fixed)
        self.mfu = gf.MeshFem("partial", mfu, self.u_free)
        self.nbasic_u = mfu.nbdof()
        # Contact nodes; a multiplier only where the displacement it acts on is free.
        bottom = mfs.basic_dof_on_region(BOTTOM)
        xy = mfs.basic_dof_nodes(bottom)
        fixed_xy = fixed.reshape(-1, 2)             # per node of mfu: x, y prescribed
        node_of = {tuple(np.round(p, 12)): i for i, p in enumerate(nodes_u[:, 0::2].T)}
        unode = np.array([node_of[tuple(np.round(p, 12))] for p in xy.T])
        order = np.argsort(xy[0])
        self.x = xy[0][order]
        self.u_nodes = unode[order]
        self.ln_dofs = np.sort(bottom[~fixed_xy[unode, 1]])
        self.lt_dofs = np.sort(bottom[~fixed_xy[unode, 0]])
        self.mf_ln = gf.MeshFem("partial", mfs, self.ln_dofs)
        self.mf_lt = gf.MeshFem("partial", mfs, self.lt_dofs)
        self.scalar_nodes = bottom[order]
        self.mfs = mfs

        mim = gf.MeshIm(m, gf.Integ("IM_TRIANGLE(2)"))
        vertex = gf.MeshIm(m, gf.Integ("IM_NC(2,1)"))   # its faces: the trapezoid rule
        md = gf.Model("real")
        md.add_fem_variable("u", self.mfu)
        md.add_fem_variable("ln", self.mf_ln)
        md.add_fem_variable("lt", self.mf_lt)
        for name, value in (("lambda_star", E * nu / (1 - nu**2)),
                            ("mu_lame", E / (2 * (1 + nu))), ("alpha", self.alpha),
                            ("cn", contact["stiffness"]), ("g", contact["g"]),
                            ("muf", contact["mu"]), ("r", contact["augmentation"])):
            md.add_initialized_data(name, [float(value)])
        md.add_initialized_data("f", np.array(scene["body_force"]["value"], float))
        md.add_initialized_data("fN", np.array(scene["traction"][0]["value"], float))
        md.add_initialized_data("N", [0.0, -1.0])
        md.add_initialized_data("T", [1.0, 0.0])
        md.add_fem_data("Uh", self.mfu)
        md.add_isotropic_linearized_elasticity_brick(mim, "u", "lambda_star", "mu_lame")
        md.add_source_term(mim, "f.Test_u - alpha*(Sym(Grad_Uh):Grad_Test_u)")
        md.add_source_term(mim, "fN.Test_u", TOP)
        md.add_macro("s", "u.N")
        md.add_macro("Pn", "cn*pos_part(min(s, g))")
        md.add_macro("Rn", "pos_part(r*(s - g) - ln)")
        md.add_macro("St", "max(-muf*Pn, min(muf*Pn, lt - r*(u.T)))")
        md.add_nonlinear_term(vertex, "(Pn + Rn)*(Test_u.N) - St*(Test_u.T)"
                                      " - (ln + Rn)/r*Test_ln - (lt - St)/r*Test_lt", BOTTOM)
        self.md = md
        self.unknowns = int(md.from_variables().size)

    @staticmethod
    def _check(scene):
        """The peer writes only the paper scene's law: say so for anything else."""
        contact, memory = scene["contact"], scene["memory"]
        expected = {"memory.kernel": (memory["kernel"], "constant"),
                    "time.rule": (scene["time"]["rule"], "paper"),
                    "contact.friction_law": (contact["friction_law"], "compliance"),
                    "contact.slip": (contact["slip"], "total"),
                    "contact.gap": (contact["gap"], 0.0),
                    "contact.boundary": (contact["boundary"], "bottom"),
                    "discretization.degree": (scene["discretization"]["degree"], 1),
                    "discretization.contact_quadrature":
                        (scene["discretization"]["contact_quadrature"], "nodal"),
                    "traction": ([t["boundary"] for t in scene["traction"]], ["top"]),
                    "dirichlet": ([(b["boundary"], b.get("components", "all"))
                                   for b in scene["dirichlet"]],
                                  [("left", "all"), ("right", [0])])}
        for key, (value, wanted) in expected.items():
            if value != wanted:
                raise SystemExit(f"peer.py: {key} = {value!r}; the GetFEM peer writes only "
                                 f"{wanted!r}")

    def solve_linear(self, rhs):
        """The Newton step: the tangent matrix's system solved by MUMPS through GetFEM
        (linear = "mumps"), or by SciPy's SuperLU with the minimum-degree ordering of
        A^T + A (linear = "superlu"), on the matrix GetFEM assembled."""
        K = self.md.tangent_matrix()
        if self.linear == "mumps":
            return np.asarray(gf.linsolve_mumps(K, rhs)).ravel()
        from scipy.sparse import csc_matrix
        from scipy.sparse.linalg import spsolve
        pointers, rows = K.csc_ind()
        A = csc_matrix((K.csc_val(), rows, pointers), shape=K.size())
        return spsolve(A, rhs, permc_spec="MMD_AT_PLUS_A")

    def newton(self):
        """Newton's method from the current variables; returns the iteration count."""
        md = self.md
        for it in range(MAX_IT + 1):
            tick = time.perf_counter()
            md.assembly("build_all")
            rhs = md.rhs()
            self.clock["assembly"] += time.perf_counter() - tick
            norm = np.linalg.norm(rhs)
            if it == 0:
                norm0 = norm
            if norm <= ATOL or (it > 0 and norm <= RTOL * norm0):
                return it
            if it == MAX_IT:
                raise RuntimeError(f"GetFEM peer: no convergence in {MAX_IT} iterations "
                                   f"(residual {norm:.3e}, first {norm0:.3e})")
            tick = time.perf_counter()
            du = self.solve_linear(rhs)
            self.clock["linear"] += time.perf_counter() - tick
            md.to_variables(md.from_variables() + du)

    def contact_values(self):
        """Per contact node (sorted by x): u_nu, p_nu + R_nu and sigma_tau . tau."""
        md = self.md
        u = np.zeros(self.nbasic_u)
        u[self.u_free] = md.variable("u")
        u = u.reshape(-1, 2)
        ln = np.zeros(self.mfs.nbdof())
        lt = np.zeros(self.mfs.nbdof())
        ln[self.ln_dofs] = md.variable("ln")
        lt[self.lt_dofs] = md.variable("lt")
        ln, lt = ln[self.scalar_nodes], lt[self.scalar_nodes]
        c, g, mu, r = (float(md.variable(n)[0]) for n in ("cn", "g", "muf", "r"))
        un = -u[self.u_nodes, 1]
        ut = u[self.u_nodes, 0]
        p = c * np.maximum(0.0, np.minimum(un, g))
        R = np.maximum(0.0, r * (un - g) - ln)
        st = np.clip(lt - r * ut, -mu * p, mu * p)
        return {"u_nu": un, "reaction_nu": p + R, "sigma_tau": st}

    def run(self):
        """t_0 and the scene's steps from u = 0: per state a dict of its Newton iterations,
        wall seconds (history update and Newton loop), the seconds of assembly and of linear
        solves within them, and the contact values."""
        md = self.md
        md.to_variables(np.zeros(self.unknowns))
        md.set_variable("Uh", np.zeros(self.mfu.nbdof()))
        states, P, last = [], None, None
        for n in range(self.steps + 1):
            self.clock = {"assembly": 0.0, "linear": 0.0}
            tick = time.perf_counter()
            if n > 0:                                  # the history of eq (19), paper rule
                md.set_variable("Uh", P + self.k * last)
            iterations = self.newton()
            u = md.variable("u").copy()
            P = np.zeros_like(u) if P is None else P + 0.5 * self.k * (last + u)
            last = u
            seconds = time.perf_counter() - tick
            states.append(dict(iterations=iterations, wall_s=seconds, **self.clock,
                               values=self.contact_values()))
        return states


def contactvisco_values(table):
    """The same quantities from a contactvisco contact table (nodes sorted by x)."""
    order = np.argsort(table["x"][:, 0])
    return np.asarray(table["x"][order, 0]), {
        "u_nu": table["u_nu"][order], "reaction_nu": table["reaction_nu"][order],
        "sigma_tau": table["sigma_tau_vector"][order, 0]}


def agreement(cv_result, peer_states, peer_x):
    """max over states and nodes of |difference| / max |contactvisco value|, per quantity."""
    worst = {}
    for table, state in zip(cv_result.contact, peer_states):
        x, reference = contactvisco_values(table)
        assert np.allclose(x, peer_x, atol=1e-12), "contact nodes differ"
        for key, ref in reference.items():
            scale = max(np.abs(ref).max(), 1e-300)
            worst[key] = max(worst.get(key, 0.0),
                             float(np.abs(state["values"][key] - ref).max() / scale))
    return worst


def contactvisco_run(scene):
    """One run of contactvisco, outputs off: (Newton seconds of the steps after t_0, result)."""
    result = cv.solve(scene)
    return sum(s["wall_s"] for s in result.steps[1:]), result


def peer_run(peer):
    """One run of the peer: (seconds of the steps after t_0, states)."""
    states = peer.run()
    return sum(s["wall_s"] for s in states[1:]), states


#: contactvisco's configurations: the default (predicted first iterate) and without the
#: prediction; "direct" is added where the default's linear solver is not MUMPS throughout
#: (from AUTO_ITERATIVE unknowns on, linear_solver = "auto" is iterative, for the first state
#: only below AUTO_DIRECT_LATER).
CONTACTVISCO = {"extrapolate": {"predictor": "extrapolate"}, "none": {"predictor": "none"}}
DIRECT = {"predictor": "extrapolate", "linear_solver": "direct"}
REPEAT = 2


def measure(n, peers):
    """Both solvers on the paper scene at n x n cells, best of REPEAT runs each, the runs of
    all configurations taken in turn (so that a change of the machine's load falls on all of
    them): a row of the table."""
    row = {"cells": n, "load_before": os.getloadavg()}
    scenes = {name: cv.load_scene("paper", geometry={"cells": [n, n]}, solver=solver)
              for name, solver in CONTACTVISCO.items()}
    best = {"extrapolate": contactvisco_run(scenes["extrapolate"])}
    first = best["extrapolate"][1]
    if first.linear_solver != "preonly/lu":
        scenes["direct"] = cv.load_scene("paper", geometry={"cells": [n, n]}, solver=DIRECT)
    points, cells = dolfinx_triangles(first)
    runners = {name: (contactvisco_run, scene) for name, scene in scenes.items()}
    runners.update({linear: (peer_run, GetfemPeer(scenes["extrapolate"], points, cells, linear))
                    for linear in peers})
    for round_ in range(REPEAT):
        for name, (run, argument) in runners.items():
            if round_ == 0 and name == "extrapolate":
                continue                               # its first run is above
            seconds, payload = run(argument)
            if name not in best or seconds < best[name][0]:
                best[name] = (seconds, payload)
    results = {name: best[name][1] for name in scenes}
    for name, result in results.items():
        row[name] = dict(
            iterations=[s["newton_iterations"] for s in result.steps],
            setups=[s.get("preconditioner_setups") for s in result.steps],
            newton_s=best[name][0], t0_s=result.steps[0]["wall_s"],
            linear_solver=result.linear_solver, linear_system=result.linear_system)
    row["unknowns_contactvisco"] = sum(first.problem.count_unknowns().values())
    worst_all = 0.0
    for linear in peers:
        peer, (seconds, states) = runners[linear][1], best[linear]
        worst = {p: agreement(r, states, peer.x) for p, r in results.items()}
        difference = max(max(w.values()) for w in worst.values())
        worst_all = max(worst_all, difference)
        print(f"{n}^2, GetFEM with {linear}: largest relative contact difference "
              f"{difference:.2e} " + str({p: {k: f"{v:.1e}" for k, v in w.items()}
                                           for p, w in worst.items()}), flush=True)
        if difference > AGREEMENT:
            raise SystemExit(f"the two solvers disagree at {n}^2 cells ({difference:.2e} > "
                             f"{AGREEMENT:g}): the timing would compare different problems")
        row["unknowns_peer"] = peer.unknowns
        row[linear] = dict(iterations=[s["iterations"] for s in states], newton_s=seconds,
                           t0_s=states[0]["wall_s"], agreement=worst,
                           assembly_s=sum(s["assembly"] for s in states[1:]),
                           linear_s=sum(s["linear"] for s in states[1:]))
    row["difference"] = worst_all
    for name in results:
        for linear in peers:
            row[name][f"ratio_{linear}"] = row[name]["newton_s"] / row[linear]["newton_s"]
    row["load_after"] = os.getloadavg()
    print(f"{n}^2: " + ", ".join(f"{name} {best[name][0]:.3f} s" for name in runners),
          flush=True)
    return row


def line(r):
    """A table line of a row of measure()."""
    e, none, mumps = r["extrapolate"], r["none"], r["mumps"]
    direct, superlu = r.get("direct"), r.get("superlu")
    count = lambda entry: sum(entry["iterations"][1:])   # noqa: E731
    return (f"| {r['cells']}^2 | {r['unknowns_contactvisco']} / {r['unknowns_peer']} | "
            f"{count(e)} / {count(none)} / {count(mumps)} | "
            f"{e['newton_s']:.3f} ({e['linear_solver']}) | {none['newton_s']:.3f} | "
            + (f"{direct['newton_s']:.3f} | " if direct else "(the default) | ")
            + f"{mumps['newton_s']:.3f} ({mumps['linear_s']:.3f}) | "
            + (f"{superlu['newton_s']:.3f} ({superlu['linear_s']:.3f}) | " if superlu
               else "- | ")
            + f"**{e['ratio_mumps']:.2f}** | {none['ratio_mumps']:.2f} | "
            + (f"{direct['ratio_mumps']:.2f} | " if direct else "- | ")
            + f"{r['difference']:.1e} | {r['load_before'][0]:.1f}-{r['load_after'][0]:.1f} |")


HEADER = ("| cells | unknowns contactvisco / GetFEM | Newton iterations, 10 steps: contactvisco / "
          "predictor none / GetFEM | contactvisco s (its linear solver) | predictor none s | "
          "linear_solver direct s | GetFEM+MUMPS s (its solves) | GetFEM+SciPy SuperLU s "
          "(its solves) | ratio to GetFEM+MUMPS | ratio, predictor none | ratio, direct | "
          "largest contact difference | load (1 min, before-after) |")


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--sizes", type=int, nargs="+", default=[32, 64, 128])
    parser.add_argument("--superlu", action="store_true",
                        help="also the peer with SciPy's SuperLU in place of MUMPS (slower)")
    args = parser.parse_args()
    if MPI.COMM_WORLD.size != 1:
        sys.exit("peer.py runs on one rank (the peer is serial)")
    peers = ("mumps", "superlu") if args.superlu else ("mumps",)
    rows = [measure(n, peers) for n in args.sizes]
    write("peer", rows, HEADER, line)


if __name__ == "__main__":
    main()
