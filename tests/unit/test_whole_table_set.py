"""A whole table given by --set (or as a Python dict) is checked as the scene file's table
would be: a free-form table (a relaxation function, a gmsh script's parameters, PETSc options)
replaces the scene's, a declared table is merged key by key, and the three routes (file,
--set, load_scene) give the same scene."""
import pytest

from contactvisco import api
from contactvisco.errors import SceneError
from contactvisco.scene import loader

SHEAR = {"instantaneous": 0.4, "tau": [1.0], "moduli": [0.1]}
SHEAR_TOML = "{instantaneous = 0.4, tau = [1.0], moduli = [0.1]}"


def test_relaxation_function_given_whole(tmp_path):
    """viscoelastic.shear={...moduli...} over a scene whose shear has fractions: the scene's
    table is replaced, not merged (merging would give moduli and fractions together), and the
    derived E = 9 K G0 / (3 K + G0) is the instantaneous one of the new function."""
    by_set = loader.load("sphere_creep", [f"viscoelastic.shear={SHEAR_TOML}"])
    by_api = api.load_scene("sphere_creep", viscoelastic={"shear": SHEAR})
    by_table = loader.load("sphere_creep", [
        f"viscoelastic={{shear={SHEAR_TOML}, bulk={{instantaneous=0.8333333333333334}}}}"])
    bulk = 0.8333333333333334
    young = 9 * bulk * 0.4 / (3 * bulk + 0.4)
    for scene in (by_set, by_api, by_table):
        assert dict(scene["viscoelastic"]["shear"]) == SHEAR
        assert scene["material"]["E"] == pytest.approx(young, rel=1e-12)
    # the dotted route reaches the same scene once fractions are dropped
    dotted = loader.load("sphere_creep", [f"viscoelastic.shear={SHEAR_TOML}",
                                          "viscoelastic.shear.moduli=[0.1]"])
    assert dotted["material"]["E"] == pytest.approx(young, rel=1e-12)


@pytest.mark.parametrize("text, key", [
    ("viscoelastic.shear={instantaneous=0.4, tau=[1.0], modli=[0.1]}",
     "viscoelastic.shear"),                                 # misspelled inside the table
    ("viscoelastic.shear={instantaneous=-0.4}", "viscoelastic.shear"),
    ("viscoelastic.shear=5", "viscoelastic.shear"),
    ("contact={law='signorini'}", "contact.law"),            # no such key in [contact]
    ("time={T=-1.0}", "time.T"),
])
def test_whole_table_keeps_the_file_checks(text, key):
    """A whole table's bad key or value is refused as in a file, naming the key."""
    with pytest.raises(SceneError) as err:
        loader.load("sphere_creep" if text.startswith("visco") else "paper", [text])
    assert key in str(err.value)


def test_declared_table_merged_key_by_key():
    """contact={stiffness=...} changes that key and keeps the scene file's others (g, mu)."""
    base = loader.load("paper")
    scene = loader.load("paper", ["contact={stiffness=1234.0}"])
    assert scene["contact"]["stiffness"] == 1234.0
    assert scene["contact"]["g"] == base["contact"]["g"]
    assert scene["contact"]["mu"] == base["contact"]["mu"]


def test_gmsh_parameters_given_whole():
    """geometry.parameters={radius=...} replaces the script's parameter table (the script's
    defaults fill the rest); an unknown parameter is refused naming the script."""
    scene = loader.load("hertz", ["geometry.parameters={radius=2.0}"])
    assert dict(scene["geometry"]["parameters"]) == {"radius": 2.0}
    with pytest.raises(SceneError, match="geometry.parameters.depth"):
        loader.load("hertz", ["geometry.parameters={depth=3.0}"])
