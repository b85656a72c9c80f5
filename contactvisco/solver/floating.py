"""The floating rigid motions of a Newton matrix: its null space for the Krylov solver, a
stabilization for the direct one.

A part of the mesh held only by contact (contactvisco.fem.parts: a floating rigid motion f,
which no prescribed component restrains) makes the Newton matrix J singular in an iterate
whose active contact conditions do not hold f: two cylinders touching at one node before
loading, frictionless, leave the upper one free to turn about a point of its diameter (held
in x). A direct factorization then meets a pivot of round-off size, and an algebraic
multigrid a singular coarse problem: GMRES breaks down.

At every Jacobian, J f_k and J^T f_k are formed for the orthonormal floating motions
F = [f_1 .. f_m] (m mat-vecs each); the combinations F a with |J F a| <= NULL_TOLERANCE
||J||_inf |F a| span J's null space among them (the eigenvectors of (J F)^T (J F) of small
eigenvalue), those of J^T F its left null space.

The Krylov solver (attach). They are handed to it as MatNullSpace and transpose
MatNullSpace: PETSc removes the left null space from the right-hand side and the null space
from the preconditioned vectors, so that the step is the solution orthogonal to the free
motion (the pseudo-inverse's choice), J du = -F projected on J's range. Where J holds every
floating motion nothing is attached, and the solve is the usual one. Where the residual
itself has a share along a left null motion (the load pushes the free body and no active
contact holds it), the Newton equation has no solution, and the least-squares step never
moves the body: at h = 0.01 no node of the two cylinders is active at the first iterate, the
load (12 % of F) pushes the upper body down freely, and after UNBALANCED_JACOBIANS such
Jacobians in a row the solve stops with UNBALANCED (a SceneError naming
solver.linear_solver).

The direct solver (stabilize). Where J has a null motion, the factorization's step along it
is the residual's share over a pivot of round-off size: its length, and even its sign,
change with the order of the floating-point operations (the ranks' partition, MUMPS's
scheduling), and a step that moves the body away from the contact leaves Newton drifting. So
J is solved with a stiffness eps = STABILIZATION ||J||_inf added on the diagonal of the
floating motions' components (those where some f_k is not zero), in that Jacobian only:

    (J + eps M) du = -F,        M = diag(1 on the floating components).

The step along an unbalanced free motion f is then -(f . F) / eps: in the direction the load
pushes, into the contact, of a length fixed by F rather than by round-off. Where J holds
every floating motion (every iterate near the solution) nothing is added, so Newton's
equation, its solution and its last, quadratic iterations are unchanged.
"""
from __future__ import annotations

import numpy as np
from petsc4py import PETSc

from contactvisco.fem import parts

#: |J f| / (||J||_inf |f|) below which a floating motion f is in J's null space (measured: 3e-13
#: for the free turn of the upper cylinder, 1e-3 and more once two contact nodes hold it).
NULL_TOLERANCE = 1e-8

#: |g . F| / |F| above which the residual F has a share along a left null motion g: a load
#: that no active contact condition balances (the step would be a free rigid motion).
UNBALANCED_TOLERANCE = 1e-8

#: The direct solver's stiffness on the floating components where J has a null motion, per
#: ||J||_inf: the free step -(f . F) / eps overshoots the contact (the next iterate presses
#: the body in, and the contact pushes it back), which Newton recovers from; measurements in
#: docs/interface.md.
STABILIZATION = 1e-8

#: Consecutive Jacobians with an unbalanced residual after which the Krylov solver stops.
UNBALANCED_JACOBIANS = 2

#: Why the Krylov solver stops there (solver.linear_solver).
UNBALANCED = ("solver.linear_solver = 'iterative': a Newton matrix leaves a rigid motion of a "
              "body held only by contact free while the load pushes along it (no active "
              "contact condition holds the body in that iterate: it touches at no node, or "
              "at one frictionless node), so the Newton step has no solution for a Krylov "
              "solver; use solver.linear_solver = 'direct' (or 'auto', which takes it for "
              "such bodies)")


class FloatingNullSpace:
    """The floating rigid motions of a problem and, per Jacobian, J's null spaces among them.

    Parameters
    ----------
    vectors : list of petsc4py.PETSc.Vec
        Orthonormal floating motions in u's layout.
    """

    def __init__(self, vectors, direct: bool = False):
        self.vectors = vectors
        self.direct = direct                # stabilize (direct solver), else attach
        self.found: list[int] = []          # per Jacobian: the dimension of J's null space
        self.unbalanced = 0                 # consecutive Jacobians with an unbalanced F

    @classmethod
    def of(cls, problem, template: PETSc.Vec,
           direct: bool = False) -> "FloatingNullSpace | None":
        """The floating motions of a problem's mesh parts (fem.parts.floating_motions),
        orthonormalized (modified Gram-Schmidt), or None if it has none.

        Parameters
        ----------
        problem : contactvisco.fem.problem.Problem
            The problem (its space V and prescribed components u_fixed).
        template : petsc4py.PETSc.Vec
            A vector of u's layout (owned entries).
        direct : bool, optional
            For the direct solver (prepare stabilizes J) rather than the Krylov solver
            (prepare attaches J's null spaces).

        Returns
        -------
        FloatingNullSpace or None
            With the basis f_k, f_k . f_l = delta_kl.
        """
        labels, count = parts.part_labels(problem.V)
        motions = parts.floating_motions(problem.V, problem.u_fixed, labels, count)
        if not motions:
            return None
        vectors = []
        for motion in motions:
            vec = template.duplicate()
            vec.array[:] = motion.ravel()
            for earlier in vectors:
                vec.axpy(-earlier.dot(vec), earlier)
            vec.normalize()
            vectors.append(vec)
        return cls(vectors, direct)

    def _null(self, apply, scale: float) -> list[PETSc.Vec]:
        """The combinations F a, |a| = 1, with |apply(F a)| <= NULL_TOLERANCE scale: the
        eigenvectors of H = (A F)^T (A F) of eigenvalue below (NULL_TOLERANCE scale)^2."""
        images = []
        for vec in self.vectors:
            image = vec.duplicate()
            apply(vec, image)
            images.append(image)
        m = len(images)
        H = np.array([[images[k].dot(images[l]) for l in range(m)] for k in range(m)])
        for image in images:
            image.destroy()
        w, a = np.linalg.eigh(0.5 * (H + H.T))
        out = []
        for j in np.flatnonzero(np.sqrt(np.maximum(w, 0.0)) <= NULL_TOLERANCE * scale):
            vec = self.vectors[0].duplicate()
            vec.set(0.0)
            vec.maxpy(a[:, j], self.vectors)
            vec.normalize()
            out.append(vec)
        return out

    def prepare(self, A: PETSc.Mat, residual: PETSc.Vec | None = None) -> int:
        """The Newton matrix A made ready for the solver: stabilize for the direct one,
        attach for the Krylov one; returns the dimension of A's null space among the
        floating motions."""
        return self.stabilize(A) if self.direct else self.attach(A, residual)

    def stabilize(self, A: PETSc.Mat) -> int:
        """Where A has a null space among the floating motions, A += eps M, M the diagonal
        with 1 on the components that a floating motion moves and eps = STABILIZATION
        ||A||_inf (module description); nothing where A holds them all.

        Parameters
        ----------
        A : petsc4py.PETSc.Mat
            The assembled Newton matrix J (changed in place).

        Returns
        -------
        int
            The dimension of J's null space among the floating motions (before the
            stabilization).
        """
        scale = A.norm(PETSc.NormType.NORM_INFINITY)
        right = self._null(A.mult, scale)
        for vec in right:
            vec.destroy()
        self.found.append(len(right))
        if right:
            moved = np.any([vec.array != 0.0 for vec in self.vectors], axis=0)
            stiffness = self.vectors[0].duplicate()
            stiffness.array[:] = STABILIZATION * scale * moved
            A.setDiagonal(stiffness, addv=PETSc.InsertMode.ADD_VALUES)
            stiffness.destroy()
        return len(right)

    def attach(self, A: PETSc.Mat, residual: PETSc.Vec | None = None) -> int:
        """Give A its null space and its transpose's among the floating motions (empty where
        A holds them all), and count in `unbalanced` the consecutive Jacobians whose residual
        F lies outside J's range, max_g |g . F| / |F| > UNBALANCED_TOLERANCE over the left
        null motions g (the Newton step J du = -F has no solution; the Krylov solver's is the
        least-squares one, which may bring the contact in and hold the motion at the next
        iterate, or not).

        Parameters
        ----------
        A : petsc4py.PETSc.Mat
            The assembled Newton matrix J, the Krylov solver's operator.
        residual : petsc4py.PETSc.Vec, optional
            F at the Jacobian's iterate.

        Returns
        -------
        int
            The dimension of J's null space among the floating motions.
        """
        scale = A.norm(PETSc.NormType.NORM_INFINITY)
        comm = A.getComm()
        right, left = self._null(A.mult, scale), self._null(A.multTranspose, scale)
        share = 0.0
        if residual is not None and left and residual.norm() > 0.0:
            share = max(abs(g.dot(residual)) for g in left) / residual.norm()
        self.unbalanced = self.unbalanced + 1 if share > UNBALANCED_TOLERANCE else 0
        A.setNullSpace(PETSc.NullSpace().create(vectors=right, comm=comm))
        A.setTransposeNullSpace(PETSc.NullSpace().create(vectors=left, comm=comm))
        for vec in right + left:
            vec.destroy()
        self.found.append(len(right))
        return len(right)

    def destroy(self):
        """Free the motions' vectors."""
        for vec in self.vectors:
            vec.destroy()
        self.vectors = []
