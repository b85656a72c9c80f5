"""Newton's first iterate from a coarser mesh (solver.first_iterate = "coarse",
contactvisco.solver.coarse_start): the carried values, the coarsened scene, and runs that
converge to the state of the default start."""
import gc
import weakref

import numpy as np
import pytest
from mpi4py import MPI

from contactvisco.errors import SceneError
from contactvisco.scene import loader as scene_module
from contactvisco.solver import coarse_start
from contactvisco.solver.time_loop import simulate

KEYS = ("u_nu", "u_tau", "lambda_nu", "reaction_nu", "reaction_tau")


def test_carry_is_exact_on_nodes_and_a_convex_combination_between():
    rng = np.random.default_rng(3)
    source = rng.random((200, 2))
    values = rng.random((200, 3))
    exact = coarse_start.carry(source, values, source[:50], 3)
    assert np.array_equal(exact, values[:50])
    constant = coarse_start.carry(source, np.full((200, 1), 2.5), rng.random((40, 2)), 3)
    assert np.allclose(constant, 2.5, rtol=0, atol=1e-14)
    targets = rng.random((300, 2))
    carried = coarse_start.carry(source, values, targets, 3)
    from scipy.spatial import cKDTree
    _, index = cKDTree(source).query(targets, k=3)
    nearest = values[index]                              # (300, 3 neighbours, 3 components)
    assert np.all(carried >= nearest.min(axis=1) - 1e-14)
    assert np.all(carried <= nearest.max(axis=1) + 1e-14)
    assert not np.allclose(carried, values[index[:, 0]])  # not the nearest value alone


def test_the_coarse_scene_divides_the_cells_or_multiplies_the_mesh_sizes():
    paper = scene_module.load("paper", ["geometry.cells=[32, 24]"])
    assert coarse_start.coarse_scene(paper, 4)["geometry"]["cells"] == [8, 6]
    assert coarse_start.coarse_scene(paper, 16)["geometry"]["cells"] == [2, 2]
    assert paper["geometry"]["cells"] == [32, 24]        # the fine scene is left as it was
    hertz = scene_module.load("hertz")
    params = coarse_start.coarse_scene(hertz, 2)["geometry"]["parameters"]
    for name, value in hertz["geometry"]["parameters"].items():
        scale = 2.0 if name in ("h_contact", "h_far") else 1.0
        assert params[name] == pytest.approx(scale * value), name


@pytest.mark.parametrize("override, key", [
    ("solver.coarse_factor=1", "solver.coarse_factor"),
    ("solver.coarse_factor=2.5", "solver.coarse_factor"),
    ("solver.first_iterate='fine'", "solver.first_iterate"),
])
def test_bad_coarse_options_are_refused_by_name(override, key):
    with pytest.raises(SceneError) as err:
        scene_module.load("paper", [override])
    assert err.value.key == key, err.value


def test_a_mesh_from_a_file_has_no_coarse_start(tmp_path):
    from contactvisco.fem import geometry as geometry_module
    hertz = scene_module.SCENE_DIR / "hertz.toml"
    path = geometry_module.mesh_file(scene_module.load("hertz")["geometry"])
    text = hertz.read_text()
    start, end = text.index("[geometry]"), text.index("[", text.index("[geometry]") + 1)
    scene = tmp_path / "from_file.toml"
    scene.write_text(text[:start] + f'[geometry]\ntype = "gmsh"\nfile = "{path}"\n\n'
                     + text[end:])
    assert scene_module.load(str(scene))["geometry"]["file"] == str(path)
    with pytest.raises(SceneError) as err:
        scene_module.load(str(scene), ["solver.first_iterate='coarse'"])
    assert err.value.key == "solver.first_iterate", err.value
    assert "file" in str(err.value) and "'previous'" in str(err.value)
    assert coarse_start.coarse_start_refused(scene_module.load(str(scene))) is not None


def test_auto_starts_from_a_coarse_run_at_the_measured_sizes_only(monkeypatch):
    from contactvisco.fem import geometry as geometry_module
    from contactvisco.fem.problem import build
    scene = scene_module.load("paper", ["geometry.cells=[8, 8]", "output.probes=[]"])
    assert scene["solver"]["first_iterate"] == "auto"
    problem = build(scene, geometry_module.build(scene, MPI.COMM_WORLD))
    assert not coarse_start.wanted(scene, problem)             # 162 unknowns
    monkeypatch.setitem(coarse_start.AUTO_UNKNOWNS, 2, 100)
    assert coarse_start.wanted(scene, problem)
    scene["solver"]["first_iterate"] = "previous"
    assert not coarse_start.wanted(scene, problem)
    scene["solver"]["first_iterate"] = "coarse"
    monkeypatch.setitem(coarse_start.AUTO_UNKNOWNS, 2, 10**9)
    assert coarse_start.wanted(scene, problem)


def _run(name, overrides):
    result = simulate(scene_module.load(name, ["output.probes=[]", *overrides]),
                      comm=MPI.COMM_WORLD, progress=False, keep_tables=True)
    return ([s["newton_iterations"] for s in result.steps], result.tables)


@pytest.mark.mpi
@pytest.mark.parametrize("name, overrides", [
    ("paper", ["geometry.cells=[64, 64]", "time.T=0.4", "time.steps=4"]),
    ("block3d", ["time.T=0.3", "time.steps=3"]),
    ("hertz", []),
])
def test_the_coarse_start_converges_to_the_default_starts_state(name, overrides):
    """The start changes Newton's path, not the state it stops at (and takes fewer iterations
    at the first loaded state, no more later): with both solved to
    |F| <= 1e-13 the contact tables agree to 1e-10 of each column's largest value, on 1 and
    on 2 ranks (the coarse solution is gathered across ranks before it is carried)."""
    tight = ["solver.petsc_options={snes_atol=1e-14, snes_rtol=1e-12}"]
    counts, tables = {}, {}
    for start in ("previous", "coarse"):
        counts[start], tables[start] = _run(name, overrides + tight + [
            f"solver.first_iterate='{start}'"])
    assert len(tables["coarse"]) == len(tables["previous"])
    for new, old in zip(tables["coarse"], tables["previous"]):
        for key in KEYS:
            if key not in old:
                continue
            a, b = np.asarray(new[key]), np.asarray(old[key])
            scale = max(np.max(np.abs(b)), 1e-300)
            assert np.max(np.abs(a - b)) <= 1e-10 * scale, key
    loaded = next(i for i, n in enumerate(counts["previous"]) if n > 0)
    assert counts["coarse"][loaded] < counts["previous"][loaded], counts
    # hertz's second state has the first one's load: the coarse run takes no iteration
    # there, and the fine run keeps its state (0 iterations, as from 'previous')
    assert all(c <= p for c, p in zip(counts["coarse"][loaded + 1:],
                                      counts["previous"][loaded + 1:])), counts


def test_a_cut_step_or_a_failed_coarse_run_ends_the_coarse_start():
    scene = scene_module.load("paper", ["geometry.cells=[16, 16]", "output.probes=[]",
                                        "solver.first_iterate='coarse'"])
    from contactvisco.fem import geometry as geometry_module
    from contactvisco.fem.problem import build
    problem = build(scene, geometry_module.build(scene, MPI.COMM_WORLD))
    start = coarse_start.create(scene, problem, MPI.COMM_WORLD, None)
    assert start.apply(0.0) and start.used == 1
    assert np.any(problem.u.x.array != 0.0)              # the coarse solution, carried
    start.apply(0.1)
    assert start.used == 2
    mesh = weakref.ref(start.problem.V.mesh)
    assert not start.apply(0.05)                         # before the coarse run's last state
    assert start.released and start.snes is None
    gc.collect()
    assert mesh() is None                                # nothing holds the coarse run
    assert not start.apply(0.2)
    assert coarse_start.create(scene_module.load("paper", ["output.probes=[]"]), problem,
                               MPI.COMM_WORLD, None) is None    # auto, 32 x 32 cells
    said = []
    failing = coarse_start.create(scene, problem, MPI.COMM_WORLD, None, said.append)
    failing.scene["solver"]["petsc_options"] = {"snes_max_it": 1}
    before = problem.u.x.array.copy()
    assert not failing.apply(0.0) and failing.released
    assert np.array_equal(problem.u.x.array, before)     # the fine unknowns left as they were
    assert said and said[0].startswith("the coarse run failed at t = 0")


def test_a_coarse_run_that_cannot_be_built_leaves_the_fine_run_as_without_it(monkeypatch,
                                                                             capsys):
    from contactvisco.fem import problem as problem_module
    overrides = ["geometry.cells=[16, 16]", "time.T=0.2", "time.steps=2"]
    expected, _ = _run("paper", overrides + ["solver.first_iterate='previous'"])

    def refuse(scene, geometry):
        raise SceneError("the coarse mesh has a rank without cells", key="geometry.cells")
    monkeypatch.setattr(problem_module, "build", refuse)
    scene = scene_module.load("paper", ["output.probes=[]", *overrides,
                                        "solver.first_iterate='coarse'"])
    result = simulate(scene, comm=MPI.COMM_WORLD, progress=True)
    assert [s["newton_iterations"] for s in result.steps] == expected
    assert "no coarse first iterate (the coarse mesh has a rank without cells" in \
        capsys.readouterr().out
