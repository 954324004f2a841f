"""The printout and model file assembled from per-term templates (symbolic/template.py) equal the
sympy derivation as expressions, and a warm `lsindy identify` never imports sympy."""
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import sympy as sp

from lsindy_cas import LagrangianSINDy, Library, systems
from lsindy_cas.mechanics.euler_lagrange import EulerLagrange
from lsindy_cas.paper.table1 import PAPER_SETUPS
from lsindy_cas.symbolic.template import format_float, text

SRC = Path(__file__).resolve().parents[1] / "src"
# The strings carry 15 significant digits (as the sympy Floats of the model file did) and both
# sides are sums of the same double products, so they agree to round-off: 1e-12 relative.
RTOL = 1e-12


def _parse(s, names):
    syms = {n: sp.Symbol(n, real=True) for n in names}
    return sp.sympify(s, locals=syms)


def _names(coords):
    return [p + c + s for c in coords for p, s in (("", ""), ("", "_dot"), ("", "_ddot"),
                                                   ("Q_", ""))]


def _same(a, b, names):
    """a and b (strings or sympy) equal as expressions: every coefficient of a - b, expanded,
    within RTOL of the largest coefficient of b."""
    a = _parse(a, names) if isinstance(a, str) else a
    b = _parse(b, names) if isinstance(b, str) else b
    ref = sp.expand(b).as_coefficients_dict()
    scale = max([abs(float(c)) for c in ref.values()] + [1.0])
    diff = sp.expand(a - b).as_coefficients_dict()
    return all(abs(float(c)) <= RTOL * scale for c in diff.values())


def _model(system, setup=None, features=None, degree=None, dissipation=None, rho=None):
    """A LagrangianSINDy whose coefficients are the system's true energy in the setup's library
    (no fit: the expressions are what is tested)."""
    setup = setup and PAPER_SETUPS[setup]
    lib = Library.polynomial(system.coords, features or setup.features, degree or setup.degree)
    model = LagrangianSINDy(lib, dissipation=dissipation)
    model._validate()
    model._set_coefficients(lib.coefficients(system.hamiltonian), rayleigh=rho)
    return model


def _check(model):
    names = _names(model.coords_)
    t = model.texts(15)
    assert _same(t["hamiltonian"], model.hamiltonian_, names)
    assert _same(t["lagrangian"], model.lagrangian_, names)
    eqs = model.equations_of_motion()
    assert len(t["equations"]) == len(eqs)
    for (lhs, rhs), e in zip(t["equations"], eqs):
        assert _same(lhs, e.lhs, names) and _same(rhs, e.rhs, names)
        assert "_ddot" in lhs and "_ddot" not in rhs
    if t["rayleigh"] is not None:
        assert _same(t["rayleigh"], model.rayleigh_, names)
    # the model file's strings are the same ones
    d = model.to_dict()
    assert d["hamiltonian"] == t["hamiltonian"]
    assert d["equations_of_motion"] == [f"{a} = {b}" for a, b in t["equations"]]


@pytest.mark.parametrize("name", ["spherical", "cart", "double"])
def test_paper_systems_equal_sympy(name):
    system = {"spherical": systems.spherical_pendulum, "cart": systems.cart_pendulum,
              "double": systems.double_pendulum}[name]()
    _check(_model(system, name))


def test_friction_model_equals_sympy():
    cart = systems.cart_pendulum()
    model = _model(cart, "cart", dissipation=["x_dot**2", "Abs(x_dot)", "theta_dot**2"],
                   rho=np.array([0.3, 0.05, 0.0]))
    assert model.has_friction_
    t = model.texts(15)
    assert "sign(x_dot)" in t["equations"][0][1]        # the Coulomb force, exact sign
    _check(model)


def test_fitted_prior_model_equals_sympy():
    sph = systems.spherical_pendulum()
    lib = Library.polynomial(sph.coords, PAPER_SETUPS["spherical"].features, 4)
    model = LagrangianSINDy(lib, n_terms=3, prior=["theta_dot**2", "cos(theta)"])
    model.fit([sph.simulate(t_end=1.0, u=1.0)])
    assert sorted(model.terms()) == ["cos(theta)", "phi_dot**2*sin(theta)**2", "theta_dot**2"]
    _check(model)


def test_ode_equals_the_sympy_route():
    model = _model(systems.double_pendulum(), "double")
    ref = EulerLagrange(model.library.coords, model.lagrangian_).ode()
    ode = model.ode()
    rng = np.random.default_rng(3)
    for _ in range(20):
        x, u = rng.uniform(-2, 2, 4), rng.uniform(-1, 1, 2)
        a, b = np.asarray(ode(x, u)).ravel(), np.asarray(ref(x, u)).ravel()
        # the same formula on the same doubles, two SX graphs: round-off apart
        np.testing.assert_allclose(a, b, rtol=1e-10, atol=1e-12)


def test_rounded_printout_merges_monomials():
    model = _model(systems.spherical_pendulum(), "spherical")
    out = str(model)
    assert "H = 0.5*phi_dot**2*sin(theta)**2 + 0.5*theta_dot**2 + 9.81*cos(theta)" in out
    assert "1.0*phi_ddot*sin(theta)**2 = Q_phi - 2.0*phi_dot*theta_dot*sin(theta)*cos(theta)" in out


@pytest.mark.parametrize("name", ["spherical", "cart", "double"])
def test_sums_print_as_sympy_prints_them(name):
    """Same string as sympy's, term order included, for random 4-term sums of the library."""
    setup = PAPER_SETUPS[name]
    coords = {"spherical": ["theta", "phi"], "cart": ["x", "theta"],
              "double": ["theta1", "theta2"]}[name]
    lib = Library.polynomial(coords, setup.features, setup.degree)
    rng = np.random.default_rng(5)
    for _ in range(40):
        S = rng.choice(len(lib), 4, replace=False)
        coef = np.zeros(len(lib))
        coef[S] = rng.standard_normal(4)
        ref = str(sp.Add(*[sp.Float(coef[j], 15) * lib.exprs[j] for j in S]))
        assert text(lib.template.combine(coef), 15) == ref


@pytest.mark.parametrize("x", [0.5, 1.0, -9.81, 1e-5, 1.5e-5, 123456789012345.0, 1e15, 2.5e16,
                               -3.0000000000000004, 0.1 + 0.2, 7.123456789012345e-9])
def test_format_float_as_sympy(x):
    assert format_float(x, 15) == str(sp.Float(x, 15) * sp.Symbol("y")).split("*")[0]


def test_text_signs_and_constants():
    assert text({"x": -1.0, "1": 2.5, "y": 0.0}, 15) == "-1.0*x + 2.5"
    assert text({"x": -1.0}, 15, lead="Q_x") == "Q_x - 1.0*x"
    assert text({}, 15) == "0"


def test_rows_cached_for_the_model_terms_only_and_rebuilt_when_damaged(tmp_path, monkeypatch):
    monkeypatch.setenv("LSINDY_CACHE_DIR", str(tmp_path / "cache"))
    model = _model(systems.spherical_pendulum(), "spherical")
    first = model.texts(15)
    (rows,) = (tmp_path / "cache").glob("rows-*.json")
    assert sorted(json.loads(rows.read_text())["terms"]) == sorted(model.terms())
    rows.write_text(rows.read_text()[:40])                    # a truncated record: a miss
    again = _model(systems.spherical_pendulum(), "spherical")
    assert again.texts(15) == first


def test_model_file_loads_without_sympy_when_warm(tmp_path):
    """A saved model is read back (library from the cache, coefficients by name, mass-matrix
    check in CasADi) in a process that never imports sympy."""
    env = dict(os.environ, LSINDY_CACHE_DIR=str(tmp_path / "cache"),
               PYTHONPATH=os.pathsep.join([str(SRC), os.environ.get("PYTHONPATH", "")]))
    code = ("import sys; from lsindy_cas import LagrangianSINDy; "
            "m = LagrangianSINDy.load(sys.argv[1]); print(m.texts(15)['hamiltonian']); "
            "print('sympy' in sys.modules)")
    model = _model(systems.cart_pendulum(), "cart")
    path = model.save(tmp_path / "m.json")
    out = [subprocess.run([sys.executable, "-c", code, str(path)], capture_output=True,
                          text=True, env=env, check=True).stdout.split("\n") for _ in range(2)]
    assert out[0][0] == out[1][0] == model.texts(15)["hamiltonian"]
    assert out[1][1] == "False"                       # the second process: cache warm


def _identify(tmp, csv, out, cache):
    """`lsindy identify` in a child Python (cli.main in process); returns whether sympy was
    imported by the end of the run."""
    code = ("import sys; from lsindy_cas.cli import main; "
            "rc = main(sys.argv[1:]); print('SYMPY', 'sympy' in sys.modules); sys.exit(rc)")
    env = dict(os.environ, LSINDY_CACHE_DIR=str(cache), OPENBLAS_NUM_THREADS="1",
               PYTHONPATH=os.pathsep.join([str(SRC), os.environ.get("PYTHONPATH", "")]))
    r = subprocess.run([sys.executable, "-c", code, "identify", str(csv), "--coords", "theta,phi",
                        "--features", "cos(theta),sin(theta),theta_dot,phi,phi_dot",
                        "--degree", "4", "--terms", "3", "--json", str(out)],
                       capture_output=True, text=True, env=env, cwd=tmp)
    assert r.returncode == 0, r.stderr
    return r.stdout.strip().splitlines()[-1] == "SYMPY True"


def test_warm_identify_does_not_import_sympy(tmp_path):
    from lsindy_cas.data.trajectory import Trajectory
    tr = systems.spherical_pendulum().simulate(t_end=1.0, u=1.0)
    csv = Trajectory(tr.t, tr.q, tr.qd, tr.coords, Q=tr.Q).save(tmp_path / "run.csv")  # no q̈
    cache = tmp_path / "cache"
    assert _identify(tmp_path, csv, tmp_path / "cold.json", cache)      # builds with sympy
    assert not _identify(tmp_path, csv, tmp_path / "warm.json", cache)  # reads the cache
    cold, warm = (json.loads((tmp_path / f).read_text()) for f in ("cold.json", "warm.json"))
    names = _names(cold["coords"])
    for key in ("hamiltonian", "lagrangian"):
        assert _same(warm[key], cold[key], names)
    for a, b in zip(warm["equations_of_motion"], cold["equations_of_motion"]):
        (al, ar), (bl, br) = a.split(" = "), b.split(" = ")
        assert _same(al, bl, names) and _same(ar, br, names)
    assert warm["hamiltonian_terms"] == cold["hamiltonian_terms"]
    assert LagrangianSINDy.load(tmp_path / "warm.json").terms() == cold["hamiltonian_terms"]


def test_cache_key_reads_sympy_version_without_importing_it(monkeypatch):
    from lsindy_cas.symbolic import fcache
    monkeypatch.delitem(sys.modules, "sympy")          # as in a process that never imported it
    assert fcache.sympy_version.__wrapped__() == sp.__version__   # from sympy/release.py
    assert "sympy" not in sys.modules
