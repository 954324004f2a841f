"""The support search on a Dask cluster gives the single-process answer."""
import numpy as np
import pytest

from lsindy_cas import LagrangianSINDy, Library, systems

pytestmark = pytest.mark.needs("distributed")


def _spherical(passive):
    s = systems.spherical_pendulum()
    lib = Library.polynomial(s.coords, ["cos(theta)", "sin(theta)", "theta_dot", "phi", "phi_dot"], 4)
    if passive:
        return s, lib, [s.simulate(t_end=3.0, u=0.0)], [s.simulate(t_end=0.1, u=1.0)]
    return s, lib, [s.simulate(t_end=1.0, u=1.0)], None


@pytest.mark.parametrize("passive", [False, True], ids=["driven", "passive"])
def test_two_worker_cluster_gives_the_single_process_answer(client, passive):
    """Full C(125, 3) search (no priors; passive: with the two pendulum priors): identical supports
    in identical order, the same scores (to round-off), the same winner, coefficients to 1e-12."""
    s, lib, trajs, scale = _spherical(passive)
    kw = dict(n_terms=3) if not passive else dict(n_terms=3, prior=["theta_dot**2", "cos(theta)"])
    one = LagrangianSINDy(lib, **kw).fit(trajs, scale)
    many = LagrangianSINDy(lib, **kw).fit(trajs, scale, client=client)
    assert many.support_ == one.support_
    assert set(one.support_) == set(np.flatnonzero(lib.coefficients(s.hamiltonian)))
    np.testing.assert_array_equal(many.search_.supports, one.search_.supports)   # index sets
    # the same fits in other processes (other chunking, memory alignment, BLAS threads): scores
    # lie in [0, 1] (relative residual or normalised λ_min); ill-conditioned supports can
    # amplify ulp-level differences by cond(G), so 1e-9 absolute, far below any real mismatch
    np.testing.assert_allclose(many.search_.scores, one.search_.scores, rtol=0, atol=1e-9)
    np.testing.assert_allclose(many.coef_, one.coef_, rtol=0, atol=1e-12)


def test_subtree_groups_cover_every_subtree_in_order():
    from lsindy_cas.identify.distributed import _groups
    sizes = np.array([10, 6, 3, 1, 0, 0])
    groups = _groups(sizes, 3)
    assert np.array_equal(np.concatenate(groups), np.arange(6))
    assert len(groups) <= 3


def test_unreachable_scheduler_is_one_clear_error():
    from lsindy_cas.identify.distributed import connect
    with pytest.raises(ValueError, match="no Dask scheduler answered"):
        connect("tcp://127.0.0.1:1", timeout=1.0)
    with pytest.raises(ValueError, match="give 'local' or an address"):
        connect("localhost:8786")
