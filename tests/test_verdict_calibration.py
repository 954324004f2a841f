"""Standard errors behind the verdict: the noise floor of the propagated errors, the Gauss–Newton
errors of refined coefficients, and the verdict on refined coefficients."""
import numpy as np
import pytest

from lsindy_cas import Trajectory
from lsindy_cas.identify import findings as F
from lsindy_cas.identify.findings import Finding, code_of
from lsindy_cas.identify.refine import refine
from lsindy_cas.identify.standard_errors import difference_noise
from lsindy_cas.identify.status import REL_STD_PROPAGATED, refined_status
from lsindy_cas.mechanics.euler_lagrange import simulate_ode
from lsindy_cas.mechanics.parametric import ParametricDynamics

TERMS, DISS = ["theta_dot**2", "cos(theta)"], ["theta_dot**2"]
TRUE = np.array([0.5, 9.81, 0.15])        # θ̈ = −9.81 sin θ − 0.3 θ̇ (θ from the downward vertical)
SIGMA_Q, SIGMA_V = 1e-2, 3e-2


@pytest.fixture(scope="module")
def clean():
    ode = ParametricDynamics(["theta"], TERMS, DISS).bind(TRUE)
    t = np.arange(301) * 0.01
    return [(t, simulate_ode(ode, x0, t, 0.0, 1)[0]) for x0 in [(2.0, 0.0), (0.5, 3.0)]]


def _noisy(clean, rng, scale=1.0):
    return [Trajectory(t, X[:, :1] + scale * SIGMA_Q * rng.normal(size=(len(t), 1)),
                       X[:, 1:] + scale * SIGMA_V * rng.normal(size=(len(t), 1)), ["theta"])
            for t, X in clean]


def test_difference_noise_finds_white_noise_on_a_smooth_signal():
    t = np.arange(2000) * 0.01
    X = np.column_stack([np.sin(2 * t), 3 * np.cos(5 * t)])
    noisy = X + np.random.default_rng(0).normal(size=X.shape) * [1e-3, 1e-2]
    # 1994 sixth differences: the median's own scatter is ~5 %; the signal adds (ωΔt)^6 ≈ 2e-8
    np.testing.assert_allclose(difference_noise(noisy), [1e-3, 1e-2], rtol=0.15)
    assert np.all(difference_noise(X) < 1e-6)          # no noise: the signal's trace only
    assert np.all(difference_noise(X[:5]) == 0)         # too short to tell


def test_refined_errors_scale_with_the_noise_and_fixed_terms_have_none(clean):
    """One noise draw at σ and at 2σ (the same draw doubled): to first order the errors double."""
    res = [refine(["theta"], TERMS, TRUE, _noisy(clean, np.random.default_rng(3), s), DISS,
                  fixed="theta_dot**2", steps=2) for s in (1.0, 2.0)]
    assert all(r.success for r in res)
    assert res[0].std[0] == 0 and np.all(res[0].std[1:] > 0)      # the normalisation is fixed
    # linearisation: the ratio is 2 up to the curvature over errors of ~0.1 %: 10 % is ample
    np.testing.assert_allclose(res[1].std[1:] / res[0].std[1:], 2.0, rtol=0.1)
    # and the actual errors are of that size (4 standard errors: a gross miscalibration only)
    assert np.all(np.abs(res[0].coef - TRUE)[1:] < 4 * res[0].std[1:])


@pytest.mark.slow    # ~40 s: 30 refinements
def test_refined_errors_match_the_scatter(clean):
    """Over 30 noise draws the RMS error of each free coefficient is its mean standard error
    (measured 1.01 and 0.95 on 40 draws); an RMS over 30 draws is itself uncertain by ~13 %, so
    the ratio must lie within 0.7–1.4."""
    rng = np.random.default_rng(11)
    err, std = [], []
    for _ in range(30):
        r = refine(["theta"], TERMS, TRUE, _noisy(clean, rng), DISS, fixed="theta_dot**2", steps=2)
        err.append(r.coef - TRUE)
        std.append(r.std)
    ratio = np.sqrt(np.mean(np.square(err), axis=0))[1:] / np.mean(std, axis=0)[1:]
    assert np.all((0.7 < ratio) & (ratio < 1.4)), ratio


def _reasons():
    return [Finding("the coefficient of a is determined only to ±6 % (...)", F.STD_PROPAGATED,
                    {"relative_std": 0.06}),
            Finding("a short simulation drifts", F.SIMULATION_DRIFT, {"drift": 0.1})]


def test_refined_status_replaces_only_the_coefficient_findings():
    names, coef = ["a", "b", "c"], np.array([1.0, -2.0, 0.0])
    small = np.array([0.01, 0.02, 0.0])                 # 1 % of each: determined
    status, reasons = refined_status(_reasons(), coef, small, names, "how")
    assert status == "undetermined" and [code_of(r) for r in reasons] == [F.SIMULATION_DRIFT]
    status, reasons = refined_status(_reasons()[:1], coef, small, names, "how")
    assert status == "ok" and reasons == []
    # still open: one finding on the refined errors, naming the term and how they were obtained
    large = np.array([0.01, 2.5 * REL_STD_PROPAGATED * 2.0, 0.0])
    status, reasons = refined_status(_reasons()[:1], coef, large, names, "how")
    assert status == "undetermined" and len(reasons) == 1
    assert code_of(reasons[0]) == F.STD_PROPAGATED and "of b" in reasons[0] and "(how;" in reasons[0]
    assert reasons[0].numbers["relative_std"] == pytest.approx(2.5 * REL_STD_PROPAGATED)
    # no refined errors: the balance's findings stand
    status, reasons = refined_status(_reasons(), coef, None, names, "how")
    assert status == "undetermined" and len(reasons) == 2
