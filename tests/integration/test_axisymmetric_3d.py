"""Axisymmetry = 3D: one sphere-on-cylinder problem (studies.revolution) in the meridian
half-plane and on a quarter cylinder of tetrahedra. The reference P_ref is the axisymmetric
run at h = a/32 (20004 unknowns; its own error is below 0.05 %, from the runs at a/16 and
a/32). Measured total forces, relative to P_ref = 1.56435e-3:

    axisymmetric a/4 (423 unknowns):    +3.27 %
    3D           a/2 (864 unknowns):    +15.1 %
    3D           a/4 (2372 unknowns):   +4.85 %
    3D           a/8 (12408 unknowns):  +1.83 %

The same on 2 ranks (the test is marked mpi).
"""
import pytest
from mpi4py import MPI

from contactvisco.studies.revolution import sphere_on_cylinder

pytestmark = pytest.mark.mpi

COMM = MPI.COMM_WORLD


@pytest.fixture(scope="module")
def reference():
    return sphere_on_cylinder("axisymmetric", 32, comm=COMM)["P"]


def test_axisymmetric_and_3d_agree_to_the_3d_error(reference):
    """At a/4 both runs overestimate P (the discrete contact zone is too stiff); the two
    differ by less than the 3D run's error against P_ref, and the 3D error falls towards the
    axisymmetric reference by more than 2.5 from a/2 to a/4 (measured 3.1)."""
    axi = sphere_on_cylinder("axisymmetric", 4, comm=COMM)["P"]
    coarse, solid = (sphere_on_cylinder("3d", n, comm=COMM)["P"] for n in (2, 4))
    error_3d = abs(solid / reference - 1.0)
    error_axi = abs(axi / reference - 1.0)
    assert abs(axi - solid) < error_3d * reference, (axi, solid, reference)
    assert error_axi < error_3d
    assert abs(coarse / reference - 1.0) > 2.5 * error_3d, (coarse, solid, reference)
    assert error_3d < 0.06


def test_finer_3d_run_approaches_the_axisymmetric_reference(reference):
    """3D at a/8 (12408 unknowns): its error against P_ref falls below 2 % (measured 1.83 %),
    by more than 2 from a/4."""
    solid = sphere_on_cylinder("3d", 8, comm=COMM)["P"]
    assert abs(solid / reference - 1.0) < 0.02
    assert abs(solid / reference - 1.0) < 0.0485 / 2
