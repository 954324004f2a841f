"""`lsindy identify` end to end on systems that are not in the paper, and its bad-input contract."""
import json
import subprocess
import sys

import numpy as np
import pytest

from lsindy_cas import LagrangianSINDy, Trajectory, systems
from lsindy_cas.cli import main


def run_cli(*args):
    """Run the real console entry point in a subprocess (what a user sees)."""
    return subprocess.run([sys.executable, "-m", "lsindy_cas.cli", *map(str, args)],
                          capture_output=True, text=True, timeout=300)


def test_identify_mass_spring_from_csv(tmp_path):
    """Not in the paper: m = 2, k = 5 oscillator, coordinate 's', varied input, CSV files."""
    s = systems.mass_spring(m=2.0, k=5.0, name="s")
    files = []
    for i, u in enumerate([lambda t, x: np.sin(3 * t), lambda t, x: 1.0 - t]):
        tr = s.simulate(x0=(0.3 * i, 0.1), t_end=2.0, u=u)
        files.append(tr.save(tmp_path / f"run{i}.csv"))
    out = tmp_path / "model.json"
    r = run_cli("identify", *files, "--coords", "s", "--features", "s,s_dot,cos(s)", "--degree", "2",
                "--terms", "2", "--json", out)
    assert r.returncode == 0, r.stderr
    d = json.loads(out.read_text())
    assert set(d["hamiltonian_terms"]) == {"s**2", "s_dot**2"}
    # CSV carries no accelerations -> integral form; quadrature error ~1e-6 at 100 Hz
    assert d["hamiltonian_terms"]["s_dot**2"] == pytest.approx(1.0, rel=1e-4)
    assert d["hamiltonian_terms"]["s**2"] == pytest.approx(2.5, rel=1e-4)
    assert d["lagrangian_terms"]["s**2"] == pytest.approx(-2.5, rel=1e-4)
    model = LagrangianSINDy.load(out)
    xdot = np.asarray(model.ode()([0.4, 0.0], [1.0])).ravel()
    assert xdot[1] == pytest.approx((1.0 - 5.0 * 0.4) / 2.0, rel=1e-3)   # s̈ = (u − k s)/m


def test_identify_pendulum_other_parameters_and_names(tmp_path):
    """A cart-pendulum with other masses/length and coordinate names, with exact accelerations."""
    s = systems.cart_pendulum(mc=2.0, mp=0.3, L=0.5, names=("pos", "ang"))
    files = [s.simulate(x0=(0, 1.0, 0, 0), t_end=1.5, u=lambda t, x: 2 * np.sign(np.sin(4 * t)))
             .save(tmp_path / "a.npz")]
    out = tmp_path / "m.json"
    r = run_cli("identify", *files, "--coords", "pos,ang", "--features",
                "cos(ang),sin(ang),ang_dot,pos,pos_dot", "--degree", "3", "--terms", "4",
                "--prior", "ang_dot**2,cos(ang)", "--json", out)
    assert r.returncode == 0, r.stderr
    terms = json.loads(out.read_text())["hamiltonian_terms"]
    expected = {"pos_dot**2": 1.15, "ang_dot**2": 0.0375, "ang_dot*pos_dot*cos(ang)": 0.15,
                "cos(ang)": -0.3 * 9.81 * 0.5}
    assert set(terms) == set(expected)
    for k, v in expected.items():
        assert terms[k] == pytest.approx(v, rel=1e-6)


@pytest.fixture
def good_csv(tmp_path):
    return systems.cart_pendulum().simulate(t_end=1.0, u=1.0).save(tmp_path / "good.csv")


def _write(path, header, rows):
    path.write_text(header + "\n" + "\n".join(",".join(map(str, r)) for r in rows) + "\n")
    return path


BASE = ["--coords", "x,theta", "--features", "cos(theta),sin(theta),theta_dot,x,x_dot", "--degree", "3"]


@pytest.mark.parametrize("case, extra, needle", [
    ("missing file", ["nope.csv", *BASE, "--terms", "4"], "no such file"),
    ("unknown coordinate", ["GOOD", "--coords", "x,theta", "--features", "cos(phi)", "--terms", "1"], "unknown name"),
    ("unparsable", ["GOOD", "--coords", "x,theta", "--features", "cos(theta", "--terms", "1"], "cannot parse"),
    ("prior not in library", ["GOOD", *BASE, "--terms", "4", "--prior", "theta_dot**5"], "not in the library"),
    ("k too large", ["GOOD", *BASE, "--terms", "999"], "library size"),
    ("bad terms", ["GOOD", *BASE, "--terms", "four"], "invalid int"),
    ("missing coords", ["GOOD", "--features", "x"], "required"),
    ("time limit zero", ["GOOD", *BASE, "--terms", "4", "--time-limit", "0"], "--time-limit must be positive"),
    ("time limit negative", ["GOOD", *BASE, "--time-limit", "-5"], "--time-limit must be positive"),
    ("time limit nan", ["GOOD", *BASE, "--time-limit", "nan"], "--time-limit must be positive"),
    ("time limit text", ["GOOD", *BASE, "--time-limit", "soon"], "invalid float"),
])
def test_cli_bad_input_one_line_exit_2(good_csv, case, extra, needle):
    args = [str(good_csv) if a == "GOOD" else a for a in extra]
    r = run_cli("identify", *args)
    assert r.returncode == 2, case
    assert needle in r.stderr, r.stderr
    assert len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert "Traceback" not in r.stderr


@pytest.mark.parametrize("case, header, rows, needle", [
    ("nan", "t,x,theta,x_dot,theta_dot", [[i * 0.01, 0, 1, 0, np.nan if i == 3 else 0] for i in range(10)], "NaN"),
    ("inf", "t,x,theta,x_dot,theta_dot", [[i * 0.01, 0, np.inf, 0, 0] for i in range(10)], "NaN or inf"),
    ("non-increasing t", "t,x,theta,x_dot,theta_dot", [[0.01 * (i % 5), 0, 1, 0, 0] for i in range(10)], "strictly increasing"),
    ("too few samples", "t,x,theta,x_dot,theta_dot", [[i * 0.01, 0, 1, 0, 0] for i in range(3)], "too few samples"),
    ("mismatched lengths", "t,x,theta,x_dot,theta_dot", [[0.0, 0, 1, 0, 0], [0.01, 0, 1, 0]], "columns"),
    ("missing column", "t,x,theta,x_dot", [[i * 0.01, 0, 1, 0] for i in range(10)], "theta_dot"),
])
def test_cli_bad_files(tmp_path, capsys, case, header, rows, needle):
    path = _write(tmp_path / "bad.csv", header, rows)
    code = main(["identify", str(path), *BASE, "--terms", "4"])
    err = capsys.readouterr().err
    assert code == 2, case
    assert needle in err, err
    assert len(err.strip().splitlines()) == 1


def test_trajectory_roundtrip_csv_npz(tmp_path):
    tr = systems.double_pendulum().simulate(t_end=0.2, u=1.0)
    for ext in ("csv", "npz"):      # exact: npz is binary, the CSV is written with %.17g
        back = Trajectory.load(tr.save(tmp_path / f"d.{ext}"), ["theta1", "theta2"])
        np.testing.assert_array_equal(back.X, tr.X)
        np.testing.assert_array_equal(back.Q, tr.Q)
        np.testing.assert_array_equal(back.qdd, tr.qdd)


def test_trajectory_validation():
    t = np.arange(10) * 0.1
    with pytest.raises(ValueError, match="shape"):
        Trajectory(t, np.zeros((9, 1)), np.zeros((10, 1)), ["q"])
    with pytest.raises(TypeError, match="numeric"):
        Trajectory(t, [["a"]] * 10, np.zeros((10, 1)), ["q"])
    with pytest.raises(ValueError, match="do not match"):
        Trajectory(t, np.zeros((10, 1)), np.zeros((10, 1)), ["q"]).reorder(["r"])


@pytest.mark.parametrize("seed, written", [(0, True), (1, False)])
def test_cli_pure_noise_exits_3_whether_or_not_a_model_passes(tmp_path, seed, written):
    """Pure noise: for seed 0 a model passes the rules but is judged undetermined (printout and
    file written); for seed 1 no admissible model exists at all.  Both are data that do not
    determine the energy, not bad options: exit 3 with one line on stderr either way (the
    second used to exit 2, as if the options were unusable)."""
    rng = np.random.default_rng(seed)
    t = np.arange(301) * 0.01
    tr = Trajectory(t, rng.standard_normal((301, 1)), rng.standard_normal((301, 1)), ["s"],
                    Q=rng.standard_normal((301, 1)))
    path = tr.save(tmp_path / "noise.csv")
    out = tmp_path / "model.json"
    r = run_cli("identify", path, "--coords", "s", "--features", "s,s_dot", "--degree", "2",
                "--json", out)
    assert r.returncode == 3, r.stderr
    lines = [ln for ln in r.stderr.strip().splitlines() if not ln.startswith("search")]
    assert len(lines) == 1 and "Traceback" not in r.stderr, r.stderr
    assert lines[0].startswith("lsindy identify: the data do not determine the model: ")
    assert out.exists() == written
    if not written:
        assert "cannot identify the energy" in lines[0]


def test_no_admissible_model_at_the_given_k_is_a_verdict_not_bad_input(capsys):
    """The README's noisy cart runs with --terms 3: the search runs and finds no physically
    admissible 3-term energy (the true one has 4 terms).  That is about the data, so the exit
    code is 3 (undetermined), one line on stderr, not 2 (bad input)."""
    from pathlib import Path
    data = Path(__file__).resolve().parents[1] / "examples" / "data"
    files = sorted(str(p) for p in data.glob("cart_noisy*.csv"))
    assert files
    code = main(["identify", *files, *BASE, "--prior", "theta_dot**2,cos(theta)", "--terms", "3"])
    err = capsys.readouterr().err
    assert code == 3, err
    assert "the data do not determine the model" in err and "3-term" in err, err
    assert len(err.strip().splitlines()) == 1, err
