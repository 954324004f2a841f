"""``lsindy export``: the generated C agrees with the Python model to round-off."""
import ctypes
import json
import shutil
import subprocess

import numpy as np
import pytest

from lsindy_cas import LagrangianSINDy
from lsindy_cas.cli import main
from lsindy_cas.control.ocp import rk4_step

pytestmark = pytest.mark.skipif(shutil.which("gcc") is None, reason="needs the system C compiler")



def _load(folder, name):
    lib = folder / f"lib{name}.so"
    subprocess.run(["gcc", "-O2", "-shared", "-fPIC", str(folder / f"{name}.c"), "-o", str(lib),
                    "-lm"], check=True, capture_output=True)
    return ctypes.CDLL(str(lib))


def _call(clib, fname, x, u):
    f = getattr(clib, fname)
    dbl = ctypes.POINTER(ctypes.c_double)
    xa, ua = (ctypes.c_double * len(x))(*x), (ctypes.c_double * len(u))(*u)
    out = (ctypes.c_double * len(x))()
    arg = (dbl * 2)(ctypes.cast(xa, dbl), ctypes.cast(ua, dbl))
    res = (dbl * 1)(ctypes.cast(out, dbl))
    iw = (ctypes.c_longlong * 64)()
    w = (ctypes.c_double * 4096)()
    f.restype = ctypes.c_int
    assert f(arg, res, iw, w, 0) == 0
    return np.array(out[:])


def test_generated_c_matches_python(cart_model, tmp_path):
    out = tmp_path / "c"
    out.mkdir()
    assert main(["export", str(cart_model), "--c", str(out), "--dt", "0.05", "--substeps", "2",
                 "--name", "cart"]) == 0
    assert {p.name for p in out.iterdir()} == {"cart.c", "cart.h", "README.md"}
    clib = _load(out, "cart")
    model = LagrangianSINDy.load(cart_model)
    ode = model.ode()
    step = rk4_step(ode, 4, 2, 0.05, 2)
    rng = np.random.default_rng(7)
    for _ in range(20):
        x = rng.uniform(-3, 3, 4)
        u = rng.uniform(-10, 10, 2)
        # the same expression graph compiled by gcc instead of evaluated by CasADi's VM:
        # differences are a few ulps of the largest intermediate
        np.testing.assert_allclose(_call(clib, "cart_ode", x, u), np.asarray(ode(x, u)).ravel(),
                                   rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(_call(clib, "cart_step", x, u), np.asarray(step(x, u)).ravel(),
                                   rtol=1e-12, atol=1e-12)


def test_export_bad_input(cart_model, tmp_path, capsys):
    assert main(["export", str(cart_model), "--c", str(tmp_path / "missing")]) == 2
    assert "no such directory" in capsys.readouterr().err
    assert main(["export", str(cart_model), "--c", str(tmp_path), "--dt", "0"]) == 2
    assert "--dt" in capsys.readouterr().err
    empty = tmp_path / "empty.json"
    empty.write_text(json.dumps({"coords": ["x"]}))
    assert main(["export", str(empty), "--c", str(tmp_path)]) == 2
    assert "lacks hamiltonian_terms" in capsys.readouterr().err
    assert main(["export", str(cart_model), "--c", str(tmp_path), "--name", "a-b"]) == 2
    assert "C identifier" in capsys.readouterr().err
