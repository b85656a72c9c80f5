"""`contactvisco fit FIT.toml --out DIR` (docs/identification.md): the files it writes, its
exit status when the optimizer stops before converging (3, the last state written) and on a
bad fit description (2, the key named)."""
import json

import pytest
from mpi4py import MPI

from helpers import run_cli

pytestmark = [pytest.mark.processes,
              pytest.mark.skipif(MPI.COMM_WORLD.size > 1,
                                 reason="starts its own (MPI) processes; run on one rank")]

COARSE = ('geometry.parameters={radius = 10.0, height = 10.0, h_contact = 0.04, h_far = 3.0, '
          'refine = 0.3, growth = 0.15}')
FIT = f"""[fit]
jacobian = "finite-differences"
difference = "forward"
max_evaluations = 2

[[experiment]]
scene = "sphere_creep"
data = "data.csv"
set = ['{COARSE}']
noise = 1e-5

[[parameter]]
key = "viscoelastic.shear.fractions.0"
initial = 0.4
bounds = [0.05, 0.9]
"""
DATA = "t,force,depth\n0,-0.0015,0.0099\n1.5,-0.0015,0.0126\n3,-0.0015,0.0135\n"


def test_a_fit_stopped_early_writes_its_files_and_exits_3(tmp_path):
    """Two evaluations of the residual allowed, each with a Jacobian of one forward difference:
    four forward runs, not converged, exit 3; fit.json
    holds the estimate, curves.csv one row per sample, fit.png exists."""
    (tmp_path / "data.csv").write_text(DATA)
    (tmp_path / "fit.toml").write_text(FIT)
    out = tmp_path / "out"
    done = run_cli("fit", tmp_path / "fit.toml", "--out", out)
    assert done.returncode == 3, done.stderr
    assert "viscoelastic.shear.fractions.0 = " in done.stdout
    report = json.loads((out / "fit.json").read_text())
    assert report["success"] is False and report["residual_evaluations"] == 2
    assert report["evaluations"] == 4
    assert report["parameters"][0]["key"] == "viscoelastic.shear.fractions.0"
    rows = (out / "curves.csv").read_text().splitlines()
    assert rows[0] == "experiment,t,force,measured_depth,fitted_depth" and len(rows) == 4
    assert (out / "fit.png").stat().st_size > 0


def test_a_bad_fit_description_exits_2_naming_the_key(tmp_path):
    (tmp_path / "data.csv").write_text(DATA)
    (tmp_path / "fit.toml").write_text(FIT.replace("bounds = [0.05, 0.9]", "bounds = [0.9]"))
    done = run_cli("fit", tmp_path / "fit.toml", "--out", tmp_path / "out")
    assert done.returncode == 2
    assert "parameter[0].bounds" in done.stderr
