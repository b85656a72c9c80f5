"""Bad and hostile input: a scene is data and never runs code, creates no file outside --out,
and every value the model cannot use stops the run before any assembly with a message that
names the value, where it came from and what is allowed; what Newton cannot solve (a NaN, a
step that will not converge) stops with the step named; the command line exits non-zero
without a traceback. The command-line cases (exit codes) run on one rank."""
import json
import pathlib

import numpy as np
import pytest
import ufl
from dolfinx import fem
from mpi4py import MPI
from petsc4py import PETSc

from contactvisco.errors import SceneError
from contactvisco.fem import compat, geometry
from contactvisco.fem import problem as problem_module
from contactvisco.model.stability import stability_number
from contactvisco.scene import expressions
from contactvisco.scene import loader as scene_module
from contactvisco.solver import newton as solver_module
from contactvisco.solver.newton import NewtonFailure
from contactvisco.solver.time_loop import simulate
from helpers import HARD_IRONING, newton_limit, run_cli

COMM = MPI.COMM_WORLD


# ---- expressions: never run, refused at load and at build, evaluated like numpy ----

def attacks(marker: pathlib.Path) -> list[str]:
    """Expressions that would run code or exhaust the machine if they were evaluated."""
    return [
        "().__class__.__base__.__subclasses__()",
        "sin.__globals__['__builtins__']['__import__']('os').system('touch " + str(marker) + "')",
        f"__import__('os').system('touch {marker}')",
        f"open('{marker}', 'w')",
        "(lambda: 1)()",
        "[c for c in ().__class__.__base__.__subclasses__()][0]",
        "{'a': 1}['a']",
        "x.__class__",
        "x[0].__class__",
        "exp.__module__",
        "x[0:1]",
        "x[7]",
        "'text'",
        "9**9**9",
        "2.0**1e10",
        "-" * 60 + "1",
        "sin(" * 60 + "x[0]" + ")" * 60,
        "x[0] + " * 200 + "1",
        "min(x[0], x[1], t)",
        "x[0] < 1",
        "conditional(1, 2, 3)",
    ]


@pytest.mark.parametrize("key", ["traction.0.value", "body_force.value", "dirichlet.0.value",
                                 "contact.gap"])
def test_attack_expressions_are_refused_at_load(tmp_path, key):
    marker = tmp_path / "pwn"
    for text in attacks(marker):
        value = json.dumps(text) if key == "contact.gap" else f"[0.0, {json.dumps(text)}]"
        with pytest.raises(SceneError) as err:
            scene_module.load("paper", [f"{key}={value}"])
        message = str(err.value)
        assert f"(from --set {key}=" in message, message
        assert "not allowed" in message or "overflows" in message or "characters" in message \
            or "nested too deeply" in message, message
    assert not marker.exists()


def test_attack_expressions_are_refused_at_build(tmp_path):
    """The same texts placed into a resolved scene (past the load check) stop at the build."""
    marker = tmp_path / "pwn"
    mesh = geometry.build(scene_module.load("paper", ["geometry.cells=[2, 2]"]), COMM).mesh
    context = expressions.Context(mesh)
    for text in attacks(marker):
        with pytest.raises(SceneError, match="traction\\[0\\]"):
            context.scalar(text, "traction[0].value[1]")
    assert not marker.exists()


def test_limits_name_what_is_allowed():
    with pytest.raises(SceneError, match="1001 characters; at most 1000"):
        expressions.parse("1" + "+1" * 500, "w")
    with pytest.raises(SceneError, match="nested too deeply \\(at most 50"):
        expressions.parse("(" * 40 + "-" * 55 + "1" + ")" * 40, "w")
    with pytest.raises(SceneError, match="allowed: numbers, x\\[0\\], x\\[1\\], t, .*sqrt"):
        expressions.parse("x.real", "w", 2)


def test_whitelisted_expressions_evaluate_like_numpy():
    """The walker builds the UFL a Python reading of the text means: precedence, unary minus
    with **, chained comparisons, and/or/not, every function; compared at the mesh nodes."""
    scene = scene_module.load("paper", ["geometry.cells=[6, 6]"])
    mesh = geometry.build(scene, COMM).mesh
    context = expressions.Context(mesh)
    context.t.value = 0.3
    V = compat.scalar_space(mesh, "CG", 2)
    X = V.tabulate_dof_coordinates()
    x0, x1, t = X[:, 0], X[:, 1], 0.3
    cases = [
        ("-x[0]**2 + 2*x[1]/3 - t", -x0**2 + 2 * x1 / 3 - t),
        ("conditional(0.2 < x[0] <= 0.6 and not x[1] > 0.5, 1.0, -2.0)",
         np.where((0.2 < x0) & (x0 <= 0.6) & ~(x1 > 0.5), 1.0, -2.0)),
        ("conditional(x[0] < 0.3 or x[1] >= 0.7, sin(pi*x[0]), exp(-x[1]))",
         np.where((x0 < 0.3) | (x1 >= 0.7), np.sin(np.pi * x0), np.exp(-x1))),
        ("sqrt(1 + x[0]) * ln(2 + x[1]) + log(e) + abs(x[0] - 0.5) + atan2(x[1], 1 + x[0])",
         np.sqrt(1 + x0) * np.log(2 + x1) + 1 + np.abs(x0 - 0.5) + np.arctan2(x1, 1 + x0)),
        ("max(x[0], t) - min(x[1], 0.5) + cos(x[0]) * tan(0.1 * x[1])",
         np.maximum(x0, t) - np.minimum(x1, 0.5) + np.cos(x0) * np.tan(0.1 * x1)),
        ("2**0.5 * -3 + 10 / 4", np.full_like(x0, 2**0.5 * -3 + 10 / 4)),
    ]
    f = fem.Function(V)
    for text, expected in cases:
        value = context.scalar(text, "w")
        f.interpolate(fem.Expression(ufl.as_ufl(value), compat.interpolation_points(V)))
        assert np.allclose(f.x.array, expected, rtol=1e-13, atol=1e-13), text


def test_constant_expressions_that_overflow_or_turn_complex():
    for text, words in [("9**9**9", "overflows"), ("1e308 * 10", "overflows"),
                        ("(-8)**(1/3)", "complex"), ("1 / (2 - 2)", "division by zero"),
                        ("x[0] + exp(1000)", "overflows"), ("sqrt(-1) * t", "domain error")]:
        with pytest.raises(SceneError, match=words):
            scene_module.load("paper", [f"body_force.value=[0.0, '{text}']"])


# ---- scene values: refused at load with the value, its origin and what is allowed ----

SCENE_ERRORS = [  # (scene, overrides, words)
    # values out of range, misspelled keys, wrong types (the paper scene)
    ("paper", ["material.E=0"], "material.E must be > 0, got 0 (from --set material.E=0)"),
    ("paper", ["material.E=-5"], "material.E must be > 0"),
    ("paper", ["material.nu=1.0"], "material.nu must lie in (-1, 1.0) for plane_stress"),
    ("paper", ["material.model='plane_strain'", "material.nu=0.5"],
     "(-1, 0.5) for plane_strain"),
    ("paper", ["material.model='shell'"],
     "material.model must be plane_stress, plane_strain, 3d or axisymmetric"),
    ("paper", ["contact.g=-0.05"], "contact.g must be >= 0 (inf: no bound), got -0.05"),
    ("paper", ["contact.mu=-0.2"], "contact.mu must be a finite number >= 0"),
    ("paper", ["contact.stiffness=-1"], "contact.stiffness must be a finite number >= 0"),
    ("paper", ["contact.augmentation=0"], "contact.augmentation must be > 0"),
    ("paper", ["time.T=0"], "time.T must be > 0"),
    ("paper", ["time.steps=0"], "time.steps must be an integer >= 1"),
    ("paper", ["time.steps=2.5"], "time.steps must be an integer >= 1, got 2.5"),
    ("paper", ["time.rule='euler'"], "time.rule must be paper, trapezoid or exponential"),
    ("paper", ["contact.stifness=1"], "did you mean 'stiffness'"),
    ("paper", ["materials.E=1"], "no scene key 'materials'"),
    ("paper", ["geometry.cells=3"], "geometry.cells must be a list, got 3"),
    ("paper", ["geometry.cells=[0, 4]"], "geometry.cells must be positive integers"),
    ("paper", ["geometry.upper=[0.0, 1.0]"], "geometry.upper must exceed geometry.lower"),
    ("paper", ["geometry.lower=[0, 0, 0]"],
     "need 2 entries for material.model = 'plane_stress'"),
    ("paper", ["material.E='stiff'"], "material.E must be > 0, got 'stiff'"),
    ("paper", ["material.E=nan"], "material.E must be > 0, got nan"),
    ("paper", ["traction=5"], "traction must be a list of tables"),
    ("paper", ["traction.0.value=[0.0, -20.0, 1.0]"],
     "traction[0].value must be a list of 2 components"),
    ("paper", ["body_force.value=[1.0]"], "body_force.value must be a list of 2 components"),
    ("paper", ["dirichlet.0.components=[2]"], "components 0..1 of a 2D displacement"),
    ("paper", ["output.probes=[[0.5]]"],
     "output.probes[0] must be a list of 2 finite numbers"),
    ("paper", ["memory.kernel='powerlaw'"],
     "memory.kernel must be none, constant, exponential, prony"),
    ("paper", ["memory.kernel='exponential'", "memory.alpha=[1.0]", "memory.tau=[0.0]"],
     "memory.tau must be > 0"),
    ("paper", ["memory.kernel='table'", "memory.times=[0.0, 0.0]", "memory.values=[1.0, 2.0]"],
     "memory.times must increase"),
    ("paper", ["preset='quick'"], "unknown preset 'quick'"),
    ("paper", ["discretization.degree=3"], "discretization.degree must be 1 or 2"),
    ("paper", ["geometry.diagonal='up'"], "geometry.diagonal must be left, right, crossed"),
    ("paper", ["output.fields=['u', 'strain']"], "output.fields must be a list of u, sigma"),
    ("paper", ["contact.g=0"], "contact.mu = 0.2 has no effect"),
    ("paper", ["body_force.value=[0.0, '-10 * y']"],
     "body_force.value[1] = '-10 * y': the name 'y' is not allowed"),
    ("paper", ["traction.0.value=[0.0, '-20 *']"],
     "traction[0].value[1] = '-20 *' is not a valid expression"),
    # paths, sizes, booleans posing as numbers, tables posing as values
    ("hertz", ["geometry.script='/tmp/evil'"], "not a path; got '/tmp/evil'"),
    ("hertz", ["geometry.script='../meshes/rectangle'"], "built-in mesh script"),
    ("hertz", ["geometry.script='refinement'"], "built-in mesh script"),
    ("hertz", ["geometry.script=''"], "built-in mesh script"),
    ("ironing", ["geometry.parameters.h=0"], "geometry.parameters.h must be a finite number > 0"),
    ("ironing", ["geometry.parameters.h=-0.1"], "must be a finite number > 0"),
    ("ironing", ["geometry.parameters.h=nan"], "must be a finite number > 0"),
    ("ironing", ["geometry.parameters.h=true"], "must be a finite number > 0"),
    ("ironing", ["geometry.parameters.h=1e-5"], "would make about 9e+10 cells"),
    ("ironing", ["geometry.parameters.depth=1"], "has no parameter depth; it has length"),
    ("hertz", ["geometry.parameters.radius=0"], "geometry.parameters.radius must be"),
    ("ironing", ["geometry.parameters.length=1e5"], "geometry.parameters.h: mesh size 0.05 for "
                                                     "a body up to 100000 long"),
    ("block3d", ["geometry.parameters.h=0.001"], "would make about 1e+09 cells"),
    ("paper", ["geometry.cells=[1000000, 1000000]"], "asks for 1e+12 boxes (at most 1e+08"),
    ("paper", ["geometry.lower=[-1e308, 0]", "geometry.upper=[1e308, 1]"],
     "must lie within +-1e+100"),
    ("paper", ["name='../outside'"], "name must be a plain folder name"),
    ("paper", ["name='/tmp/abs'"], "name must be a plain folder name"),
    ("paper", ["name='..'"], "name must be a plain folder name"),
    ("paper", ["name=''"], "name must be a plain folder name"),
    ("paper", ["time.steps=true"], "time.steps must be an integer >= 1, got True"),
    ("paper", ["geometry.cells=[true, 4]"], "geometry.cells must be positive integers"),
    ("paper", ["solver.max_cuts=false"], "solver.max_cuts must be an integer"),
    ("paper", ["discretization.degree=true"], "discretization.degree must be 1 or 2, got True"),
    ("paper", ["contact.g=true"], "contact.g must be >= 0"),
    ("paper", ["output.snapshot_max_nodes=true"], "output.snapshot_max_nodes must be an int"),
    ("paper", ["output.xdmf=1"], "output.xdmf must be true or false, got 1"),
    ("paper", ["time.allow_unstable='yes'"], "time.allow_unstable must be true or false"),
    ("paper", ["memory.kernel='prony'", "memory.terms=[{alpha=1.0, tau=true}]"],
     "memory.terms[0].tau must be > 0"),
    ("paper", ["material.E=1e-320"], "material.E must lie in [1e-100, 1e+100]"),
    ("paper", ["material.E=1e200"], "material.E must lie in"),
    ("paper", ["contact.stiffness=1e-200"], "contact.stiffness must be 0 or lie in"),
    ("paper", ["contact.g.x=1"], "'contact.g' is a value (0.05), not a table"),
    ("paper", ["dirichlet.7.value=1"], "'dirichlet' is a list of 2 table(s); the index must "
                                       "be 0..1"),
    ("paper", ["dirichlet.first.value=1"], "the index must be 0..1"),
    ("paper", ["material=5"], "'material' is a table; set its keys"),
    ("paper", ["time=5"], "'time' is a table"),
    ("paper", ["material={E=5, poisson=0.3}"], "unknown scene key 'material.poisson'"),
    ("paper", ["geometry.file='mesh.geo'", "geometry.type='gmsh'"],
     "geometry.file must be a gmsh .msh file, got 'mesh.geo' (a .geo file is a gmsh script"),
    ("hertz", ["geometry.script=nan", "geometry.file='mesh.geo'"], "exactly one of"),
    ("paper", ["solver.petsc_options={'ksp type'='cg'}"], "is not a PETSc option name"),
    ("paper", ["solver.petsc_options.ksp_type=[1]"], "must be a string, number or boolean"),
]


@pytest.mark.parametrize("name, overrides, words", SCENE_ERRORS,
                         ids=[f"{n} {' '.join(o)}" for n, o, _ in SCENE_ERRORS])
def test_scene_errors(name, overrides, words):
    with pytest.raises(SceneError) as err:
        scene_module.load(name, overrides)
    assert words in str(err.value)


# ---- files, boundaries, presets and tables: refused with the file, line or key named ----

def test_geo_files_are_refused(tmp_path):
    scene = {"geometry": {"type": "gmsh", "file": str(tmp_path / "body.geo")}}
    with pytest.raises(SceneError, match="must be a gmsh .msh file.*can run commands"):
        scene_module.resolve(scene)
    resolved = scene_module.resolve({"geometry": {"type": "gmsh", "file": "x.msh"}})
    resolved["geometry"]["file"] = str(tmp_path / "body.geo")   # past the scene check
    with pytest.raises(SceneError, match="must be a gmsh .msh file"):
        geometry.build(resolved, COMM)


def test_a_large_file_that_is_no_mesh_is_refused_from_its_header(tmp_path):
    """200 MB of zeros (a sparse file): refused from its first bytes, not read through."""
    path = tmp_path / "zeros.msh"
    if COMM.rank == 0:
        with open(path, "wb") as f:
            f.truncate(200 * 2**20)
    path = COMM.bcast(str(path), root=0)
    scene = scene_module.resolve({"geometry": {"type": "gmsh", "file": path}})
    with pytest.raises(SceneError, match="not a gmsh .msh file \\(it does not start with "
                                         "\\$MeshFormat\\)"):
        geometry.build(scene, COMM)


BUILD_ERRORS = [
    (["contact.boundary='floor'"], "no boundary named 'floor'"),
    (["traction.0.boundary='lid'"], "no boundary named 'lid'"),
]


@pytest.mark.parametrize("overrides, words", BUILD_ERRORS, ids=[o[0] for o, _ in BUILD_ERRORS])
def test_build_errors(overrides, words):
    scene = scene_module.load("paper", ["geometry.cells=[4, 4]"] + overrides)
    with pytest.raises(SceneError) as err:
        problem_module.build(scene, geometry.build(scene, COMM))
    assert words in str(err.value)


def test_missing_and_unreadable_mesh_files(tmp_path):
    missing = scene_module.resolve({"geometry": {"type": "gmsh", "file": str(tmp_path / "no.msh")}})
    with pytest.raises(SceneError, match="no mesh file"):
        geometry.build(missing, COMM)
    bad = tmp_path / "bad.msh"
    if COMM.rank == 0:
        bad.write_text("this is not a mesh\n")
    path = COMM.bcast(str(bad), root=0)
    broken = scene_module.resolve({"geometry": {"type": "gmsh", "file": path}})
    if COMM.size == 1:     # tmp_path differs per rank; one rank suffices for reading a file
        with pytest.raises(SceneError, match="cannot read mesh file"):
            geometry.build(broken, COMM)


@pytest.mark.skipif(COMM.size > 1, reason="writes a mesh with gmsh on one rank")
def test_contact_boundary_inside_the_body(tmp_path):
    import gmsh
    gmsh.initialize()
    gmsh.option.setNumber("General.Terminal", 0)
    occ = gmsh.model.occ
    square = occ.addRectangle(0, 0, 0, 1, 1)
    line = occ.addLine(occ.addPoint(0.2, 0.5, 0), occ.addPoint(0.8, 0.5, 0))
    occ.fragment([(2, square)], [(1, line)])
    occ.synchronize()
    inner = [t for d, t in gmsh.model.getEntities(1)
             if abs(gmsh.model.occ.getCenterOfMass(1, t)[1] - 0.5) < 1e-9]
    gmsh.model.setPhysicalName(1, gmsh.model.addPhysicalGroup(1, inner), "inner")
    gmsh.model.addPhysicalGroup(2, [t for _, t in gmsh.model.getEntities(2)])
    gmsh.model.mesh.generate(2)
    gmsh.write(str(tmp_path / "inner.msh"))
    gmsh.finalize()
    scene = scene_module.resolve({"geometry": {"type": "gmsh", "file": str(tmp_path / "inner.msh")},
                                  "contact": {"boundary": "inner", "stiffness": 1.0}})
    with pytest.raises(SceneError, match="facets inside the body"):
        problem_module.build(scene, geometry.build(scene, COMM))


def test_presets_do_not_launder_booleans(tmp_path):
    """A preset scales cells and steps: true * 0.5 would round to a valid 1."""
    path = tmp_path / "bools.toml"
    path.write_text('[geometry]\ncells = [true, 4]\n[[dirichlet]]\nboundary = "left"\n')
    with pytest.raises(SceneError, match="geometry.cells must be positive integers"):
        scene_module.load(str(path), ["preset='fast'"])
    path.write_text('[time]\nsteps = true\n[[dirichlet]]\nboundary = "left"\n')
    with pytest.raises(SceneError, match="time.steps must be an integer >= 1, got True"):
        scene_module.load(str(path), ["preset='accurate'"])
    assert scene_module.load("ironing", ["preset='fast'"])["geometry"]["parameters"] == {
        "length": 3.0, "height": 0.5, "h": 0.1}          # sizes scaled, lengths kept


def test_endless_or_binary_scene_files(tmp_path):
    with pytest.raises(SceneError, match="not a built-in scene .* and no such file"):
        scene_module.load("/dev/zero")
    large = tmp_path / "large.toml"
    with open(large, "wb") as f:
        f.truncate(10 * 2**20)
    with pytest.raises(SceneError, match="larger than 1000000 bytes: not a scene"):
        scene_module.load(str(large))
    binary = tmp_path / "binary.toml"
    binary.write_bytes(b"\xff\xfe\x00name")
    with pytest.raises(SceneError, match="cannot read scene file .*binary.toml"):
        scene_module.load(str(binary))


def test_material_pairs_conflict_names_both(tmp_path):
    path = tmp_path / "lame.toml"
    path.write_text('[material]\nmodel = "plane_strain"\nlambda = 57.7\nmu = 38.5\n'
                    '[[dirichlet]]\nboundary = "left"\n')
    scene = scene_module.load(str(path))
    assert scene["material"]["E"] == pytest.approx(38.5 * (3 * 57.7 + 2 * 38.5) / (57.7 + 38.5))
    with pytest.raises(SceneError) as err:
        scene_module.load(str(path), ["material.E=5"])
    message = str(err.value)
    assert "material.E (--set material.E)" in message
    assert "material.lambda (the scene file), material.mu (the scene file)" in message
    with pytest.raises(SceneError, match="not both"):
        scene_module.load(str(path), ["material.nu=0.2"])
    with pytest.raises(SceneError, match="not both"):
        scene_module.load("paper", ["material.mu=5"])


def test_unstable_paper_rule_needs_allow_unstable():
    """b = k alpha (1 + nu) / E: 2.6 at 5 steps over T = 10 is refused with the fix named;
    time.allow_unstable = true lets it run; a single step amplifies only from b = 2 on."""
    unstable = ["time.T=10", "time.steps=5"]
    assert stability_number(scene_module.load(
        "paper", unstable + ["time.rule='trapezoid'"])) == pytest.approx(2.6)
    with pytest.raises(SceneError) as err:
        scene_module.load("paper", unstable)
    message = str(err.value)
    assert "b = k R(0) (1 + nu) / E = 2.6 >= 1" in message and "time.steps > 13" in message
    assert "time.allow_unstable = true" in message and "(from --set time.steps=5)" in message
    assert scene_module.load("paper", unstable + ["time.allow_unstable=true"])
    assert scene_module.load("paper", ["time.steps=1"])                  # b = 1.3, one step
    with pytest.raises(SceneError, match="unstable"):
        scene_module.load("paper", ["time.steps=1", "time.T=2"])       # b = 2.6, one step


def test_origin_follows_toml_tables(tmp_path):
    """The origin of a value in the second [[dirichlet]] table is that table's line, not the
    first line with the same key."""
    path = tmp_path / "two.toml"
    path.write_text('name = "two"\n[[dirichlet]]\nboundary = "left"\nvalue = 0.0\n'
                    '[[dirichlet]]\nboundary = "right"\ncomponents = [0]\n'
                    'value = "x.__class__"\n')
    with pytest.raises(SceneError, match="two.toml, line 8: value = \"x.__class__\""):
        scene_module.load(str(path))


def test_error_names_the_scene_file_line(tmp_path):
    path = tmp_path / "mine.toml"
    path.write_text('[material]\nmodel = "plane_strain"\nE = 100.0\nnu = 0.6\n')
    with pytest.raises(SceneError, match=r"mine.toml, line 4: nu = 0.6"):
        scene_module.load(str(path))


def test_unreadable_scene_file(tmp_path):
    path = tmp_path / "broken.toml"
    path.write_text("[material\nE = 1")
    with pytest.raises(SceneError, match="broken.toml"):
        scene_module.load(str(path))


def test_probe_outside_the_body_is_named():
    scene = scene_module.load("paper", ["geometry.cells=[4, 4]",
                                        "output.probes=[[0.5, 0.5], [0.5, 1.25]]"])
    with pytest.raises(SceneError) as err:
        geometry.build(scene, COMM)
    message = str(err.value)
    assert "output.probes[1] = [0.5, 1.25] is outside the body" in message
    assert "spans [0.0, 0.0] to [1.0, 1.0]" in message
    rotated = scene_module.load("paper", ["geometry.cells=[4, 4]", "geometry.rotation=90",
                                          "output.probes=[[-0.5, 0.5]]"])
    geometry.build(rotated, COMM)                # inside once the body is rotated


# ---- rigid motions: a body no condition holds is refused with the free motion named ----

def build(name, overrides):
    scene = scene_module.load(name, overrides)
    return problem_module.build(scene, geometry.build(scene, COMM))


@pytest.mark.parametrize("overrides, free", [
    (["dirichlet=[]", "contact.mu=0"], "(translation along x)"),
    (["dirichlet=[]", "contact.mu=0", "geometry.rotation=30", "output.probes=[]"],
     "(translation along (0.866, 0.5))"),
    (["contact.mu=0", "dirichlet=[{boundary='left', components=[1]}]"],
     "(translation along x)"),
])
def test_free_rigid_motions_are_named(overrides, free):
    """A body pressed on a frictionless compliance layer and held by no Dirichlet condition
    can slide along the layer: stopped before solving, with the sliding direction."""
    with pytest.raises(SceneError) as err:
        build("paper", ["geometry.cells=[4, 4]"] + overrides)
    assert f"free to move rigidly {free}" in str(err.value)
    assert "contact.mu = 0" in str(err.value)


def test_free_rotation_about_a_point():
    """u_y = 0 on the left side alone leaves x-translation and the rotation about (0, y) free,
    for any y: named with the point on x = 0."""
    scene = scene_module.resolve({"geometry": {"cells": [3, 3]},
                                  "dirichlet": [{"boundary": "left", "components": [1]}]})
    with pytest.raises(SceneError) as err:
        problem_module.build(scene, geometry.build(scene, COMM))
    assert "(translation along x; rotation about z about the point (0, 0.5))" in str(err.value)


def test_frictionless_cylinder_may_rotate_about_its_centre():
    """Hertz without its symmetry condition: the frictionless arc holds both translations but
    not the rotation about the cylinder's centre (0, R)."""
    with pytest.raises(SceneError) as err:
        build("hertz", ["dirichlet=[]"])
    message = str(err.value)
    start = message.index("about the point (") + len("about the point (")
    point = [float(v) for v in message[start:message.index(")", start)].split(",")]
    assert abs(point[0]) < 0.01 and abs(point[1] - 1.0) < 0.01


@pytest.mark.parametrize("name", scene_module.builtin_names())
def test_builtin_scenes_are_held(name):
    """Every built-in scene passes the rigid-motion check (built on a coarse mesh)."""
    coarse = {"paper": ["geometry.cells=[4, 4]"], "block3d": ["geometry.parameters.h=0.25"],
              "ironing": ["geometry.parameters.h=0.1"],
              "creep": ["geometry.parameters.h=0.2", "geometry.parameters.h_bottom=0.2"],
              "hertz": [], "sphere_creep": []}[name]
    problem = build(name, coarse)
    from contactvisco.fem.rigid import free_motions
    assert free_motions(problem) == []


def test_friction_counts_as_a_tangential_restraint():
    """The documented rule: with mu > 0 and a compliance law the layer holds sliding, so the
    paper scene without Dirichlet conditions is accepted (and without friction refused). Its
    answer is then the unique one: loads and layer are symmetric about x = 1/2, so u_x = 0 on
    that line, and 1 and 2 ranks agree."""
    with pytest.raises(SceneError, match="translation along x"):
        build("paper", ["geometry.cells=[4, 4]", "dirichlet=[]", "contact.mu=0"])
    from contactvisco.solver.time_loop import simulate
    scene = scene_module.load("paper", ["geometry.cells=[8, 8]", "dirichlet=[]",
                                        "time.steps=3", "geometry.diagonal='crossed'",
                                        "output.probes=[[0.5, 0.0], [0.5, 1.0], [1.0, 0.0]]"])
    result = simulate(scene, comm=COMM, progress=False)
    alone = simulate(scene, comm=MPI.COMM_SELF, progress=False)
    for step, single in zip(result.steps, alone.steps):
        u = np.array([p["u"] for p in step["probes"]])
        assert np.all(np.abs(u[:2, 0]) < 1e-9 * np.abs(u).max())      # symmetric
        assert np.abs(u[2, 1]) > 1e-3                                     # pressed down
        assert np.allclose(u, [p["u"] for p in single["probes"]], rtol=1e-7, atol=1e-12)


# ---- what Newton cannot solve: stopped with the step named, or cut and recovered ----

@pytest.mark.mpi
def test_non_finite_residual_is_caught():
    """A body force that divides by zero: Newton stops at once with the NaN named and the step
    given, and no NaN result is accepted."""
    scene = scene_module.load("paper", ["geometry.cells=[4, 4]", "time.steps=1",
                                        "body_force.value=[0.0, '1 / (x[0] - x[0])']"])
    with pytest.raises(NewtonFailure) as err:
        simulate(scene, comm=COMM, progress=False)
    assert "the initial state (t = 0)" in str(err.value) and "NaN or Inf" in str(err.value)


@pytest.mark.mpi
def test_step_cutting_recovers():
    """A moving load in 5 large steps (HARD_IRONING), run without cuts, then with one Newton
    iteration fewer than its hardest step took (newton_limit): the steps that fail are halved
    (up to 4 times in a row), no accepted state took more than the limit, and the run ends
    in the same contact state as the uncut one; the memory uses the exact non-uniform
    weights. Run on one rank (COMM_SELF): the iteration counts depend on the partition."""
    uncut = simulate(scene_module.load("ironing", HARD_IRONING), comm=MPI.COMM_SELF,
                     progress=False, keep_tables=True)
    assert not any(s["cuts"] for s in uncut.steps)
    limit = newton_limit(s["newton_iterations"] for s in uncut.steps)
    cut = simulate(scene_module.load("ironing", HARD_IRONING + [
        f"solver.petsc_options={{snes_max_it={limit}}}"]), comm=MPI.COMM_SELF,
        progress=False, keep_tables=True)
    assert max(s["newton_iterations"] for s in cut.steps) <= limit
    assert any(s["cuts"] > 0 for s in cut.steps) and len(cut.steps) > len(uncut.steps)
    assert cut.steps[-1]["t"] == pytest.approx(1.0)
    assert cut.steps[-1]["status_counts"] == uncut.steps[-1]["status_counts"]
    a, b = cut.tables[-1], uncut.tables[-1]
    assert abs(a["u_nu"] - b["u_nu"]).max() < 0.05 * abs(b["u_nu"]).max()


@pytest.mark.mpi
def test_step_cutting_gives_up_with_a_clear_message():
    """A step Newton cannot take in the iterations allowed, even halved, stops the run with the
    step, the cuts and the residual history named. The paper scene with its loads ramped from
    0 (u = 0 solves the first state in 0 iterations) and one Newton iteration allowed: the
    first step from the unloaded state brings the bottom into contact, which one Newton
    iteration from outside contact cannot solve (it leaves |F| at a third of its start on
    both routes, far above the tolerance), so the step and its first half both fail."""
    scene = scene_module.load("paper", ["geometry.cells=[4, 4]", "time.steps=2",
                                        "output.probes=[]", "solver.max_cuts=1",
                                        "body_force.value=[0.0, '-10 * t']",
                                        "traction.0.value=[0.0, '-20 * t']",
                                        "solver.petsc_options={snes_max_it=1}"])
    with pytest.raises(NewtonFailure) as err:
        simulate(scene, comm=COMM, progress=False)
    message = str(err.value)
    assert "step to t = 0.25 (from t = 0 after 1 cuts)" in message
    assert "residual history |F|" in message and "(2 values)" in message


# ---- PETSc options of a scene: under the solver's prefix, reported when no solver read them ----

#: Whether petsc4py gives PETSc's record of the options objects read (Options.used): the report
#: of unused options rests on it (petsc4py 3.18 has none, 3.25 has it).
READS_KNOWN = hasattr(PETSc.Options, "used")


def direct_solver(petsc_options: str):
    """The MUMPS solver of a small paper scene with these solver.petsc_options, its problem
    and its problem (to be loaded: at t = 0 Newton has nothing to solve)."""
    problem = build("paper", ["geometry.cells=[4, 4]", "time.steps=1", "output.probes=[]",
                              "solver.linear_solver='direct'",
                              f"solver.petsc_options={petsc_options}"])
    return problem, solver_module.create(problem, COMM)


def scene_unused() -> set[str]:
    return {name.split()[0] for name in solver_module.unused_options([])}


def with_solver(before: dict, newton) -> dict:
    """The database `before` plus the solver's options, which are all under its prefix."""
    now = PETSc.Options().getAll()
    ours = {key: value for key, value in now.items() if key not in before}
    assert ours and all(key.startswith(newton.options.prefix) for key in ours)
    assert {key: value for key, value in now.items() if key in before} == before
    return now


def test_options_read_while_solving_act():
    """MUMPS reads ICNTL(14) (workspace increase, %) when it first factors, inside the solve:
    a scene's value reaches the factor (the default is not 55), is in PETSc's database under
    the solver's prefix from its set-up to its destruction and nowhere else, and is not
    reported unused once read; misspelled options are (where PETSc's record of reads is
    available; without it nothing is reported)."""
    before = PETSc.Options().getAll()
    problem, default = direct_solver("{}")
    try:
        problem.time.stage(1.0)
        assert default.solve() >= 1
        icntl_default = default.snes.getKSP().getPC().getFactorMatrix().getMumpsIcntl(14)
    finally:
        default.destroy()
    assert icntl_default != 55
    problem, newton = direct_solver("{mat_mumps_icntl_14=55, mat_mumps_icntl_14x=55, "
                                    "snes_rtol_x=1.0}")
    key = newton.options.prefix + "mat_mumps_icntl_14"
    try:
        set_up = with_solver(before, newton)      # the solver's options, nothing unprefixed
        assert set_up[key] == "55" and "mat_mumps_icntl_14" not in set_up
        if READS_KNOWN:
            assert {"-mat_mumps_icntl_14", "-mat_mumps_icntl_14x"} <= scene_unused()  # setup
        present = []                   # getAll does not mark options as read
        newton.snes.setMonitor(lambda snes, it, norm: present.append(
            PETSc.Options().getAll().get(key)))
        problem.time.stage(1.0)
        iterations = []
        for _ in range(2):             # the second from the converged state: 0 iterations
            iterations.append(newton.solve())
            assert newton.residuals[-1] < 1e-8
            assert PETSc.Options().getAll() == set_up       # unchanged by the solves
        assert iterations[0] >= 1
        assert present == ["55"] * (sum(iterations) + 2)      # a monitor call per iterate
        assert newton.snes.getKSP().getPC().getFactorMatrix().getMumpsIcntl(14) == 55
    finally:
        newton.destroy()
    assert PETSc.Options().getAll() == before
    unused = scene_unused()
    if READS_KNOWN:
        assert "-mat_mumps_icntl_14" not in unused
        assert {"-mat_mumps_icntl_14x", "-snes_rtol_x"} <= unused
    else:
        assert not unused


def test_two_solvers_keep_their_own_options():
    """Two solvers alive at once, with other scene options, each read their own: the Newton
    tolerance at set-up, MUMPS's ICNTL(14) in the first solve (made after both exist, the
    first solver's after the second was set up)."""
    before = PETSc.Options().getAll()
    first, one = direct_solver("{snes_rtol=1e-9, mat_mumps_icntl_14=55}")
    second, two = direct_solver("{snes_rtol=1e-11, mat_mumps_icntl_14=35}")
    try:
        assert one.options.prefix != two.options.prefix
        assert one.snes.getTolerances()[0] == pytest.approx(1e-9)
        assert two.snes.getTolerances()[0] == pytest.approx(1e-11)
        for problem, newton in ((first, one), (second, two)):
            problem.time.stage(1.0)
            assert newton.solve() >= 1 and newton.residuals[-1] < 1e-8
        factors = [n.snes.getKSP().getPC().getFactorMatrix() for n in (one, two)]
        assert [f.getMumpsIcntl(14) for f in factors] == [55, 35]
        one.destroy()
        assert with_solver(before, two)[two.options.prefix + "snes_rtol"] == "1e-11"
    finally:
        one.destroy()
        two.destroy()
    assert PETSc.Options().getAll() == before


def test_failing_solve_leaves_no_options():
    """An option value PETSc checks only in the solve stops it with a message naming the
    scene's option; the database then holds the solver's prefixed options besides what it
    held before, and after the solver is destroyed what it held before."""
    before = PETSc.Options().getAll()
    problem, newton = direct_solver("{pc_factor_mat_solver_type='nonsense'}")
    try:
        set_up = with_solver(before, newton)
        problem.time.stage(1.0)
        with pytest.raises(SceneError, match="while setting up the solve.*"
                                             "-pc_factor_mat_solver_type nonsense"):
            newton.solve()
        assert PETSc.Options().getAll() == set_up
    finally:
        newton.destroy()
    assert PETSc.Options().getAll() == before


# ---- the command line: exit codes and messages (one rank; each starts its own process) ----

COARSE = ["--quiet", "--set", "geometry.cells=[4, 4]"]
SMALL = ["--set", "geometry.cells=[4, 4]", "--set", "time.steps=2", "--quiet"]


@pytest.mark.skipif(COMM.size > 1, reason="starts its own processes; run on one rank")
@pytest.mark.parametrize("args, code, words", [
    (["run", "paper", *COARSE, "--set", "material.E=0"], 2, "material.E must be > 0"),
    (["run", "paper", *COARSE, "--set", "body_force.value=[0.0, '1/(x[0]-x[0])']",
      "--set", "time.steps=1"], 3, "NaN or Inf"),
    (["run", "paper", *COARSE, "-snes_max_it", "1", "--set", "time.steps=1"], 3,
     "likely cause"),
    (["run", "paper", "--set", "material.E=1e-320"], 2, "material.E must lie in"),
    (["run", "ironing", "--set", "geometry.parameters.h=0"], 2,
     "geometry.parameters.h must be a finite number > 0"),
    (["run", "hertz", "--set", "geometry.parameters.radius=0"], 2, "radius must be"),
    (["run", "paper", "--set", "contact.g.x=1"], 2, "not a table"),
    (["run", "paper", "--set", "dirichlet.7.value=1"], 2, "the index must be 0..1"),
    (["run", "paper", "--set", "material=5"], 2, "'material' is a table"),
    (["run", "paper", "stray"], 2, "unrecognized arguments: stray"),
    (["run", "paper", "--out", ""], 2, "--out needs a folder name"),
    (["run", "paper", "--set", "time.steps=true"], 2, "time.steps must be an integer"),
    (["run", "paper", "--set", "output.probes=[[0.5, 2.0]]", *SMALL], 2,
     "output.probes[0] = [0.5, 2.0] is outside the body (the mesh spans [0.0, 0.0] to "
     "[1.0, 1.0]) (from --set output.probes=[[0.5, 2.0]])"),
    (["run", "paper", "--set", "dirichlet=[]", "--set", "contact.mu=0", *SMALL], 2,
     "free to move rigidly (translation along x)"),
    (["run", "paper", "-ksp_type", "nonsense", *SMALL], 2,
     "PETSc rejected a command-line option value (PETSc error 86: unknown type); the given "
     "options it had read: -ksp_type nonsense"),
    (["run", "paper", "-pc_factor_mat_solver_type", "nonsense", *SMALL], 2,
     "while setting up the solve (its message is above); given options it had read: "
     "-pc_factor_mat_solver_type nonsense"),
    (["run", "paper", "--set", "solver.petsc_options.snes_rtol='abc'", *SMALL], 2,
     "solver.petsc_options.snes_rtol: PETSc rejected an option value"),
    (["run", "paper", "--set", "solver.petsc_options.mat_mumps_icntl_14='abc'", *SMALL], 2,
     "while setting up the solve (its message is above); given options it had read: "
     "-mat_mumps_icntl_14 abc"),
    pytest.param(["run", "paper", "-snes_monitr", "-snes_rtol", "1e-9", *SMALL], 0,
                 "PETSc options no solver used: -snes_monitr (misspelled",
                 marks=pytest.mark.skipif(not READS_KNOWN, reason="petsc4py without "
                                          "Options.used: PETSc's record of reads is missing")),
])
def test_command_line(tmp_path, args, code, words):
    marker = tmp_path / "out"
    if "--out" not in args:
        args = args + ["--out", str(marker)]
    proc = run_cli(*args, cwd=tmp_path)
    assert proc.returncode == code, proc.stderr
    assert words in proc.stderr and "Traceback" not in proc.stderr, proc.stderr
    if code == 0:
        assert "-snes_rtol" not in proc.stderr         # a used option is not reported


@pytest.mark.skipif(COMM.size > 1, reason="starts its own processes; run on one rank")
def test_command_line_attack_runs_nothing(tmp_path):
    marker = tmp_path / "pwn"
    text = f"sin.__globals__['__builtins__']['__import__']('os').system('touch {marker}')"
    proc = run_cli("run", "paper", "--set", f"traction.0.value=[0.0, {json.dumps(text)}]",
                   "--out", str(tmp_path / "out"), cwd=tmp_path)
    assert proc.returncode == 2 and "is not allowed" in proc.stderr, proc.stderr
    assert not marker.exists() and not (tmp_path / "out").exists()
    proc = run_cli("run", "paper", "--set", "name='../escaped'", cwd=tmp_path / "..")
    assert proc.returncode == 2 and "plain folder name" in proc.stderr
    assert not (tmp_path.parent / "escaped").exists()


@pytest.mark.skipif(COMM.size > 1, reason="starts its own processes; run on one rank")
def test_output_folder_not_writable(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("")
    proc = run_cli("run", "paper", "--out", str(blocker / "sub"))
    assert proc.returncode == 2 and "is not writable" in proc.stderr
    assert "Traceback" not in proc.stderr


@pytest.mark.skipif(COMM.size > 1, reason="starts its own processes; run on one rank")
def test_plot_on_cut_files(tmp_path):
    (tmp_path / "summary.json").write_text('{"scene": {"name": "paper", "contact": {"g": 0.')
    proc = run_cli("plot", str(tmp_path))
    assert proc.returncode == 2 and "damaged or incomplete" in proc.stderr, proc.stderr
    assert "JSONDecodeError" in proc.stderr and "Traceback" not in proc.stderr
    (tmp_path / "summary.json").write_text('{"scene": {"contact": {"g": 0.05}}, "steps": []}')
    (tmp_path / "snapshots.npz").write_bytes(b"PK\x03\x04cut")
    proc = run_cli("plot", str(tmp_path))
    assert proc.returncode == 2 and "BadZipFile" in proc.stderr, proc.stderr
    assert "Traceback" not in proc.stderr
