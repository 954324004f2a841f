"""``--candidates``: an explicit candidate list in place of --features/--degree (identify, library)."""
import json
from pathlib import Path

import pytest

from lsindy_cas.cli import main

DATA = Path(__file__).resolve().parents[1] / "examples" / "data"
CART = [str(DATA / "cart_run1.csv"), str(DATA / "cart_run2.csv")]
TERMS = ("x_dot**2,theta_dot**2,theta_dot*x_dot*cos(theta),cos(theta),sin(theta),"
         "x_dot*theta_dot*sin(theta),x_dot**2*cos(theta)")


def test_identify_with_explicit_candidates_finds_the_cart_energy(tmp_path, capsys):
    out = tmp_path / "m.json"
    code = main(["identify", *CART, "--coords", "x,theta", "--candidates", TERMS,
                 "--prior", "theta_dot**2,cos(theta)", "--json", str(out)])
    assert code == 0
    d = json.loads(out.read_text())
    # mc = 1, mp = 0.1, L = 1, g = 9.81: H = 0.55 ẋ² + 0.05 θ̇² + 0.1 ẋθ̇ cos θ − 0.981 cos θ
    truth = {"x_dot**2": 0.55, "theta_dot**2": 0.05, "theta_dot*x_dot*cos(theta)": 0.1,
             "cos(theta)": -0.981}
    assert set(d["hamiltonian_terms"]) == set(truth)
    for k, v in truth.items():      # clean simulated data: the fit is exact to ~1e-14
        assert d["hamiltonian_terms"][k] == pytest.approx(v, rel=1e-9)
    assert d["status"]["status"] == "ok"


def test_library_lists_explicit_candidates(capsys):
    assert main(["library", "--coords", "theta1,theta2", "--candidates",
                 "theta1_dot**2,theta1_dot*theta2_dot*cos(theta1 - theta2),cos(theta1)"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[1].split(maxsplit=1)[1] == "theta1_dot*theta2_dot*cos(theta1 - theta2)"
    assert out[-1] == "3 terms (2 coordinates, explicit candidates)"


@pytest.mark.parametrize("args, says", [
    (["--candidates", "theta_dot**2,foo(theta)"], "unsupported function"),
    (["--candidates", "theta_dot**2,,cos(theta)"], "term #2 is empty"),
    (["--candidates", "theta_dot**2,cos(phi)"], "unknown name"),
    (["--candidates", "theta_dot**2", "--degree", "3"], "not both"),
    (["--candidates", "theta_dot**2", "--features", "cos(theta)"], "not both"),
    ([], "--features"),
])
def test_bad_candidates_are_one_line_exit_2(args, says, capsys):
    assert main(["library", "--coords", "theta", *args]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and says in err[0]
