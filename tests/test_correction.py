"""The online input-gain correction (``control.correction.InputGainCorrection``) on synthetic
transitions of a plant that differs from the model by a known input gain and offset."""

import casadi as ca
import numpy as np
import pytest

from lsindy_cas.control.correction import InputGainCorrection

DT = 0.05


def _model_step():
    """RK4-exact double integrator with a second, unactuated input: x = [p, v], u = (force, 0)."""
    x, u = ca.SX.sym("x", 2), ca.SX.sym("u", 2)
    return ca.Function("F", [x, u], [ca.vertcat(x[0] + DT * x[1] + DT**2 / 2 * u[0],
                                                 x[1] + DT * u[0] + 0.1 * u[1])])


def _plant(step, x, force, gain, bias):
    x_u = np.asarray(step(x, [force, 0.0])).ravel()
    x_0 = np.asarray(step(x, [0.0, 0.0])).ravel()
    return x_u + gain * (x_u - x_0) + bias


def test_converges_to_the_plant_gain_and_offset():
    step = _model_step()
    gain, bias = np.array([0.3, -0.2]), np.array([1e-3, -0.02])
    corr = InputGainCorrection(step, 0, forgetting=0.95)
    rng = np.random.default_rng(0)
    for _ in range(1000):
        x = rng.normal(size=2)
        force = rng.choice([-10.0, 0.0, 10.0])
        corr.update(x, force, _plant(step, x, force, gain, bias))
    # noise-free data: exact once forgetting has washed out the prior (whose pull is largest
    # on the position, where the input's one-step effect F dt^2 / 2 is only 1.25 cm; after 200
    # samples it still holds that gain 2 % low, after 1000 it is gone)
    np.testing.assert_allclose(corr.gain, gain, atol=1e-6)
    np.testing.assert_allclose(corr.bias, bias, atol=1e-6)
    x = np.array([0.4, -1.0])
    np.testing.assert_allclose(corr.predict(x, 10.0), _plant(step, x, 10.0, gain, bias),
                               atol=1e-6)
    corr.reset()
    assert not corr.estimate.any()
    np.testing.assert_array_equal(corr.predict(x, 10.0), np.asarray(step(x, [10.0, 0])).ravel())


def test_gain_is_bounded_by_max_gain():
    step = _model_step()
    corr = InputGainCorrection(step, 0, max_gain=0.5)
    rng = np.random.default_rng(1)
    for _ in range(100):
        x = rng.normal(size=2)
        force = rng.choice([-10.0, 10.0])
        corr.update(x, force, _plant(step, x, force, np.array([0.0, 0.9]), 0.0))
    assert corr.gain[1] == 0.5


@pytest.mark.parametrize("kwargs, exc, word", [
    ({"forgetting": 0.0}, ValueError, "forgetting"),
    ({"forgetting": 1.5}, ValueError, "forgetting"),
    ({"forgetting": "0.9"}, TypeError, "forgetting"),
    ({"max_gain": -0.1}, ValueError, "max_gain"),
])
def test_bad_arguments(kwargs, exc, word):
    with pytest.raises(exc, match=word):
        InputGainCorrection(_model_step(), 0, **kwargs)
    with pytest.raises(ValueError, match="input_index"):
        InputGainCorrection(_model_step(), 2)


def test_update_is_the_per_component_rls_step():
    """The batched update equals the textbook two-parameter RLS step, component by component
    (gain and bias regressed on the input's one-step effect, forgetting, covariance bound)."""
    step = _model_step()
    corr = InputGainCorrection(step, 0, forgetting=0.9)
    theta, cov = corr.estimate.copy(), corr.cov.copy()
    rng = np.random.default_rng(2)
    for _ in range(200):
        x, force = rng.normal(size=2), float(rng.choice([-10.0, 10.0]))
        x_next = _plant(step, x, force, np.array([0.2, -0.1]), np.array([0.01, 0.0]))
        x_next += rng.normal(0.0, 1e-3, size=2)
        x_u = np.asarray(step(x, [force, 0.0])).ravel()
        x_0 = np.asarray(step(x, [0.0, 0.0])).ravel()
        for i in range(2):
            phi = np.array([x_u[i] - x_0[i], 1.0])
            k = cov[i] @ phi / (0.9 + phi @ cov[i] @ phi)
            theta[i] += k * (x_next[i] - x_u[i] - phi @ theta[i])
            cov[i] = np.clip((cov[i] - np.outer(k, cov[i] @ phi)) / 0.9, -1e3, 1e3)
        theta[:, 0] = np.clip(theta[:, 0], -0.5, 0.5)
        corr.update(x, force, x_next)
        np.testing.assert_allclose(corr.estimate, theta, rtol=1e-12, atol=1e-15)
        np.testing.assert_allclose(corr.cov, cov, rtol=1e-12, atol=1e-15)


def test_lean_term_converges_to_the_plant_stiffness():
    """Synthetic: the plant adds ``stiffness * sin(x[0] - upright)`` to the gain/offset error;
    with ``lean=(0, upright)`` the three-parameter RLS recovers all three, exactly on noise-free
    data; without it the prediction keeps the lean's error."""
    step = _model_step()
    gain, bias = np.array([0.3, -0.2]), np.array([1e-3, -0.02])
    stiff, up = np.array([0.0, 0.7]), 0.3
    corr = InputGainCorrection(step, 0, forgetting=0.95, lean=(0, up))
    plain = InputGainCorrection(step, 0, forgetting=0.95)
    rng = np.random.default_rng(3)
    for _ in range(1000):
        x = rng.normal(size=2)
        force = rng.choice([-10.0, 0.0, 10.0])
        x_next = _plant(step, x, force, gain, bias) + stiff * np.sin(x[0] - up)
        corr.update(x, force, x_next)
        plain.update(x, force, x_next)
    np.testing.assert_allclose(corr.stiffness, stiff, atol=1e-6)
    np.testing.assert_allclose(corr.gain, gain, atol=1e-6)
    np.testing.assert_allclose(corr.bias, bias, atol=1e-6)
    x = np.array([0.9, -1.0])
    truth = _plant(step, x, 10.0, gain, bias) + stiff * np.sin(x[0] - up)
    np.testing.assert_allclose(corr.predict(x, 10.0), truth, atol=1e-6)
    assert abs(plain.predict(x, 10.0) - truth)[1] > 0.1
    assert not plain.stiffness.any() and plain.estimate.shape == (2, 2)   # off: as before
    corr.reset()
    assert corr.estimate.shape == (2, 3) and not corr.estimate.any()


def test_lean_term_on_a_cart_pendulum_with_stronger_gravity_is_the_hand_derived_one():
    """Model and plant differ only in g (10 % more on the plant): the push acts alike (gain 0)
    and, near the upright, the pole's rate error per interval is (omega_p^2 - omega_m^2) dt
    sin(phi) with omega^2 = (m_c + m_p) g / (m_c L) for the point-mass pole."""
    from lsindy_cas import systems
    from lsindy_cas.control.ocp import rk4_step
    mc, mp, L, g = 0.8, 0.2, 0.7, 9.81
    model = rk4_step(systems.cart_pendulum(mc=mc, mp=mp, L=L, g=g).ode(), 4, 2, DT, 1)
    plant = rk4_step(systems.cart_pendulum(mc=mc, mp=mp, L=L, g=1.1 * g).ode(), 4, 2, DT, 1)
    corr = InputGainCorrection(model, 0, lean=(1, np.pi))
    rng = np.random.default_rng(4)
    for _ in range(400):
        x = np.array([0.0, np.pi, 0.0, 0.0]) + rng.normal(scale=[0.3, 0.05, 0.3, 0.3])
        force = float(rng.choice([-10.0, 0.0, 10.0]))
        corr.update(x, force, np.asarray(plant(x, [force, 0.0])).ravel())
    expected = 0.1 * (mc + mp) * g / (mc * L) * DT    # theta'' = +omega^2 sin(theta - pi)
    assert corr.stiffness[3] == pytest.approx(expected, rel=0.02)    # measured 0.3 %
    assert abs(corr.gain[3]) < 0.01


@pytest.mark.parametrize("lean, exc", [((1,), TypeError), ("1", TypeError),
                                       ((2, 0.0), ValueError), ((0, float("nan")), ValueError),
                                       ((0, "pi"), TypeError)])
def test_bad_lean(lean, exc):
    with pytest.raises(exc, match="lean"):
        InputGainCorrection(_model_step(), 0, lean=lean)
