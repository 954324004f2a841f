"""The significance rule may pass over a better-scoring support: a case where that is right.

The paper's cart-pendulum run (1 s, F = 1 N) with noise σ = 1e-2 on every column, seed 1 of
``benchmarks/noise_sweep.py``: the best-scoring physically admissible 4-term support has a term
that is not significantly non-zero (jackknife), and scores about 4x better than the true one.
The rule rejects it and the next supports, and the support chosen is the true one.  (So a rule
"never choose a worse-scoring support than the best admissible one" would report a wrong model
here; the rich-protocol sweep at σ = 5e-2, where such a swap could have cost the true model, found
none in 90 fits: ``benchmarks/results/noise_headline_rich.md``.)
"""
import numpy as np
import pytest

from lsindy_cas import LagrangianSINDy, Library
from lsindy_cas.data.smoothing import add_noise


@pytest.mark.slow
def test_the_rule_passes_over_a_better_scoring_wrong_support(load_script):
    sweep = load_script("benchmarks/noise_sweep.py")
    setup = sweep.PAPER_SETUPS["cart"]
    system, clean = sweep.clean_data("cart", "paper", 1)
    lib = Library.polynomial(system.coords, setup.features, setup.degree)
    rng = np.random.default_rng([1, 20])            # the benchmark's noise for seed 1, σ = 1e-2
    noisy = [add_noise(tr, 1e-2, rng) for tr in clean]
    model = LagrangianSINDy(lib, prior=setup.prior).fit(noisy)
    truth = tuple(np.flatnonzero(lib.coefficients(system.hamiltonian)))
    assert model.search_.support == truth
    passed_over = [c for c in model.search_.candidates
                   if getattr(c.reason, "code", None) == "not_significant"
                   and c.score < model.search_.score]
    assert passed_over, "no better-scoring support was rejected as insignificant"
    # the best of them scores at least twice better than the truth: not a near tie
    assert min(c.score for c in passed_over) < 0.5 * model.search_.score
    assert all(set(c.support) != set(truth) for c in passed_over)
