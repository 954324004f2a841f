import importlib.util
from pathlib import Path

import numpy as np
import pytest

from lsindy_cas import systems
from lsindy_cas.paper.table1 import PAPER_SETUPS


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
