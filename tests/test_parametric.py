"""ParametricDynamics: equations of motion with symbolic coefficients, against hand derivations."""
import numpy as np
import pytest

from lsindy_cas import systems
from lsindy_cas.mechanics.parametric import ParametricDynamics


def test_single_pendulum_with_friction_is_the_hand_derived_equation():
    # L = a1 θ̇² + a2 cos θ + a3 sin θ,  R = r1 θ̇² + r2 |θ̇|_ε:
    # 2 a1 θ̈ = Q − a2 sin θ + a3 cos θ − 2 r1 θ̇ − r2 tanh(θ̇/ε)
    eps = 0.05
    dyn = ParametricDynamics(["theta"], ["theta_dot**2", "cos(theta)", "sin(theta)"],
                             ["theta_dot**2", "Abs(theta_dot)"], eps=eps)
    ode = dyn.ode()
    rng = np.random.default_rng(0)
    for _ in range(20):
        th, w, Q = rng.uniform(-4, 4), rng.uniform(-0.3, 0.3) * rng.choice([1, 30]), rng.normal()
        p = rng.uniform(0.1, 2.0, 5)
        want = (Q - p[1] * np.sin(th) + p[2] * np.cos(th) - 2 * p[3] * w
                - p[4] * np.tanh(w / eps)) / (2 * p[0])
        got = np.asarray(ode([th, w], [Q], p)).ravel()
        # both sides are a handful of floating-point operations: 1e-12 relative
        np.testing.assert_allclose(got, [w, want], rtol=1e-12, atol=1e-12)


def test_bind_and_friction_force():
    dyn = ParametricDynamics(["s"], ["s_dot**2", "s**2"], ["s_dot**2", "Abs(s_dot)"], eps=1e-3)
    f = dyn.friction()
    # far above ε the smooth sign is 1 to double precision; at rest it is 0
    np.testing.assert_allclose(np.asarray(f([0.0, 2.0], [1, 1, 0.5, 0.25])).ravel(), [-2.0 - 0.25])
    np.testing.assert_allclose(np.asarray(f([0.0, 0.0], [1, 1, 0.5, 0.25])).ravel(), [0.0])
    ode = dyn.bind([0.5, -2.0, 0.0, 0.0])        # m = 1, k = 4: s̈ = -4 s
    np.testing.assert_allclose(np.asarray(ode([1.0, 0.0], [0.0])).ravel(), [0.0, -4.0])


def test_cart_pendulum_matches_the_benchmark_system(cart):
    # true L = (mc+mp)/2 ẋ² + mpL²/2 θ̇² + mpL ẋθ̇ cos θ + mpgL cos θ (θ from the downward vertical)
    terms = ["x_dot**2", "theta_dot**2", "x_dot*theta_dot*cos(theta)", "cos(theta)"]
    p = [1.1 / 2, 0.1 / 2, 0.1, 0.1 * 9.81]
    ode = ParametricDynamics(cart.coords, terms).bind(p)
    truth = cart.ode()
    rng = np.random.default_rng(1)
    for _ in range(20):
        x, u = rng.normal(size=4) * [1, 3, 2, 4], rng.normal(size=2)
        # the same equations through two CasADi graphs: agreement to rounding, 1e-10 relative
        np.testing.assert_allclose(np.asarray(ode(x, u)).ravel(), np.asarray(truth(x, u)).ravel(),
                                   rtol=1e-10, atol=1e-12)


@pytest.mark.parametrize("terms, diss, match", [
    (["theta_dot**2"], ["theta**2"], "velocities only"),
    (["theta_dot**2"], ["2"], "velocities only"),
    ([], [], "at least one"),
    (["theta_dot**2"], ["phi_dot**2"], "unknown name"),
])
def test_bad_terms_are_refused(terms, diss, match):
    with pytest.raises(ValueError, match=match):
        ParametricDynamics(["theta"], terms, diss)


def test_bad_eps_and_coefficient_count():
    with pytest.raises(ValueError, match="eps"):
        ParametricDynamics(["theta"], ["theta_dot**2"], eps=0.0)
    with pytest.raises(ValueError, match="p must have 2"):
        ParametricDynamics(["theta"], ["theta_dot**2", "cos(theta)"]).bind([1.0])
