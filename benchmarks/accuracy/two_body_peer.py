"""Two viscoelastic bodies in frictional contact, solved by contactvisco and by an independent
solver of the same discrete problem, node by node (run by hand:
python benchmarks/accuracy/two_body_peer.py, about a minute, writes
results/two_body_peer.{json,md}; tested by tests/integration/test_two_body_peer.py).

The scene (`scene()`): the paper's body (0, 1) x (0, 1) (Ouafik 2024, sec. 4: plane stress,
E = 100, nu = 0.3, clamped at x = 0, u_x = 0 at x = 1, f0 = (0, -10), fN = (0, -20) on its
top) on a layer (0, 1) x (-0.5, 0), clamped at its bottom, the master; meshes/two_blocks.py
with 16 slave against 22 master segments along y = 0 (non-matching). Each body has its own
memory kernel of the paper's kind, R = alpha I (alpha = 100 in the body, 50 in the layer; a
[[body]] table each); the interface law is the paper's: normal compliance c = 100 up to the
bound g = 0.05, friction bounded by mu p_nu(u_nu), mu = 0.2 (contact.friction_law =
"compliance"), on u_rel = u_slave - Pi u_master. Both time rules: "paper" (eq 19 as printed)
and "exponential" (each exponential of the kernel integrated exactly against the
piecewise-linear strain; for the constant kernel, tau = inf, its weights are k/2 and k/2:
the trapezoid rule), both pairings ("mortar", "node_to_segment").

The peer (`Peer`) shares with contactvisco only the triangles (taken from contactvisco's
DOLFINx mesh, one GetFEM mesh per body, so that the bodies' coinciding interface nodes stay
apart) and the scene's numbers:

- GetFEM assembles per body the P1 matrices of int A eps(u) : eps(v) (plane stress,
  lambda* = E nu / (1 - nu^2)) and of int eps(u) : eps(v) (the memory, R = alpha I), and
  the load vector; the Dirichlet conditions are eliminated (u lives on the free dofs);
- the memory recursion is written on the displacements (eps is linear in u): paper's rule
  (eq 19: the trapezoid rule on [t_0, t_n], the left point on [t_n, t_{n+1}]), for
  R = alpha exp(-t/tau) I and d = exp(-k/tau) (1 for the constant kernel),
  H_{n+1} = alpha eps(d P_n + k d u_n), P_n = d P_{n-1} + k/2 (d u_{n-1} + u_n), P_0 = 0; exponential
  rule, for R = alpha exp(-t/tau) I, S_{n+1} = d S_n + w0 u_n + w1 u_{n+1} with d = e^-z,
  w0 = tau^2 (1 - d)/k - tau d, w1 = tau (1 - d) - w0 (z = k/tau; k/2 and k/2 at tau = inf),
  H_{n+1} = alpha eps(d S_n + w0 u_n) + alpha w1 eps(u_{n+1}), the last term implicit;
- the interface operator Pi is built here (`node_to_segment`, `mortar`): node to segment,
  the master's P1 shape functions at the closest point of each slave node; mortar,
  Pi = D^-1 M, D_i = int N_i, M_ik = int Phi_i N^m_k with the dual basis Phi = 2 N_1 - N_2,
  2 N_2 - N_1 on each slave segment, each slave segment cut at the projections of the master
  nodes and each piece integrated by Simpson's rule (exact: the integrand is quadratic);
  nu_i = -n_m and h_i = n_m . (x_i - (Pi x)_i) from the closest point's master segment;
- at each slave node i (weight w_i = int N_i ds, the vertex rule), with s = u_rel . nu - h,
  u_tau = u_rel . tau (tau = (-nu_y, nu_x)), the multipliers lambda_nu, lambda_tau and the
  augmentation r (contact.augmentation):

      p_nu = c (min(s, g))_+,   R_nu = (r (s - g) - lambda_nu)_+,
      sigma_tau = clamp(lambda_tau - r u_tau, -mu p_nu, mu p_nu),
      f_i = w_i ((p_nu + R_nu) nu - sigma_tau tau)        (the slave's nodal force),
      G_nu = -w_i/r (lambda_nu + R_nu),   G_tau = -w_i/r (lambda_tau - sigma_tau);

  the slave node receives f_i and the master's nodes -Pi_ik f_i (F = F_el + T^T f(T u),
  T = I - Pi on the slave rows);
- Newton on (u, lambda_nu, lambda_tau) with its generalized (semismooth) Jacobian written
  here by hand (the derivative of each max/min/clamp on the branch the iterate is on),
  SciPy's sparse LU for each step, from the last converged state, until the residual is
  below 1e-11 of the step's first one (or 1e-13).

At a slave node whose component is prescribed (the clamp at x = 0, the roller u_x = 0 at
x = 1) two conventions are written (`prescribed`):

- "relative" (what contactvisco solves, docs/interface.md "Held slave nodes"):
  u_rel = u_slave - Pi u_master at every component of every slave node and the master
  receives -Pi^T f of every one (the slave's prescribed rows take their part as a support
  reaction);
- "held" (a former rule, kept to measure what it changes): that component of u_rel is the
  slave's own prescribed value, its multiplier is held at 0, and the master receives nothing
  from it.

They differ only where a prescribed slave component carries contact force: here the
roller's node at x = 1, at the bound, whose friction the layer feels in "relative" only,
and the clamped corner.
"""
from __future__ import annotations

import math
import pathlib
import sys

import numpy as np

try:
    import getfem as gf
except ImportError:
    sys.exit("two_body_peer.py needs GetFEM's Python interface: apt-get install -y "
             "python3-getfem (the Debian route's .venv sees it)")
from scipy import sparse
from scipy.sparse.linalg import spsolve

#: The peer's Newton test: residual 2-norm below RTOL of the step's first (or ATOL).
RTOL, ATOL, MAX_IT = 1e-11, 1e-13, 60
#: Nodes on the interface y = 0 and on the Dirichlet sides: coordinates within TOL.
TOL = 1e-10
#: Pieces of a slave segment shorter than this (reference length) are left out.
PIECE = 1e-14


def scene(pairing: str = "mortar", rule: str = "paper", steps: int = 10,
          kernels=((100.0, math.inf), (50.0, math.inf))) -> dict:
    """The raw scene of the module description: the paper's body on a layer.

    Parameters
    ----------
    pairing : str
        contact.pairing, "mortar" or "node_to_segment".
    rule : str
        time.rule, "paper" or "exponential".
    steps : int
        time.steps over T = 1.
    kernels : tuple
        (alpha, tau) of the body and of the layer: R(t) = alpha exp(-t/tau) I (tau = inf:
        the paper's constant kernel R = alpha I).

    Returns
    -------
    dict
        The raw scene (loader.resolve takes it).
    """
    def memory(alpha, tau):
        if math.isinf(tau):
            return {"kernel": "constant", "alpha": alpha}
        return {"kernel": "exponential", "alpha": [alpha], "tau": [tau]}

    return {
        "name": "two_bodies",
        "geometry": {"type": "gmsh", "script": "two_blocks",
                     "parameters": {"height": 1.0, "depth": 0.5, "h_slave": 1 / 16,
                                    "h_master": 1 / 22, "split_sides": 1}},
        "material": {"model": "plane_stress", "E": 100.0, "nu": 0.3},
        "dirichlet": [{"boundary": "slave_left", "components": "all"},
                      {"boundary": "slave_right", "components": [0]},
                      {"boundary": "bottom", "components": "all"}],
        "body_force": {"value": [0.0, "conditional(x[1] > 0, -10.0, 0.0)"]},
        "traction": [{"boundary": "top", "value": [0.0, -20.0]}],
        "body": [{"name": "body", "cells": "slave_body", "memory": memory(*kernels[0])},
                 {"name": "layer", "cells": "master_body", "memory": memory(*kernels[1])}],
        # Both solvers keep the reference pairing (the body slides up to 0.057 along the
        # layer, past half of a master segment, 0.023): the same discrete problem.
        "contact": {"boundary": "slave", "stiffness": 100.0, "g": 0.05, "mu": 0.2,
                    "pairing": pairing, "sliding_limit": math.inf},
        "obstacle": {"shape": "body", "boundary": "master"},
        "time": {"T": 1.0, "steps": steps, "rule": rule},
        "solver": {"petsc_options": {"snes_rtol": 1e-12, "snes_atol": 1e-13}},
        "output": {"probes": []},
    }


# --- the interface operator, written here -------------------------------------------------

def interface_segments(points, cells, upper: bool):
    """The boundary segments on y = 0 of the body above (upper) or below it: per segment its
    two node indices and the outward unit normal (away from the cell's third vertex)."""
    centroid_y = points[cells, 1].mean(axis=1)
    mine = cells[centroid_y > 0] if upper else cells[centroid_y < 0]
    count, owner = {}, {}
    for tri in mine:
        for a, b, c in ((0, 1, 2), (1, 2, 0), (2, 0, 1)):
            key = tuple(sorted((int(tri[a]), int(tri[b]))))
            count[key] = count.get(key, 0) + 1
            owner[key] = int(tri[c])
    segments, normals = [], []
    for (a, b), n in count.items():
        if n != 1 or abs(points[a, 1]) > TOL or abs(points[b, 1]) > TOL:
            continue
        t = points[b] - points[a]
        normal = np.array([t[1], -t[0]]) / np.linalg.norm(t)
        if normal @ (points[owner[(a, b)]] - points[a]) > 0:
            normal = -normal
        segments.append((a, b))
        normals.append(normal)
    order = np.argsort([points[list(s), 0].mean() for s in segments])
    return np.array(segments)[order], np.array(normals)[order]


def closest_points(x, points, segments):
    """Per point of x: the index of the closest master segment and the local coordinate
    xi in [0, 1] of the closest point on it (the first segment of equal distance)."""
    a, b = points[segments[:, 0]], points[segments[:, 1]]
    t = b - a
    xi = np.clip(np.einsum("psd,sd->ps", x[:, None, :] - a[None], t) / (t * t).sum(1), 0, 1)
    p = a[None] + xi[..., None] * t[None]
    distance = np.linalg.norm(x[:, None, :] - p, axis=2)
    which = np.argmin(distance, axis=1)
    return which, xi[np.arange(len(x)), which]


def node_to_segment(slave_nodes, master_nodes, points, master_segments):
    """Pi_ik = N_k(p_i): the master's P1 shape functions at the closest point p_i of each
    slave node (rows: slave_nodes, columns: master_nodes)."""
    column = {int(k): j for j, k in enumerate(master_nodes)}
    which, xi = closest_points(points[slave_nodes], points, master_segments)
    Pi = np.zeros((len(slave_nodes), len(master_nodes)))
    for i, (s, e) in enumerate(zip(which, xi)):
        a, b = master_segments[s]
        Pi[i, column[int(a)]] += 1.0 - e
        Pi[i, column[int(b)]] += e
    return Pi


def mortar(slave_nodes, master_nodes, points, slave_segments, slave_normals,
           master_segments, master_normals):
    """Pi = D^-1 M with D_i = int N_i ds and M_ik = int Phi_i (N^m_k o chi) ds, Phi the dual
    basis (2 N_1 - N_2, 2 N_2 - N_1) of each slave segment, chi along the slave normal: each
    slave segment cut at the projections of the master nodes, Simpson's rule on each piece.
    Returns (Pi, D)."""
    row = {int(k): j for j, k in enumerate(slave_nodes)}
    column = {int(k): j for j, k in enumerate(master_nodes)}
    M = np.zeros((len(slave_nodes), len(master_nodes)))
    D = np.zeros(len(slave_nodes))
    for (A, B), n_s in zip(slave_segments, slave_normals):
        t = points[B] - points[A]
        length = np.linalg.norm(t)
        D[row[int(A)]] += length / 2
        D[row[int(B)]] += length / 2
        for (P, Q), n_m in zip(master_segments, master_normals):
            if n_s @ n_m >= 0:
                continue
            xi_P = (points[P] - points[A]) @ t / length**2
            xi_Q = (points[Q] - points[A]) @ t / length**2
            lo, hi = max(0.0, min(xi_P, xi_Q)), min(1.0, max(xi_P, xi_Q))
            if hi - lo <= PIECE:
                continue
            for xi, weight in ((lo, 1.0), (0.5 * (lo + hi), 4.0), (hi, 1.0)):
                weight *= length * (hi - lo) / 6.0
                eta = (xi - xi_P) / (xi_Q - xi_P)
                phi = (2 * (1 - xi) - xi, 2 * xi - (1 - xi))
                for node, value in ((A, phi[0]), (B, phi[1])):
                    M[row[int(node)], column[int(P)]] += weight * value * (1 - eta)
                    M[row[int(node)], column[int(Q)]] += weight * value * eta
    return M / D[:, None], D


# --- the peer ----------------------------------------------------------------------------

def dolfinx_nodes(problem):
    """The P1 nodes of contactvisco's displacement space as (coordinates (n, 2), triangles
    (m, 3) of node indices): node j is the dof block j of problem.u."""
    V = problem.V
    points = V.tabulate_dof_coordinates()[:, :2].copy()
    dofmap = V.dofmap.list
    cells = np.asarray(dofmap) if isinstance(dofmap, np.ndarray) else \
        np.asarray(dofmap.array).reshape(-1, 3)
    return points, cells


def exponential_weights(k, tau):
    """(d, w0, w1) of one step k for exp(-t/tau) (module description; tau = inf: 1, k/2,
    k/2; a series below z = 1e-3)."""
    if math.isinf(tau):
        return 1.0, k / 2, k / 2
    z = k / tau
    d = math.exp(-z)
    if z < 1e-3:
        w0 = k * (0.5 - z / 3 + z**2 / 8 - z**3 / 30)
        w1 = k * (1 - z / 2 + z**2 / 6 - z**3 / 24) - w0
    else:
        w0 = tau**2 * (1 - d) / k - tau * d
        w1 = tau * (1 - d) - w0
    return d, w0, w1


class Peer:
    """The discrete problem of `scene()` assembled and solved independently (module
    description).

    Parameters
    ----------
    raw : dict
        The scene (`scene()`): its materials, kernels, loads, law, rule and steps are read.
    points, cells : numpy.ndarray
        contactvisco's P1 nodes and triangles (`dolfinx_nodes`).
    prescribed : str
        "held" or "relative" (module description).
    """

    def __init__(self, raw, points, cells, prescribed="held"):
        self.raw, self.points, self.prescribed = raw, points, prescribed
        gf.util_trace_level(0)
        gf.util_warning_level(0)
        n = len(points)
        self.n = n
        nu = raw["material"]["nu"]
        centroid_y = points[cells, 1].mean(axis=1)
        K = sparse.csr_matrix((2 * n, 2 * n))
        self.memory = []                        # per body: (alpha, tau, G_b)
        f = np.zeros(2 * n)
        for body, upper in zip(raw["body"], (True, False)):
            E = body.get("material", {}).get("E", raw["material"]["E"])
            K_b, G_b, f_b = self._assemble(cells[(centroid_y > 0) == upper], E, nu, upper)
            K, f = K + K_b, f + f_b
            memory = body["memory"]
            tau = math.inf if memory["kernel"] == "constant" else memory["tau"][0]
            alpha = memory["alpha"] if memory["kernel"] == "constant" else memory["alpha"][0]
            self.memory.append((float(alpha), float(tau), G_b))
        self.K, self.f = K, f
        x, y = points[:, 0], points[:, 1]
        fixed = np.zeros((n, 2), bool)
        slave = np.zeros(n, bool)
        slave[np.unique(cells[centroid_y > 0])] = True
        fixed[slave & (np.abs(x) < TOL)] = True                     # clamp
        fixed[slave & (np.abs(x - 1) < TOL), 0] = True              # roller
        fixed[~slave & (np.abs(y + 0.5) < TOL)] = True              # the layer's bottom
        self.fixed = fixed.reshape(-1)
        self.free = np.flatnonzero(~self.fixed)
        self._interface(cells)
        law = raw["contact"]
        self.c, self.g, self.mu = law["stiffness"], law["g"], law["mu"]
        self.r = law.get("augmentation", 1.0)

    def _assemble(self, cells, E, nu, upper):
        """GetFEM's P1 matrices of one body on its own mesh: int A eps:eps, int eps:eps and
        the loads (f0 and fN on the upper body), scattered to the global 2 n dofs."""
        nodes = np.unique(cells)
        local = {int(j): i for i, j in enumerate(nodes)}
        m = gf.Mesh("empty", 2)
        m.add_convex(gf.GeoTrans("GT_PK(2,1)"),
                     np.ascontiguousarray(self.points[cells].transpose(2, 1, 0)))
        mfu = gf.MeshFem(m, 2)
        mfu.set_classical_fem(1)
        mim = gf.MeshIm(m, gf.Integ("IM_TRIANGLE(2)"))
        zero = np.zeros(mfu.nbdof())
        lam, mu = E * nu / (1 - nu**2), E / (2 * (1 + nu))
        A = gf.asm("generic", mim, 2, f"{lam}*Div_u*Div_Test_u + {2 * mu}*Sym(Grad_u):"
                   "Grad_Test_u", -1, "u", 1, mfu, zero)
        G = gf.asm("generic", mim, 2, "Sym(Grad_u):Grad_Test_u", -1, "u", 1, mfu, zero)
        load = np.zeros(mfu.nbdof())
        if upper:
            TOP = 7
            m.set_region(TOP, m.outer_faces_with_direction([0.0, 1.0], 0.01))
            load += gf.asm("generic", mim, 1, "[0,-10].Test_u", -1, "u", 1, mfu, zero)
            load += gf.asm("generic", mim, 1, "[0,-20].Test_u", TOP, "u", 1, mfu, zero)
        # GetFEM's dofs -> the global dofs 2 j + component, by the nodes' coordinates.
        where = {tuple(np.round(self.points[j], 9)): j for j in nodes}
        xy = mfu.basic_dof_nodes()
        to_global = np.array([2 * where[tuple(np.round(xy[:, q], 9))] + q % 2
                              for q in range(mfu.nbdof())])
        assert len(set(to_global.tolist())) == mfu.nbdof() == 2 * len(local)

        def scatter(Mat):
            pointers, rows = Mat.csc_ind()
            local_matrix = sparse.csc_matrix((Mat.csc_val(), rows, pointers),
                                             shape=tuple(Mat.size())).tocoo()
            return sparse.csr_matrix((local_matrix.data, (to_global[local_matrix.row],
                                      to_global[local_matrix.col])), shape=(2 * self.n,) * 2)

        f = np.zeros(2 * self.n)
        f[to_global] = load
        return scatter(A), scatter(G), f

    def _interface(self, cells):
        """The slave and master interface nodes, Pi of contact.pairing, nu, tau, h, w."""
        points = self.points
        s_seg, s_nor = interface_segments(points, cells, True)
        m_seg, m_nor = interface_segments(points, cells, False)
        slave = np.unique(s_seg)
        slave = slave[np.argsort(points[slave, 0])]
        master = np.unique(m_seg)
        master = master[np.argsort(points[master, 0])]
        if self.raw["contact"]["pairing"] == "mortar":
            Pi, _ = mortar(slave, master, points, s_seg, s_nor, m_seg, m_nor)
        else:
            Pi = node_to_segment(slave, master, points, m_seg)
        which, _ = closest_points(points[slave], points, m_seg)
        n_m = m_nor[which]
        self.nu_dir = -n_m
        self.tau_dir = np.stack([-self.nu_dir[:, 1], self.nu_dir[:, 0]], axis=1)
        self.h = np.einsum("id,id->i", n_m, points[slave] - Pi @ points[master])
        w = np.zeros(len(points))
        for a, b in s_seg:
            half = 0.5 * np.linalg.norm(points[b] - points[a])
            w[a] += half
            w[b] += half
        self.w = w[slave]
        self.slave, self.master, self.Pi = slave, master, Pi
        # T: u_rel (2 per slave node) from u (2 n); "held": no Pi in a prescribed row.
        rows, cols, vals = [], [], []
        held = np.zeros((len(slave), 2), bool)
        for i, s in enumerate(slave):
            for q in range(2):
                rows.append(2 * i + q), cols.append(2 * s + q), vals.append(1.0)
                held[i, q] = self.prescribed == "held" and self.fixed[2 * s + q]
                if held[i, q]:
                    continue
                for j, k in enumerate(master):
                    if Pi[i, j] != 0.0:
                        rows.append(2 * i + q), cols.append(2 * k + q)
                        vals.append(-Pi[i, j])
        self.T = sparse.csr_matrix((vals, (rows, cols)), shape=(2 * len(slave), 2 * self.n))
        self.Tf = self.T[:, self.free]
        # a multiplier where its direction is not held (nu and tau along the axes here)
        axis_nu = np.argmax(np.abs(self.nu_dir), axis=1)
        axis_tau = np.argmax(np.abs(self.tau_dir), axis=1)
        ids = np.arange(len(slave))
        self.has_ln = ~held[ids, axis_nu]
        self.has_lt = ~held[ids, axis_tau]

    # --- the law and its generalized Jacobian --------------------------------------------

    def law(self, u_rel, ln, lt):
        """Per slave node: s, u_tau, p_nu, R_nu, sigma_tau, the nodal forces f (m, 2), the
        multiplier residuals and the generalized derivatives (module description)."""
        nu, tau, w, r = self.nu_dir, self.tau_dir, self.w, self.r
        c, g, mu = self.c, self.g, self.mu
        s = np.einsum("id,id->i", u_rel, nu) - self.h
        ut = np.einsum("id,id->i", u_rel, tau)
        Pn = c * np.maximum(0.0, np.minimum(s, g))
        dPn = np.where((s > 0) & (s < g), c, 0.0)
        a = r * (s - g) - ln
        Rn = np.maximum(0.0, a)
        active = a > 0
        dRn_s, dRn_l = np.where(active, r, 0.0), np.where(active, -1.0, 0.0)
        q = lt - r * ut
        bound = mu * Pn
        stick = np.abs(q) < bound
        St = np.clip(q, -bound, bound)
        sign = np.sign(q)
        dSt_s = np.where(stick, 0.0, sign * mu * dPn)
        dSt_ut = np.where(stick, -r, 0.0)
        dSt_l = np.where(stick, 1.0, 0.0)
        f = w[:, None] * ((Pn + Rn)[:, None] * nu - St[:, None] * tau)
        Gn = -w / r * (ln + Rn)
        Gt = -w / r * (lt - St)
        outer = lambda p, q_: np.einsum("ia,ib->iab", p, q_)          # noqa: E731
        df_du = w[:, None, None] * (((dPn + dRn_s)[:, None, None]) * outer(nu, nu)
                                    - dSt_s[:, None, None] * outer(tau, nu)
                                    - dSt_ut[:, None, None] * outer(tau, tau))
        df_dln = w[:, None] * dRn_l[:, None] * nu
        df_dlt = -w[:, None] * dSt_l[:, None] * tau
        dGn_du = -(w / r * dRn_s)[:, None] * nu
        dGn_dln = -w / r * (1 + dRn_l)
        dGt_du = (w / r)[:, None] * (dSt_s[:, None] * nu + dSt_ut[:, None] * tau)
        dGt_dlt = -w / r * (1 - dSt_l)
        return dict(s=s, ut=ut, Pn=Pn, Rn=Rn, St=St, f=f, Gn=Gn, Gt=Gt, df_du=df_du,
                    df_dln=df_dln, df_dlt=df_dlt, dGn_du=dGn_du, dGn_dln=dGn_dln,
                    dGt_du=dGt_du, dGt_dlt=dGt_dlt, stick=stick, active=active)

    def system(self, z, A, b):
        """Residual and generalized Jacobian of z = (u_free, lambda_nu, lambda_tau) for the
        bulk part A u - b (on the free dofs)."""
        nf, m = len(self.free), len(self.slave)
        iln, ilt = np.flatnonzero(self.has_ln), np.flatnonzero(self.has_lt)
        u = np.zeros(2 * self.n)
        u[self.free] = z[:nf]
        ln, lt = np.zeros(m), np.zeros(m)
        ln[iln] = z[nf:nf + len(iln)]
        lt[ilt] = z[nf + len(iln):]
        law = self.law((self.T @ u).reshape(-1, 2), ln, lt)
        Tf = self.Tf
        F = A @ z[:nf] - b + Tf.T @ law["f"].reshape(-1)
        R = np.concatenate([F, law["Gn"][iln], law["Gt"][ilt]])
        blocks = sparse.block_diag(list(law["df_du"]), format="csr")
        J_uu = A + Tf.T @ blocks @ Tf

        def column_block(values, index):       # (2m, len(index)): per node a 2-vector
            rows = (2 * index[:, None] + np.arange(2)).reshape(-1)
            cols = np.repeat(np.arange(len(index)), 2)
            return sparse.csr_matrix((values[index].reshape(-1), (rows, cols)),
                                     shape=(2 * m, len(index)))

        J_uln = Tf.T @ column_block(law["df_dln"], iln)
        J_ult = Tf.T @ column_block(law["df_dlt"], ilt)
        J_lnu = column_block(law["dGn_du"], iln).T @ Tf
        J_ltu = column_block(law["dGt_du"], ilt).T @ Tf
        J = sparse.bmat([[J_uu, J_uln, J_ult],
                         [J_lnu, sparse.diags(law["dGn_dln"][iln]), None],
                         [J_ltu, None, sparse.diags(law["dGt_dlt"][ilt])]], format="csc")
        return R, J, u, ln, lt, law

    def newton(self, z, A, b):
        """Semismooth Newton from z; returns (z, iterations)."""
        for it in range(MAX_IT + 1):
            R, J, *_ = self.system(z, A, b)
            norm = np.linalg.norm(R)
            if it == 0:
                first = norm
            if norm <= ATOL or (it > 0 and norm <= RTOL * first):
                return z, it
            z = z - spsolve(J, R)
        raise RuntimeError(f"two-body peer: no convergence in {MAX_IT} iterations "
                           f"(residual {norm:.3e}, first {first:.3e})")

    def run(self):
        """t_0 and the steps: per state the Newton iterations, the contact values at the
        slave nodes (sorted by x) and the master's interface displacement (sorted by x)."""
        time_table = self.raw["time"]
        steps, rule = time_table["steps"], time_table["rule"]
        k = time_table["T"] / steps
        free = self.free
        nf = len(free)
        z = np.zeros(nf + int(self.has_ln.sum() + self.has_lt.sum()))
        history = [np.zeros(2 * self.n) for _ in self.memory]   # P_n, or S_n
        last = None
        states = []
        for n in range(steps + 1):
            A = self.K
            H = np.zeros(2 * self.n)
            if n > 0:
                for (alpha, tau, G), Y in zip(self.memory, history):
                    if rule == "paper":
                        d = math.exp(-k / tau)
                        H += alpha * (G @ (d * Y + k * d * last))
                    else:
                        d, w0, w1 = exponential_weights(k, tau)
                        H += alpha * (G @ (d * Y + w0 * last))
                        A = A + (alpha * w1) * G
            A = A.tocsr()[free][:, free]
            b = (self.f - H)[free]
            z, iterations = self.newton(z, A, b)
            _, _, u, ln, lt, law = self.system(z, A, b)
            for j, ((alpha, tau, G), Y) in enumerate(zip(self.memory, history)):
                if n == 0:
                    continue
                if rule == "paper":
                    d = math.exp(-k / tau)
                    history[j] = d * Y + 0.5 * k * (d * last + u)
                else:
                    d, w0, w1 = exponential_weights(k, tau)
                    history[j] = d * Y + w0 * last + w1 * u
            last = u
            states.append(dict(
                iterations=iterations, u_nu=law["s"] + self.h,
                reaction_nu=law["Pn"] + law["Rn"], sigma_tau=law["St"],
                u_tau=law["ut"], master=u.reshape(-1, 2)[self.master].copy(),
                stick=law["stick"], bound=law["active"]))
        return states


# --- contactvisco's side and the comparison ------------------------------------------------

def contactvisco_run(raw):
    """contactvisco on the scene: (its Problem, per state the contact table and the master's
    interface displacement). The Problem is taken from the time loop's build (read only)."""
    from mpi4py import MPI
    from contactvisco.scene import loader
    from contactvisco.solver import time_loop
    built = []
    original = time_loop.build

    def keep(scene, geometry):
        built.append(original(scene, geometry))
        return built[-1]

    displacements = []
    time_loop.build = keep
    try:
        result = time_loop.simulate(
            loader.resolve(raw), comm=MPI.COMM_WORLD, progress=False, keep_tables=True,
            on_step=lambda record: displacements.append(
                built[0].u.x.array.reshape(-1, 2).copy()))
    finally:
        time_loop.build = original
    return built[0], result, displacements


def compare(raw, prescribed="relative"):
    """Both solvers on the scene: per quantity the largest difference over states and nodes
    relative to contactvisco's largest value, and what the test asserts about the state.

    Parameters
    ----------
    raw : dict
        The scene (`scene()`).
    prescribed : str
        The peer's convention at prescribed slave components ("held" or "relative").

    Returns
    -------
    dict
        ``worst`` {quantity: relative difference}, the peer's ``states``, contactvisco's
        ``tables``, ``peer`` and contactvisco's Newton ``iterations``.
    """
    problem, result, displacements = contactvisco_run(raw)
    points, cells = dolfinx_nodes(problem)
    peer = Peer(raw, points, cells, prescribed)
    states = peer.run()
    assert len(states) == len(result.tables) == len(displacements)
    ours, theirs = {}, {}
    for table, u, state in zip(result.tables, displacements, states):
        order = np.argsort(table["x"][:, 0])
        assert np.allclose(table["x"][order], points[peer.slave], atol=1e-12)
        assert np.allclose(table["weight"][order], peer.w, rtol=1e-12)
        for key, mine, other in (
                ("u_nu", table["u_nu"][order], state["u_nu"]),
                ("reaction_nu", table["reaction_nu"][order], state["reaction_nu"]),
                ("sigma_tau", table["sigma_tau_vector"][order, 0],
                 state["sigma_tau"] * peer.tau_dir[:, 0]),
                ("master", u[peer.master], state["master"])):
            ours.setdefault(key, []).append(mine)
            theirs.setdefault(key, []).append(other)
    worst = {key: float(np.abs(np.array(theirs[key]) - np.array(ours[key])).max()
                        / max(np.abs(np.array(ours[key])).max(), 1e-300)) for key in ours}
    return dict(worst=worst, states=states, tables=result.tables, peer=peer,
                iterations=[s["newton_iterations"] for s in result.steps])


def main():
    from mpi4py import MPI
    if MPI.COMM_WORLD.size != 1:
        sys.exit("two_body_peer.py runs on one rank (the peer is serial)")
    sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1]))  # common.py
    from common import write_results
    rows, finals = [], {}
    cases = [(p, r, "constant") for p in ("mortar", "node_to_segment")
             for r in ("paper", "exponential")]
    cases += [("mortar", r, "exponential") for r in ("paper", "exponential")]
    for prescribed in ("relative", "held"):
        for pairing, rule, kind in cases:
            if prescribed == "held" and kind != "constant":
                continue
            kernels = KERNELS[kind]
            out = compare(scene(pairing, rule, kernels=kernels), prescribed)
            finals[pairing, rule, kind, prescribed] = out["states"][-1]
            rows.append(dict(pairing=pairing, rule=rule, kernels=kind, prescribed=prescribed,
                             worst=out["worst"], newton=out["iterations"],
                             peer_newton=[s["iterations"] for s in out["states"]]))
    lines = ["| peer's convention | pairing | rule | kernels | u_nu | normal reaction | "
             "tangential reaction | master's interface displacement |", "|---|---|---|---|---|---|---|---|"]
    lines += [f"| {r['prescribed']} | {r['pairing']} | {r['rule']} | {r['kernels']} | "
              + " | ".join(f"{r['worst'][k]:.1e}" for k in ("u_nu", "reaction_nu", "sigma_tau",
                                                              "master")) + " |" for r in rows]
    for rule in ("paper", "exponential"):
        a = finals["mortar", rule, "constant", "relative"]
        b = finals["node_to_segment", rule, "constant", "relative"]
        difference = np.abs(a["reaction_nu"] - b["reaction_nu"]).max() / \
            np.abs(a["reaction_nu"]).max()
        lines.append(f"\n{rule} rule: mortar and node to segment differ at T by "
                     f"{difference:.3f} of the largest normal reaction")
    write_results("two_body_peer", rows, lines)


#: The kernels of the runs of main(): (alpha, tau) of the body and of the layer.
KERNELS = {"constant": ((100.0, math.inf), (50.0, math.inf)),
           "exponential": ((100.0, 0.3), (-20.0, 0.1))}


if __name__ == "__main__":
    main()
