"""The input hold: a held input changing every sample and a smoothly varying sampled force are
both identified with the default ``hold="auto"``, which decides from the data."""
import numpy as np
import pytest

from lsindy_cas import LagrangianSINDy, Library, Trajectory, systems
from lsindy_cas.cli import main

TRUE = {"x_dot**2": 0.55, "theta_dot**2": 0.05, "theta_dot*x_dot*cos(theta)": 0.1,
        "cos(theta)": -0.981}


def _fit(trajs, hold="auto"):
    lib = Library.polynomial(["x", "theta"], "cos(theta),sin(theta),theta_dot,x,x_dot", degree=3)
    return LagrangianSINDy(lib, n_terms=4, prior=["theta_dot**2", "cos(theta)"],
                           hold=hold).fit(trajs)


def _logged(tr, every=1):
    """What a logger writes: every ``every``-th sample, no exact accelerations."""
    s = slice(None, None, every)
    return Trajectory(tr.t[s], tr.q[s], tr.qd[s], tr.coords, Q=tr.Q[s])


def _held_runs():
    cart = systems.cart_pendulum()
    # a multisine held over each 10 ms sample: every sample different, as a digital controller's
    u = lambda t, x: 2.0 * np.sin(3.0 * t) + 0.7 * np.sin(11.0 * t + 1.0)   # noqa: E731
    return [_logged(cart.simulate(x0=x0, t_end=2.0, u=u))
            for x0 in [(0, np.pi / 4, 0, 0), (0.2, 2.0, 0, -0.5)]]


def _smooth_runs():
    """A force that varies smoothly in time (integrated as such), sampled at 100 Hz."""
    from scipy.integrate import solve_ivp

    ode = systems.cart_pendulum().ode()
    force = lambda t: 2.0 * np.sin(3.0 * t) + 0.7 * np.sin(11.0 * t + 1.0)   # noqa: E731
    t = np.arange(201) * 0.01
    runs = []
    for x0 in [(0, np.pi / 4, 0, 0), (0.2, 2.0, 0, -0.5)]:
        sol = solve_ivp(lambda ti, x: np.asarray(ode(x, [force(ti), 0.0])).ravel(), (0, 2.0), x0,
                        method="DOP853", t_eval=t, rtol=1e-11, atol=1e-12)
        Q = np.column_stack([force(t), np.zeros_like(t)])
        runs.append(Trajectory(t, sol.y[:2].T, sol.y[2:].T, ["x", "theta"], Q=Q))
    return runs


@pytest.mark.parametrize("runs, expected", [(_held_runs, "zoh"), (_smooth_runs, "smooth")])
def test_auto_hold_identifies_both_kinds_of_input(runs, expected):
    model = _fit(runs())
    assert model.hold_ == expected
    assert set(model.hold_errors_) == {"zoh", "smooth"}
    terms = model.terms()
    assert set(terms) == set(TRUE)
    for name, value in TRUE.items():
        # target 1e-3 relative; the quadrature of the right work integral is ~1e-6
        assert terms[name] == pytest.approx(value, rel=1e-3), name
    assert model.to_dict()["hold"] == expected
    assert "input hold of the work integral: " + expected in str(model.diagnostics_)


def test_the_wrong_hold_is_biased():
    """Why auto must not guess from how often the force changes: the held input read as smooth
    is off by percent on the same data (the case a user met)."""
    model = _fit(_held_runs(), hold="smooth")
    assert abs(model.terms()["cos(theta)"] / TRUE["cos(theta)"] - 1) > 1e-2


def test_sparse_switches_are_held_without_a_second_fit():
    cart = systems.cart_pendulum()
    tr = _logged(cart.simulate(t_end=2.0, u=lambda t, x: 1.5 * np.sign(np.sin(4 * t))))
    model = _fit([tr])
    assert model.hold_ == "zoh" and not hasattr(model, "hold_errors_")


def test_hold_bad_input(tmp_path, capsys):
    lib = Library.polynomial(["x"], "x,x_dot", degree=2)
    with pytest.raises(ValueError, match="hold must be one of"):
        LagrangianSINDy(lib, hold="linear").fit(_held_runs()[0].reorder(["x", "theta"]))
    path = _held_runs()[0].save(tmp_path / "run.csv")
    with pytest.raises(SystemExit) as exc:
        main(["identify", str(path), "--coords", "x,theta", "--features", "x_dot",
              "--hold", "linear"])
    assert exc.value.code == 2 and "--hold" in capsys.readouterr().err
