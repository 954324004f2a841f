import numpy as np
import pytest

from lsindy_cas import systems
from lsindy_cas.reproduce import PAPER_SETUPS


@pytest.fixture(scope="session")
def cart():
    return systems.cart_pendulum()


@pytest.fixture(scope="session")
def paper_setups():
    return PAPER_SETUPS


@pytest.fixture
def rng():
    return np.random.default_rng(20200101)
