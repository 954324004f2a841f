"""The model's coefficients re-estimated online (``control.coefficients``, ``adapt_model``):
the parametric form read from a model's Lagrangian, the filter on a plant whose physical
parameters differ by known factors, and the controller's use of the estimate."""

import numpy as np
import pytest

from lsindy_cas.control.coefficients import CoefficientEstimator, parametric_form
from lsindy_cas.control.cart_pendulum.upright import swing_up_gate
from lsindy_cas.control.mpc import wrap_angle
from lsindy_cas.control.ocp import rk4_step
from lsindy_cas.paper import systems
from lsindy_cas.paper.swingup import Plant, random_starts, run_episode

G = 9.81
DT = 0.05


def _physical(mc, mp, L):
    """Hand-derived Lagrangian coefficients of the cart-pendulum (DESIGN.md convention):
    L = (mc + mp)/2 x_dot^2 + mp L^2/2 theta_dot^2 + mp L x_dot theta_dot cos(theta)
        + mp g L cos(theta)."""
    return {"x_dot**2": (mc + mp) / 2, "theta_dot**2": mp * L ** 2 / 2,
            "theta_dot*x_dot*cos(theta)": mp * L, "cos(theta)": mp * G * L}


def _form(model):
    ode, p0, names = parametric_form(model, ["x", "theta"])
    return ode, dict(zip(names, p0)), names


def test_parametric_form_of_the_exact_cart_pendulum_is_the_hand_derived_lagrangian():
    ode, coef, _ = _form(systems.cart_pendulum(mc=0.6, mp=0.2, L=1.0))
    expected = _physical(0.6, 0.2, 1.0)
    assert set(coef) == set(expected)
    for name, value in expected.items():
        assert coef[name] == pytest.approx(value, rel=1e-12), name


def test_parametric_form_of_an_identified_model_reproduces_its_equations():
    from lsindy_cas.paper.swingup import identify_cart_pendulum
    model, _ = identify_cart_pendulum()
    ode, p0, names = parametric_form(model, list(model.coords_))
    x, u = np.array([0.3, 2.0, -0.4, 1.1]), np.array([5.0, 0.0])
    np.testing.assert_allclose(np.asarray(ode(x, u, p0)).ravel(),
                               np.asarray(model.ode()(x, u)).ravel(), rtol=1e-10, atol=1e-12)
    # the identified coefficients are the paper plant's (mc 1, mp 0.1, L 1) to the fit's 1e-6
    for name, value in _physical(1.0, 0.1, 1.0).items():
        assert dict(zip(names, p0))[name] == pytest.approx(value, rel=1e-4), name


def _friction_model(tmp_path):
    """A model file with viscous and Coulomb friction in its Rayleigh function, loaded."""
    import json
    from lsindy_cas.identify.estimator import LagrangianSINDy
    path = tmp_path / "friction.json"
    path.write_text(json.dumps({
        "coords": ["x", "theta"], "actuated": ["x"],
        "hamiltonian_terms": {"x_dot**2": 0.5, "theta_dot**2": 0.049, "cos(theta)": -1.3734,
                              "theta_dot*x_dot*cos(theta)": 0.14},
        "rayleigh_terms": {"x_dot**2": 0.2, "Abs(x_dot)": 0.3, "theta_dot**2": 0.002}}))
    return LagrangianSINDy.load(path)


def test_parametric_form_of_a_model_file_with_friction(tmp_path):
    """Viscous and Coulomb terms of the Rayleigh function are coefficients too (the smoothed
    Coulomb force of the model's own ODE, checked at random states inside)."""
    model = _friction_model(tmp_path)
    ode, p0, names = parametric_form(model, list(model.coords_))
    # L = T - V: the kinetic terms keep their sign, the potential's flips
    lagrangian = dict(zip(names[:4], p0[:4]))
    assert lagrangian == pytest.approx({"x_dot**2": 0.5, "theta_dot**2": 0.049,
                                        "cos(theta)": 1.3734, "theta_dot*x_dot*cos(theta)": 0.14})
    assert dict(zip(names[4:], p0[4:])) == pytest.approx(
        {"x_dot**2": 0.2, "Abs(x_dot)": 0.3, "theta_dot**2": 0.002})


def test_the_default_controller_on_a_model_file_with_friction(tmp_path):
    """The default (``adapt_model="stall"``) on a model with viscous and Coulomb friction: its
    coefficients' NLP builds beside the model's own, and before a stall the forces are those
    of ``adapt_model=False``."""
    from lsindy_cas.mpc import SwingUpMPC
    model = _friction_model(tmp_path)
    step = rk4_step(model.ode(), 4, 2, DT, 4)
    forces = []
    for adapt_model in (False, None):
        ctrl = SwingUpMPC(model, adapt_model=adapt_model)
        x, applied = np.array([0.0, 0.2, 0.0, 0.0]), []
        for _ in range(40):
            applied.append(ctrl(x))
            x = np.asarray(step(x, [applied[-1], 0.0])).ravel()
        forces.append(applied)
    assert ctrl.adapt_model == "stall" and ctrl._nlps[1].coef0.size == 7
    assert forces[1] == forces[0] and set(forces[0]) <= {-10.0, 0.0, 10.0}


def test_parametric_form_bad_models():
    class NoLagrangian:
        coords = ["x", "theta"]

        def ode(self):
            return systems.cart_pendulum().ode()

    with pytest.raises(ValueError, match="no Lagrangian"):
        parametric_form(NoLagrangian(), ["x", "theta"])

    class Inconsistent(NoLagrangian):  # a Lagrangian that is not the model's ODE
        lagrangian = systems.cart_pendulum(mc=2.0).lagrangian

    with pytest.raises(ValueError, match="could not be rebuilt"):
        parametric_form(Inconsistent(), ["x", "theta"])


def _transitions(true_step, n, seed):
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        x = np.array([rng.uniform(-1, 1), rng.uniform(-np.pi, np.pi), rng.uniform(-2, 2),
                      rng.uniform(-4, 4)])
        force = float(rng.choice([-10.0, 0.0, 10.0]))
        out.append((x, force, np.asarray(true_step(x, [force, 0.0])).ravel()))
    return out


def test_estimator_converges_to_the_plant_coefficients():
    """Noise-free transitions of a plant with cart -10 %, pole mass and length +10 %: the
    filter, from the nominal model's coefficients, ends at the plant's (hand-derived)."""
    nominal = systems.cart_pendulum(mc=0.6, mp=0.2, L=1.0)
    true = systems.cart_pendulum(mc=0.54, mp=0.22, L=1.1)
    ode, p0, names = parametric_form(nominal, ["x", "theta"])
    est = CoefficientEstimator(rk4_step(ode, 4, 2, DT, 1), p0, input_index=0)
    true_step = rk4_step(true.ode(), 4, 2, DT, 1)  # the same RK4 map: no discretisation gap
    expected = np.array([_physical(0.54, 0.22, 1.1)[n] for n in names])
    errors = {}
    for i, (x, force, nxt) in enumerate(_transitions(true_step, 400, 0), 1):
        est.update(x, force, nxt)
        errors[i] = np.abs(est.coef / expected - 1).max()
    # exact data: what is left is the prior's pull (prior 0.5 |p0|; m_p L^2 is 33 % off), the
    # posterior's, which shrinks as 1/n (measured 1.3e-3, 4.4e-4, 6.4e-5 after 20, 60, 400)
    assert errors[20] < 3e-3 and errors[60] < 1e-3 and errors[400] < 1e-4
    assert errors[400] < errors[60] / 4
    assert est.n_updates == 400
    assert np.all(est.std < 0.01 * np.abs(p0))
    est.reset()
    np.testing.assert_array_equal(est.coef, p0)


def test_estimator_stays_within_max_change_and_skips_non_finite():
    nominal = systems.cart_pendulum(mc=0.6, mp=0.2, L=1.0)
    true = systems.cart_pendulum(mc=0.6, mp=0.4, L=1.0)  # m_p L^2 twice the prior's
    ode, p0, names = parametric_form(nominal, ["x", "theta"])
    est = CoefficientEstimator(rk4_step(ode, 4, 2, DT, 1), p0, input_index=0, max_change=0.25)
    true_step = rk4_step(true.ode(), 4, 2, DT, 1)
    for x, force, nxt in _transitions(true_step, 40, 1):
        est.update(x, force, nxt)
    assert np.all(np.abs(est.coef - p0) <= 0.25 * np.abs(p0) + 1e-15)
    assert np.abs(est.coef - p0).max() == pytest.approx(0.25 * np.abs(p0).max())
    before, n = est.coef.copy(), est.n_updates
    est.update(np.zeros(4), 0.0, np.array([np.nan, 0.0, 0.0, 0.0]))
    np.testing.assert_array_equal(est.coef, before)
    assert est.n_updates == n
    with pytest.raises(ValueError):
        CoefficientEstimator(rk4_step(ode, 4, 2, DT, 1), p0, input_index=0, prior=0.0)
    with pytest.raises(ValueError):
        CoefficientEstimator(rk4_step(ode, 4, 2, DT, 1), p0, input_index=0, noise=-1.0)


def test_ocp_param_step_at_the_plant_coefficients_is_the_plant_step():
    from lsindy_cas.mpc import SwingUpMPC
    ctrl = SwingUpMPC(systems.cart_pendulum(mc=0.6, mp=0.2, L=1.0), adapt_model=True)
    true = systems.cart_pendulum(mc=0.54, mp=0.22, L=1.1)
    names = parametric_form(systems.cart_pendulum(mc=0.6, mp=0.2, L=1.0), ["x", "theta"])[2]
    p_true = [_physical(0.54, 0.22, 1.1)[n] for n in names]
    true_step = rk4_step(true.ode(), 4, 2, DT, 1)
    for x, force, nxt in _transitions(true_step, 5, 2):
        got = np.asarray(ctrl.ocp.param_step(x, [force, 0.0], p_true)).ravel()
        np.testing.assert_allclose(got, nxt, rtol=1e-12, atol=1e-12)
    # the NLP's parameter vector carries the estimate after state, gain and reference
    p = ctrl.nlp.parameters(np.zeros(4), 0.0, None, p_true)
    np.testing.assert_array_equal(p[9:], p_true)
    np.testing.assert_array_equal(ctrl.nlp.parameters(np.zeros(4))[9:], ctrl.ocp.param_values)


def test_adapt_model_defaults_and_bad_values(shared_mpc):
    # by default the estimate waits for a stall (the paper plant's pulse balancer and the
    # sequence balancer's plants); the step solves the model as given until then
    for plant in ({}, {"mc": 0.8, "mp": 0.2, "L": 0.7}):
        ctrl = shared_mpc(plant)
        assert ctrl.adapt_model == "stall" and ctrl.estimator.stall is not None
        assert ctrl.nlp.coef0 is None and ctrl._nlps[1].coef0 is not None
        off = shared_mpc(plant, adapt_model=False)
        assert off.adapt_model is False and off.estimator is None and off._nlps is None
        assert off.nlp.coef0 is None
    on = shared_mpc({"mc": 0.8, "mp": 0.2, "L": 0.7}, adapt_model=True)
    assert on.adapt_model is True and on.estimator is not None and on._nlps is None
    from lsindy_cas.mpc import SwingUpMPC
    with pytest.raises(ValueError, match="adapt_model"):
        SwingUpMPC(systems.cart_pendulum(), adapt_model="yes")

    class NoLagrangian:
        coords = ["x", "theta"]
        actuated = "x"

        def ode(self):
            return systems.cart_pendulum().ode()

    for value in (True, "stall"):
        with pytest.raises(ValueError, match="no Lagrangian"):
            SwingUpMPC(NoLagrangian(), adapt_model=value, balance=False)
    # the default on a model whose coefficients cannot be read: off, no error
    assert SwingUpMPC(NoLagrangian(), balance=False).adapt_model is False


def _mismatched_episode(adapt_model, balance=True):
    """Start 12 of the 60-start family seed on 0.6/0.2/1.0 with its cart 10 % lighter, its pole
    10 % heavier and longer, controlled on the nominal model (lost with the input
    gain and lean corrections alone, held with the plant's own equations in the plan)."""
    from lsindy_cas.mpc import SwingUpMPC
    nominal = systems.cart_pendulum(mc=0.6, mp=0.2, L=1.0)
    true = systems.cart_pendulum(mc=0.54, mp=0.22, L=1.1)
    ctrl = SwingUpMPC(nominal, dt=DT, adapt_model=adapt_model, balance=balance)
    ep = run_episode(ctrl, Plant(true, DT), random_starts(60, 0)[12])
    return ctrl, ep


def test_estimated_coefficients_swing_up_a_mismatched_plant():
    ctrl, ep = _mismatched_episode(True)
    assert ep.success
    names = parametric_form(systems.cart_pendulum(mc=0.6, mp=0.2, L=1.0), ["x", "theta"])[2]
    expected = np.array([_physical(0.54, 0.22, 1.1)[n] for n in names])
    # closed-loop data with the plant's fine integration against the model's one RK4 step
    # per 50 ms: within 2 % of the plant's coefficients (the prior was up to 33 % off)
    np.testing.assert_allclose(ctrl.estimator.coef, expected, rtol=0.02)


@pytest.mark.slow
def test_the_same_episode_is_lost_without_the_estimate():
    """With the sequence balancer's success band term off (``success_weight=0``); with that
    term, as by default, this start is held without the estimate too."""
    no_success_term = {"method": "auto", "success_weight": 0.0}
    assert not _mismatched_episode(False, no_success_term)[1].success


def test_the_stall_gate_holds_the_prior_until_the_pole_stays_far_from_the_top():
    """``stall = (far, steps)``: the plan's coefficients are the prior until ``steps`` updates
    in a row end in a state ``far`` accepts (here: the pole 1 rad or more from the upright, the
    angle wrapped), then the estimate for the rest of the episode; a state near the top restarts
    the count, and ``reset`` closes the gate again."""
    nominal = systems.cart_pendulum(mc=0.6, mp=0.2, L=1.0)
    true = systems.cart_pendulum(mc=0.54, mp=0.22, L=1.1)
    ode, p0, _ = parametric_form(nominal, ["x", "theta"])
    est = CoefficientEstimator(rk4_step(ode, 4, 2, DT, 1), p0, input_index=0)
    assert est.released and est.released_at == 0  # no gate: the estimate at once
    assert est.plan(0.3) == {"gain": 0.0, "coef": est.coef}  # the estimate carries the gain
    est.stall = (lambda s: abs(wrap_angle(s[1] - np.pi)) >= 1.0, 3)
    est.reset()
    true_step = rk4_step(true.ode(), 4, 2, DT, 1)
    far, near = np.array([0.0, 0.3, 0.0, 0.0]), np.array([0.0, -np.pi + 0.5, 0.0, 0.0])
    gate = []
    for state in (far, far, near, far, far, far, near):
        nxt = np.asarray(true_step(far, [10.0, 0.0])).ravel()
        est.update(far, 10.0, np.r_[state[:2], nxt[2:]])  # the pole angle as given
        gate.append(est.released)
        if not est.released:  # the plan without an estimator: the model, the correction's gain
            assert est.plan(0.3) == {"gain": 0.3} and est.released_at is None
    # near the top (0.5 rad off, through the wrap at -pi) restarts the count; once open it stays
    assert gate == [False, False, False, False, False, True, True]
    assert est.released_at == 6 and est.plan(0.3) == {"gain": 0.0, "coef": est.coef}
    assert not np.array_equal(est.coef, p0)
    est.reset()
    assert not est.released and est.released_at is None and est.plan(0.3) == {"gain": 0.3}


def test_a_gate_needs_coefficients_and_a_callable():
    from lsindy_cas.mpc import SwingUpMPC
    from lsindy_cas.control.mpc import DiscreteInputMPC
    ctrl = SwingUpMPC(systems.cart_pendulum(), balance=False)
    ocp = ctrl.ocp
    with pytest.raises(ValueError, match="gate needs coefficients"):
        DiscreteInputMPC(ocp.ode, ocp.levels, input_index=0, stage_residual=ocp.stage_residual,
                         terminal_residual=ocp.terminal_residual, dt=DT, horizon=5,
                         gate=(lambda s: True, 3))
    ode, p0, _ = parametric_form(systems.cart_pendulum(), ["x", "theta"])
    step = rk4_step(ode, 4, 2, DT, 1)
    with pytest.raises(TypeError, match="stall"):
        CoefficientEstimator(step, p0, input_index=0, stall=(3, 3))
    with pytest.raises(ValueError, match="stall"):
        CoefficientEstimator(step, p0, input_index=0, stall=(lambda s: True, 0))
    for stall, miss in (((lambda s: True, 3), 0.5), (None, lambda s0, s: True)):
        with pytest.raises(TypeError, match="miss must be callable"):
            CoefficientEstimator(step, p0, input_index=0, stall=stall, miss=miss)
    with pytest.raises(ValueError, match=r"\(far, steps\) or \(far, steps, miss\)"):
        DiscreteInputMPC(ocp.ode, ocp.levels, input_index=0, stage_residual=ocp.stage_residual,
                         terminal_residual=ocp.terminal_residual, dt=DT, horizon=5,
                         coefficients=(ode, p0), gate=(lambda s: True, 3, None, 1))


def _rising(up, leans, rate=1.0):
    """Predicted states of a pole rising through ``leans`` (rad from the upright ``up``, on the
    positive side) with rate ``rate``."""
    return np.array([[0.0, up + a, 0.0, rate] for a in leans])


def test_the_swing_up_gate_calls_a_turn_short_of_the_planned_top_a_missed_approach():
    """``swing_up_gate``: far is the pole ``stall[0]`` rad or more from the upright; a missed
    approach is a transition in which the pole's rate changes sign (it turned round) between
    ``missed[0]`` and ``missed[1]`` rad from the upright, the angle wrapped, the cart ignored,
    on a swing that the plan made at the transition's start had reaching within ``missed[0]``
    of the upright before turning round itself."""
    far, steps, miss = swing_up_gate(1, np.pi, 0.05, (2.0, 3.0), (0.4, 1.3))
    assert steps == 60
    assert far(np.array([0.0, 0.0, 0.0, 0.0])) and not far(np.array([0.0, np.pi + 1.9, 0, 0]))
    up = np.pi
    to_top = _rising(up, [0.9, 0.6, 0.3])  # the plan: this swing reaches the top

    def turned(off, before=-2.0, after=1.0, cart=0.0, plan=None):
        # the plan on the pole's side (the sign of off), rising: its rate of before's sign
        plan = to_top if plan is None else plan
        side, rate = np.sign(wrap_angle(off)), np.sign(before)
        plan = np.array([[p[0], up + side * (p[1] - up), p[2], rate * p[3]] for p in plan])
        return bool(miss(np.array([cart, up + off, 0.0, before]),
                         np.array([cart, up + off, 5.0, after]), plan))

    # a pole on the positive side rising (rate < 0 there) and turning back
    for off, want in ((0.8, True), (1.29, True), (0.41, True), (0.39, False), (1.31, False),
                      (2 * np.pi + 0.8, True)):
        assert turned(off) is want, off
    assert turned(-0.8, before=2.0, after=-1.0)  # the other side, rates mirrored
    assert not turned(0.8, -2.0, -0.5)  # no turn: no miss
    assert turned(0.8, cart=up + 3.0)  # the cart ignored
    # the plan turned round itself first, or never came within 0.4 rad: no miss; no plan: none
    assert not turned(0.8, plan=_rising(up, [0.9, 0.7, 0.3], rate=-1.0))
    assert not turned(0.8, plan=_rising(up, [0.9, 0.6, 0.5]))
    assert not miss(np.array([0.0, up + 0.8, 0.0, -2.0]), np.array([0.0, up + 0.8, 0, 1.0]), None)
    assert swing_up_gate(1, np.pi, 0.05, (2.0, 3.0), None)[2] is None


def test_the_gate_opens_at_the_first_missed_approach():
    """With ``miss``, the plan takes up the estimate at the first transition ``miss`` accepts,
    even if the pole was never far for long (``released_at`` counts that transition)."""
    ode, p0, _ = parametric_form(systems.cart_pendulum(mc=0.6, mp=0.2, L=1.0), ["x", "theta"])
    far, steps, miss = swing_up_gate(1, np.pi, DT, (2.0, 3.0), (0.4, 1.3))
    est = CoefficientEstimator(rk4_step(ode, 4, 2, DT, 1), p0, input_index=0,
                               stall=(far, steps), miss=miss)
    assert est.miss is miss and not est.released
    # the pole rising towards the top (rate > 0 at pi - 1.5, pi - 1.0) then falling back at
    # 0.7 rad; every plan has it rising on to the top
    path = [np.array([0.0, np.pi - a, 0.0, r]) for a, r in
            ((2.5, 4.0), (1.5, 3.0), (1.0, 1.0), (0.7, -0.5), (1.0, -2.0))]
    plan = np.array([[0.0, np.pi - a, 0.0, 1.0] for a in (0.6, 0.3)])
    gate = []
    for prev, nxt in zip(path, path[1:]):
        est.update(prev, 0.0, nxt, plan)
        gate.append(est.released)
    assert gate == [False, False, True, True] and est.released_at == 3
    est.reset()
    assert not est.released and est.released_at is None
    for prev, nxt in zip(path, path[1:]):  # without the plans: no missed approach
        est.update(prev, 0.0, nxt)
    assert not est.released


def test_adapt_model_stall_sets_the_gate(shared_mpc):
    ctrl = shared_mpc({"mc": 0.8, "mp": 0.2, "L": 0.7}, adapt_model="stall")
    far, steps = ctrl.estimator.stall
    assert ctrl.STALL == (2.0, 3.0)
    assert steps == 60 and not ctrl.estimator.released  # 3 s at dt = 0.05
    # the pole (index 1) 2 rad or more from the upright, the angle wrapped
    for off, want in ((2.01, True), (1.99, False), (-2.01, True), (np.pi, True),
                      (2 * np.pi - 1.5, False), (2 * np.pi - 2.5, True)):
        assert bool(far(np.array([0.3, ctrl.upright + off, 0.0, 0.0]))) is want, off
    assert not far(np.array([ctrl.upright + 3.0, ctrl.upright, 0.0, 0.0]))  # the cart ignored
    # ... or at once when the pole turns round 0.4-1.3 rad from the upright (a missed approach)
    assert ctrl.MISSED == (0.4, 1.3) and callable(ctrl.estimator.miss)
    plan = _rising(ctrl.upright, [-0.6, -0.3])  # on the negative side, the rate > 0: rising
    turn = (lambda off: ctrl.estimator.miss(np.array([0.0, ctrl.upright - off, 0.0, 1.0]),
                                             np.array([0.0, ctrl.upright - off, 0.0, -1.0]),
                                             plan))
    assert turn(0.8) and not turn(0.2) and not turn(2.0)
    assert shared_mpc({"mc": 0.8, "mp": 0.2, "L": 0.7}, adapt_model=True).estimator.stall is None


def test_until_the_gate_opens_the_stall_option_applies_the_default_forces():
    """Until its gate opens, ``adapt_model="stall"`` solves the NLP of the model as given with
    the online correction's gain: the same forces as without the option, exactly.  (Solving
    the coefficients' NLP instead, as an earlier version did without the gain, would not: even
    with the gain, that NLP's rounding differs and changed 1 in 20 mismatched family episodes.)"""
    from lsindy_cas.mpc import SwingUpMPC
    nominal = systems.cart_pendulum(mc=0.7, mp=0.4, L=0.8)
    plant = Plant(systems.cart_pendulum(mc=0.63, mp=0.44, L=0.88), DT)
    forces = []
    for adapt_model in (False, "stall"):
        ctrl = SwingUpMPC(nominal, dt=DT, adapt_model=adapt_model)
        forces.append(run_episode(ctrl, plant, random_starts(60, 1)[0], t_end=2.5).forces)
    # it solved the NLP of the model as given; the one with the coefficients waits
    assert not ctrl.estimator.released and ctrl.nlp is ctrl._nlps[0] and ctrl.nlp.coef0 is None
    assert ctrl._nlps[1].coef0 is not None
    assert ctrl.correction.gain[ctrl.plan_gain_index] != 0  # the gain the first version lost
    np.testing.assert_array_equal(forces[1], forces[0])


@pytest.mark.slow
def test_a_stalled_swing_up_is_rescued_by_the_estimate():
    """Held-out seed 2, start 5 of 0.6/0.2/1.0 with the cart and pole mass 10 % lighter and the
    pole 10 % longer: on the nominal model every relaxed plan reaches the top 1-2 s ahead but
    the pole swings at the bottom for 10 s (never within 2.4 rad of the top); with the estimate
    released after 3 s of that, it is up and held."""
    from lsindy_cas.mpc import SwingUpMPC
    from lsindy_cas.paper.swingup import wrap_angle
    nominal = systems.cart_pendulum(mc=0.6, mp=0.2, L=1.0)
    true = systems.cart_pendulum(mc=0.54, mp=0.18, L=1.1)
    x0 = random_starts(60, 2)[5]
    for adapt_model, up in ((False, False), (None, True)):  # None: the default, "stall"
        ctrl = SwingUpMPC(nominal, dt=DT, adapt_model=adapt_model)
        ep = run_episode(ctrl, Plant(true, DT), x0)
        assert bool(ep.success) is up
        if not up:
            assert np.abs(wrap_angle(ep.X[:, 1] - np.pi)).min() > 2.3
        else:
            assert ctrl.estimator.released


def _short_pole_episode(adapt_model):
    """Held-out seed 1, start 18 of 2.0/0.3/0.3 with cart and pole 10 % heavier and the pole
    10 % shorter, on the nominal model (lost by the model as given -- each
    planned approach falls short or overshoots, 10 s without the top -- and held with the
    estimate taken up at the first approach that turned round short of the top)."""
    from lsindy_cas.mpc import SwingUpMPC
    nominal = systems.cart_pendulum(mc=2.0, mp=0.3, L=0.3)
    true = systems.cart_pendulum(mc=2.2, mp=0.33, L=0.27)
    ctrl = SwingUpMPC(nominal, dt=DT, adapt_model=adapt_model)
    return ctrl, run_episode(ctrl, Plant(true, DT), random_starts(60, 1)[18])


def test_a_missed_approach_lets_the_estimate_into_the_plan():
    ctrl, ep = _short_pole_episode(None)  # the default
    assert ep.success and ep.time_to_upright < 5.0
    # taken up at a missed approach, well before a 3 s stall could have opened the gate
    assert ctrl.estimator.released and ctrl.estimator.released_at < 40


@pytest.mark.slow
def test_the_short_pole_episode_is_lost_without_the_estimate():
    ctrl, ep = _short_pole_episode(False)
    assert not ep.success and ctrl.estimator is None
