"""Input that used to end in an internal error (issue 35) is a scene error naming the key, or
runs: a huge number in an expression, a Hencky strain that underflows, a strain energy whose
tangent is a plain constant, a constant surface distance."""
import pytest
from mpi4py import MPI

from contactvisco.errors import SceneError
from contactvisco.scene import loader as scene_module
from contactvisco.solver.time_loop import simulate

COMM = MPI.COMM_WORLD
SMALL = ["geometry.cells=[4, 2]", "time.steps=3"]


@pytest.mark.parametrize("sets, key, words", [
    (["contact.gap=0", "obstacle.shape='surface'", "obstacle.distance='1e300 * x[1]'"],
     "obstacle.distance", "too large"),
    (["contact.gap=0", "obstacle.shape='surface'", "obstacle.distance='x[1] + 1e101'"],
     "obstacle.distance", "too large"),
    (["material.law='hencky'", "material.hencky_strain=1e-300"], "material.hencky_strain",
     "must be > 0, in [1e-100"),
])
def test_refused_at_load_naming_the_key(sets, key, words):
    with pytest.raises(SceneError, match=words.replace("[", "\\[")) as err:
        scene_module.load("hertz" if "obstacle.shape='surface'" in sets else "paper", sets)
    assert err.value.key == key


@pytest.mark.mpi
def test_energy_written_with_numbers_runs_as_its_symbolic_form():
    """The linear law as numbers (a constant tangent) and with lmbda, mu_lame: the same run."""
    from contactvisco.model.material import lame_constants
    lam, mu = lame_constants("plane_stress", 100.0, 0.3)         # the paper scene's model
    runs = []
    for energy in (f"{lam!r} / 2 * tr_eps**2 + {mu!r} * dev_eps2",
                   "lmbda / 2 * tr_eps**2 + mu_lame * dev_eps2"):
        scene = scene_module.load("paper", SMALL + ["material.E=100.0", "material.nu=0.3",
                                                    "material.law='energy'",
                                                    f"material.energy='{energy}'",
                                                    "time.rule='trapezoid'"])
        result = simulate(scene, comm=COMM, progress=False)
        runs.append([c for r in result.steps for probe in r["probes"] for c in probe["u"]])
    assert runs[0] == pytest.approx(runs[1], rel=1e-9, abs=1e-15)
    assert max(abs(c) for c in runs[0]) > 1e-3
