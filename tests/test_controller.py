"""The generic controller (``control.system``, ``local``, ``search``, ``controller``,
``episodes``) on problems with known answers: build errors, the input that holds a target, the
LQR gain against scipy on a finite-difference linearisation, the discrete sequence choice against
brute force, which coordinates are angles, a time-optimal double integrator for the beam search,
the goal bookkeeping with scripted states, and closed loops on the Acrobot and Furuta pendulum."""
import itertools
import json
from pathlib import Path

import casadi as ca
import numpy as np
import pytest
from scipy.linalg import solve_discrete_are

from lsindy_cas import LagrangianSINDy, systems
from lsindy_cas.control.controller import Controller
from lsindy_cas.control.episodes import GoalClock, run_episode
from lsindy_cas.control.local import LocalPolicy, equilibrium_input
from lsindy_cas.control.search import BeamSearch
from lsindy_cas.control.system import ControlledSystem
from lsindy_cas.control.task import Task

ROOT = Path(__file__).resolve().parents[1]
TASKS = ROOT / "examples" / "tasks"
DATA = ROOT / "examples" / "data"

# the cart-pendulum upright (theta from hanging, upright pi), forces on the cart
UPRIGHT = {"target": {"theta": np.pi}, "band": {"theta": 0.1, "theta_dot": 0.5}}


def cart_task(goal=UPRIGHT, inputs=None, **kw):
    return Task(dt=0.05, inputs=inputs or {"x": {"levels": [-10.0, 0.0, 10.0]}}, goal=goal, **kw)


def controlled(model, task, seed=0):
    return ControlledSystem(model, task.bind(model.coords), np.random.default_rng(seed))


def acrobot():
    """gymnasium's Acrobot-v1 as a MechanicalSystem: T and V from its _dsdt parameters
    (examples/acrobot.py TRUE_H), the torque on the elbow (Q_theta2)."""
    kinetic = ("1.75*theta1_dot**2 + 0.5*theta1_dot**2*cos(theta2) + 1.25*theta1_dot*theta2_dot"
               " + 0.5*theta1_dot*theta2_dot*cos(theta2) + 0.625*theta2_dot**2")
    potential = "-14.7*cos(theta1) - 4.9*cos(theta1)*cos(theta2) + 4.9*sin(theta1)*sin(theta2)"
    return systems.MechanicalSystem("acrobot", ["theta1", "theta2"], kinetic, potential,
                                    actuated="theta2", x0=(0.0, 0.0, 0.0, 0.0))


# ====================================================================== build errors
def test_task_must_be_a_task():
    with pytest.raises(TypeError, match="task must be a Task"):
        Controller(systems.cart_pendulum(), {"dt": 0.05})


def test_model_must_have_coordinates():
    with pytest.raises(TypeError, match="model"):
        Controller(object(), cart_task())


def test_negative_kinetic_energy_is_rejected():
    """T = −ṡ²: the mass matrix is −2 everywhere."""
    neg = systems.MechanicalSystem("negative mass", ["s"], kinetic="-1.0*s_dot**2",
                                   potential="2.5*s**2", actuated="s", x0=(0.0, 0.0))
    task = Task(dt=0.1, inputs={"s": {"bounds": [-1.0, 1.0]}},
                goal={"target": {}, "band": {"s": 0.1}})
    with pytest.raises(ValueError, match="kinetic part is not positive definite"):
        Controller(neg, task)


def test_kinetic_part_indefinite_away_from_the_target_is_rejected():
    """T = ẋ²/2 + cos(θ) θ̇²/2 is positive at the target θ = 0 but negative for |θ| > π/2:
    the check samples states over a turn, not only the target."""
    sys_ = systems.MechanicalSystem("bad", ["x", "theta"],
                                    kinetic="0.5*x_dot**2 + 0.5*cos(theta)*theta_dot**2",
                                    potential="-cos(theta)", actuated="x", x0=(0, 0, 0, 0))
    task = cart_task(goal={"target": {}, "band": {"theta": 0.1}})
    with pytest.raises(ValueError, match="kinetic part is not positive definite"):
        Controller(sys_, task)


def test_saved_model_with_a_negated_mass_term_never_reaches_the_controller(tmp_path):
    """A model file whose x_dot**2 term is negated: ``LagrangianSINDy.load`` already refuses it
    (ValueError naming the kinetic part), so the controller's own check is a second line."""
    path = tmp_path / "neg.json"
    path.write_text(json.dumps({
        "coords": ["x", "theta"], "actuated": ["x"],
        "hamiltonian_terms": {"x_dot**2": -0.55, "theta_dot**2": 0.05,
                              "theta_dot*x_dot*cos(theta)": 0.1, "cos(theta)": -0.981}}))
    with pytest.raises(ValueError, match="kinetic part is not positive definite"):
        LagrangianSINDy.load(path)


def test_relative_energy_model_is_rejected(cart_model, tmp_path):
    """A model known only up to a factor (passive data without a scale record)."""
    d = json.loads(Path(cart_model).read_text())
    d["energy_scale"] = "relative"
    path = tmp_path / "relative.json"
    path.write_text(json.dumps(d))
    model = LagrangianSINDy.load(path)
    with pytest.raises(ValueError, match="only up to a factor"):
        Controller(model, cart_task())
    # the same file with an absolute scale builds
    Controller(LagrangianSINDy.load(cart_model), cart_task())


def test_target_that_is_not_an_equilibrium_is_rejected():
    """θ = π/2 (pole horizontal): gravity pulls with g/L = 9.81 rad/s² and a cart force cannot
    cancel it at rest (θ̈ ∝ cos θ · u = 0)."""
    task = cart_task(goal={"target": {"theta": np.pi / 2}, "band": {"theta": 0.1}})
    with pytest.raises(ValueError, match="not a rest state") as info:
        Controller(systems.cart_pendulum(), task)
    assert "9.81" in str(info.value)


def test_target_held_only_by_inputs_outside_the_levels_is_rejected():
    """The mass-spring (k = 5) held at s = 0.1 needs Q = k·0.1 = 0.5 > the largest level 0.2."""
    task = Task(dt=0.1, inputs={"s": {"levels": [-0.2, 0.0, 0.2]}},
                goal={"target": {"s": 0.1}, "band": {"s": 0.05}})
    with pytest.raises(ValueError, match=r"needs the input\(s\) \[0.5\], outside"):
        Controller(systems.mass_spring(m=2.0, k=5.0), task)


def test_reach_condition_no_state_satisfies_is_rejected():
    task = cart_task(goal={"reach": "cos(theta) > 2"})
    with pytest.raises(ValueError, match="no state at rest satisfies goal.reach"):
        Controller(systems.cart_pendulum(), task)


def test_task_naming_a_missing_coordinate_is_rejected_before_the_build():
    with pytest.raises(ValueError, match="inputs.phi"):
        Controller(systems.cart_pendulum(), cart_task(inputs={"phi": {"levels": [1.0]}}))


# ====================================================================== known answers
def test_equilibrium_input_upright_is_zero():
    """Upright is an equilibrium of the free cart-pendulum: u* = 0 (to sin(π) ≈ 1.2e-16 times
    m g L ≈ 1: 1e-12 is rounding, not a force)."""
    task = cart_task()
    cs = controlled(systems.cart_pendulum(), task)
    u, residual, inside = equilibrium_input(cs, task.bind(["x", "theta"]).target,
                                            task.bind(["x", "theta"]).inputs)
    assert u.shape == (1,) and abs(u[0]) < 1e-12 and residual < 1e-12 and inside


@pytest.mark.parametrize("s, k", [(0.1, 5.0), (-0.3, 2.0)])
def test_equilibrium_input_holding_a_spring(s, k):
    """m s̈ = −k s + Q: rest at s needs Q = k s exactly (the ODE is linear in s and Q, so the
    least squares is exact to rounding: rel 1e-12)."""
    task = Task(dt=0.1, inputs={"s": {"bounds": [-2.0, 2.0]}},
                goal={"target": {"s": s}, "band": {"s": 0.05}})
    b = task.bind(["s"])
    cs = controlled(systems.mass_spring(m=2.0, k=k), task)
    u, residual, inside = equilibrium_input(cs, b.target, b.inputs)
    assert u[0] == pytest.approx(k * s, rel=1e-12)
    assert residual < 1e-12 and inside
    # the controller holds it with the same input
    ctrl = Controller(systems.mass_spring(m=2.0, k=k), task)
    assert ctrl.u_star[0] == pytest.approx(k * s, rel=1e-12)
    # outside narrower bounds
    narrow = [i for i in Task(dt=0.1, inputs={"s": {"bounds": [-0.1, 0.1]}},
                              goal={"reach": "s > 0"}).bind(["s"]).inputs]
    assert equilibrium_input(cs, b.target, narrow)[2] is False


def test_lqr_gain_matches_scipy_on_a_finite_difference_linearisation():
    """LocalPolicy linearises the RK4 map by automatic differentiation; here the map is
    differenced by hand (central, h = 1e-5: truncation h²·f'''/6 ~ 1e-10 and rounding
    eps·|x|/h ~ 1e-11, measured max error 5e-11 in A and B) and the DARE solved by scipy.  The
    DARE and the gain amplify that by ~1e2 (measured 2e-9 relative in K): rtol 1e-6."""
    task = cart_task(inputs={"x": {"bounds": [-10.0, 10.0]}})
    b = task.bind(["x", "theta"])
    cs = controlled(systems.cart_pendulum(), task)
    xs, us = b.target, np.zeros(1)
    Q, R = np.array([1.0, 100.0, 1.0, 4.0]), np.array([0.01])
    pol = LocalPolicy(cs, xs, us, b.inputs, Q, R)

    def f(x, u):
        return np.asarray(cs.step(x, u)).ravel()

    h = 1e-5
    A = np.column_stack([(f(xs + h * e, us) - f(xs - h * e, us)) / (2 * h) for e in np.eye(4)])
    B = np.column_stack([(f(xs, us + h * e) - f(xs, us - h * e)) / (2 * h) for e in np.eye(1)])
    P = solve_discrete_are(A, B, np.diag(Q), np.diag(R))
    K = np.linalg.solve(np.diag(R) + B.T @ P @ B, B.T @ P @ A)
    np.testing.assert_allclose(pol.A, A, atol=1e-8)
    np.testing.assert_allclose(pol.B, B, atol=1e-8)
    np.testing.assert_allclose(pol.K, K, rtol=1e-6)
    np.testing.assert_allclose(pol.P, P, rtol=1e-6)
    # the closed loop of the linear model is stable (the DARE's point)
    assert np.max(np.abs(np.linalg.eigvals(pol.A - pol.B @ pol.K))) < 1.0
    # continuous inputs: u = clip(u* − K z), z with the angle wrapped
    z = np.array([0.01, 0.02, -0.03, 0.04])
    assert pol(xs + z)[0] == pytest.approx(float(np.clip(-(K @ z)[0], -10, 10)), rel=1e-6)
    far = xs + np.array([0.0, 0.5, 0.0, 3.0])                       # saturates at the bound
    assert pol(far)[0] == -10.0
    wrapped = xs + z - np.array([0.0, 2 * np.pi, 0.0, 0.0])        # θ a turn lower: same input
    assert pol(wrapped)[0] == pytest.approx(pol(xs + z)[0], rel=1e-9)


def _brute_force_costs(pol, Z, levels, depth):
    """Cost of every level sequence on the linear model from each row of Z:
    Σ_{j<d} (z_jᵀQz_j + v_jᵀRv_j) + z_dᵀPz_d, z_{j+1} = A z_j + B v_j, v = u − u*."""
    seqs = np.array(list(itertools.product(levels, repeat=depth)))       # (S, d)
    costs = np.zeros((len(Z), len(seqs)))
    for s, seq in enumerate(seqs):
        z = Z.copy()
        for u in seq:
            v = np.array([u]) - pol.u_star
            costs[:, s] += np.einsum("ri,ij,rj->r", z, pol.Q, z) + v @ pol.R @ v
            z = z @ pol.A.T + v @ pol.B.T
        costs[:, s] += np.einsum("ri,ij,rj->r", z, pol.P, z)
    return seqs, costs


def test_discrete_choice_equals_brute_force_enumeration():
    """Levels {−10, 0, 10}, depth 6 (729 sequences): for 50 random states near upright, the
    policy's input is the first level of the cheapest sequence found by simulating every
    sequence on the linear model (A, B, Q, R, P), and the policy's per-sequence affine part
    (2 zᵀc_s + r_s) differs from the brute-force cost by the same amount for every sequence."""
    task = cart_task()
    b = task.bind(["x", "theta"])
    cs = controlled(systems.cart_pendulum(), task)
    pol = LocalPolicy(cs, b.target, np.zeros(1), b.inputs, np.array([1.0, 100.0, 1.0, 4.0]),
                      np.array([0.01]), depth=6)
    assert pol.depth == 6 and len(pol.seq_r) == 729
    rng = np.random.default_rng(7)
    Z = rng.normal(size=(50, 4)) * np.array([0.3, 0.1, 0.5, 0.5])
    seqs, costs = _brute_force_costs(pol, Z, [-10.0, 0.0, 10.0], 6)
    best = seqs[np.argmin(costs, axis=1), 0]
    got = pol.inputs_for(b.target + Z)[:, 0]
    # the choices are decided by clear margins, so the argmin is the same, not merely close:
    # the gap to the best sequence starting with another level is > 1e-6 of the cost here
    for r in range(len(Z)):
        other = costs[r][seqs[:, 0] != best[r]].min()
        assert other - costs[r].min() > 1e-6 * costs[r].min()
    np.testing.assert_array_equal(got, best)
    # both enumerate in itertools.product order: the quadratic common part cancels
    diff = costs - (2.0 * Z @ pol.seq_c.T + pol.seq_r)
    np.testing.assert_allclose(diff, diff[:, :1] * np.ones((1, 729)),
                               rtol=1e-9, atol=1e-9 * np.abs(costs).max())


def test_sequence_depth_is_capped_at_729_sequences():
    """Two inputs with 3 levels each: 9 choices per sample, 9^3 = 729: depth 3 whatever asked."""
    dp = systems.double_pendulum()
    task = Task(dt=0.05, inputs={"theta1": {"levels": [-1.0, 0.0, 1.0]},
                                 "theta2": {"levels": [-1.0, 0.0, 1.0]}},
                goal={"target": {}, "band": {"theta1": 0.1}})
    b = task.bind(dp.coords)
    pol = LocalPolicy(controlled(dp, task), b.target, np.zeros(2), b.inputs, np.ones(4),
                      np.ones(2), depth=6)
    assert pol.depth == 3 and pol.seq_c.shape == (729, 4)


def test_angles_of_the_double_pendulum():
    dp = systems.double_pendulum()
    task = Task(dt=0.05, inputs={"theta1": {"levels": [-1.0, 0.0, 1.0]}},
                goal={"target": {}, "band": {"theta1": 0.1}})
    np.testing.assert_array_equal(controlled(dp, task).angles, [True, True, False, False])


def test_angles_of_a_spring_are_none():
    ms = systems.mass_spring()
    task = Task(dt=0.1, inputs={"s": {"bounds": [-1.0, 1.0]}}, goal={"reach": "s > 0.1"})
    np.testing.assert_array_equal(controlled(ms, task).angles, [False, False])


def test_angles_of_the_cart_pendulum():
    task = cart_task()
    np.testing.assert_array_equal(controlled(systems.cart_pendulum(), task).angles,
                                  [False, True, False, False])


def test_cart_far_from_its_target_is_not_reached():
    goal = {"target": {"x": 0.0, "theta": np.pi}, "band": {"x": 0.2, "theta": 0.1}}
    ctrl = Controller(systems.cart_pendulum(), cart_task(goal=goal))
    assert ctrl.reached([0.0, np.pi, 0.0, 0.0])
    assert not ctrl.reached([2 * np.pi, np.pi, 0.0, 0.0])


def test_controller_reached_wraps_the_pole_angle():
    """The pole (an angle) is compared modulo 2π: −π + 0.05 is inside a 0.1 band about π."""
    ctrl = Controller(systems.cart_pendulum(), cart_task())
    assert ctrl.reached([0.0, -np.pi + 0.05, 0.0, 0.0])
    assert not ctrl.reached([0.0, -np.pi + 0.15, 0.0, 0.0])
    assert not ctrl.reached([0.0, np.pi, 0.0, 0.6])                 # θ̇ band 0.5
    with pytest.raises(ValueError):
        ctrl.reached([0.0, np.pi, 0.0])                             # wrong length


# ====================================================================== beam search
def _double_integrator():
    """p⁺ = p + v + u/2, v⁺ = v + u over one sample of 1 s (exact for a held force)."""
    x, u = ca.SX.sym("x", 2), ca.SX.sym("u", 1)
    return ca.Function("step", [x, u], [ca.vertcat(x[0] + x[1] + u[0] / 2, x[1] + u[0])])


def _rest_at(p_goal):
    def capture(X):
        return (np.abs(X[:, 0] - p_goal) <= 1e-9) & (np.abs(X[:, 1]) <= 1e-9)

    def cost(X):
        return (X[:, 0] - p_goal) ** 2 + X[:, 1] ** 2
    return capture, cost


def _closed_loop(search, step, x, n_max=30):
    """Apply the search's first input each sample; the states until capture (or n_max)."""
    X = [np.asarray(x, float)]
    for _ in range(n_max):
        i = search(X[-1])
        if i is None:
            return X, None
        X.append(np.asarray(step(X[-1], search.candidates[i])).ravel())
        if search.capture(X[-1][None, :])[0]:
            break
    return X, True


@pytest.mark.parametrize("p_goal, v_max, steps", [
    # rest to rest with |u| <= 1: full thrust n samples then full brake n samples covers
    # Σ(j + ½) + Σ(n − j − ½) = n² (a coast sample at speed n adds n); 3 samples reach at most
    # p = 2 (u = +1, 0, −1), so p = 4 needs 4 samples: (+1, +1, −1, −1)
    (4.0, np.inf, 4),
    # p = 6 = 2² + 2: thrust 2, coast 1 at speed 2, brake 2: 5 samples (4 reach at most 4)
    (6.0, np.inf, 5),
    # with |v| <= 1.5 the speed (an integer) is at most 1: ½ + coasts + ½ = 4 needs
    # (+1, 0, 0, 0, −1): 5 samples
    (4.0, 1.5, 5),
])
def test_beam_search_finds_the_time_optimal_bang_bang(p_goal, v_max, steps):
    step = _double_integrator()
    capture, cost = _rest_at(p_goal)
    lower, upper = np.array([-np.inf, -v_max]), np.array([np.inf, v_max])
    search = BeamSearch(step, [[-1.0], [0.0], [1.0]], depth=12, width=64, cost=cost,
                        capture=capture, lower=lower, upper=upper)
    X, ok = _closed_loop(search, step, [0.0, 0.0])
    assert ok and capture(X[-1][None, :])[0]
    assert len(X) - 1 == steps
    X = np.array(X)
    assert np.all((X >= lower) & (X <= upper))
    # the plan made at the start already had that length (it stops at the first capture)
    search.reset()
    search(np.zeros(2))
    assert search.captured and len(search.plan) == steps - 1


def test_beam_search_never_plans_outside_the_limits():
    """A track −5 <= p <= 2.2 and |v| <= 1.5 with the goal p = 2 at rest: every state of the
    closed loop stays inside, from several starts (some moving towards a wall).  With |v| <= 1
    every change of speed moves p by ½ and a coast by 1, so rest at p = 2 is reachable from
    rest at an integer p or from speed ±1 at a half-integer p: the starts are such."""
    step = _double_integrator()
    capture, cost = _rest_at(2.0)
    lower, upper = np.array([-5.0, -1.5]), np.array([2.2, 1.5])
    for x0 in ([0.0, 0.0], [-3.5, 1.0], [1.5, 1.0], [-4.5, -1.0], [-5.0, 0.0]):
        search = BeamSearch(step, [[-1.0], [0.0], [1.0]], depth=15, width=16, cost=cost,
                            capture=capture, lower=lower, upper=upper)
        X, ok = _closed_loop(search, step, x0)
        X = np.array(X)
        assert ok and capture(X[-1:])[0], x0
        assert np.all((X >= lower) & (X <= upper)), (x0, X)


def test_beam_search_returns_none_when_every_input_leaves_the_limits():
    """At the wall p = 2.2 moving at v = 1: p⁺ = 3.2 + u/2 >= 2.7 for every u."""
    step = _double_integrator()
    capture, cost = _rest_at(2.0)
    search = BeamSearch(step, [[-1.0], [0.0], [1.0]], depth=5, width=8, cost=cost,
                        capture=capture, lower=np.array([-5.0, -1.5]),
                        upper=np.array([2.2, 1.5]))
    assert search(np.array([2.2, 1.0])) is None and search.plan is None


def _counting(search):
    """Count the search's expansions (calls of its mapped model map) per call."""
    calls = []
    advance = search._advance

    def counted(X, U):
        calls[-1] += 1
        return advance(X, U)

    search._advance = counted

    def call(x):
        calls.append(0)
        return BeamSearch.__call__(search, x)
    return call, calls


@pytest.mark.parametrize("restart", [False, True])
def test_budgeted_search_expands_at_most_its_budget_per_call_and_still_arrives(restart):
    """A search 5 samples deep with a budget of 2 runs over 3 calls; on the exact model the
    closed loop still arrives at rest at p = 6 in the time-optimal 5 samples when the search
    goes on from the inputs applied meanwhile (those of its best partial sequence, there
    being no previous plan); restarting from the measured state at every call still arrives."""
    step = _double_integrator()
    capture, cost = _rest_at(6.0)
    search = BeamSearch(step, [[-1.0], [0.0], [1.0]], depth=12, width=64, cost=cost,
                        capture=capture, lower=np.array([-np.inf, -np.inf]),
                        upper=np.array([np.inf, np.inf]), budget=2, restart=restart)
    call, calls = _counting(search)
    X = [np.zeros(2)]
    for _ in range(30):
        i = call(X[-1])
        X.append(np.asarray(step(X[-1], search.candidates[i])).ravel())
        if capture(X[-1][None, :])[0]:
            break
    assert capture(X[-1][None, :])[0]
    assert max(calls) <= 2
    if not restart:
        # one search, spread over calls; its plan then kept to the goal without searching
        assert len(X) - 1 == 5 and search.stats["searches"] == 1


def test_budgeted_search_applies_the_previous_plan_while_it_searches():
    """A plan that no longer captures is replaced by a search spread over calls; meanwhile the
    inputs applied are the old plan's, and the new plan starts where they leave off."""
    step = _double_integrator()
    capture, cost = _rest_at(6.0)
    search = BeamSearch(step, [[-1.0], [0.0], [1.0]], depth=12, width=64, cost=cost,
                        capture=capture, lower=np.array([-np.inf, -np.inf]),
                        upper=np.array([np.inf, np.inf]), budget=1)
    old = np.array([2, 2, 1, 0, 0, 1, 1])        # +1, +1, 0, −1, −1, 0, 0: ends at p = 4
    search.plan, search.captured = old, True
    applied = [search(np.zeros(2)) for _ in range(2)]
    assert applied == [2, 2] and search._job is not None


# ====================================================================== goal bookkeeping
class StubController:
    """What run_episode and GoalClock use of a controller: task, bound, reset, call, reached
    (the band test without the angle check: wrap nothing)."""

    def __init__(self, task, coords=("s",)):
        self.task = task
        self.bound = task.bind(list(coords))
        self.calls, self.resets = 0, 0
        self.n = 2 * len(coords)

    def reset(self):
        self.resets += 1

    def __call__(self, x):
        self.calls += 1
        return np.zeros(len(self.task.inputs))

    def reached(self, x):
        if self.bound.target is not None:
            return self.bound.reached_band(x, np.zeros(self.n, bool))
        return float(self.bound.reach[1](x)) >= 0


def scripted(states):
    """A plant that ignores x and u and returns the next scripted state."""
    it = iter(states)
    return lambda x, u: np.asarray(next(it), float)


def _target_task(hold, duration=1.0, limits=None):
    return Task(dt=0.1, inputs={"s": {"levels": [-1.0, 0.0, 1.0]}},
                goal={"target": {"s": 0.0}, "band": {"s": 0.1}, "hold": hold},
                limits=limits or {}, episode={"duration": duration})


IN, OUT = [0.0, 0.0], [1.0, 0.0]


def test_goal_clock_needs_hold_over_dt_samples_after_entering():
    """hold 0.3 s at dt 0.1: the band must hold at the entering sample and 3 more; the time to
    goal is the entering sample's.  0.3 / 0.1 = 2.9999999999999996 in floats: still 3."""
    ctrl = StubController(_target_task(hold=0.3))
    clock = GoalClock(ctrl)
    assert clock.need == 3
    seq = [OUT, IN, IN, IN, OUT, IN, IN, IN, IN, IN]   # in at 1-3 (too short), in again from 5
    done = [clock.update(np.array(x), k) for k, x in enumerate(seq)]
    assert done == [False] * 8 + [True, True]
    assert clock.done_at == 5


def test_goal_clock_empty_target_still_needs_the_hold():
    task = Task(dt=0.1, inputs={"s": {"levels": [-1.0, 0.0, 1.0]}},
                goal={"target": {}, "band": {"s": 0.1}, "hold": 1.0})
    assert GoalClock(StubController(task)).need == 10


def test_goal_clock_zero_hold_and_reach_goal_count_the_first_sample():
    ctrl = StubController(_target_task(hold=0.0))
    clock = GoalClock(ctrl)
    assert clock.need == 0 and clock.update(np.array(IN), 0) and clock.done_at == 0
    reach = Task(dt=0.1, inputs={"s": {"levels": [1.0]}}, goal={"reach": "s > 0.5"})
    clock = GoalClock(StubController(reach))
    assert clock.need == 0
    assert not clock.update(np.array([0.4, 0.0]), 1) and clock.update(np.array([0.6, 0.0]), 2)
    assert clock.done_at == 2


def test_run_episode_target_goal_time_to_goal_and_length():
    """duration 1.0 at dt 0.1: 10 samples; in the band from sample 5 on, hold 0.3 s (samples
    5-8): success, time to goal 0.5 s; a target goal runs on after the goal (hold seen)."""
    ctrl = StubController(_target_task(hold=0.3))
    x0 = np.array(OUT)
    states = [OUT, OUT, OUT, OUT, IN, IN, IN, IN, IN, IN]          # samples 1..10
    r = run_episode(ctrl, scripted(states), x0)
    assert ctrl.resets == 1 and ctrl.calls == 10
    assert r.X.shape == (11, 2) and r.U.shape == (10, 1)
    assert r.success and r.within_limits
    assert r.time_to_goal == pytest.approx(0.5, abs=1e-12)
    s = r.summary()
    assert set(s) == {"x0", "success", "time_to_goal", "within_limits", "steps",
                      "step_ms_median", "step_ms_max"}
    assert s["steps"] == 10 and s["time_to_goal"] == 0.5 and s["success"] is True


def test_run_episode_hold_not_finished_in_time_is_a_failure():
    """In the band from sample 8: samples 8-10 are 0.2 s, short of hold 0.3 s."""
    ctrl = StubController(_target_task(hold=0.3))
    states = [OUT] * 7 + [IN] * 3
    r = run_episode(ctrl, scripted(states), np.array(OUT))
    assert not r.success and r.time_to_goal is None and r.within_limits


def test_run_episode_leaving_the_limits_is_a_failure_even_at_the_goal():
    ctrl = StubController(_target_task(hold=0.0, limits={"s": [-0.5, 0.5]}))
    states = [IN, [0.7, 0.0]] + [IN] * 8                           # sample 2 off the track
    r = run_episode(ctrl, scripted(states), np.array(IN))
    assert r.time_to_goal == 0.0                                   # in the band at the start
    assert not r.within_limits and not r.success


def test_run_episode_reach_goal_stops_at_the_goal():
    task = Task(dt=0.1, inputs={"s": {"levels": [1.0]}}, goal={"reach": "s > 0.5"},
                episode={"duration": 2.0})
    ctrl = StubController(task)
    states = [[0.2, 0.0], [0.4, 0.0], [0.6, 0.0], [0.4, 0.0]] + [[0.0, 0.0]] * 20
    r = run_episode(ctrl, scripted(states), np.zeros(2))
    assert r.success and r.time_to_goal == pytest.approx(0.3, abs=1e-12)
    assert len(r.U) == 3 and len(r.X) == 4                         # stopped at sample 3
    r = run_episode(ctrl, scripted(states), np.zeros(2), stop_at_goal=False, duration=1.0)
    assert r.success and len(r.U) == 10 and r.time_to_goal == pytest.approx(0.3, abs=1e-12)


def test_run_episode_non_finite_state_ends_it_as_outside():
    ctrl = StubController(_target_task(hold=0.0))
    states = [OUT, [np.nan, 0.0]] + [IN] * 8
    r = run_episode(ctrl, scripted(states), np.array(OUT))
    assert len(r.U) == 2 and not r.within_limits and not r.success and r.time_to_goal is None


# ====================================================================== closed loops
def test_acrobot_reaches_the_goal_within_100_steps_on_its_true_model():
    """gymnasium-like starts (every state uniform in ±0.1), the task file of examples/tasks,
    the true energy; 100 steps of 0.2 s.  (Measured: 63-64 steps from these starts.)"""
    ctrl = Controller(acrobot(), Task.load(TASKS / "acrobot.toml"))
    np.testing.assert_array_equal(ctrl.system.angles, [True, True, False, False])

    def plant(x, u):
        return np.asarray(ctrl.system.step(x, u)).ravel()

    rng = np.random.default_rng(0)
    for _ in range(3):
        x0 = rng.uniform(-0.1, 0.1, 4)
        r = run_episode(ctrl, plant, x0, duration=100 * 0.2)
        assert r.success, r.summary()
        assert len(r.U) <= 100
        # the goal test is the condition itself: tip height above 1 m at the last state
        t1, t2 = r.X[-1, :2]
        assert -np.cos(t1) - np.cos(t1 + t2) >= 1.0
        assert set(np.unique(r.U)) <= {-1.0, 0.0, 1.0}


def test_furuta_model_swings_up_and_holds():
    """The Furuta pendulum's identified model and its task file: swing up from hanging and
    hold 3 s inside the band, on the model itself, from 2 of 2 seeded starts (measured: goal
    at 3.0-3.9 s of 10 s)."""
    model = LagrangianSINDy.load(DATA / "furuta_model.json")
    task = Task.load(TASKS / "furuta.toml")
    ctrl = Controller(model, task)

    def plant(x, u):
        return np.asarray(ctrl.system.step(x, u)).ravel()

    rng = np.random.default_rng(0)
    ok = 0
    for _ in range(2):
        r = run_episode(ctrl, plant, ctrl.bound.start(rng))
        ok += r.success
        if r.success:
            # the last 3 s are inside the band (the hold is the tail of the run here)
            tail = r.X[-int(round(task.goal.hold / task.dt)):]
            assert all(ctrl.reached(x) for x in tail)
            assert set(np.unique(r.U)) <= {-0.03, 0.0, 0.03}
    assert ok == 2


def test_cyclic_coordinates_are_found_and_ignored_where_the_goal_does_not_care():
    """The cart-pendulum's energy does not depend on x (cyclic); a goal that neither bands nor
    limits x leaves it out of the local policy's error, one that limits it keeps it."""
    free = Controller(systems.cart_pendulum(), cart_task(
        goal={"target": {"theta": np.pi}, "band": {"theta": 0.1, "theta_dot": 0.5}}))
    np.testing.assert_array_equal(free.system.cyclic, [True, False, False, False])
    np.testing.assert_array_equal(free.local.ignore, [True, False, False, False])
    assert free.local.errors([5.0, np.pi, 0.0, 0.0])[0, 0] == 0.0
    limited = Controller(systems.cart_pendulum(), cart_task(
        goal={"target": {"theta": np.pi}, "band": {"theta": 0.1, "theta_dot": 0.5}},
        limits={"x": [-2.0, 2.0]}))
    assert not np.any(limited.local.ignore)
    assert limited.local.errors([1.5, np.pi, 0.0, 0.0])[0, 0] == 1.5
