"""``lsindy export``: the generated C agrees with the Python model to round-off."""
import ctypes
import json
import os
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


def test_friction_and_relative_models_export(tmp_path, capsys):
    """A model with viscous and Coulomb friction, energy relative (passive data): the C code carries
    the friction forces (Coulomb as the ODE's tanh) and matches the Python ODE."""
    path = tmp_path / "fric.json"
    path.write_text(json.dumps({
        "coords": ["x", "theta"], "actuated": ["x"], "energy_scale": "relative",
        "normalised_by": "theta_dot**2",
        "hamiltonian_terms": {"x_dot**2": 11.0, "theta_dot**2": 1.0,
                              "theta_dot*x_dot*cos(theta)": 2.0, "cos(theta)": -19.62},
        "rayleigh_terms": {"x_dot**2": 3.0, "theta_dot**2": 0.1, "Abs(x_dot)": 4.0}}))
    model = LagrangianSINDy.load(path)
    out = tmp_path / "c"
    out.mkdir()
    assert main(["export", str(path), "--c", str(out), "--name", "fric"]) == 0
    # the relative scale is stated: the response to u is up to a factor
    assert "energy is relative" in capsys.readouterr().err
    readme = (out / "README.md").read_text()
    assert "Energy relative" in readme and "`theta_dot**2`" in readme
    clib = _load(out, "fric")
    ode = model.ode()
    rng = np.random.default_rng(3)
    xs = rng.uniform(-2, 2, (20, 4))
    xs[:3, 2] = [0.0, 1e-3, -5e-3]          # cart velocities where the smooth sign bends
    for x in xs:
        u = rng.uniform(-10, 10, 2)
        want = np.asarray(ode(x, u)).ravel()
        np.testing.assert_allclose(_call(clib, "fric_ode", x, u), want, rtol=1e-12, atol=1e-12)
    # the friction is really in there: the same state without it accelerates differently
    frictionless = LagrangianSINDy.load(path)
    d = json.loads(path.read_text())
    del d["rayleigh_terms"]
    path.write_text(json.dumps(d))
    frictionless = LagrangianSINDy.load(path)
    x = np.array([0.0, 0.5, 0.7, -0.3])
    assert not np.allclose(np.asarray(frictionless.ode()(x, [0, 0])).ravel(),
                           _call(clib, "fric_ode", x, np.zeros(2)))


def test_export_refuses_unwritable_or_file_target(cart_model, tmp_path, capsys):
    target = tmp_path / "not_a_dir"
    target.write_text("x")
    assert main(["export", str(cart_model), "--c", str(target)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err
    locked = tmp_path / "locked"
    locked.mkdir(mode=0o500)
    if os.access(locked, os.W_OK):          # root ignores the mode bits: a read-only file system
        locked = "/sys"
        if not os.path.isdir(locked):
            pytest.skip("running as root without a read-only file system to write into")
    assert main(["export", str(cart_model), "--c", str(locked)]) == 2
    err = capsys.readouterr().err
    assert "not writable" in err and err.count("\n") == 1


def test_absolute_model_readme_has_no_relative_note(cart_model, tmp_path, capsys):
    assert main(["export", str(cart_model), "--c", str(tmp_path)]) == 0
    assert "relative" not in (tmp_path / "README.md").read_text()
    assert "relative" not in capsys.readouterr().err
