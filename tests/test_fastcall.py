"""``NumericFunction``: a CasADi function called through preallocated buffers gives what the
ordinary call gives, bit for bit, for vector, matrix and several outputs."""

import casadi as ca
import numpy as np
import pytest

from lsindy_cas.control.fastcall import NumericFunction


def _rk4_step(dt=0.05):
    """One RK4 step of a damped pendulum with a force input: x (2,), u (2,) -> x_next (2,)."""
    x, u = ca.SX.sym("x", 2), ca.SX.sym("u", 2)

    def f(z):
        return ca.vertcat(z[1], -9.81 * ca.sin(z[0]) - 0.1 * z[1] + u[0] - 0.3 * u[1])

    k1 = f(x)
    k2 = f(x + dt / 2 * k1)
    k3 = f(x + dt / 2 * k2)
    k4 = f(x + dt * k3)
    return ca.Function("F", [x, u], [x + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)])


def test_vector_function_equals_the_ordinary_call_bit_for_bit():
    f = _rk4_step()
    fast = NumericFunction(f)
    rng = np.random.default_rng(0)
    for _ in range(50):
        x, u = rng.normal(size=2), rng.normal(size=2) * 10
        expected = np.asarray(f(x, u))
        got = fast(x, u)
        assert got.shape == expected.shape == (2, 1)
        np.testing.assert_array_equal(got, expected)


def test_matrix_arguments_several_outputs_and_no_aliasing():
    a = ca.SX.sym("a", 2, 3)
    s = ca.SX.sym("s")
    f = ca.Function("g", [a, s], [s * a.T, ca.sum1(a), ca.sin(a[1, 2])])
    fast = NumericFunction(f)
    A = np.arange(6.0).reshape(2, 3) + 0.5  # rows and columns distinct: catches order errors
    first = fast(A, 2.0)
    for got, expected in zip(first, f(A, 2.0)):
        np.testing.assert_array_equal(got, np.asarray(expected))
    assert [g.shape for g in first] == [(3, 2), (1, 3), (1, 1)]
    kept = first[0].copy()
    fast(-A, 3.0)  # a later call does not overwrite what an earlier one returned
    np.testing.assert_array_equal(first[0], kept)


def test_sparse_function_is_called_the_ordinary_way():
    x = ca.SX.sym("x", ca.Sparsity.diag(3))
    f = ca.Function("d", [x], [2 * x])
    fast = NumericFunction(f)
    np.testing.assert_array_equal(np.asarray(fast(np.eye(3))), np.asarray(f(np.eye(3))))


def test_wrong_arguments():
    fast = NumericFunction(_rk4_step())
    with pytest.raises(TypeError, match="takes 2 arguments"):
        fast(np.zeros(2))
    with pytest.raises(ValueError, match="shape"):
        fast(np.zeros(3), np.zeros(2))
