"""One support-fitting core: the exhaustive search and the beam fit a support the same way."""
import numpy as np

from lsindy_cas.identify import selection
from lsindy_cas.identify.fitting import coef_on_support, normalise_columns, null_vector
from lsindy_cas.identify.search import best_subset


def _passive_two_conserved(rng):
    """Passive columns where support {0,1,2,3} conserves a 2-dimensional family of combinations.

    Columns 0..3 live in a 2-dimensional function space, so A_S has a 2-dimensional null space;
    only the actuated scale record tells which combination (``truth``) is the energy.
    """
    t = np.linspace(0, 3, 300)
    u1, u2, u3, u4 = np.sin(2 * t), np.cos(3 * t) + 0.2 * t, np.exp(-t) * t, t ** 2
    A = np.column_stack([u1, u2, u1 + 2 * u2, u1 - u2, u3, u4]) * [1.0, 30.0, 0.01, 5.0, 1.0, 2.0]
    N = np.linalg.svd(A[:, :4])[2][-2:].T                   # (4, 2) null basis
    truth = np.zeros(6)
    truth[:4] = N @ np.array([0.7, -1.3])
    As = rng.standard_normal((40, 6))
    return A, rng.standard_normal((300, 6)), (As, As @ truth), truth


def test_exhaustive_and_beam_fit_a_passive_support_alike(rng):
    A, D, scale, truth = _passive_two_conserved(rng)
    full = best_subset(A, None, 4, D=D, scale_system=scale)
    prev = best_subset(A, None, 3, D=D, scale_system=scale)
    beam = selection._beam(A, None, D, 4, prev, selection._Columns(6, []), None, scale)
    assert full.support == beam.support == (0, 1, 2, 3)
    assert full.null_dim == beam.null_dim == 2
    # exact by construction: both refit the winner with coef_on_support on the same A and support
    np.testing.assert_array_equal(full.coef, beam.coef)
    # the scale record picks the right member of the 2-dimensional family
    np.testing.assert_allclose(full.coef, truth, rtol=1e-9, atol=1e-12 * np.abs(truth).max())


def test_coef_on_support_driven_is_unit_free(rng):
    A = rng.standard_normal((50, 4))
    b = A[:, :2] @ [2.0, -1.0]
    coef, null_dim = coef_on_support(A * [1e3, 1e-3, 1, 1], b, [0, 1])
    np.testing.assert_allclose(coef[:2], [2e-3, -1e3], rtol=1e-10)
    assert null_dim == 0 and not np.any(coef[2:])


def test_normalise_columns_keeps_zero_columns():
    A = np.array([[3.0, 0.0], [4.0, 0.0]])
    An, s = normalise_columns(A)
    np.testing.assert_allclose(An, [[0.6, 0.0], [0.8, 0.0]])
    np.testing.assert_allclose(s, [5.0, 1.0])
    v = null_vector(np.column_stack([A[:, 0], 2 * A[:, 0]]))
    np.testing.assert_allclose(v / v[0], [1.0, -0.5])
