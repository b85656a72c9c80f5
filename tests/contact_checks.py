"""The discrete contact conditions (eqs 11-12) at the contact nodes of a contact table."""
import numpy as np


def assert_contact_conditions(table, g, tol=1e-10, prescribed_tangential=None,
                              direction_tol=1e-8):
    """s <= g (s = u_nu - h the penetration); R = -lambda_nu >= 0 and (g - s) R = 0; the normal reaction is p_nu + R;
    |sigma_tau| <= radius (mu p_nu(u_nu), or mu (p_nu + R) for Coulomb's law), sigma_tau
    tangential; on sliding nodes sigma_tau = -radius slip / |slip| (slip: u_tau or its
    increment over the step). Returns the number of sliding nodes checked.

    prescribed_tangential: boolean mask of nodes whose tangential displacement is prescribed
    (their tangential reaction is carried by the Dirichlet condition).
    direction_tol: an error e in a node's friction equation turns sigma_tau by about
    e / (r |u_tau|), so the sliding direction gets a looser bound than the others."""
    u_nu, R = table["penetration"], -table["lambda_nu"]
    assert np.all(u_nu <= g + tol), np.max(u_nu - g)
    assert np.all(R >= -tol)
    if np.isfinite(g):
        assert np.max(np.abs((g - u_nu) * R)) < tol
    free = u_nu < g - 1e-6
    assert np.max(np.abs(R[free]), initial=0.0) < tol
    assert np.allclose(table["reaction_nu"], table["p_nu"] + R, atol=tol)

    # The slip the friction law acts on: u_tau, or the step's increment (slip = "increment").
    sig, ut, radius = table["sigma_tau_vector"], table["slip_vector"], table["radius"]
    assert np.all(np.linalg.norm(sig, axis=1) <= radius + tol)
    assert np.max(np.abs(np.einsum("ij,ij->i", sig, table["normal"]))) < tol
    sliding = (np.linalg.norm(ut, axis=1) > 1e-8) & (radius > 0)
    if prescribed_tangential is not None:
        sliding &= ~prescribed_tangential
    direction = ut[sliding] / np.linalg.norm(ut[sliding], axis=1)[:, None]
    expected = -radius[sliding, None] * direction
    assert np.max(np.abs(sig[sliding] - expected), initial=0.0) < direction_tol
    return int(sliding.sum())
