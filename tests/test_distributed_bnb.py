"""The branch and bound on a Dask cluster gives the single-process answer, and its workers prune
with the shared incumbent."""
import numpy as np
import pytest

from lsindy_cas import LagrangianSINDy, Library, systems
from lsindy_cas.identify import distributed_bnb, selection
from lsindy_cas.identify.bnb import branch_and_bound

pytestmark = pytest.mark.needs("distributed")


@pytest.fixture
def on_workers(monkeypatch):
    """No warm-up and no frontier on the driver: the whole search runs in tasks."""
    monkeypatch.setattr(distributed_bnb, "WARMUP", 0.0)
    monkeypatch.setattr(distributed_bnb, "FRONTIER", 0)


def _noisy(seed, m=120, p=24, k=5, passive=False):
    """A sparse model in badly scaled columns with enough noise that the proof takes many nodes."""
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(m, p)) * rng.uniform(0.1, 10, p)
    truth = sorted(rng.choice(p, k, replace=False).tolist())
    if passive:            # a near-null combination of the true columns
        A[:, truth[0]] = A[:, truth[1:]] @ rng.uniform(0.5, 2, k - 1) + 0.05 * rng.normal(size=m)
        return A, None, A
    b = A[:, truth] @ rng.uniform(0.5, 2, k) + 3.0 * rng.normal(size=m)
    return A, b, None


@pytest.mark.parametrize("passive", [False, True], ids=["driven", "passive"])
@pytest.mark.parametrize("seed", [0, 1])
def test_subtree_tasks_give_the_single_process_answer(client, passive, seed):
    """All of the search in tasks of 0.2 s (root handed out, open nodes returned and handed out
    again): the same support, proven, coefficients equal to 1e-12 (both refit the winner on A with
    the same function, so in fact bit for bit)."""
    A, b, D = _noisy(seed, passive=passive)
    banned = set()
    one = branch_and_bound(A, b, 5, D=D)
    banned.add(one.support)                 # and again with the unconstrained winner refused

    def admissible(S, coef):
        return S not in banned, "banned"

    for adm in (None, admissible):
        one = branch_and_bound(A, b, 5, D=D, admissible=adm)
        many = distributed_bnb.branch_and_bound_distributed(client, A, b, 5, D=D, admissible=adm,
                                                            warmup=0.0, task_seconds=0.2)
        assert many.support == one.support
        assert many.proven and one.proven and many.gap <= 1e-12 and many.method == "bnb"
        np.testing.assert_allclose(many.coef, one.coef, rtol=0, atol=1e-12)
        assert many.score == pytest.approx(one.score, rel=0, abs=1e-12)
        assert many.tasks >= 1 and many.nodes >= 1
        # which rejected supports were visited depends on the order of discovery (as between the
        # trees of one process); the winner is listed as admissible in both
        assert any(c.support == one.support and c.admissible for c in many.candidates)


def test_a_shared_incumbent_prunes_in_the_workers(client):
    """One task on the whole tree, once with the shared value unset (inf) and once holding the
    optimum: with it the task expands fewer nodes and accepts nothing (no support beats the
    optimum by more than the resolution); at -inf (the driver's stop) it expands nothing and hands
    every node back open — pruning them would make a tree stopped by the time limit look
    exhausted, i.e. proven (the bug this guards: proven = True with gap 0.08)."""
    import uuid
    from distributed import Variable
    from lsindy_cas.identify.bnb import BnbSearch
    A, b, _ = _noisy(3)
    one = branch_and_bound(A, b, 5)
    s = BnbSearch(A, b, 5, [], None, None, None, 1e-12, 10).start(False)
    tmpl, = client.scatter([[distributed_bnb._template(s)]], broadcast=True)
    entries = [(key, node) for key, _, node in s.heap]
    out = {}
    for value in (np.inf, one.score, -np.inf):
        var = Variable(f"test-{uuid.uuid4().hex}", client=client)
        var.set(float(value))
        out[value] = client.submit(distributed_bnb._run_task, tmpl, 0, entries, np.inf, var.name,
                                   600.0, pure=False).result()
        var.delete()
    free, shared, stop = out[np.inf], out[one.score], out[-np.inf]
    assert not free["open"] and free["winner"].support == one.support
    assert not shared["open"] and shared["winner"] is None
    assert shared["counts"][2] < free["counts"][2]
    assert stop["counts"][2] == 0 and len(stop["open"]) == len(entries)
    assert stop["lower_pruned"] == np.inf and stop["winner"] is None


@pytest.mark.parametrize("screen", [False, True], ids=["library order", "screening order"])
def test_distributed_nodes_stay_close_to_one_process(client, on_workers, screen):
    """Workers prune as well as one process: on one tree (with "auto" the trees a process would
    not have reached run in parallel and count too) the nodes over all tasks are within 1.5x of
    one process's (+ 20 for the expansions a task makes before another's incumbent reaches it)."""
    A, b, _ = _noisy(4, m=150, p=28)
    one = branch_and_bound(A, b, 5, screen=screen)
    many = distributed_bnb.branch_and_bound_distributed(client, A, b, 5, task_seconds=0.2,
                                                        screen=screen)
    assert many.support == one.support and many.proven and many.tasks >= 1
    assert many.nodes <= 1.5 * one.nodes + 20, (many.nodes, one.nodes)


def _spherical(passive):
    s = systems.spherical_pendulum()
    lib = Library.polynomial(s.coords, ["cos(theta)", "sin(theta)", "theta_dot", "phi", "phi_dot"], 4)
    if passive:
        return lib, [s.simulate(t_end=3.0, u=0.0)], [s.simulate(t_end=0.1, u=1.0)]
    return lib, [s.simulate(t_end=1.0, u=1.0)], None


@pytest.mark.parametrize("passive", [False, True], ids=["driven", "passive"])
def test_estimator_routes_branch_and_bound_to_the_cluster(client, on_workers, monkeypatch, passive):
    """With the exhaustive budget at 0 the fit takes the branch and bound; with a client it runs
    in tasks and gives the single-process fit: support, coefficients to 1e-12, proven."""
    monkeypatch.setattr(selection, "EXHAUSTIVE", 0)
    lib, trajs, scale = _spherical(passive)
    kw = dict(n_terms=3, prior=["theta_dot**2"]) if passive else dict(n_terms=3)
    one = LagrangianSINDy(lib, **kw).fit(trajs, scale)
    many = LagrangianSINDy(lib, **kw).fit(trajs, scale, client=client)
    assert one.search_.method == many.search_.method == "bnb"
    assert many.search_.tasks >= 1 and many.search_.proven
    assert many.support_ == one.support_
    np.testing.assert_allclose(many.coef_, one.coef_, rtol=0, atol=1e-12)


def test_time_limit_returns_best_so_far_not_proven(client, on_workers, monkeypatch):
    """Pure noise (every support scores alike: one process needs ~3,800 nodes, 0.5-2 s, to
    prove it, far more than one 0.02 s task expands -- with 0.2 s tasks a fast machine proved it
    before the first result came back; a slower machine expands fewer); the driver's clock
    stands still, then jumps past the 5 s limit once a task has brought a winner back (so
    however long the cluster takes to start the tasks, the limit binds there and only there):
    the tasks out are stopped and merged, and the best support found so far is returned, marked
    not proven, with its gap, never better than the optimum."""
    from lsindy_cas.identify.bnb import branch_and_bound
    state = {"jumped": False}
    merge = distributed_bnb._Run._merge

    def clock():
        return 1e6 if state["jumped"] else 0.0

    def merge_then_jump(self, fut):
        merge(self, fut)
        state["jumped"] = state["jumped"] or self.best is not None

    monkeypatch.setattr(distributed_bnb, "_clock", clock)
    monkeypatch.setattr(distributed_bnb._Run, "_merge", merge_then_jump)
    rng = np.random.default_rng(1)      # k = 4: one process needs ~3,800 nodes (k = 6: ~9,000)
    A, b = rng.normal(size=(300, 60)), rng.normal(size=300)
    res = distributed_bnb.branch_and_bound_distributed(client, A, b, 4, time_limit=5.0,
                                                       task_seconds=0.02)
    assert not res.proven and res.gap > 0 and not res.interrupted and res.tasks >= 1
    optimum = branch_and_bound(A, b, 4)          # one process, proven (test_bnb checks it)
    assert optimum.proven and res.score >= optimum.score - 1e-12


def test_ctrl_c_on_the_driver_returns_best_so_far(client, on_workers, monkeypatch):
    """Ctrl-C after the first task that came back with a winner there (not simply the first
    task: on a slow machine the warm-up and a 0.2 s task may not reach a leaf): the tasks out are
    told to stop (shared value -inf) and merged, and the best admissible support found so far is
    returned, not proven."""
    calls = {"n": 0}

    def report(self):
        if self.best is not None and calls["n"] == 0:
            calls["n"] += 1
            raise KeyboardInterrupt

    monkeypatch.setattr(distributed_bnb._Run, "_report", report)
    rng = np.random.default_rng(1)
    A, b = rng.normal(size=(300, 60)), rng.normal(size=300)
    res = distributed_bnb.branch_and_bound_distributed(client, A, b, 6, task_seconds=0.2)
    assert res.interrupted and not res.proven and res.gap >= 0 and res.tasks >= 1
    assert len(res.support) == 6 and np.isfinite(res.score)


@pytest.mark.parametrize("kwargs, match", [
    (dict(warmup=-1.0), "warmup"), (dict(task_seconds=0.0), "task_seconds"),
    (dict(time_limit=-2.0), "time_limit"), (dict(k=99), "n_terms")])
def test_bad_input(client, kwargs, match):
    A, b, _ = _noisy(0, m=30, p=8, k=3)
    kwargs = dict(dict(k=3), **kwargs)
    with pytest.raises(ValueError, match=match):
        distributed_bnb.branch_and_bound_distributed(client, A, b, kwargs.pop("k"), **kwargs)


@pytest.mark.slow
def test_cli_scheduler_local_runs_the_branch_and_bound_on_the_cluster(tmp_path):
    """`lsindy identify --terms 4` on the spherical pendulum: C(125, 4) = 9.7 M supports, beyond
    the exhaustive budget, so branch and bound; `--scheduler local --workers 2` writes the same
    model (terms and coefficients to 1e-12) with a proven certificate."""
    import json
    import subprocess
    import sys
    path = systems.spherical_pendulum().simulate(t_end=1.0, u=1.0).save(tmp_path / "run.csv")
    base = ["identify", path, "--coords", "theta,phi", "--features",
            "cos(theta),sin(theta),theta_dot,phi,phi_dot", "--degree", "4", "--terms", "4"]
    models = []
    for extra in ([], ["--scheduler", "local", "--workers", "2"]):
        out = tmp_path / f"m{len(models)}.json"
        r = subprocess.run([sys.executable, "-m", "lsindy_cas.cli", *map(str, base), "--json",
                            str(out), *extra], capture_output=True, text=True, timeout=600)
        assert r.returncode == 0, r.stderr[-2000:]
        models.append(json.loads(out.read_text()))
    one, many = models
    assert one["search"]["method"] == many["search"]["method"] == "bnb"
    assert one["search"]["proven"] and many["search"]["proven"]
    assert set(many["hamiltonian_terms"]) == set(one["hamiltonian_terms"])
    for name, value in one["hamiltonian_terms"].items():
        assert many["hamiltonian_terms"][name] == pytest.approx(value, rel=0, abs=1e-12)
