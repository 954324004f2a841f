import functools
import json
import importlib
import importlib.util
import os
from pathlib import Path

import numpy as np
import pytest

from lsindy_cas import systems

# The controllers compile their NLP by default where gcc is (about 8 s for each new model and
# options, then cached); the suite builds dozens of controllers, so it runs them uncompiled
# unless $LSINDY_JIT says otherwise.  The compiled path has its own tests (test_staged.py:
# the default resolved, the compiled solvers and a closed loop against the uncompiled one).
os.environ.setdefault("LSINDY_JIT", "0")
from lsindy_cas.paper.table1 import PAPER_SETUPS


# Optional dependencies a test may need: mark it ``@pytest.mark.needs("pysindy")`` and it is
# skipped, with the install hint as the reason, when that package cannot be imported.  Per test,
# so everything else in the file still runs without the extra.
OPTIONAL = {"pysindy": "pip install 'lsindy_cas[bench]'",
            "mujoco": "pip install 'lsindy_cas[mujoco]'",
            "distributed": "pip install 'lsindy_cas[dask]'"}


@functools.lru_cache(maxsize=None)
def _importable(name):
    try:
        importlib.import_module(name)
    except ImportError:
        return False
    return True


def pytest_configure(config):
    config.addinivalue_line("markers", "needs(package): skip unless the optional package imports")


def pytest_runtest_setup(item):
    for mark in item.iter_markers(name="needs"):
        for name in mark.args:
            if name not in OPTIONAL:
                raise ValueError(f"needs({name!r}): not an optional dependency, expected one of "
                                 f"{sorted(OPTIONAL)}")
            if not _importable(name):
                pytest.skip(f"needs {name}, an optional dependency ({OPTIONAL[name]})")


@pytest.fixture(scope="session")
def client():
    """A Dask client on a 2-worker LocalCluster, shared by the Dask tests of one test process
    (tests marked ``needs("distributed")``: skipped before this runs when it is missing)."""
    from lsindy_cas.identify.distributed import connect
    c = connect("local", n_workers=2)
    yield c
    c.close()


@pytest.fixture(scope="session")
def cart():
    return systems.cart_pendulum()


@pytest.fixture(scope="session")
def paper_setups():
    return PAPER_SETUPS


@pytest.fixture
def rng():
    return np.random.default_rng(20200101)


@pytest.fixture(scope="session")
def load_script():
    """Import a repository script (e.g. ``"mpc/swingup.py"``) that is not part of the package."""
    root = Path(__file__).resolve().parents[1]

    def load(relative):
        path = root / relative
        spec = importlib.util.spec_from_file_location(path.stem + "_script", path)
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
        return module

    return load


@pytest.fixture
def cart_model(tmp_path):
    """The cart-pendulum's true energy as a model file (actuated on x)."""
    path = tmp_path / "cart.json"
    path.write_text(json.dumps({
        "coords": ["x", "theta"], "actuated": ["x"],
        "hamiltonian_terms": {"x_dot**2": 0.55, "theta_dot**2": 0.05,
                              "theta_dot*x_dot*cos(theta)": 0.1, "cos(theta)": -0.981}}))
    return path


@pytest.fixture(autouse=True, scope="session")
def _function_cache(tmp_path_factory):
    """The CasADi Function cache (symbolic/fcache.py) in a folder of this session, not the user's
    (subprocesses of the CLI tests inherit it)."""
    import os
    old = os.environ.get("LSINDY_CACHE_DIR")
    os.environ["LSINDY_CACHE_DIR"] = str(tmp_path_factory.mktemp("fcache"))
    yield
    if old is None:
        os.environ.pop("LSINDY_CACHE_DIR", None)
    else:
        os.environ["LSINDY_CACHE_DIR"] = old


@pytest.fixture(scope="session")
def shared_mpc():
    """``shared_mpc(plant, **options)``: ``SwingUpMPC(systems.cart_pendulum(**plant), **options)``
    built once per test process and configuration (a build is ~1.3 s: NLP solvers, lookahead,
    balancers), for tests that only READ a controller's defaults (weights, nlp.max_iters,
    ocp.stage_residual, kick(), balancer, handover).  Never step, reset or modify one: a test
    that does builds its own controller."""
    from lsindy_cas.mpc import SwingUpMPC
    built = {}

    def get(plant=None, **options):
        plant = dict(plant or {})
        key = (repr(sorted(plant.items())), repr(sorted(options.items())))
        if key not in built:
            built[key] = SwingUpMPC(systems.cart_pendulum(**plant), **options)
        return built[key]

    return get


@pytest.fixture(scope="session")
def table_cell():
    """``table_cell(name, scheme)``: ``paper.table1.run_cell(name, scheme)`` computed once per
    test process (the spherical and double pendulum cells take 3-4 s each and are checked by
    several files).  The cell and its model are shared: read them, never modify or refit them."""
    from lsindy_cas.paper.table1 import run_cell
    return functools.lru_cache(maxsize=None)(run_cell)
