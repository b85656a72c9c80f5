"""Force control of the obstacle: its displacement d (the force-controlled components, k <= 3
of them) is an unknown of the same Newton step as u and the multipliers, with the resultant
contact force prescribed, G(w, d) = g(w, d) + F(t) = 0 (fem.obstacle.force_forms).

The Newton system of the coupled unknowns w = (u, lambda) is bordered by k columns and rows,

    [ K    B ] [dw]     [F]
    [ c^T  E ] [dd] = - [G],      B = dF/dd, c = dg/dw, E = dg/dd,

and solved by the Schur complement with the linear solver of K itself: X = K^-1 B (k extra
solves with the operator the Newton step factorizes or preconditions anyway), then for the
Newton step dw_0 = -K^-1 F,

    S = E - c^T X,    dd = S^-1 (-G - c^T dw_0),    dw = dw_0 - X dd.

K is the condensed system of contactvisco.solver.condensed (u's size): a column (b_u, b_lambda)
of the coupled system is condensed node by node like a residual (condense_rhs), and the
multiplier part of X is recovered like a multiplier step (recover). S is k x k; it is singular
when no contact node can carry a change of the obstacle's force (nothing in contact): the solve
then stops with a named error rather than drifting.
"""
from __future__ import annotations

import numpy as np
from dolfinx import fem
from dolfinx.fem.petsc import assemble_vector
from mpi4py import MPI
from petsc4py import PETSc

from contactvisco.errors import SceneError
from contactvisco.fem.obstacle import displacement_at
from contactvisco.solver.condensed import condense_rhs, recover

_ADD, _REVERSE = PETSc.InsertMode.ADD, PETSc.ScatterMode.REVERSE

#: S is singular below this fraction of its natural size r * (the contact boundary's measure).
SINGULAR = 1e-12


def through_the_body(force: str, moved: float, size: float, where: str) -> SceneError:
    """The message of an obstacle driven more than the body's size in one step."""
    return SceneError(
        f"{force}: the force drives the obstacle by {moved:.6g} in one step, more than the "
        f"body's size {size:.6g}: it passes through the body, which cannot carry such a "
        f"force ({where}); lower obstacle.force, or reach it in more steps (time.steps) if "
        f"the body can carry it", key="obstacle.force")


def _held(scene: dict, component: int) -> bool:
    """Whether a [[dirichlet]] condition of the scene prescribes this component somewhere."""
    for condition in scene.get("dirichlet") or ():
        given = condition.get("components", "all")
        if given == "all" or component in list(given):
            return True
    return False


def _form(a):
    return None if a is None or a.empty() else fem.form(a)


class ObstacleForce:
    """The bordering of the condensed Newton system (module description) for a problem whose
    obstacle has force-controlled components.

    Parameters
    ----------
    problem : contactvisco.fem.problem.Problem
        The problem; ``problem.contact.obstacle.force_forms`` holds the forms.
    system : contactvisco.solver.condensed.NodalCondensation
        The condensed system of the problem.
    """

    def __init__(self, problem, system):
        self.problem, self.system = problem, system
        self.obstacle = problem.contact.obstacle
        forms = self.obstacle.force_forms
        self.k = len(self.obstacle.controlled)
        self.g = [fem.form(f) for f in forms["g"]]
        self.B = [[_form(f) for f in row] for row in forms["B"]]
        self.C = [[_form(f) for f in row] for row in forms["C"]]
        self.E = [[_form(f) for f in row] for row in forms["E"]]
        self.comm = problem.V.mesh.comm
        nodes = problem.contact.nodes
        measure = self.comm.allreduce(float(nodes.weights[nodes.owned].sum()), MPI.SUM)
        self.natural = float(problem.constants["r"].value) * max(measure, 1e-300)
        self.X_u = [system.J_red.createVecRight() for _ in range(self.k)]
        self.c_u = [system.J_red.createVecRight() for _ in range(self.k)]
        self.rhs = system.J_red.createVecLeft()
        self.X_l = self.c_l = self.S = self.G_J = None

    def destroy(self):
        for vec in self.X_u + self.c_u + [self.rhs]:
            vec.destroy()

    def _vector(self, form, bs):
        """An assembled vector's values at the owned contact nodes, (n, bs)."""
        vec = assemble_vector(form)
        vec.ghostUpdate(addv=_ADD, mode=_REVERSE)
        values = vec.array.reshape(-1, bs)[self.system.own].copy()
        vec.destroy()
        return values

    def _scalar(self, form) -> float:
        return 0.0 if form is None else self.comm.allreduce(fem.assemble_scalar(form), MPI.SUM)

    def residual(self) -> np.ndarray:
        """G = g + F(t) at the current fields, shape (k,) (every rank)."""
        F = self.obstacle.force_at(float(self.obstacle.t.value))
        return np.array([self._scalar(g) for g in self.g]) + F

    def _multiplier_rows(self, forms) -> np.ndarray:
        """(n, m): the multiplier components' rows of the given per-multiplier forms at the
        owned contact nodes, zero where a multiplier is fixed."""
        s = self.system
        out = np.zeros((len(s.own), s.m))
        for a, form in enumerate(forms):
            if form is not None:
                out[:, s.offsets[a]:s.offsets[a + 1]] = self._vector(form, s.bs[a])
        return out * s.free

    def linearize(self, ksp):
        """At the iterate of the last Jacobian (the fields hold it, the condensed matrix and
        node blocks are built): X = K^-1 B, c, E, S and G. Raises SceneError if S is
        singular (no equilibrium of the obstacle can be found from here)."""
        s, parts = self.system, self.system.parts
        d = s.d
        self.G_J = self.residual()
        ksp.setOperators(s.J_red, s.J_red)
        self.X_l = []
        for j in range(self.k):
            b_u = (self._vector(self.B[j][0], d) if self.B[j][0] is not None
                   else np.zeros((len(s.own), d)))
            b_u[s.fixed_u] = 0.0
            b_l = self._multiplier_rows(self.B[j][1:])
            self.rhs.set(0.0)
            self.rhs.array.reshape(-1, d)[s.own] = condense_rhs(parts, b_u, b_l)
            ksp.solve(self.rhs, self.X_u[j])
            X_nodes = self.X_u[j].array.reshape(-1, d)[s.own]
            self.X_u[j].scale(-1.0)
            s.J_contact.mult(self.X_u[j], s._Jdu)        # J (-X_u) at the contact rows
            self.X_u[j].scale(-1.0)
            step = recover(parts, parts["B"], parts["C"], b_u, b_l, -X_nodes,
                           s._Jdu.array.reshape(-1, d))
            self.X_l.append(-step)
        self.c_l = []
        for j in range(self.k):
            vec = assemble_vector(self.C[j][0])
            vec.ghostUpdate(addv=_ADD, mode=_REVERSE)
            self.c_u[j].array[:] = vec.array
            vec.destroy()
            self.c_l.append(self._multiplier_rows(self.C[j][1:]))
        E = np.array([[self._scalar(e) for e in row] for row in self.E])
        cX = np.array([[self.c_u[j].dot(self.X_u[i])
                        + self.comm.allreduce(float(np.sum(self.c_l[j] * self.X_l[i])),
                                              MPI.SUM)
                        for i in range(self.k)] for j in range(self.k)])
        self.S = E - cX
        self.active = self._active_components()
        S = self.S[np.ix_(self.active, self.active)]
        smallest = np.linalg.svd(S, compute_uv=False).min() if len(self.active) else 0.0
        if not smallest > SINGULAR * self.natural:
            raise self.no_equilibrium()

    def _start(self) -> np.ndarray:
        """The obstacle's position at the last equilibrium (where the step started)."""
        obstacle = self.obstacle
        if obstacle.committed is not None:
            return np.asarray(obstacle.committed, float)
        return displacement_at(obstacle.scene["obstacle"], float(obstacle.t.value),
                               obstacle.dim)

    def pushing_direction(self) -> np.ndarray:
        """m: the unit direction in which the obstacle pushes the body, the mean of -nu over
        the contact boundary weighted by the nodes' shares of it (nu, the obstacle's normal,
        points into the obstacle; the contact force on the body is along -nu). Collective;
        zero when the normals cancel (an obstacle inside a hole)."""
        nodes = self.problem.contact.nodes
        local = -(nodes.weights[nodes.owned, None] * nodes.normals[nodes.owned]).sum(axis=0)
        total = np.zeros_like(local)
        self.comm.Allreduce(local, total, op=MPI.SUM)
        size = np.linalg.norm(total)
        return total / size if size > 0 else total

    def _force_text(self, t: float) -> str:
        obstacle = self.obstacle
        given = ", ".join(f"[{j}] = {v!r}" for j, v in zip(obstacle.controlled,
                                                          obstacle.scene["obstacle"]["force"]))
        values = np.round(obstacle.force_at(t), 12).tolist()
        return (f"obstacle.force (components {given} of obstacle.force_components = "
                f"{obstacle.controlled}) = {values} at t = {t:g}")

    def no_equilibrium(self) -> SceneError:
        """Why no contact node can carry the prescribed force (S singular), as one of four
        messages naming obstacle.force: the force pulls (F . m < 0: contact only pushes),
        the obstacle went through the body (it moved more than the body's size L since the
        last equilibrium), a tangential force above what friction carries (the normal block
        of S regular, a tangential component's row empty: every node slips), or the obstacle
        out of contact. Collective (every rank reaches the same one)."""
        obstacle = self.obstacle
        t = float(obstacle.t.value)
        controlled = np.asarray(obstacle.controlled, int)
        F = obstacle.force_at(t)
        m = self.pushing_direction()[controlled]
        start, d = self._start(), obstacle.displacement()
        moved = float(np.linalg.norm((d - start)[controlled]))
        size = self.problem.length_scale
        where = (f"the obstacle at d = {np.round(d, 12).tolist()}, the last equilibrium at "
                 f"d = {np.round(start, 12).tolist()}")
        force = self._force_text(t)
        pushing = ", ".join(f"{v:.3g}" for v in self.pushing_direction())
        if np.linalg.norm(m) > 0.5 and float(F @ m) < 0:
            return SceneError(
                f"{force}: the force pulls the obstacle away from the body (its part along "
                f"the direction in which the obstacle pushes the body, m = ({pushing}), is "
                f"F . m = {float(F @ m):.6g} < 0), and contact only pushes; give a force "
                f"with F . m > 0 (the obstacle's force on the body points into the body)",
                key="obstacle.force")
        if moved > size:
            return through_the_body(force, moved, size, where)
        free = [i for i, j in enumerate(controlled) if not _held(obstacle.scene, int(j))]
        if free:
            R = self.problem.load_resultant()
            parts = ", ".join(
                f"obstacle.force[{i}] = {F[i]:.6g} (component {controlled[i]}; the loads' "
                f"resultant along it R = {R[controlled[i]]:.6g})" for i in free)
            return SceneError(
                f"{force}: the body floats: no [[dirichlet]] condition holds it along "
                f"component(s) {[int(controlled[i]) for i in free]}, so only the obstacle "
                f"does, and the body and the obstacle move together without a force to "
                f"tell where ({parts}; {where}); hold the body along that component (a "
                f"[[dirichlet]] condition), or prescribe the obstacle's displacement there "
                f"(obstacle.displacement) instead of its force", key="obstacle.force")
        if obstacle.scene["contact"]["mu"] != 0:
            normal = [i for i, j in enumerate(controlled) if abs(m[i]) >= 0.5]
            # a tangential component whose column of S vanishes: moving the obstacle along
            # it changes no force (every node slips; its row keeps mu dP/dd)
            tangential = [i for i in range(self.k) if i not in normal
                          and np.max(np.abs(self.S[:, i])) <= SINGULAR * self.natural]
            block = self.S[np.ix_(normal, normal)]
            carried = len(normal) == 0 or (
                np.linalg.svd(block, compute_uv=False).min() > SINGULAR * self.natural)
            if tangential and carried:
                names = ", ".join(f"obstacle.force[{i}] (component {controlled[i]})"
                                  for i in tangential)
                return SceneError(
                    f"{force}: {names} acts along the contact surface and exceeds what "
                    f"friction can carry: every contact node slips (Coulomb: the tangential "
                    f"force is at most mu times the normal force P; contact.mu = "
                    f"{obstacle.scene['contact']['mu']!r}), so no position of the obstacle "
                    f"balances it ({where}); keep the tangential force below mu P, or "
                    f"prescribe that component's displacement (obstacle.displacement) "
                    f"instead", key="obstacle.force")
        return SceneError(
            f"{force}: no contact node can carry it: the obstacle is out of contact "
            f"({where}); start it in contact (a gap of 0 at its first point), or bring it "
            f"into contact under displacement control first", key="obstacle.force")

    def check_move(self) -> None:
        """Refuse an iterate that moves the obstacle by more than the body's size L since the
        last equilibrium: the force has driven it through the body (a small-deformation
        contact cannot follow it there)."""
        obstacle = self.obstacle
        controlled = obstacle.controlled
        start, d = self._start(), obstacle.displacement()
        moved = float(np.linalg.norm((d - start)[controlled]))
        if moved > self.problem.length_scale:
            t = float(obstacle.t.value)
            raise through_the_body(
                self._force_text(t), moved, self.problem.length_scale,
                f"the obstacle at d = {np.round(d, 12).tolist()}, the last equilibrium at "
                f"d = {np.round(start, 12).tolist()}")

    def _active_components(self) -> np.ndarray:
        """The controlled components the step solves for. A component whose row and column of
        S vanish (no contact node can carry a force along it: a frictionless plane pushed
        along its tangent) and whose prescribed force is balanced (G_j = 0) leaves the state
        unchanged whatever d_j: it is held where it is (dd_j = 0), so a frictionless pressing
        can precede a tangential force. Any other vanishing component stays in S, which is
        then singular (no equilibrium)."""
        small = SINGULAR * self.natural
        balanced = SINGULAR * self.natural * self.problem.length_scale
        held = [j for j in range(self.k)
                if np.max(np.abs(self.S[j, :])) <= small and np.max(np.abs(self.S[:, j])) <= small
                and abs(self.G_J[j]) <= balanced]
        if len(held) == self.k:
            held = []                    # nothing in contact at all: no equilibrium
        return np.array([j for j in range(self.k) if j not in held], dtype=int)

    def correct(self, vectors, du, dl) -> np.ndarray:
        """The bordered step from the condensed one (du, dl): dd = S^-1 (-G - c^T (du, dl)),
        then v -= X_u dd for each PETSc vector v of `vectors` (the iterate), the multipliers
        -= X_lambda dd and d += dd. Returns dd."""
        s = self.system
        cw = np.array([self.c_u[j].dot(du)
                       + self.comm.allreduce(float(np.sum(self.c_l[j] * dl)), MPI.SUM)
                       for j in range(self.k)])
        dd = np.zeros(self.k)
        active = self.active
        dd[active] = np.linalg.solve(self.S[np.ix_(active, active)], (-self.G_J - cw)[active])
        for x in vectors:
            for j in range(self.k):
                x.axpy(-dd[j], self.X_u[j])
            x.ghostUpdate(addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)
        s.add_to_multipliers(-sum(X * dd[j] for j, X in enumerate(self.X_l)))
        d = self.obstacle.displacement()
        d[self.obstacle.controlled] += dd
        self.obstacle.set_displacement(d)
        self.check_move()
        return dd

    def replace(self) -> bool:
        """After a converged solve: place a curved obstacle at its converged position (its
        normals and gaps evaluated there, as displacement control evaluates them at d(t))
        when it moved more than 1e-12 of the body's size from where they were evaluated.
        Returns whether it was placed again (the solve must then continue)."""
        obstacle = self.obstacle
        if obstacle.scene["obstacle"]["shape"] == "plane":
            return False                 # the plane's gap and normal do not depend on d
        d = obstacle.displacement()
        moved = np.max(np.abs(d - np.asarray(obstacle.reference.value)))
        if not moved > 1e-12 * self.problem.length_scale:
            return False
        obstacle.place(d)
        return True
