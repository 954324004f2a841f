"""The shared argument checks of ``lsindy_cas._validate``."""
import types

import pytest

from lsindy_cas import systems
from lsindy_cas._validate import (check_bool, check_choice, check_int, check_real,
                                  relative_energy)


def test_relative_energy_reads_the_models_scale_record():
    assert relative_energy(types.SimpleNamespace(energy_scale_="relative"))
    assert not relative_energy(types.SimpleNamespace(energy_scale_="absolute"))
    # a system (exact equations) and an older model without the attribute are absolute
    assert not relative_energy(systems.cart_pendulum())
    assert not relative_energy(object())


def test_checks_name_the_argument_and_convert():
    assert check_int("n", 3, low=1) == 3 and isinstance(check_real("dt", 1, positive=True), float)
    with pytest.raises(TypeError, match="n must be an integer"):
        check_int("n", True)
    with pytest.raises(ValueError, match="dt"):
        check_real("dt", 0.0, positive=True)
    with pytest.raises(ValueError, match="mode must be one of"):
        check_choice("mode", "x", ("a", "b"))
    assert check_bool("jit", False) is False
    with pytest.raises(TypeError, match="jit must be True or False, got 1"):
        check_bool("jit", 1)
