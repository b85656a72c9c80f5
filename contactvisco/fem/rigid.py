"""Rigid-body motions a scene leaves free: found before solving, because elasticity does not
see them and Newton would return one of infinitely many answers (which one depends on the
partition).

A rigid motion is m(x) = a + W (x - c) with W skew (2D: 3 motions, 3D: 6). It is restrained
when it moves some constrained quantity:

- a Dirichlet condition on component i at a node x: m_i(x) != 0;
- the contact law at a contact node with normal nu: m(x) . nu != 0 (a compliance stiffness or
  a bound g resists normal motion);
- friction (contact.mu > 0): also the tangential part m(x) - (m(x) . nu) nu.

The rule is conservative in one respect and documented: contact counts as a restraint whether
or not the body is pressed into it, and friction restrains sliding only while the body is
pressed. The restrained motions form the range of the Gram matrix G = sum_k mean_r c_r c_r^T
of the constraint rows c_r (one entry per basis motion), averaged per kind k (Dirichlet,
normal, tangential) so that a short clamped boundary weighs as much as a long contact one; the
free ones are its null space. Eigenvalues below RESTRAINT_TOLERANCE times the largest count as
zero: a frictionless circular contact boundary alone resists the rotation about its centre
only through the chords of its end facets (a relative eigenvalue of about 1e-5 on the Hertz
mesh, against 0.07 and more for every held built-in scene), which is no restraint.
"""
from __future__ import annotations

import numpy as np
from mpi4py import MPI

from contactvisco.errors import SceneError

AXES = "xyz"

#: Relative eigenvalue of the constraint Gram matrix below which a motion counts as free.
RESTRAINT_TOLERANCE = 1e-4


def _basis(X: np.ndarray, centre: np.ndarray, scale: float) -> tuple[np.ndarray, list[str]]:
    """Rigid motions evaluated at points X (n, d): array (modes, n, d) and their names."""
    n, d = X.shape
    Y = (X - centre) / scale
    modes, names = [], []
    for c in range(d):
        mode = np.zeros((n, d))
        mode[:, c] = 1.0
        modes.append(mode)
        names.append(f"translation along {AXES[c]}")
    pairs = [(0, 1, "z")] if d == 2 else [(1, 2, "x"), (2, 0, "y"), (0, 1, "z")]
    for a, b, axis in pairs:                  # rotation about `axis`: e_a -> e_b
        mode = np.zeros((n, d))
        mode[:, a], mode[:, b] = -Y[:, b], Y[:, a]
        modes.append(mode)
        names.append(f"rotation about {axis}")
    return np.array(modes).reshape(len(modes), n, d), names


def _bounding_box(mesh) -> tuple[np.ndarray, float]:
    """Centre and largest side of the mesh's bounding box over all ranks: the point and
    length the basis motions are scaled by, so the Gram matrix is free of units."""
    comm = mesh.comm
    d = mesh.geometry.dim
    x = mesh.geometry.x[:, :d]
    lower, upper = np.empty(d), np.empty(d)
    comm.Allreduce(x.min(axis=0), lower, op=MPI.MIN)
    comm.Allreduce(x.max(axis=0), upper, op=MPI.MAX)
    return 0.5 * (lower + upper), float(np.max(upper - lower))


def _gram(problem, centre: np.ndarray, scale: float, modes: int) -> np.ndarray:
    """G = sum_k mean_r c_r c_r^T over the constraint rows c_r of each kind k (Dirichlet,
    normal, tangential), summed over ranks; each rank adds its owned nodes only."""
    comm = problem.V.mesh.comm
    d = problem.V.mesh.geometry.dim
    owned = problem.V.dofmap.index_map.size_local
    X = problem.V.tabulate_dof_coordinates()[:owned, :d]
    kinds = {"dirichlet": [np.zeros((modes, modes)), 0],
             "normal": [np.zeros((modes, modes)), 0],
             "tangential": [np.zeros((modes, modes)), 0]}

    def add(kind, rows):
        kinds[kind][0] += rows @ rows.T
        kinds[kind][1] += rows.shape[1]

    fixed = problem.u_fixed[:owned] > 0
    for c in range(d):          # the motions evaluated at the constrained nodes only
        add("dirichlet", _basis(X[fixed[:, c]], centre, scale)[0][:, :, c])
    part = problem.contact
    if part is not None:
        nodes, on = part.nodes, part.nodes.owned
        Xc = part.Q_coordinates[nodes.nodes[on], :d]
        normals = nodes.normals[on]
        motion, _ = _basis(Xc, centre, scale)
        normal = np.einsum("mnd,nd->mn", motion, normals)
        add("normal", normal)
        if part.lambda_tau is not None:             # friction: mu > 0 with a compliance law
            tangential = motion - normal[:, :, None] * normals[None]
            for c in range(d):
                add("tangential", tangential[:, :, c])
    G = np.zeros((modes, modes))
    for gram, count in kinds.values():
        gram, count = comm.allreduce(gram, op=MPI.SUM), comm.allreduce(count, op=MPI.SUM)
        if count:
            G += gram / count
    return G


def _describe(null: np.ndarray, names: list[str], centre: np.ndarray,
              scale: float) -> list[str]:
    """Names of the motions spanning the null space `null` (modes, k) of G: basis motions
    lying (nearly) in it are named as they are; the rest of it is named from its orthonormal
    basis (2D: a rotation about some point, else a translation or a combination)."""
    modes = len(names)
    d = len(centre)
    projection = null @ null.T
    pure = [k for k in range(modes) if projection[k, k] > 0.999]
    free = [names[k] for k in pure]
    rest = null - np.eye(modes)[:, pure] @ (np.eye(modes)[:, pure].T @ null)
    directions, singular_values, _ = np.linalg.svd(rest, full_matrices=False)
    described = []
    for v in directions[:, singular_values > 1e-3].T:
        v = v / v[np.argmax(np.abs(v))]
        if d == 2 and abs(v[2]) > 1e-8:
            # a Tx + b Ty + c R about the centre = c (rotation about the point p)
            p = centre + scale * np.array([-v[1], v[0]]) / v[2]
            p[np.abs(p) < 1e-9 * scale] = 0.0
            described.append(f"rotation about z about the point ({p[0]:.4g}, {p[1]:.4g})")
        elif np.all(np.abs(v[d:]) < 1e-8):
            direction = v[:d] / np.linalg.norm(v[:d])
            described.append("translation along (" + ", ".join(f"{c:.3g}" for c in direction)
                             + ")")
        else:
            described.append("the combination " + " + ".join(
                f"{coef:.3g} ({name})" for coef, name in zip(v, names) if abs(coef) > 1e-8))
    return free + described


def free_motions(problem) -> list[str]:
    """Names of the rigid motions that neither the Dirichlet conditions nor the contact law
    of a built Problem restrain (empty when the body is held): the null space of the
    constraint Gram matrix G, eigenvalues below RESTRAINT_TOLERANCE times the largest."""
    mesh = problem.V.mesh
    centre, scale = _bounding_box(mesh)
    names = _basis(np.zeros((0, mesh.geometry.dim)), centre, scale)[1]
    G = _gram(problem, centre, scale, len(names))
    w, vectors = np.linalg.eigh(G)
    null = vectors[:, w <= RESTRAINT_TOLERANCE * max(w.max(), 1e-300)]
    if null.shape[1] == 0:
        return []
    return _describe(null, names, centre, scale)


def check(problem) -> None:
    """Stop with a scene error naming the free rigid motions, if any."""
    free = free_motions(problem)
    if not free:
        return
    contact = problem.scene["contact"]
    frictionless = contact is not None and problem.contact.lambda_tau is None
    raise SceneError(
        f"dirichlet: the body is free to move rigidly ({'; '.join(free)}): neither the "
        "Dirichlet conditions nor the contact law hold it, so the solution is not unique. "
        "Add a [[dirichlet]] condition on the free components"
        + ("; a contact boundary without friction (contact.mu = 0, or no compliance "
           "stiffness) leaves sliding along it free" if frictionless else "")
        + " (a contact boundary restrains normal motion, with friction mu > 0 also "
          "sliding)")
