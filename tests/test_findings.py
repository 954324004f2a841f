"""The verdict depends on typed findings (codes), never on the wording of the messages.

Every message the diagnostics, the admissibility rules and the status write is reworded here (to
"reworded N", followed by the words the status once searched the messages for); the verdicts,
and the codes of the reasons behind them, of representative fits must not change.
"""
import ast
import itertools
import json
import pickle
import sys
from pathlib import Path

import numpy as np
import pytest

from lsindy_cas import LagrangianSINDy, Library, Trajectory, load_trajectories
from lsindy_cas.identify import findings as F
from lsindy_cas.identify import status
from lsindy_cas.identify.findings import Finding, code_of

from test_status import CART_FEATURES, CART_FILES, _spherical_passive
from test_status_noise import _sweep_cell

# the substrings status.py used to search the messages for: a reworded message containing them
# must not change anything either
DECOY = " — uniquely; work unexplained; significantly; came out zero"
OLD_SUBSTRINGS = ("uniquely", "work unexplained", "significantly", "came out zero")


def _cart_files():
    """The README's cart runs: clean, status ok."""
    lib = Library.polynomial(["x", "theta"], CART_FEATURES, 3)
    return LagrangianSINDy(lib, prior=["theta_dot**2", "cos(theta)"]).fit(
        load_trajectories(CART_FILES, ["x", "theta"]))


def _pure_noise():
    """Pure noise (test_diagnostics): undetermined; its "work unexplained" warning is dropped
    (the noise accounts for it) and other reasons decide."""
    rng = np.random.default_rng(0)
    t = np.arange(301) * 0.01
    tr = Trajectory(t, rng.standard_normal((301, 1)), rng.standard_normal((301, 1)), ["s"],
                    Q=rng.standard_normal((301, 1)))
    return LagrangianSINDy(Library.polynomial(["s"], "s,s_dot", 2)).fit(tr)


CASES = {   # name: (fit, its status)
    "cart files": (_cart_files, "ok"),
    # ok although a rejected support (not positive definite) fits 6x better in raw residual
    "spherical sigma 1e-2, rivals": (lambda: _sweep_cell("spherical", 1e-2, 0)[0], "ok"),
    "cart sigma 1e-2": (lambda: _sweep_cell("cart", 1e-2, 1)[0], "undetermined"),
    "spherical sigma 3e-2, work unexplained": (lambda: _sweep_cell("spherical", 3e-2, 0)[0],
                                               "undetermined"),
    "pure noise": (_pure_noise, "undetermined"),
    "passive spherical": (lambda: _spherical_passive(1.0, 0.3, integral=True)[0], "ok"),
}


def _verdict(model):
    d = model.diagnostics_
    return {"status": model.status_,
            "reasons": [code_of(r) for r in model.status_reasons_],
            "warnings": [code_of(w) for w in d.warnings],
            "traps": [code_of(t) for t in d.traps],
            "near_ties": [(tuple(t[0]), t[2], code_of(t[3])) for t in d.near_ties],
            "checks": sorted(d.checks)}


def _messages(model):
    d = model.diagnostics_
    return list(model.status_reasons_) + list(d.warnings) + list(d.traps) + \
        [t[3] for t in d.near_ties if t[3]]


@pytest.fixture
def reworded(monkeypatch):
    """Reword every finding: the ones made from now on, and the module-level constants."""
    count = itertools.count()
    original = Finding.__new__

    def new(cls, message, code, numbers=None):
        return original(cls, f"reworded {next(count)}{DECOY}", code, numbers)

    monkeypatch.setattr(Finding, "__new__", staticmethod(new))
    n_constants = 0
    for name, module in list(sys.modules.items()):
        if not name.startswith("lsindy_cas") or module is None:
            continue
        for attr, value in list(vars(module).items()):
            if isinstance(value, Finding):
                monkeypatch.setattr(module, attr, Finding(str(value), value.code,
                                                          dict(value.numbers)))
                n_constants += 1
    assert n_constants >= 5      # the admissibility reasons and their imports
    return count


@pytest.mark.parametrize("case", list(CASES))
def test_verdicts_do_not_depend_on_the_wording(case, request):
    fit, status_ = CASES[case]
    before = fit()
    assert before.status_ == status_
    expected = _verdict(before)
    assert all(code_of(m) in F.CODES for m in _messages(before))   # every message has a code
    request.getfixturevalue("reworded")
    after = fit()
    assert all(str(m).startswith("reworded ") for m in _messages(after))   # the rewording took
    assert _verdict(after) == expected


def test_representative_verdicts_cover_the_filters():
    """The cases above exercise what the status decides by code: a "work unexplained" warning
    the noise accounts for is dropped, and rejected runner-ups are judged as rivals or not."""
    for model in (_pure_noise(), _sweep_cell("spherical", 3e-2, 0)[0]):
        assert F.WORK_UNEXPLAINED in [code_of(w) for w in model.diagnostics_.warnings]
        assert F.WORK_UNEXPLAINED not in [code_of(r) for r in model.status_reasons_]
        assert model.status_ == "undetermined"
    cart = _sweep_cell("cart", 1e-2, 1)[0]
    codes = {code_of(t[3]) for t in cart.diagnostics_.near_ties}
    assert {F.NOT_POSITIVE_DEFINITE, F.EXCLUDED_COORDINATE} <= codes
    assert "rival_chi_ratio" in cart.diagnostics_.checks      # a rival was judged


def test_rivals_and_filters_by_code():
    """A rejection reason is a rival energy by its code alone, whatever it says."""
    for code in (F.REDUCIBLE, F.EXCLUDED_COORDINATE, F.NOT_SIGNIFICANT, F.PRIOR_ZERO,
                 F.COEFFICIENT_ZERO):
        assert not status._rival(Finding("a rival energy", code))
    for code in (F.NOT_POSITIVE_DEFINITE, F.VELOCITY_LINEAR, F.ALL_ZERO, F.NO_COEFFICIENTS):
        assert status._rival(Finding("came out zero, not significantly", code))
    assert status._rival("a user's own rule")          # a plain string: no code, a rival
    assert not status._rival("") and not status._rival(None)
    reasons = [Finding("work unexplained", F.NULL_SPACE), Finding("uniquely", F.WORK_UNEXPLAINED)]
    assert [code_of(r) for r in status._without(reasons, F.NULL_SPACE)] == [F.WORK_UNEXPLAINED]


def test_status_decides_by_code_not_by_message_text():
    """No condition in status.py tests a message for a substring."""
    src = Path(status.__file__).read_text()
    tree = ast.parse(src)
    for node in ast.walk(tree):
        if isinstance(node, ast.Compare) and any(isinstance(op, (ast.In, ast.NotIn))
                                                 for op in node.ops):
            operands = [node.left] + node.comparators
            assert not any(isinstance(o, ast.Constant) and isinstance(o.value, str)
                           for o in operands), ast.unparse(node)
    docstrings = {id(n.body[0].value) for n in ast.walk(tree)
                  if isinstance(n, (ast.Module, ast.FunctionDef, ast.ClassDef)) and n.body
                  and isinstance(n.body[0], ast.Expr) and isinstance(n.body[0].value, ast.Constant)}
    constants = [n.value for n in ast.walk(tree) if isinstance(n, ast.Constant)
                 and isinstance(n.value, str) and id(n) not in docstrings]
    for old in OLD_SUBSTRINGS:
        assert not any(old in c for c in constants), old
    for pattern in ('" in w', '" not in w', "not in reason", '" in reason'):
        assert pattern not in src, pattern
    assert "REDUCIBLE_REASON" not in src and "EXCLUDED_REASON" not in src


def test_finding_is_its_message():
    f = Finding("the data cannot identify the energy", F.NULL_SPACE, {"extra": 2})
    assert f == "the data cannot identify the energy" and str(f) == f.message == f
    assert f.code == "null_space" and f.numbers["extra"] == 2
    assert "identify" in f and json.dumps([f]) == '["the data cannot identify the energy"]'
    back = pickle.loads(pickle.dumps(f))
    assert back == f and back.code == f.code and dict(back.numbers) == {"extra": 2}
    with pytest.raises(AttributeError):
        f.code = "other"
    with pytest.raises(TypeError):
        f.numbers["extra"] = 3
    with pytest.raises(ValueError, match="unknown finding code"):
        Finding("x", "no_such_code")
    assert code_of("plain") is None


def test_model_file_records_the_codes_and_old_files_load(tmp_path):
    model = _pure_noise()
    assert model.status_ == "undetermined" and model.status_reasons_
    path = model.save(tmp_path / "m.json")
    d = json.loads(path.read_text())
    assert d["status"]["reasons"] == model.status_reasons_
    assert d["status"]["codes"] == [r.code for r in model.status_reasons_]
    back = LagrangianSINDy.load(path)
    assert back.status_reasons_ == model.status_reasons_
    assert [code_of(r) for r in back.status_reasons_] == d["status"]["codes"]
    del d["status"]["codes"]                    # a file from before the codes
    path.write_text(json.dumps(d))
    old = LagrangianSINDy.load(path)
    assert old.status_ == model.status_ and old.status_reasons_ == model.status_reasons_
    assert all(code_of(r) is None for r in old.status_reasons_)
