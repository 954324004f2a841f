"""The disk cache of a library's CasADi Functions (symbolic/fcache.py): same numbers, never breaks."""
import json

import numpy as np
import pytest

from lsindy_cas.symbolic import fcache
from lsindy_cas.symbolic.library import Library

FEATURES = "cos(theta),sin(theta),theta_dot,phi,phi_dot"


def _values(lib):
    rng = np.random.default_rng(7)
    X, Xd = rng.standard_normal((40, 4)), rng.standard_normal((40, 4))
    return [lib.theta(X), lib.gamma(X, Xd), lib.grad(X), lib.dtheta_dqd(X), lib.d2theta_dqd2(X)]


def _fresh():
    return Library.polynomial(["theta", "phi"], FEATURES, 2)


@pytest.fixture
def cache(tmp_path, monkeypatch):
    monkeypatch.setenv("LSINDY_CACHE_DIR", str(tmp_path / "cache"))
    return tmp_path / "cache"


def _same(a, b):
    # the cached Functions are CasADi's own serialisation of the built ones: bit for bit
    return all(np.array_equal(x, y) for x, y in zip(a, b))


def test_second_library_loads_the_same_functions(cache, monkeypatch):
    ref = _values(_fresh())
    files = list(cache.glob("library-*.json"))
    assert len(files) == 1
    monkeypatch.setattr(Library, "_build_functions",
                        lambda self: pytest.fail("built again instead of loaded"))
    assert _same(_values(_fresh()), ref)


def test_other_terms_other_file(cache):
    _values(_fresh())
    _values(Library.polynomial(["theta", "phi"], FEATURES, 1))
    assert len(list(cache.glob("library-*.json"))) == 2


@pytest.mark.parametrize("damage", ["garbage", "truncated", "wrong key", "bad function"])
def test_damaged_file_is_rebuilt(cache, damage):
    ref = _values(_fresh())
    (path,) = cache.glob("library-*.json")
    text = path.read_text()
    data = json.loads(text)
    if damage == "garbage":
        path.write_text("not json")
    elif damage == "truncated":
        path.write_text(text[:len(text) // 2])
    elif damage == "wrong key":
        data["key"] = "0" * 64
        path.write_text(json.dumps(data))
    else:
        data["functions"]["grad"] = data["functions"]["theta"]     # wrong shapes
        path.write_text(json.dumps(data))
    assert _same(_values(_fresh()), ref)
    rewritten = json.loads(path.read_text())          # and the file is good again
    assert rewritten["key"] != "0" * 64
    assert rewritten["functions"]["grad"] != rewritten["functions"]["theta"]


def test_unwritable_cache_never_breaks_a_run(tmp_path, monkeypatch):
    blocker = tmp_path / "a_file"
    blocker.write_text("")
    monkeypatch.setenv("LSINDY_CACHE_DIR", str(blocker / "cache"))    # cannot be created
    with monkeypatch.context() as m:
        m.setenv("LSINDY_CACHE_DIR", "off")
        ref = _values(_fresh())
    assert _same(_values(_fresh()), ref)
    assert blocker.read_text() == ""


def test_switched_off(tmp_path, monkeypatch):
    monkeypatch.setenv("LSINDY_CACHE_DIR", "off")
    assert fcache.cache_dir() is None
    _values(_fresh())
    monkeypatch.delenv("LSINDY_CACHE_DIR")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    assert fcache.cache_dir() == tmp_path / "lsindy_cas"


def test_polynomial_library_from_cached_names(cache, monkeypatch):
    built = Library.polynomial(["theta", "phi"], FEATURES, 3)
    assert len(list(cache.glob("polynomial-*.json"))) == 1
    monkeypatch.setattr("sympy.Mul", lambda *a: pytest.fail("products formed again"))
    lib = Library.polynomial(["theta", "phi"], FEATURES, 3)
    assert lib.names == built.names and lib.spec == built.spec and len(lib) == len(built)
    monkeypatch.undo()
    # each term parses from its name to the same sympy expression (checked before caching)
    assert list(lib.exprs) == list(built.exprs)
    assert lib.index("theta_dot**2") == built.index("theta_dot**2")
    assert lib.index("theta_dot*theta_dot") == built.index("theta_dot**2")
    np.testing.assert_array_equal(lib.coefficients("2*cos(theta) + phi_dot**2*sin(theta)"),
                                  built.coefficients("2*cos(theta) + phi_dot**2*sin(theta)"))
    assert [lib.velocity_degree(j) for j in range(len(lib))] == \
        [built.velocity_degree(j) for j in range(len(built))]
    extra = Library(["theta", "phi"], ["theta**5"])
    assert (lib + extra).names == (built + extra).names
    assert _same(_values(lib), _values(built))
    with pytest.raises(ValueError, match="not in the library"):
        lib.index("theta**7")


def test_polynomial_damaged_record_is_rebuilt(cache):
    built = Library.polynomial(["theta", "phi"], FEATURES, 2)
    (path,) = cache.glob("polynomial-*.json")
    data = json.loads(path.read_text())
    data["names"] = data["names"][:3] + [7]
    path.write_text(json.dumps(data))
    assert Library.polynomial(["theta", "phi"], FEATURES, 2).names == built.names
    with pytest.raises(ValueError, match="feature"):      # bad input is still checked
        Library.polynomial(["theta", "phi"], "cos(theta),foo", 2)


def test_cached_library_index_parses_only_the_term(cache, monkeypatch):
    Library.polynomial(["theta", "phi"], FEATURES, 3)
    lib = Library.polynomial(["theta", "phi"], FEATURES, 3)
    parsed = []
    original = type(lib.coords).parse
    monkeypatch.setattr(type(lib.coords), "parse",
                        lambda self, t, **kw: parsed.append(t) or original(self, t, **kw))
    assert lib.names[lib.index("phi")] == "phi"
    assert lib.names[lib.index("cos(theta)*theta_dot")] == "theta_dot*cos(theta)"
    # "phi" is a term's own name: found without parsing; the other query and the term found
    assert parsed == ["cos(theta)*theta_dot", "theta_dot*cos(theta)"]
