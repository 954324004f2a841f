"""Every admissibility rule rejects its counter-example and lets the true energy through."""
import numpy as np
import pytest

from lsindy_cas import Library, systems
from lsindy_cas.identify.admissibility import (NO_SCALE_REASON, REDUCIBLE_REASON, Admissibility,
                                               reducible)
from lsindy_cas.identify.balance import derivative_form, integral_form
from lsindy_cas.identify.fitting import column_norms, normal_equations
from lsindy_cas.data.smoothing import add_noise

TERMS = ["s**2", "s_dot**2", "s_dot", "s", "s**4", "s*s_dot"]


@pytest.fixture(scope="module")
def setup():
    system = systems.mass_spring()
    lib = Library(["s"], TERMS)
    tr = system.simulate(t_end=2.0, u=1.0)
    bal = derivative_form(lib, [tr])
    truth = lib.coefficients(system.hamiltonian)
    return lib, bal, truth


def _rules(lib, bal, forced=("s_dot**2",), excluded=(), balance=True):
    forced = [lib.index(t) for t in forced]
    return Admissibility(lib, bal.X, forced, column_norms(bal.A), balance=bal if balance else None,
                         excluded=[lib.index(t) for t in excluded])


def _support(coef):
    return tuple(int(j) for j in np.flatnonzero(coef))


def test_true_energy_passes_every_rule(setup):
    lib, bal, truth = setup
    assert _rules(lib, bal)(_support(truth), truth) == (True, "admissible")
    assert Admissibility.for_balance(lib, bal, [lib.index("s_dot**2")])(_support(truth), truth)[0]


def test_excluded_term_is_rejected(setup):
    lib, bal, truth = setup
    coef = truth.copy()
    coef[lib.index("s")] = 1.0
    ok, why = _rules(lib, bal, excluded=["s"])(_support(coef), coef)
    assert not ok and "constant input" in why


def test_velocity_linear_term_is_rejected(setup):
    lib, bal, truth = setup
    for term in ("s_dot", "s*s_dot"):
        coef = truth.copy()
        coef[lib.index(term)] = 0.3
        ok, why = _rules(lib, bal)(_support(coef), coef)
        assert not ok and "linear in the velocities" in why


def test_missing_prior_term_is_rejected(setup):
    lib, bal, truth = setup
    coef = truth.copy()
    coef[lib.index("s**4")] = 1.0
    ok, why = _rules(lib, bal, forced=("s**2", "s_dot**2", "s**4"))(_support(coef), coef)
    assert ok                                             # all three present
    coef[lib.index("s**4")] = 0.0
    ok, why = _rules(lib, bal, forced=("s**2", "s_dot**2", "s**4"))(_support(truth), coef)
    assert not ok and "prior term(s) s**4" in why


def test_vanishing_term_is_rejected(setup):
    lib, bal, truth = setup
    coef = truth.copy()
    coef[lib.index("s**4")] = 1e-14
    ok, why = _rules(lib, bal)(_support(coef), coef)
    assert not ok and "came out zero" in why and "s**4" in why


def test_negative_definite_kinetic_part_is_rejected(setup):
    lib, bal, truth = setup
    coef = truth.copy()
    coef[lib.index("s_dot**2")] *= -1
    ok, why = _rules(lib, bal, balance=False)(_support(coef), coef)
    assert not ok and "positive definite" in why


def test_insignificant_term_is_rejected():
    """On noisy data a spurious term fitted by least squares is not significantly non-zero."""
    system = systems.mass_spring()
    lib = Library(["s"], TERMS)
    noisy = add_noise(system.simulate(t_end=2.0, u=1.0), 1e-2, np.random.default_rng(0))
    bal = integral_form(lib, [noisy])
    S = [lib.index(t) for t in ("s**2", "s_dot**2", "s**4")]
    coef = np.zeros(len(lib))
    coef[S] = np.linalg.lstsq(bal.A[:, S], bal.b, rcond=None)[0]
    rules = _rules(lib, bal)
    assert rules.physical(tuple(S), coef)[0]              # an energy, every term non-zero ...
    ok, why = rules(tuple(S), coef)
    assert not ok and "significantly" in why              # ... but s**4 is noise


def test_reducible_rule_marks_a_smaller_model_in_disguise(setup):
    lib, bal, truth = setup
    G, c = normal_equations(bal.A, bal.b)
    true_S = sorted(_support(truth))
    padded = sorted(true_S + [lib.index("s**4")])
    assert not reducible(G, c, np.array([true_S]))[0]
    assert reducible(G, c, np.array([padded]))[0]
    assert "smaller" in REDUCIBLE_REASON and "scale" in NO_SCALE_REASON
