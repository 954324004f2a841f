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
    assert not corr.theta.any()
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
    theta, cov = corr.theta.copy(), corr.cov.copy()
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
        np.testing.assert_allclose(corr.theta, theta, rtol=1e-12, atol=1e-15)
        np.testing.assert_allclose(corr.cov, cov, rtol=1e-12, atol=1e-15)
