"""The contact radius of an axisymmetric contact table (fem.contact_state.contact_radius):
exact for a gap that opens as (r - a)^{3/2} beyond the edge, bounded by the last node in
contact and the first open one, and zero without contact."""
import numpy as np
import pytest

from contactvisco.fem.contact_state import contact_radius


def table(r, a, c=1.0):
    """A table whose nodes r < a are in contact (penetration 0, status 1) and whose gap beyond
    a is c (r - a)^{3/2} (penetration -gap, status 0), rows shuffled."""
    r = np.asarray(r, float)
    gap = np.where(r > a, c * np.clip(r - a, 0.0, None) ** 1.5, 0.0)
    order = np.random.default_rng(3).permutation(r.size)
    return {"x": np.column_stack([r, np.zeros_like(r)])[order],
            "status": np.where(r <= a, 1, 0)[order], "penetration": -gap[order]}


@pytest.mark.parametrize("a", [0.31, 0.349, 0.45])
def test_a_gap_opening_as_three_halves_gives_the_edge(a):
    r = np.linspace(0.0, 1.0, 11)
    found = contact_radius(table(r, a, c=2.5))
    assert found["node"] == pytest.approx(r[r <= a].max(), abs=1e-15)
    assert found["interpolated"] == pytest.approx(a, rel=1e-12)


def test_other_gaps_stay_between_the_nodes():
    """A gap opening as (r - a)^4 (a = 0.33): the 3/2 rule places the edge beyond a, but
    never beyond the first open node."""
    r = np.linspace(0.0, 1.0, 11)
    t = table(r, 0.33)
    t["penetration"] = np.where(t["status"] > 0, 0.0, -(t["x"][:, 0] - 0.33) ** 4)
    found = contact_radius(t)
    assert found["node"] == pytest.approx(0.3)
    assert 0.33 < found["interpolated"] <= 0.4 + 1e-15


def test_no_contact_and_contact_to_the_last_node():
    r = np.linspace(0.0, 1.0, 6)
    none = table(r, -1.0)
    assert contact_radius(none) == {"node": 0.0, "interpolated": 0.0}
    full = table(r, 2.0)
    assert contact_radius(full) == {"node": 1.0, "interpolated": 1.0}
    one_open = table(r, 0.9)            # one open node beyond: no extrapolation
    assert contact_radius(one_open) == {"node": 0.8, "interpolated": 0.8}
