"""Automatic k on planted energies (benchmarks/planted.py): two-link energies with exactly k terms
of a 154-term library, two priors, clean runs under random held torques.  The scan must find the
planted support with k chosen by itself, score every k up to it (or say why not), and stop there.

Known answers: the planted coefficients.  Tolerance 1e-6 relative: clean data through the
smoothed integral form fit the planted energies to 3e-14 – 7e-14 (measured on k = 6, 8, 10), so
1e-6 leaves eight orders of margin while any other support is off by O(1).
"""
import numpy as np
import pytest

TOL = 1e-6


@pytest.fixture(scope="module")
def planted(load_script):
    return load_script("benchmarks/planted.py")


@pytest.fixture(scope="module")
def library(planted):
    lib = planted.library()
    assert len(lib) == 154
    return lib


def _fit(planted, library, k, spread, seed=0):
    from lsindy_cas import LagrangianSINDy
    coef = planted.planted(k, seed)
    truth = library.coefficients(planted.system(coef).hamiltonian)
    data = planted.strip(planted.runs(coef, spread, seed=seed))
    return LagrangianSINDy(library, prior=planted.PRIOR).fit(data), truth


def _check(model, truth, k, n_prior=2):
    S = np.flatnonzero(truth)
    assert len(S) == k
    np.testing.assert_array_equal(np.flatnonzero(model.coef_), S)    # exact support (indices)
    np.testing.assert_allclose(model.coef_[S], truth[S], rtol=TOL)
    assert model.n_terms_ == k and model.status_ == "ok"
    sel = model.selection_
    scored = [st.k for st in sel.steps]
    # every k from the first scored one up to the chosen one was scored; the scan ended there
    assert scored == list(range(scored[0], k + 1)), scored
    # every k below the first scored one is reported: no admissible model (proven), or undecided
    # (a scout stopped first) — which leaves the status ok because the chosen model fits
    assert sorted(u.k for u in sel.unscored) == list(range(n_prior, scored[0]))
    assert all(str(u.reason) for u in sel.unscored)
    assert model.diagnostics_.chi <= 2.0 or not sel.undecided


def test_planted_six_terms_large_motion(planted, library):
    model, truth = _fit(planted, library, 6, 2.5)
    _check(model, truth, 6)


def test_planted_energy_is_a_mechanical_system(planted):
    """Every planted energy has a positive-definite mass matrix over the whole circle and exactly
    k terms."""
    grid = np.linspace(-np.pi, np.pi, 181)
    for k in planted.SPLIT:
        for seed in range(3):
            coef = planted.planted(k, seed)
            assert len(coef) == k
            assert np.linalg.eigvalsh(planted._mass(coef, grid))[:, 0].min() > 0


def test_planted_rejects_an_unknown_k(planted):
    with pytest.raises(ValueError, match="k must be one of"):
        planted.planted(5)


@pytest.mark.slow
@pytest.mark.parametrize("k", [6, 7, 8, 9, 10])
@pytest.mark.parametrize("spread", [0.6, 2.5])
def test_planted_supports_small_and_large_motion(planted, library, k, spread):
    model, truth = _fit(planted, library, k, spread)
    _check(model, truth, k)
