"""A newcomer's first hour: outputs checked before the work, readable files, bounded work, input
mistakes caught, and the small command-line gaps (each case failed before it was fixed)."""
import json
import os
from pathlib import Path
import stat
import subprocess
import sys
import warnings

import numpy as np
import pytest

from lsindy_cas import Trajectory, __version__, systems
from lsindy_cas.cli import main

FEATURES = "cos(theta),sin(theta),theta_dot,x,x_dot"


def run_cli(*args):
    return subprocess.run([sys.executable, "-m", "lsindy_cas.cli", *map(str, args)],
                          capture_output=True, text=True, timeout=300)


@pytest.fixture(scope="module")
def cart_csv(tmp_path_factory):
    folder = tmp_path_factory.mktemp("cart")
    tr = systems.cart_pendulum().simulate(t_end=1.0, u=1.0)
    return tr.save(folder / "run.csv")



def identify(csv, *extra):
    return run_cli("identify", csv, "--coords", "x,theta", "--features", FEATURES, "--degree", "3",
                   "--terms", "4", "--prior", "theta_dot**2,cos(theta)", *extra)


def test_json_into_a_missing_folder_is_refused_before_the_fit(cart_csv, tmp_path):
    target = tmp_path / "nonexistent" / "dir" / "m.json"
    r = identify(cart_csv, "--json", target)
    assert r.returncode == 2
    assert len(r.stderr.strip().splitlines()) == 1 and "does not exist" in r.stderr
    assert "Traceback" not in r.stderr
    assert "H =" not in r.stdout                      # refused before the fit, not after
    assert not (tmp_path / "nonexistent").exists()    # no folder created behind the user's back


def test_json_into_an_unwritable_folder_is_refused_before_the_fit(cart_csv, tmp_path):
    locked = tmp_path / "locked"
    locked.mkdir()
    locked.chmod(0o500)
    if os.access(locked, os.W_OK):      # root ignores mode bits: use a read-only file system
        locked = Path("/sys")
        if not locked.is_dir():
            pytest.skip("running as root without a read-only file system to write into")
    try:
        r = identify(cart_csv, "--json", locked / "m.json")
    finally:
        (tmp_path / "locked").chmod(0o700)
    assert r.returncode == 2 and "not writable" in r.stderr and "H =" not in r.stdout


def test_json_naming_a_folder_is_refused(cart_csv, tmp_path):
    r = identify(cart_csv, "--json", tmp_path)
    assert r.returncode == 2 and "is a directory" in r.stderr


def test_saved_files_follow_the_umask(cart_csv, tmp_path):
    out = tmp_path / "m.json"
    old = os.umask(0o022)
    try:
        assert main(["identify", str(cart_csv), "--coords", "x,theta", "--features", FEATURES,
                     "--degree", "3", "--terms", "4", "--prior", "theta_dot**2,cos(theta)",
                     "--json", str(out)]) == 0
        sim = tmp_path / "sim.csv"
        assert main(["simulate", str(out), "--x0", "0,0.5,0,0", "--t-end", "0.1",
                     "--out", str(sim)]) == 0
    finally:
        os.umask(old)
    for path in (out, sim):          # 0666 & ~0022, as for any file the user creates
        assert stat.S_IMODE(path.stat().st_mode) == 0o644, path


def test_unbounded_simulation_is_refused_up_front(cart_model, tmp_path):
    r = run_cli("simulate", cart_model, "--x0", "0,0.5,0,0", "--t-end", "1e7",
                "--out", tmp_path / "s.csv")
    assert r.returncode == 2 and "--max-samples" in r.stderr
    assert len(r.stderr.strip().splitlines()) == 1
    assert not (tmp_path / "s.csv").exists()
    # the limit is the user's to raise
    assert main(["simulate", str(cart_model), "--x0", "0,0.5,0,0", "--t-end", "0.5",
                 "--max-samples", "10", "--out", str(tmp_path / "s.csv")]) == 2


def test_coordinates_left_out_of_coords_are_named(cart_csv):
    r = run_cli("identify", cart_csv, "--coords", "theta", "--features", "cos(theta),theta_dot",
                "--degree", "2", "--terms", "2")
    assert r.returncode == 2
    assert "also has coordinate(s) x" in r.stderr and "--coords theta,x" in r.stderr


def test_header_only_csv_is_one_clear_error(tmp_path, capsys):
    path = tmp_path / "empty.csv"
    path.write_text("t,x,x_dot\n")
    with warnings.catch_warnings():
        warnings.simplefilter("error")                 # no numpy warning leaks out
        code = main(["identify", str(path), "--coords", "x", "--features", "x,x_dot",
                     "--terms", "1"])
    assert code == 2
    err = capsys.readouterr().err
    assert "no data rows" in err and "rows have" not in err


def test_all_passive_without_scale_is_relative_and_names_the_cli_flag(tmp_path):
    """Free-swing data without --scale give the energy up to a factor, said so, with the flag
    that would make it absolute (not refused).  The cart starts moving: from rest
    the horizontal momentum is 0 throughout and ẋ·p_x ≡ 0 would be a second "conserved" term."""
    tr = systems.cart_pendulum().simulate(x0=(0.0, np.pi / 4, 0.5, 0.0), t_end=3.0, u=0.0)
    path = tr.save(tmp_path / "free.csv")
    r = identify(path)
    assert r.returncode == 0, r.stderr
    assert "up to a constant factor" in r.stdout and "--scale" in r.stdout
    assert "scale_trajectories" not in r.stdout


def test_version_and_descriptions():
    r = run_cli("--version")
    assert r.returncode == 0 and __version__ in r.stdout
    for cmd in ("identify", "simulate", "reproduce", "library", "export", "swingup"):
        text = run_cli(cmd, "--help").stdout
        usage_end = text.index("\n\n")
        # a description paragraph between the usage and the argument list
        assert not text[usage_end:].lstrip().startswith(("positional", "options")), cmd


def test_library_lists_its_terms(capsys):
    assert main(["library", "--coords", "x,theta", "--features", FEATURES, "--degree", "3"]) == 0
    out = capsys.readouterr().out.splitlines()
    # C(5 + 3, 3) - 1 = 55 monomials of degree 1..3 in 5 features
    assert out[-1].startswith("55 terms")
    assert any(line.split()[-1] == "theta_dot*x_dot*cos(theta)" for line in out[:-1])


def test_identify_has_the_api_options(cart_csv):
    r = identify(cart_csv, "--smoothing", "none", "--window", "50", "--max-terms", "6")
    assert r.returncode == 0, r.stderr
    assert "theta_dot*x_dot*cos(theta)" in r.stdout
    r = identify(cart_csv, "--window", "0")
    assert r.returncode == 2 and "--window" in r.stderr


def test_simulate_replays_a_recorded_input(cart_model, tmp_path):
    """A recorded, every-sample-different input is held over each interval, as logged."""
    dt = 0.01
    t = np.arange(51) * dt
    u = 2.0 * np.sin(7.0 * t)
    rec = Trajectory(t, np.zeros((51, 2)), np.zeros((51, 2)), ["x", "theta"],
                     Q=np.column_stack([u, np.zeros(51)]))
    rec_path = rec.save(tmp_path / "rec.csv")
    out = tmp_path / "replay.csv"
    assert main(["simulate", str(cart_model), "--x0", "0,0.5,0,0", "--u-file", str(rec_path),
                 "--out", str(out)]) == 0
    sim = Trajectory.load(out)
    truth = systems.cart_pendulum().simulate(
        x0=(0, 0.5, 0, 0), t_end=0.5, dt=dt,
        u=lambda ti, x: u[min(int(round(ti / dt)), 50)])
    np.testing.assert_allclose(sim.Q[:, 0], u)
    # same equations, same zero-order hold, same integrator tolerances: agreement ~1e-10
    np.testing.assert_allclose(sim.X, truth.X, atol=1e-8)


def test_simulate_u_file_bad_input(cart_model, tmp_path):
    bad = tmp_path / "bad.csv"
    bad.write_text("t,Q_y\n0,1\n0.1,1\n")
    r = run_cli("simulate", cart_model, "--x0", "0,0,0,0", "--u-file", bad, "--out",
                tmp_path / "o.csv")
    assert r.returncode == 2 and "Q_y" in r.stderr
    r = run_cli("simulate", cart_model, "--x0", "0,0,0,0", "--u-file", bad, "--t-end", "1",
                "--out", tmp_path / "o.csv")
    assert r.returncode == 2 and "--t-end" in r.stderr


def test_model_with_negative_kinetic_energy_is_refused(cart_model, tmp_path):
    d = json.loads(cart_model.read_text())
    d["hamiltonian_terms"]["x_dot**2"] = -0.55          # a hand-edited sign
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps(d))
    r = run_cli("simulate", bad, "--x0", "0,0.5,0,0", "--t-end", "1", "--out", tmp_path / "s.csv")
    assert r.returncode == 2 and "not positive definite" in r.stderr
    assert not (tmp_path / "s.csv").exists()
