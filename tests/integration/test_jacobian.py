"""Newton's matrix against central differences of the residual, in every branch of the
contact law (contactvisco.model.contact_law).

Where every contact node is strictly inside one branch of the law (separated, compliance,
at the bound; sticking or slipping), the residual is smooth near the iterate and Newton's
matrix must be its derivative: J w = (F(x + e w) - F(x - e w)) / (2 e) + O(e^2) for every
direction w. Two pieces are checked:

- the coupled Jacobian [[J, B], [C, D]] (the UFL derivative of the residual blocks F_u, F_nu,
  F_tau) against the central differences of the coupled residual, in random directions of
  (u, lambda_nu, lambda_tau), row by row at the contact nodes, in 2D (the paper scene with
  friction, stick and slip nodes, at and below the bound) and in 3D (block3d: the friction
  disc, whose projection's derivative is (radius / |z|) (I - t t^T) with t = z / |z|);
- the condensed matrix J_red (contactvisco.solver.condensed) at a 3D state where every node
  slips in the compliance zone: there D_i is regular, the multipliers follow u through
  F_nu = F_tau = 0 (lambda_nu = 0, lambda_tau = -mu p_nu slip / |slip|), and J_red must be
  the derivative of the reduced residual F_u(u, lambda(u)), i.e. the Schur complement
  J - B D^-1 C, including the friction bound's dependence on the pressure, mu p_nu(u).

The states are converged ones moved by a small random perturbation, which takes the nodes
off the kinks where a converged state sits (s = g at the bound); a node closer to a kink than
MARGIN (relative) is left out of the comparison, and each case asserts that the branches it
is meant to cover occur. Central differences with e = 1e-6 (relative) agree with the exact
derivative to about 1e-10 here; the tolerance is 1e-6.

On a ball of radius 0 (a separated node, s < 0) the friction force is 0 for every nearby
iterate, so its derivative is 0: the default "stick" side (the identity, contact_law.ZERO_BALL)
is not that derivative, by design (docs/model.md), and the comparison shows it.
"""
import numpy as np
import pytest
from dolfinx import fem
from dolfinx.fem.petsc import assemble_matrix, assemble_vector
from mpi4py import MPI
from petsc4py import PETSc

from contactvisco.fem import geometry, problem as problem_module
from contactvisco.model import contact_law as law
from contactvisco.scene import loader as scene_module
from contactvisco.solver.time_loop import simulate
from helpers import condensed_at

#: Relative step of the central differences, tolerance of the comparison, and the smallest
#: relative distance of a compared node from a kink of the law.
STEP, TOLERANCE, MARGIN = 1e-6, 1e-6, 1e-4

CASES = {   # scene, settings, the branches that must occur among the compared nodes
    "paper, stick and slip": ("paper", ["geometry.cells=[16, 16]", "time.T=0.4",
                                        "time.steps=4", "contact.mu=3.0"],
                              {"compliance stick", "compliance slip", "bound stick"}),
    "paper, slip": ("paper", ["geometry.cells=[16, 16]", "time.T=0.4", "time.steps=4"],
                    {"compliance slip", "bound slip"}),
    "ironing, separated": ("ironing", ["time.steps=8", "time.T=0.4"],
                           {"compliance slip", "bound slip"}),
    "block3d, disc": ("block3d", ["geometry.parameters.h=0.25", "time.T=0.5",
                                  "time.steps=5"], {"compliance slip", "bound slip"}),
}


def _solved(name, sets, zero_ball=None, monkeypatch=None):
    if zero_ball is not None:
        monkeypatch.setattr(law, "ZERO_BALL", zero_ball)
    scene = scene_module.load(name, ["output.probes=[]", *sets])
    return simulate(scene, comm=MPI.COMM_SELF, progress=False).problem


def _node_law(problem):
    """The law at the contact nodes from the node values (contact_law with numpy): the
    law's terms, z = lambda_tau,tau - r slip and the constants."""
    c = problem.contact
    d = problem.V.mesh.geometry.dim
    nodes = c.nodes.nodes
    constants = {k: float(v.value) for k, v in c.constants.items()
                 if v is not None and not isinstance(v, fem.Function)}
    constants.setdefault("g", None)
    constants["mu"] = float(c.constants["mu"].value)
    u = problem.u.x.array.reshape(-1, d)[nodes]
    lam_nu = c.lambda_nu.x.array[nodes]
    lam_tau = c.lambda_tau.x.array.reshape(-1, d)[nodes]
    previous = (None if c.u_previous is None
                else c.u_previous.x.array.reshape(-1, d)[nodes])
    terms = law.law_terms(law.NUMPY, u, c.nodes.normals, c.gap.x.array[nodes], lam_nu,
                          lam_tau, previous, constants, problem.scene["contact"]["friction_law"])
    z = law.tangential_part(lam_tau, c.nodes.normals, law.NUMPY) - constants["r"] * terms["slip"]
    return terms, z, constants, lam_nu


def branches(problem):
    """Per contact node: its branch of the law ("separated", or "compliance"/"bound" then
    "stick"/"slip") and its relative distance from the nearest kink (s = 0, s = g,
    r (s - g) = lambda_nu, |z| = radius)."""
    terms, z, k, lam_nu = _node_law(problem)
    s, radius, norm = terms["s_nu"], terms["radius"], np.linalg.norm(z, axis=1)
    length = max(np.max(np.abs(s)), 1e-300)
    force = max(np.max(radius), np.max(norm), 1e-300)
    distances = [np.abs(s) / length, np.abs(norm - radius) / force]
    normal = np.where(s >= k["g"], "bound", "compliance")
    distances += [np.abs(s - k["g"]) / length,
                  np.abs(k["r"] * (s - k["g"]) - lam_nu) / (k["r"] * length)]
    tangential = np.where(norm <= radius, "stick", "slip")
    label = np.where(s < 0, "separated", np.char.add(np.char.add(normal, " "), tangential))
    # A separated node has no ball (radius 0): |z| = radius is no kink of its law.
    distances[1] = np.where(s < 0, np.inf, distances[1])
    return label, np.min(distances, axis=0)


def _perturb(problem, seed, size=1e-3):
    """Move u (off its prescribed components) and the multipliers by a random relative
    perturbation of the given size, off the kinks of a converged state."""
    rng = np.random.default_rng(seed)
    free_u = (problem.u_fixed == 0).reshape(-1)
    for f in problem.unknowns:
        array = f.x.array
        scale = max(np.max(np.abs(array)), 1e-8)
        step = size * scale * rng.standard_normal(array.shape)
        if f is problem.u:
            step = step * free_u[:array.size]
        array[:] += step


def coupled_errors(problem, seed=0):
    """max over each contact node's rows of |J w - central difference| over the largest
    |central difference| of that block, per block (u, lambda_nu, lambda_tau): (n_blocks, n)
    for the contact nodes, and the same over the rows off Gamma_C (n_blocks,)."""
    rng = np.random.default_rng(seed)
    unknowns = problem.unknowns
    forms_F = [fem.form(f) for f in problem.F]
    forms_J = [[None if a is None else fem.form(a) for a in row] for row in problem.J]
    start = [f.x.array.copy() for f in unknowns]
    # Directions of the size of each unknown (1e-3 where it is zero, an unloaded state).
    w = [rng.standard_normal(a.shape) * max(np.max(np.abs(a)), 1e-3) for a in start]

    def residual(sign):
        for f, a, dw in zip(unknowns, start, w):
            f.x.array[:] = a + sign * STEP * dw
        out = []
        for form in forms_F:
            b = assemble_vector(form)
            b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
            out.append(b.array.copy())
            b.destroy()
        return out

    product = []
    for row in forms_J:
        total = 0.0
        for a, dw in zip(row, w):
            if a is None:
                continue
            A = assemble_matrix(a)
            A.assemble()
            x, y = A.createVecRight(), A.createVecLeft()
            x.array[:] = dw[:x.array.size]
            A.mult(x, y)
            total = total + y.array.copy()
            for obj in (A, x, y):
                obj.destroy()
        product.append(total)
    plus, minus = residual(1.0), residual(-1.0)
    for f, a in zip(unknowns, start):
        f.x.array[:] = a
    nodes = problem.contact.nodes.nodes
    at_nodes, elsewhere = [], []
    for Jw, p, m, f in zip(product, plus, minus, unknowns):
        bs = f.function_space.dofmap.index_map_bs
        difference = (p - m) / (2 * STEP)
        scale = max(np.max(np.abs(difference)), 1e-300)
        error = (np.abs(Jw - difference) / scale).reshape(-1, bs).max(axis=1)
        at_nodes.append(error[nodes])
        off = np.ones(error.size, dtype=bool)
        off[nodes] = False
        elsewhere.append(float(np.max(error[off], initial=0.0)))
    return np.array(at_nodes), np.array(elsewhere)


def _compare(problem, wanted):
    label, distance = branches(problem)
    clean = distance > MARGIN
    assert wanted <= set(label[clean]), (wanted, set(label[clean]))
    at_nodes, elsewhere = coupled_errors(problem)
    assert np.all(elsewhere <= TOLERANCE), elsewhere
    worst = {b: float(np.max(at_nodes[:, clean & (label == b)], initial=0.0))
             for b in set(label[clean])}
    assert all(error <= TOLERANCE for error in worst.values()), worst
    return label, distance, at_nodes


@pytest.mark.parametrize("case", list(CASES))
def test_coupled_jacobian_is_the_derivative(case):
    """J w equals the central differences of F to 1e-6 (relative) on the rows of every
    contact node strictly inside its branch, and off Gamma_C, at two perturbed states."""
    name, sets, wanted = CASES[case]
    problem = _solved(name, sets)
    for seed in (1, 2):
        _perturb(problem, seed)
        _compare(problem, wanted)


def test_empty_ball_stick_side_is_not_the_derivative(monkeypatch):
    """Separated nodes (s < 0: a friction ball of radius 0) at z = 0 (the unloaded state of a
    scene with an initial gap, u = 0 and lambda = 0): P_B is 0 for every z near there, so its
    derivative is 0. With the free side (contact_law.ZERO_BALL = "free") every row is the
    derivative; the default stick side (the identity) puts a stick condition into the
    lambda_tau rows (and sigma_tau's derivative into the u rows), and the comparison must
    see it (an error of order 1 in the lambda_tau rows)."""
    found = {}
    for tie in ("free", "stick"):
        monkeypatch.setattr(law, "ZERO_BALL", tie)
        scene = scene_module.load("paper", ["geometry.cells=[8, 8]", "contact.gap=0.01",
                                            "output.probes=[]"])
        problem = problem_module.build(scene, geometry.build(scene, MPI.COMM_SELF))
        label, distance = branches(problem)
        assert set(label) == {"separated"} and np.min(distance) > MARGIN
        at_nodes, elsewhere = coupled_errors(problem)
        assert np.all(elsewhere <= TOLERANCE), elsewhere
        found[tie] = at_nodes.max(axis=1)          # per block: u, lambda_nu, lambda_tau
    assert np.all(found["free"] <= TOLERANCE), found
    assert found["stick"][1] <= TOLERANCE < 0.1 < found["stick"][2], found


def _slip_multipliers(problem):
    """lambda(u) where every node slips in the compliance zone: lambda_nu = 0 (F_nu = 0 for
    s < g) and lambda_tau = -mu p_nu slip / |slip| (then z = lambda_tau - r slip points
    along -slip with |z| = mu p_nu + r |slip| > mu p_nu, and P_B(z) = lambda_tau: F_tau = 0)."""
    c = problem.contact
    d = problem.V.mesh.geometry.dim
    terms, _, _, _ = _node_law(problem)
    slip = terms["slip"]
    direction = slip / np.linalg.norm(slip, axis=1)[:, None]
    c.lambda_nu.x.array[c.nodes.nodes] = 0.0
    c.lambda_tau.x.array.reshape(-1, d)[c.nodes.nodes] = -terms["radius"][:, None] * direction


def test_condensed_matrix_is_the_derivative_of_the_reduced_residual():
    """block3d at t = 0.1 (every node slipping below the bound): J_red v equals the central
    differences of the reduced residual F_u(u, lambda(u)) (the condensed residual where
    F_nu = F_tau = 0) on every row, for random v off the prescribed components."""
    problem = _solved("block3d", ["geometry.parameters.h=0.25", "time.T=0.2", "time.steps=2"])
    _perturb(problem, 4, size=1e-4)
    label, distance = branches(problem)
    assert set(label) == {"compliance slip"} and np.min(distance) > MARGIN, set(label)
    _slip_multipliers(problem)
    system, x = condensed_at(problem)
    b = x.duplicate()
    system.residual(x, b)
    assert np.all(system.parts["nullity"] == 0)
    assert system.full_norm - b.norm() <= 1e-12 * system.full_norm   # F_nu = F_tau = 0
    system.jacobian()
    rng = np.random.default_rng(5)
    d = system.d
    v = x.duplicate()
    v.array[:] = rng.standard_normal(v.array.size) * (problem.u_fixed.reshape(-1)[
        :v.array.size] == 0) * np.max(np.abs(x.array))
    Jv = x.duplicate()
    system.J_red.mult(v, Jv)
    values = []
    for sign in (1.0, -1.0):
        y = x.copy()
        y.axpy(sign * STEP, v)
        y.ghostUpdate(addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)
        problem.u.x.array[:y.array.size] = y.array
        problem.u.x.scatter_forward()
        _slip_multipliers(problem)
        out = x.duplicate()
        system.residual(y, out)
        values.append(out.array.copy())
    difference = (values[0] - values[1]) / (2 * STEP)
    error = np.abs(Jv.array - difference).reshape(-1, d).max(axis=1)
    scale = np.max(np.abs(difference))
    contact = np.zeros(error.size, dtype=bool)
    contact[system.own] = True
    assert np.max(error[contact]) <= TOLERANCE * scale, np.max(error[contact]) / scale
    assert np.max(error[~contact]) <= TOLERANCE * scale, np.max(error[~contact]) / scale
