"""The axisymmetric body (material.model = "axisymmetric"): patch tests of a cylinder
0 <= r <= 1, 0 <= z <= 2 with memory, whose homogeneous states P1 represents exactly.

- Uniaxial: traction p along z on the top, u_z = 0 at the bottom, the side free. The state is
  homogeneous, eps = diag(e_r, e_z, e_r) in (r, z, theta) with sigma_rr = sigma_theta = 0 and
  sigma_zz = p at every step; (e_r, e_z)(t_n) follow from the memory rule applied to one
  point (model.memory.History on the 3 x 3 strain), solved here by hand: the discrete
  solution must be u = (e_r r, e_z z) to round-off. A wrong weight (no r) or hoop strain
  breaks the equilibrium of the homogeneous state and the test.
- Hydrostatic: pressure p on the side and the top with a deviatoric Prony kernel: the
  deviator of an isotropic strain is zero only with the 3D projection tr(eps)/3 I, and then
  the memory is silent: u = -p / (3 K) (r, z) at every step.
"""
import numpy as np
import pytest
from mpi4py import MPI

from contactvisco.errors import SceneError
from contactvisco.model.material import lame_constants
from contactvisco.model.memory import History
from contactvisco.model.memory_kernel import memory_terms
from contactvisco.scene import loader as scene_module
from contactvisco.solver.time_loop import simulate

E, NU, P = 50.0, 0.3, 2.0
PROBES = [[1.0, 2.0], [0.5, 1.0], [0.0, 2.0], [0.25, 0.5]]


def cylinder(case: str, memory: dict, cells=(3, 4), steps=3, rule="paper") -> dict:
    """The raw scene of the patch test `case` ("uniaxial" or "hydrostatic")."""
    traction = [{"boundary": "top", "value": [0.0, P if case == "uniaxial" else -P]}]
    if case == "hydrostatic":
        traction.append({"boundary": "right", "value": [-P, 0.0]})
    return {"name": "cylinder",
            "geometry": {"lower": [0.0, 0.0], "upper": [1.0, 2.0], "cells": list(cells)},
            "material": {"model": "axisymmetric", "E": E, "nu": NU},
            "memory": memory,
            "dirichlet": [{"boundary": "bottom", "components": [1]}],
            "traction": traction, "time": {"T": 1.0, "steps": steps, "rule": rule},
            "output": {"probes": PROBES}}


def uniaxial_reference(scene: dict) -> list[tuple[float, float]]:
    """(e_r, e_z) at each step of the homogeneous uniaxial state under the scene's memory
    rule: sigma(e) = A e + H_n + sum_part w_part P_part e with sigma_rr = 0, sigma_zz = p."""
    lam, mu = lame_constants("3d", E, NU)
    time = scene["time"]
    k = time["T"] / time["steps"]
    history = History(memory_terms(scene), k, time["rule"], 3)
    projections = {"full": lambda e: e,
                   "deviatoric": lambda e: e - np.trace(e) / 3 * np.eye(3),
                   "volumetric": lambda e: np.trace(e) / 3 * np.eye(3)}
    out = []
    for n in range(time["steps"] + 1):
        H, weights = np.zeros((3, 3)), {}
        if n > 0:
            H, weights = history.explicit(k).reshape(3, 3), history.implicit(k)

        def sigma(e):
            return (lam * np.trace(e) * np.eye(3) + 2 * mu * e + H
                    + sum(w * projections[part](e) for part, w in weights.items()))

        base = sigma(np.zeros((3, 3)))
        columns = [sigma(np.diag(b)) - base for b in ((1.0, 0.0, 1.0), (0.0, 1.0, 0.0))]
        matrix = np.array([[c[0, 0] for c in columns], [c[1, 1] for c in columns]])
        e_r, e_z = np.linalg.solve(matrix, [-base[0, 0], P - base[1, 1]])
        out.append((e_r, e_z))
        history.commit(np.diag([e_r, e_z, e_r]).ravel(), None if n == 0 else k)
    return out


@pytest.mark.parametrize("memory, rule", [
    ({"kernel": "constant", "alpha": 10.0}, "paper"),
    ({"kernel": "prony", "terms": [{"alpha": -20.0, "tau": 0.5, "part": "deviatoric"},
                                   {"alpha": -5.0, "tau": 0.2, "part": "volumetric"}]},
     "trapezoid")])
def test_uniaxial_cylinder_with_memory_is_exact(memory, rule):
    scene = scene_module.resolve(cylinder("uniaxial", memory, rule=rule))
    result = simulate(scene, comm=MPI.COMM_WORLD, progress=False)
    reference = uniaxial_reference(scene)
    assert reference[-1][1] != pytest.approx(reference[0][1], rel=1e-3)   # the memory acts
    for step, (e_r, e_z) in zip(result.steps, reference):
        for probe in step["probes"]:
            r, z = probe["x"]
            assert probe["u"] == pytest.approx([e_r * r, e_z * z], rel=1e-12, abs=1e-14)


def test_hydrostatic_cylinder_is_exact_and_the_deviatoric_memory_silent():
    memory = {"kernel": "prony", "terms": [{"alpha": -20.0, "tau": 0.5, "part": "deviatoric"}]}
    scene = scene_module.resolve(cylinder("hydrostatic", memory))
    result = simulate(scene, comm=MPI.COMM_WORLD, progress=False)
    K = E / (3 * (1 - 2 * NU))
    for step in result.steps:
        for probe in step["probes"]:
            assert probe["u"] == pytest.approx(-P / (3 * K) * np.asarray(probe["x"]),
                                               rel=1e-12, abs=1e-14)
    # the stress is -p I, the hoop component included
    from dolfinx import fem
    problem = result.problem
    sigma = fem.Function(problem.tensor_space)
    sigma.interpolate(problem.sigma_expression)
    values = sigma.x.array.reshape(-1, 3, 3)
    assert np.allclose(values, -P * np.eye(3), rtol=0, atol=1e-12 * P)


def test_axis_nodes_hold_no_radial_displacement():
    """u_r = 0 on the axis comes with the model, not from a [[dirichlet]] table."""
    scene = scene_module.resolve(cylinder("hydrostatic", {"kernel": "none"}, steps=1))
    result = simulate(scene, comm=MPI.COMM_WORLD, progress=False)
    problem = result.problem
    x = problem.V.tabulate_dof_coordinates()
    on_axis = np.abs(x[:, 0]) < 1e-12
    assert problem.u_fixed[on_axis, 0].all() and not problem.u_fixed[~on_axis, 0].any()


def test_a_mesh_that_crosses_the_axis_is_refused():
    raw = cylinder("uniaxial", {"kernel": "none"}, steps=1)
    raw["geometry"]["lower"] = [-0.5, 0.0]
    raw["dirichlet"].append({"boundary": "left", "components": [0]})
    scene = scene_module.resolve(raw)
    with pytest.raises(SceneError, match="r >= 0.*r = -0.5") as caught:
        simulate(scene, comm=MPI.COMM_WORLD, progress=False)
    assert caught.value.key == "material.model"


def test_stress_on_the_axis_is_finite_in_p2():
    """P2's stress lives at DG1 points, the axis among them, where u_r / r is 0/0: the hoop
    strain takes its limit du_r/dr there, so a linear field u = (a r, b z) gives the exact
    stress of eps = diag(a, b, a) at every point."""
    from dolfinx import fem
    from contactvisco.fem import geometry, problem as problem_module
    raw = cylinder("uniaxial", {"kernel": "none"}, steps=1)
    raw["discretization"] = {"degree": 2}
    scene = scene_module.resolve(raw)
    problem = problem_module.build(scene, geometry.build(scene, MPI.COMM_WORLD))
    problem.u.interpolate(lambda x: np.vstack([0.1 * x[0], 0.2 * x[1]]))
    sigma = fem.Function(problem.tensor_space)
    sigma.interpolate(problem.sigma_expression)
    points = problem.tensor_space.tabulate_dof_coordinates()
    assert MPI.COMM_WORLD.allreduce(int(np.sum(np.abs(points[:, 0]) < 1e-12))) > 0
    lam, mu = lame_constants("3d", E, NU)
    eps = np.diag([0.1, 0.2, 0.1])
    exact = lam * np.trace(eps) * np.eye(3) + 2 * mu * eps
    assert np.allclose(sigma.x.array.reshape(-1, 3, 3), exact, rtol=0, atol=1e-12 * E)


@pytest.mark.parametrize("q, g, regime", [(2.0, 0.05, "compliance"), (8.0, 0.05, "bound")])
def test_cylinder_pressed_onto_the_layer(q, g, regime):
    """The axisymmetric twin of test_block.test_uniform_block: a cylinder in a rigid sleeve
    (u_r = 0 at r = 1) pressed by q onto the compliant layer (stiffness c, bound g), with
    friction. Uniaxial strain: u_z = -u_nu - q z / M, M = lambda + 2 mu (3D constants),
    u_nu = q / c below the bound, g at it; every contact node, the one on the axis included,
    carries the pressure q, and the ring areas add up to the disk's, so the total force is
    q pi R^2."""
    c = 100.0
    raw = {"name": "cylinder_on_layer",
           "geometry": {"lower": [0.0, 0.0], "upper": [1.0, 1.0], "cells": [5, 4]},
           "material": {"model": "axisymmetric", "E": E, "nu": NU},
           "dirichlet": [{"boundary": "right", "components": [0]}],
           "traction": [{"boundary": "top", "value": [0.0, -q]}],
           "contact": {"boundary": "bottom", "stiffness": c, "g": g, "mu": 0.2},
           "time": {"T": 1.0, "steps": 1},
           "output": {"probes": [[0.0, 1.0], [0.5, 0.5], [1.0, 0.0], [0.0, 0.0]]}}
    result = simulate(scene_module.resolve(raw), comm=MPI.COMM_WORLD, progress=False,
                      keep_tables=True)
    lam, mu = lame_constants("3d", E, NU)
    u_nu = q / c if regime == "compliance" else g
    table = result.tables[-1]
    assert np.allclose(table["u_nu"], u_nu, rtol=0, atol=1e-12)
    assert np.allclose(table["reaction_nu"], q, rtol=0, atol=1e-10)
    assert set(table["status"]) == {1 if regime == "compliance" else 2}
    assert np.sum(table["weight"]) == pytest.approx(np.pi, rel=1e-12)
    for probe in result.steps[-1]["probes"]:
        r, z = probe["x"]
        assert probe["u"] == pytest.approx([0.0, -u_nu - q * z / (lam + 2 * mu)], abs=1e-12)
