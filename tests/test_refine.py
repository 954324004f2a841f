"""Prediction-error refinement: a perturbed start is refined to the known coefficients."""
import numpy as np
import pytest

from lsindy_cas import Trajectory
from lsindy_cas.identify.refine import predict, refine
from lsindy_cas.mechanics.euler_lagrange import simulate_ode
from lsindy_cas.mechanics.parametric import ParametricDynamics

TERMS, DISS = ["theta_dot**2", "cos(theta)"], ["theta_dot**2"]
TRUE = np.array([0.5, 9.81, 0.15])        # θ̈ = −9.81 sin θ − 0.3 θ̇ (θ from the downward vertical)


@pytest.fixture(scope="module")
def runs():
    ode = ParametricDynamics(["theta"], TERMS, DISS).bind(TRUE)
    out = []
    for x0 in [(2.0, 0.0), (0.5, 3.0)]:
        t = np.arange(301) * 0.01
        X, _, _ = simulate_ode(ode, x0, t, 0.0, 1)            # DOP853 at rtol 1e-11
        out.append(Trajectory(t, X[:, :1], X[:, 1:], ["theta"]))
    return out


def test_perturbed_start_is_refined_to_the_truth(runs):
    p0 = TRUE * [1.0, 1.05, 0.7]
    res = refine(["theta"], TERMS, p0, runs, DISS, fixed="theta_dot**2", steps=4)
    assert res.success and res.fixed == ["theta_dot**2"]
    # the data are exact to ~1e-11 and RK4 at 2.5 ms is accurate to ~1e-10 over 3 s: 1e-6 is ample
    np.testing.assert_allclose(res.coef, TRUE, rtol=1e-6)
    assert res.rms < 1e-6 < res.rms_initial
    np.testing.assert_allclose(res.x0[1], [0.5, 3.0], atol=1e-6)
    assert res.lagrangian_terms() == pytest.approx({"theta_dot**2": 0.5, "cos(theta)": 9.81})


def test_predict_matches_the_accurate_simulator(runs):
    dyn = ParametricDynamics(["theta"], TERMS, DISS)
    X = predict(dyn, TRUE, runs[0].X[0], runs[0].t, steps=4)
    # RK4 error ~ (ω h)^4 per unit time with ω ≈ 3.1 s⁻¹, h = 2.5 ms: far below 1e-7
    np.testing.assert_allclose(X, runs[0].X, atol=1e-7)


def test_coulomb_friction_stays_non_negative(runs):
    # the data have no Coulomb friction; the bound keeps its coefficient at >= 0 (here: ~0)
    res = refine(["theta"], TERMS, np.r_[TRUE * [1, 1.02, 1.1], 0.01], runs,
                 DISS + ["Abs(theta_dot)"], fixed="theta_dot**2", steps=2, eps=0.05)
    assert res.coef[3] >= 0.0
    # rtol 1e-4: the smoothed sign and RK4 at 5 ms leave a small bias, measured ~1e-6
    np.testing.assert_allclose(res.coef[:3], TRUE, rtol=1e-4)


def test_bad_input(runs):
    with pytest.raises(ValueError, match="fixed must name a term"):
        refine(["theta"], TERMS, TRUE, runs, DISS)
    with pytest.raises(ValueError, match="not one of the Lagrangian terms"):
        refine(["theta"], TERMS, TRUE, runs, DISS, fixed="sin(theta)")
    with pytest.raises(ValueError, match="p0 must hold 3"):
        refine(["theta"], TERMS, TRUE[:2], runs, DISS, fixed="theta_dot**2")
    with pytest.raises(ValueError, match="bounds"):
        refine(["theta"], TERMS, TRUE * [1, 1, -1], runs, DISS, fixed="theta_dot**2")
    with pytest.raises(ValueError, match="interval"):
        refine(["theta"], TERMS, TRUE, runs, DISS, fixed="theta_dot**2", interval=0.0)
    with pytest.raises(TypeError, match="trajectories"):
        refine(["theta"], TERMS, TRUE, [], DISS, fixed="theta_dot**2")


def test_fixed_start_keeps_the_first_sample(runs):
    start = runs[0].X[0] + [0.0, 0.01]          # a wrong first rate, kept as given
    run = Trajectory(runs[0].t, np.r_[[start[:1]], runs[0].q[1:]], np.r_[[start[1:]], runs[0].qd[1:]],
                     ["theta"])
    res = refine(["theta"], TERMS, TRUE, [run], DISS, fixed="theta_dot**2", free_start=False)
    np.testing.assert_array_equal(res.x0[0], start)
