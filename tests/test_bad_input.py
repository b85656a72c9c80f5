"""Bad input stops before any assembly with a message that names the value, where it came from
and what is allowed; the command line exits non-zero without a traceback."""
import subprocess
import sys

import pytest
from mpi4py import MPI

from contactvisco.errors import SceneError
from contactvisco.fem import geometry, problem as problem_module
from contactvisco.scene import loader as scene_module
from contactvisco.solver.time_loop import simulate
from contactvisco.solver.newton import NewtonFailure

COMM = MPI.COMM_WORLD

# (overrides of the paper scene, words the message must contain)
SCENE_ERRORS = [
    (["material.E=0"], "material.E must be > 0, got 0 (from --set material.E=0)"),
    (["material.E=-5"], "material.E must be > 0"),
    (["material.nu=1.0"], "material.nu must lie in (-1, 1.0) for plane_stress"),
    (["material.model='plane_strain'", "material.nu=0.5"], "(-1, 0.5) for plane_strain"),
    (["material.model='shell'"], "material.model must be plane_stress, plane_strain or 3d"),
    (["contact.g=-0.05"], "contact.g must be >= 0 (inf: no bound), got -0.05"),
    (["contact.mu=-0.2"], "contact.mu must be a finite number >= 0"),
    (["contact.stiffness=-1"], "contact.stiffness must be a finite number >= 0"),
    (["contact.augmentation=0"], "contact.augmentation must be > 0"),
    (["time.T=0"], "time.T must be > 0"),
    (["time.steps=0"], "time.steps must be an integer >= 1"),
    (["time.steps=2.5"], "time.steps must be an integer >= 1, got 2.5"),
    (["time.rule='euler'"], "time.rule must be paper or trapezoid"),
    (["contact.stifness=1"], "did you mean 'stiffness'"),
    (["materials.E=1"], "no scene key 'materials'"),
    (["geometry.cells=3"], "geometry.cells must be a list, got 3"),
    (["geometry.cells=[0, 4]"], "geometry.cells must be positive integers"),
    (["geometry.upper=[0.0, 1.0]"], "geometry.upper must exceed geometry.lower"),
    (["geometry.lower=[0, 0, 0]"], "need 2 entries for material.model = 'plane_stress'"),
    (["material.E='stiff'"], "material.E must be > 0, got 'stiff'"),
    (["material.E=nan"], "material.E must be > 0, got nan"),
    (["traction=5"], "traction must be a list of tables"),
    (["traction.0.value=[0.0, -20.0, 1.0]"], "traction[0].value must be a list of 2 components"),
    (["body_force.value=[1.0]"], "body_force.value must be a list of 2 components"),
    (["dirichlet.0.components=[2]"], "components 0..1 of a 2D displacement"),
    (["output.probes=[[0.5]]"], "output.probes[0] must be a list of 2 finite numbers"),
    (["memory.kernel='powerlaw'"], "memory.kernel must be none, constant, exponential, prony"),
    (["memory.kernel='exponential'", "memory.alpha=[1.0]", "memory.tau=[0.0]"],
     "memory.tau must be > 0"),
    (["memory.kernel='table'", "memory.times=[0.0, 0.0]", "memory.values=[1.0, 2.0]"],
     "memory.times must increase"),
    (["preset='quick'"], "unknown preset 'quick'"),
    (["discretization.degree=3"], "discretization.degree must be 1 or 2"),
    (["geometry.diagonal='up'"], "geometry.diagonal must be left, right, crossed"),
    (["output.fields=['u', 'strain']"], "output.fields must be a list of u, sigma"),
    (["contact.g=0"], "contact.mu = 0.2 has no effect"),
    (["body_force.value=[0.0, '-10 * y']"], "body_force.value[1] = '-10 * y': the name 'y' is "
                                            "not allowed"),
    (["traction.0.value=[0.0, '-20 *']"], "traction[0].value[1] = '-20 *' is not a valid "
                                          "expression"),
]


@pytest.mark.parametrize("overrides, words", SCENE_ERRORS,
                         ids=[" ".join(o) for o, _ in SCENE_ERRORS])
def test_scene_errors(overrides, words):
    with pytest.raises(SceneError) as err:
        scene_module.load("paper", overrides)
    assert words in str(err.value)


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


def test_non_finite_residual_is_caught():
    """A body force that divides by zero: Newton stops at once with the NaN named and the step
    given, and no NaN result is accepted."""
    scene = scene_module.load("paper", ["geometry.cells=[4, 4]", "time.steps=1",
                                        "body_force.value=[0.0, '1 / (x[0] - x[0])']"])
    with pytest.raises(NewtonFailure) as err:
        simulate(scene, comm=COMM, progress=False)
    assert "step to t = 0 (from t = 0)" in str(err.value) and "NaN or Inf" in str(err.value)


@pytest.mark.skipif(COMM.size > 1, reason="starts its own processes; run on one rank")
@pytest.mark.parametrize("args, code, words", [
    (["--set", "material.E=0"], 2, "material.E must be > 0"),
    (["--set", "body_force.value=[0.0, '1/(x[0]-x[0])']", "--set", "time.steps=1"], 3,
     "NaN or Inf"),
    (["-snes_max_it", "1", "--set", "time.steps=1"], 3, "likely cause"),
])
def test_command_line_exits_without_traceback(tmp_path, args, code, words):
    proc = subprocess.run([sys.executable, "-m", "contactvisco", "run", "paper", "--quiet",
                           "--set", "geometry.cells=[4, 4]", "--out", str(tmp_path)] + args,
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == code, proc.stderr
    assert words in proc.stderr and "Traceback" not in proc.stderr


@pytest.mark.skipif(COMM.size > 1, reason="starts its own processes; run on one rank")
def test_output_folder_not_writable(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("")
    proc = subprocess.run([sys.executable, "-m", "contactvisco", "run", "paper", "--out",
                           str(blocker / "sub")], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 2 and "is not writable" in proc.stderr
    assert "Traceback" not in proc.stderr


def test_step_cutting_recovers():
    """A moving load with 5 large steps needs up to 29 Newton iterations per step. With at most
    8 allowed, failed steps are halved (up to 4 times in a row) and the run ends in the same
    contact state as the uncut one; the memory uses the exact non-uniform weights. Run on one
    rank (COMM_SELF): the iteration counts, and so where steps are cut, depend on the
    partition, which is not reproducible between runs."""
    base = ["geometry.parameters.h=0.1", "time.steps=5", "output.probes=[]"]
    uncut = simulate(scene_module.load("ironing", base), comm=MPI.COMM_SELF, progress=False,
                     keep_tables=True)
    cut = simulate(scene_module.load("ironing", base + ["solver.petsc_options={snes_max_it=8}"]),
                   comm=MPI.COMM_SELF, progress=False, keep_tables=True)
    assert max(s["newton_iterations"] for s in uncut.steps) > 8
    assert max(s["newton_iterations"] for s in cut.steps) <= 8
    assert any(s["cuts"] > 0 for s in cut.steps) and len(cut.steps) > len(uncut.steps)
    assert cut.steps[-1]["t"] == pytest.approx(1.0)
    assert cut.steps[-1]["status_counts"] == uncut.steps[-1]["status_counts"]
    a, b = cut.tables[-1], uncut.tables[-1]
    assert abs(a["u_nu"] - b["u_nu"]).max() < 0.05 * abs(b["u_nu"]).max()


def test_step_cutting_gives_up_with_a_clear_message():
    scene = scene_module.load("ironing", ["geometry.parameters.h=0.1", "time.steps=5",
                                          "solver.max_cuts=1",
                                          "solver.petsc_options={snes_max_it=8}"])
    with pytest.raises(NewtonFailure) as err:
        simulate(scene, comm=MPI.COMM_SELF, progress=False)
    assert "after 1 cuts" in str(err.value) and "residual history" in str(err.value)
