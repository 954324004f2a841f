"""Library construction, naming and exact derivatives."""
from math import comb

import numpy as np
import pytest

from lsindy_cas import Library


def test_polynomial_size_and_names():
    lib = Library.polynomial(["x", "theta"], ["cos(theta)", "sin(theta)", "theta_dot", "x", "x_dot"], 3)
    assert len(lib) == comb(5 + 3, 3) - 1          # all monomials of degree 1..3, no constant
    assert "theta_dot*x_dot*cos(theta)" in lib.names
    assert lib.index("x_dot*theta_dot*cos(theta)") == lib.names.index("theta_dot*x_dot*cos(theta)")


def test_spherical_library_has_125_terms():
    lib = Library.polynomial(["theta", "phi"], "cos(theta),sin(theta),theta_dot,phi,phi_dot", 4)
    assert len(lib) == 125


def test_union_and_duplicates():
    a = Library(["q"], ["q**2", "q_dot**2"])
    b = Library(["q"], ["q_dot**2", "cos(q)"])
    assert (a + b).names == ["q**2", "q_dot**2", "cos(q)"]


def test_gamma_is_exact_time_derivative(rng):
    """Γ = ∇Θ·ẋ: for θ = q̇² cos q, dθ/dt = 2 q̇ q̈ cos q − q̇³ sin q."""
    lib = Library(["q"], ["q_dot**2*cos(q)", "sin(q)"])
    X = rng.normal(size=(50, 2))
    Xd = np.column_stack([X[:, 1], rng.normal(size=50)])
    q, qd, qdd = X[:, 0], X[:, 1], Xd[:, 1]
    expected = np.column_stack([2 * qd * qdd * np.cos(q) - qd**3 * np.sin(q), np.cos(q) * qd])
    np.testing.assert_allclose(lib.gamma(X, Xd), expected, rtol=1e-13, atol=1e-13)


def test_velocity_derivatives(rng):
    lib = Library(["a", "b"], ["a_dot*b_dot*cos(a)", "b_dot**2"])
    X = rng.normal(size=(7, 4))
    a, b, ad, bd = X.T
    d1 = lib.dtheta_dqd(X)                            # (N, n, p)
    np.testing.assert_allclose(d1[:, 0, 0], bd * np.cos(a), rtol=1e-14)
    np.testing.assert_allclose(d1[:, 1, 1], 2 * bd, rtol=1e-14)
    d2 = lib.d2theta_dqd2(X)                          # (N, n, n, p)
    np.testing.assert_allclose(d2[:, 0, 1, 0], np.cos(a), rtol=1e-14)
    np.testing.assert_allclose(d2[:, 1, 1, 1], 2.0)
    assert lib.velocity_degree(0) == 2 and lib.velocity_degree(1) == 2


def test_coefficients_expand_trig_sums():
    lib = Library.polynomial(["t1", "t2"], "cos(t1),cos(t2),sin(t1),sin(t2),t1_dot,t2_dot", 4)
    xi = lib.coefficients("t1_dot*t2_dot*cos(t1 - t2)")
    assert xi[lib.index("t1_dot*t2_dot*cos(t1)*cos(t2)")] == 1.0
    assert xi[lib.index("t1_dot*t2_dot*sin(t1)*sin(t2)")] == 1.0
    assert np.count_nonzero(xi) == 2


@pytest.mark.parametrize("features, message", [
    (["cos(y)"], "unknown name"),
    (["cos(theta"], "cannot parse"),
    (["besselj(1, theta)"], "unsupported function"),
    ([], "at least one"),
])
def test_bad_features(features, message):
    with pytest.raises(ValueError, match=message):
        Library.polynomial(["theta"], features, 2)


def test_bad_degree_and_coords():
    with pytest.raises(ValueError, match="degree"):
        Library.polynomial(["q"], ["q"], 0)
    with pytest.raises(TypeError, match="degree"):
        Library.polynomial(["q"], ["q"], 2.5)
    with pytest.raises(ValueError, match="invalid coordinate"):
        Library(["q_dot"], ["q_dot"])
    with pytest.raises(ValueError, match="unique"):
        Library(["q", "q"], ["q"])
    with pytest.raises(ValueError, match="not in the library"):
        Library(["q"], ["q**2"]).index("q**3")
