"""Model-predictive control with forces from a finite set, on an identified model (Sec. III-C).

:class:`SwingUpMPC` swings a cart-pendulum up and balances it with the cart force restricted to
a finite set (the paper's {-10, 0, +10} N), using only a model's ``ode()``: the actuated
coordinate is the cart, the other the pole, and the upright angle is the unstable rest
equilibrium of that ODE (:func:`find_upright`) unless given.  It is a
:class:`DiscreteInputMPC`, the multiple-shooting MPC on any CasADi ODE with a discrete input
set: each step solves a relaxation warm-started from the shifted previous solution (the input
continuous in ``[min, max]``, or partial outer convexification: one weight per admissible
level, summing to 1), by SQP with HPIPM QPs, then picks one admissible level (by default a
lookahead over all discrete sequences of a few intervals, scored against the relaxed plan's
cost-to-go; or sum-up rounding carried across steps; or plain rounding).  A failed solve falls
back to the shifted previous plan, is counted in ``stats``, and the next step re-solves with
fatrop (IPOPT without it).  Near the upright a balancer (:mod:`~lsindy_cas.control.cart_pendulum.balancer`,
:mod:`~lsindy_cas.control.cart_pendulum.sequence_balancer`) plans with the discrete pushes themselves.

Example
-------
>>> ctrl = SwingUpMPC(model, force_set=(-10.0, 0.0, 10.0), dt=0.05, horizon=40)  # doctest: +SKIP
>>> u = ctrl([0.0, 0.1, 0.0, 0.0])  # one of -10.0, 0.0, 10.0                    # doctest: +SKIP
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from ..._validate import check_choice, check_real, relative_energy
from ..mpc import DiscreteInputMPC, MPCStats
from .balancer import PulseBalancer
from ..coefficients import resolve_adapt_model
from .sequence_balancer import SequenceBalancer
from .track_guard import TrackGuard, check_guard_option
from .upright import find_upright, handover_side, step_kick, swing_up_gate, upright_kick

__all__ = ["DiscreteInputMPC", "MPCStats", "SwingUpMPC", "find_upright"]


def _energy_gap(model, coords, cart_index, pole_index, upright):
    """``casadi.Function`` x (4,) -> ``(H - H_up) / (H_up - H_down)`` from the model's own energy
    (``hamiltonian_`` of a fitted model, ``hamiltonian`` of a system) with the cart at rest: -1
    hanging still, 0 upright and still."""
    from ...symbolic.coords import Coordinates
    H = getattr(model, "hamiltonian_", None)
    H = getattr(model, "hamiltonian", None) if H is None else H
    if H is None:
        raise TypeError("weights['energy'] needs a model with an energy (hamiltonian_).")
    c = Coordinates(coords)
    energy = ca.Function("H", [ca.vertcat(c.q, c.qd)], [c.to_casadi(H)])
    x = ca.SX.sym("x", 4)
    still = ca.vertcat(*[0 if i == 2 + cart_index else x[i] for i in range(4)])
    up = np.zeros(4)
    up[pole_index] = upright
    down = up.copy()
    down[pole_index] += np.pi
    h_up, h_down = float(energy(up)), float(energy(down))
    if not abs(h_up - h_down) > 1e-12:
        raise ValueError("the model's energy is the same hanging and upright; weights['energy'] "
                         "cannot use it.")
    return ca.Function("energy_gap", [x], [(energy(still) - h_up) / (h_up - h_down)])


_SEQUENCE_ONLY = frozenset(SequenceBalancer.__init__.__kwdefaults__) - frozenset(
    PulseBalancer.__init__.__kwdefaults__)  # "auto" passes these to the sequence balancer only


def _balancer_kind(balance):
    """The balancer class and its options chosen by ``balance`` (True, False or a dict)."""
    if not isinstance(balance, (bool, dict)):
        raise TypeError(f"balance must be True, False or a dict of options, got "
                        f"{type(balance).__name__}.")
    if balance is False:
        return None, {}
    options = {} if balance is True else dict(balance)
    method = options.pop("method", "auto" if balance is True else "pulse")
    kinds = {"auto": "auto", "pulse": PulseBalancer, "sequence": SequenceBalancer}
    if method not in kinds:
        raise ValueError(f"balance['method'] must be one of {sorted(kinds)}, got {method!r}.")
    kind = kinds[method]
    own = {"track_margin", "correction"}  # set by the controller itself
    pulse = set(PulseBalancer.__init__.__kwdefaults__)
    if kind == "auto":  # options both take, and the sequence balancer's own (for it only)
        allowed = (pulse | _SEQUENCE_ONLY) - own - {"max_pushes"}
    else:
        allowed = (pulse | set(kind.__init__.__kwdefaults__)) - own
        if kind is SequenceBalancer:
            allowed.discard("max_pushes")
    unknown = set(options) - allowed
    only_seq = unknown & _SEQUENCE_ONLY
    if only_seq and only_seq == unknown:  # a dict without "method" is the pulse balancer's
        raise ValueError(f"balance keys {sorted(only_seq)} are the sequence balancer's only; "
                         f"pass balance={{'method': 'sequence', ...}} to use them.")
    if unknown:
        raise ValueError(f"balance has unknown keys {sorted(unknown)}; known: "
                         f"{sorted(allowed | {'method'})}.")
    return kind, options


class SwingUpMPC(DiscreteInputMPC):
    """Swing-up MPC for a cart-pendulum model, the force restricted to ``force_set``.

    Parameters
    ----------
    model : object
        An identified :class:`~lsindy_cas.LagrangianSINDy` (or any object with ``coords_`` or
        ``coords``, ``actuated_`` or ``actuated``, and ``ode()``) with exactly two coordinates:
        the actuated one is the cart position (m), the other the pole angle (rad).
    force_set : sequence of float
        Admissible cart forces in newtons.
    dt : float
        Control period in seconds.
    horizon : int
        Prediction horizon in control periods.
    track_limit : float
        The cart must stay in ``|x| <= track_limit`` (m).
    track_margin : float
        The predicted states are held in ``|x| <= track_limit - track_margin`` (a soft
        constraint with an exact penalty, so that a solve never becomes infeasible), leaving
        room for model error and rounding.
    upright : float, optional
        Upright pole angle; by default the unstable rest equilibrium of the model's ODE
        (:func:`find_upright`), which is pi for the downward-zero convention.
    actuated : str, optional
        Name of the cart coordinate, overriding the model's ``actuated_``.
    weights : dict, optional
        Cost weights ``{"angle", "position", "velocity", "rate", "terminal", "input",
        "rate_band", "rate_band_weight", "top_rate", "top_rate_band", "energy"}`` (see
        :attr:`default_weights`); ``rate_band`` and ``rate_band_weight`` shape the lookahead's
        penalty on pole rates above ``rate_band`` near the top; ``top_rate`` weighs, in the
        NLP's stage and terminal costs, the pole rate beyond ``top_rate_band`` (rad/s; by
        default :attr:`TOP_RATE_KICKS` of the model's kicks) scaled by ``cos^4`` of half the
        angle from the upright, so that plans arrive at the top slowly enough for the pulse
        balancer to catch them on a plant 10 % off the model; unless given, ``top_rate`` is 0
        (off) where the sequence balancer is chosen (measured to cost success there);
        ``energy`` (default 100) weighs, at the plan's end, the model's own energy with the
        cart at rest against its value upright, scaled to -1 hanging (a slope where the angle
        cost is flat, at the bottom); it needs the model's ``hamiltonian_`` (or a system's
        ``hamiltonian``); unless given, it is 0 (off) where the sequence balancer is chosen and
        for a model without an energy or with one the same hanging and upright (given
        explicitly with such a model: ``TypeError`` or ``ValueError``).
    balance : bool or dict
        Near the upright, choose the force with :class:`~lsindy_cas.control.cart_pendulum.balancer.PulseBalancer`
        (an enumerated MPC over the push sequences themselves, on the model linearised at the
        upright) instead of from the relaxed plan; a dict passes options to it (``horizon``,
        ``max_pushes``, ``rate_band``, ``angle_band``, ``region``, ``max_lean``,
        ``cart_frequency``, ``cart_damping``, ``lean_weight``, ``push_weight``,
        ``mode_weight``, ``track_weight``, ``brake_fraction``); ``{"method": "sequence"}``
        uses :class:`~lsindy_cas.control.cart_pendulum.sequence_balancer.SequenceBalancer` instead (branch
        and bound over all level sequences, for plants whose push is nearly as large as the
        band; its own options ``max_frontier``, ``violation_weight``, ``state_weights``,
        ``centre_weight``, ... are accepted then); a dict without ``"method"`` means the
        pulse balancer.  ``balance=True`` (or ``{"method": "auto"}``, which accepts the options
        both take and the sequence balancer's own, passed to it only) uses the sequence
        balancer when the model's :meth:`kick` is at least :attr:`SEQUENCE_KICK`, the pulse
        balancer otherwise.  Waiting is the balancer's main move, so ``balance=True`` uses it
        only if ``force_set`` contains 0 (a dict without 0 in the set is an error).
    guard : bool or dict
        Keep the cart on the track whatever the controller chose
        (:class:`~lsindy_cas.control.cart_pendulum.track_guard.TrackGuard`): where the model predicts that
        the chosen force followed by its stopping policy could not keep the cart inside
        ``track_limit``, apply the level that reaches least far (counted in
        ``stats.n_guard``); a dict passes ``margin``, ``factor``, ``horizon`` to it.  ``False``
        turns it off (the cart then ran to 10.5 m on a plant that cannot be balanced).
    handover : float, optional
        Distance (m) from the track's centre at which the swing-up is to hand the pole to the
        sequence balancer, on the side the cart's slower creep leaves from
        (:func:`~lsindy_cas.control.cart_pendulum.upright.handover_side`, decided at the first step after
        :meth:`reset`; the swing-up's costs are measured from there, :attr:`reference`).
        None: :attr:`HANDOVER_OFFSET` where gravity turns the pole round only beyond the
        balancer's angle band (its ``turn_lean > angle_band``), else 0 (the centre).
    adapt_lean : bool, optional
        Whether the online correction also fits the plant's gravity torque (a term in the sine
        of the pole's lean, :mod:`~lsindy_cas.control.correction`), used by the sequence
        balancer's predictions.  None: where the sequence balancer is chosen (not on the
        paper plant's pulse balancer).  Needs ``adapt`` (the default).
    adapt_model : bool or "stall", optional
        Whether the relaxed plan uses an online estimate of the model's own coefficients
        (:mod:`~lsindy_cas.control.coefficients`, read from its Lagrangian; ``estimator``);
        ``"stall"``: once a swing-up has stalled (:attr:`STALL`) or missed the top
        (:attr:`MISSED`; until then the model as given, the same forces as False).  None:
        ``"stall"`` where the model's Lagrangian gives its coefficients, else False.
    **options
        Passed to :class:`DiscreteInputMPC` (``solver``, ``relaxation``, ``rounding``,
        ``depth``, ``n_substeps``, ``max_iter``, ``tol``, ``accept_inexact``,
        ``recover_after``, ``adapt``, ``adapt_forgetting``, ``adapt_max_gain``,
        ``adapt_plan``); ``max_iter`` defaults to 7, or :attr:`SEQUENCE_MAX_ITER` where the
        sequence balancer is chosen.

    Attributes
    ----------
    upright : float
        Upright pole angle used by the cost (rad).
    weights : dict
        The cost weights in use (the defaults, those given, and the plant-dependent choices:
        ``top_rate_band``, ``top_rate`` and ``energy`` where not given).
    cart_index, pole_index : int
        Positions of the cart and pole in the model's coordinates.
    stats : MPCStats
        Solve counts and times, accumulated over episodes.
    balancer : PulseBalancer or None
        The balancer near the upright (``balance``).
    guard : TrackGuard or None
        The track guard (``guard``).
    handover : float
        Distance (m) of the hand-over from the centre; ``handover_side`` the episode's side
        (+1, -1, 0; None before its first step).
    plan_ : dict
        Last relaxed plan: ``controls`` (horizon, n_control), ``forces`` (horizon,) relaxed
        forces (N), ``states`` (horizon, 4) predicted x_1..x_N, ``success``.
    """

    #: model kick (rad/s) from which ``balance=True`` uses the sequence balancer: below it the
    #: pulse balancer's few pushes suffice (the paper's plant: 0.5 rad/s)
    SEQUENCE_KICK = 0.6

    default_weights = {"angle": 10.0, "position": 1.0, "velocity": 0.1, "rate": 0.1,
                       "terminal": 10.0, "input": 1e-2,
                       "rate_band": 0.35, "rate_band_weight": 1e3,
                       "top_rate": 1.0, "top_rate_band": None, "energy": 100.0}

    #: default ``top_rate_band``: this many of the model's kicks (1.5 rad/s on the paper plant)
    TOP_RATE_KICKS = 3.0
    #: default warm SQP cap where the sequence balancer is chosen (elsewhere 7)
    SEQUENCE_MAX_ITER = 10
    #: default ``handover`` (m) where the pole turns round only beyond the balancer's angle
    #: band (0.5/0.05/1.2, 60 starts: 32 -> 42 nominal; docs/swingup.md)
    HANDOVER_OFFSET = 0.6
    #: the pulse balancer's ``brake_fraction`` (its own default 0.5; benchmarks/results/pulse_brake.md)
    PULSE_BRAKE = 0.45
    #: ``adapt_model="stall"``: the estimate is taken up once the pole stayed this far (rad) from
    #: the upright (swung < 1.14 rad from hanging) for this long (s), a stalled swing-up ...
    STALL = (2.0, 3.0)
    #: ... or at once when the pole turns round between these angles (rad) from the upright on a
    #: swing the plan had reaching the top (a missed approach, :func:`.upright.swing_up_gate`)
    MISSED = (0.4, 1.3)

    def __init__(self, model, force_set=(-10.0, 0.0, 10.0), *, dt=0.05, horizon=40,
                 track_limit=2.0, track_margin=0.25, upright=None, actuated=None, weights=None,
                 balance=True, guard=True, handover=None, adapt_lean=None, adapt_model=None,
                 **options):
        coords = getattr(model, "coords_", None) or getattr(model, "coords", None)
        if coords is None or not hasattr(model, "ode"):
            raise TypeError("model must be a fitted cart-pendulum model with coords_ and ode().")
        if relative_energy(model):
            raise ValueError("the model's energy is relative (passive data without a scale "
                             "record): the force's effect is known only up to a constant factor, "
                             "so it cannot be controlled; identify it with a scale record "
                             "(lsindy identify --scale TRAJ, a short actuated run).")
        coords = list(coords)
        if len(coords) != 2:
            raise ValueError(f"model must have exactly two coordinates (cart, pole), got "
                             f"{coords}.")
        if actuated is None:
            act = getattr(model, "actuated_", None) or getattr(model, "actuated", None) or []
            act = [act] if isinstance(act, str) else [a for a in act if a in coords]
            if len(act) != 1:
                raise ValueError(f"model must have exactly one actuated coordinate (the cart), "
                                 f"got {act}; pass actuated= to choose one.")
            actuated = act[0]
        if actuated not in coords:
            raise ValueError(f"actuated must be one of {coords}, got {actuated!r}.")
        self.track_limit = check_real("track_limit", track_limit, positive=True)
        track_margin = check_real("track_margin", track_margin, nonnegative=True)
        if not track_margin < self.track_limit:
            raise ValueError(f"track_margin must be in [0, track_limit), got {track_margin!r}.")
        self.coords, self.cart, ic = coords, actuated, coords.index(actuated)
        ip, ode = 1 - ic, model.ode()
        if not isinstance(ode, ca.Function) or ode.size1_in(0) != 4 or ode.size1_in(1) != 2:
            raise ValueError("model.ode() must be a casadi.Function (x (4,), u (2,)) -> xdot.")
        self.upright = float(find_upright(ode, ic, ip) if upright is None else upright)
        unknown = set(weights or {}) - set(self.default_weights)
        if unknown:
            raise ValueError(f"weights has unknown keys {sorted(unknown)}; known: "
                             f"{sorted(self.default_weights)}.")
        w = dict(self.default_weights, **(weights or {}))
        kind, balance_options = _balancer_kind(balance)  # checked before the NLP is built
        kick = upright_kick(ode, ic, ip, self.upright, dt, options.get("n_substeps", 1),
                             force_set)
        if w["top_rate_band"] is None:  # a plant-dependent rate: TOP_RATE_KICKS pushes' worth
            w["top_rate_band"] = self.TOP_RATE_KICKS * kick
        sequence = kind is SequenceBalancer or (kind == "auto" and kick >= self.SEQUENCE_KICK)
        if sequence:
            # the warm SQP's cap of 7 (p99 under 20 ms on the pulse balancer's plants) cost 3 of
            # 240 nominal and 3 of 208 mismatched family episodes on the sequence one's: 10 there
            options.setdefault("max_iter", self.SEQUENCE_MAX_ITER)
        if "top_rate" not in (weights or {}) and sequence:
            # measured to help the pulse balancer's plants (paper plant: no mismatched start lost
            # with fatrop), to hurt the sequence balancer's (MuJoCo light cart: 20/20 -> 16/20)
            w["top_rate"] = 0.0
        check_guard_option(guard)
        x = ca.SX.sym("x", 4)
        # 1 - cos(a) = 2 sin(a/2)^2: a residual whose square is wrap-invariant
        half = (x[ip] - self.upright) / 2
        # arriving at the top slowly: the pole rate beyond a band, weighted by cos^4(phi / 2);
        # a fast plan is caught only if the model is right (10 % off: it spins around)
        top = ca.fmax(ca.fabs(x[2 + ip]) * ca.cos(half) ** 4 - w["top_rate_band"], 0)
        r = ca.vertcat(ca.sqrt(2 * w["angle"]) * ca.sin(half),
                       ca.sqrt(w["position"]) * x[ic] / self.track_limit,
                       ca.sqrt(w["velocity"]) * x[2 + ic], ca.sqrt(w["rate"]) * x[2 + ip],
                       ca.sqrt(w["top_rate"]) * top)
        lb, ub = np.full(4, -np.inf), np.full(4, np.inf)
        lb[ic], ub[ic] = -(self.track_limit - track_margin), self.track_limit - track_margin
        # discrete pushes near the top: keep the pole rate inside a band (rad/s)
        band = w["rate_band_weight"] * ca.fmax(
            ca.fabs(x[2 + ip]) * ca.cos(half) ** 2 - w["rate_band"], 0) ** 2
        options.setdefault("lookahead_penalty", ca.Function("band", [x], [band]))
        r_end = ca.sqrt(w["terminal"]) * r
        if "energy" not in (weights or {}) and sequence:
            # for the pulse balancer's slow pendulums, whose 2 s plans cannot see the top from
            # rest; on the sequence balancer's plants it only reshuffled hand-overs (60-start
            # family: nominal 485 -> 485, mismatch 367 -> 364; MuJoCo light cart 20 -> 18/20)
            w["energy"] = 0.0
        if check_real("weights['energy']", w["energy"], nonnegative=True) > 0:
            # the plan's end: the pole's energy against its value upright (a slope where the
            # angle cost is flat, hanging; 2.0/0.5/1.5 from rest: docs/swingup.md)
            try:
                gap = _energy_gap(model, coords, ic, ip, self.upright)
                r_end = ca.vertcat(r_end, ca.sqrt(w["energy"]) * gap(x))
            except (TypeError, ValueError):  # no energy, or one it cannot use: off by default
                if "energy" in (weights or {}):
                    raise
                w["energy"] = 0.0
        self.weights = w
        adapt_model, options["coefficients"] = resolve_adapt_model(adapt_model, model, coords)
        if adapt_model == "stall":  # until then the NLP of the model as given
            options["gate"] = swing_up_gate(ip, self.upright, check_real("dt", dt, positive=True),
                                            self.STALL, self.MISSED)
        self.adapt_model = adapt_model  # False, True or "stall"
        self.cart_index, self.pole_index = ic, ip
        # built by _before_build, after the model's step and before the NLP (bad options first)
        self._parts = (guard, balance, kind, balance_options, track_margin, handover,
                       check_choice("adapt_lean", adapt_lean, (None, False, True)))
        super().__init__(ode, force_set, input_index=ic,
                         stage_residual=ca.Function("r", [x], [r]),
                         terminal_residual=ca.Function("rN", [x], [r_end]),
                         dt=dt, horizon=horizon, state_lb=lb, state_ub=ub,
                         input_weight=w["input"], **options)
        self.plan_gain_index = 2 + ip  # the plan uses the pole's input gain (adapt_plan)

    def _before_build(self):
        """The track guard and the balancer(s), from the model's step (DiscreteInputMPC hook)."""
        guard, balance, kind, balance_options, track_margin, handover, lean = self._parts
        del self._parts
        ic, ip = self.cart_index, self.pole_index
        self.guard = None
        if guard is not False:
            self.guard = TrackGuard(self.step_function, self.levels, cart_index=ic,
                                    input_index=ic, track_limit=self.track_limit, dt=self.dt,
                                    **(guard if isinstance(guard, dict) else {}))
        self.balancer = None
        if balance is True and 0.0 not in self.levels:
            kind = None  # nothing to wait with: the relaxed plan decides everywhere
        self._escalation = None  # (pulse, sequence balancer) while "auto" may switch
        own = {PulseBalancer: {"brake_fraction": self.PULSE_BRAKE}}  # unless balance= sets it
        build = (lambda k: k(self.step_function, self.ocp.ode, self.levels, cart_index=ic,
                             pole_index=ip, upright=self.upright, track_limit=self.track_limit,
                             dt=self.dt, track_margin=track_margin, correction=self.correction,
                             **{**own.get(k, {}), **{key: v for key, v in balance_options.items()
                                if k is SequenceBalancer or key not in _SEQUENCE_ONLY}}))
        if kind == "auto":
            kind = (SequenceBalancer if self.kick() >= self.SEQUENCE_KICK
                    else PulseBalancer)
            if kind is PulseBalancer and self.correction is not None:
                # the plant's push may be stronger than the model's: switch when the online
                # estimate of the push (the correction's gain) brings it to SEQUENCE_KICK
                self._escalation = (build(PulseBalancer), build(SequenceBalancer),
                                    self.kick())
                kind = None
                self.balancer = self._escalation[0]
        if kind is not None:
            self.balancer = build(kind)
        # where the swing-up hands over (module upright): off-centre where the pole turns
        # round only beyond the balancer's angle band
        sequence = isinstance(self.balancer, SequenceBalancer)
        if lean and self.correction is None:
            raise ValueError("adapt_lean=True needs the online correction (adapt=True).")
        if (sequence if lean is None else lean) and self.correction is not None:
            self.correction.lean = (ip, float(self.upright))  # the correction's lean term
            self.correction.reset()
        if handover is None:
            hard = sequence and self.balancer.turn_lean > self.balancer.angle_band
            handover = self.HANDOVER_OFFSET if hard else 0
        self.handover = check_real("handover", handover, nonnegative=True)
        if self.handover and not sequence:
            raise ValueError("handover needs the sequence balancer (balance={'method': "
                             "'sequence'}): the side comes from its linearisation.")
        if not self.handover < self.track_limit - track_margin:
            raise ValueError(f"handover must be in [0, track_limit - track_margin), got "
                             f"{handover!r}.")

    def kick(self):
        """The model's pole-rate change (rad/s) over one period of the largest force, from rest
        at the upright (first order: ``F dt / (m_c L)``), from the linearised discrete step."""
        return step_kick(self.step_function, self.cart_index, self.pole_index, self.upright,
                          self.levels)

    def reset(self):
        """Forget the warm start, the rounding memory and the balancer's mode (see
        :meth:`DiscreteInputMPC.reset`); an escalated balancer returns to the pulse one."""
        super().reset()
        if getattr(self, "_escalation", None) is not None:
            self.balancer = self._escalation[0]
            self._escalation[1].reset()
        if getattr(self, "balancer", None) is not None:
            self.balancer.reset()
        self.handover_side = None  # decided at the next step (handover)
        if self.handover:  # otherwise a reference the user set stays
            self.reference[self.cart_index] = 0.0

    def _escalate(self):
        """With ``balance=True`` and the pulse balancer chosen from the model's kick: switch to
        the sequence balancer, for the rest of the episode, once the online correction's
        estimate of the push (``kick * (1 + gain)`` of the pole rate) reaches
        :attr:`SEQUENCE_KICK` -- the plant's push is then too large for a few pulses (measured:
        start 42 of the 80 mismatched ones, a plant 10 % lighter and shorter than the model,
        kick 0.62 rad/s, was lost by the pulse balancer and held by the sequence one)."""
        pulse, sequence, kick = self._escalation
        if self.balancer is sequence:
            return
        gain = float(self.correction.gain[2 + self.pole_index])
        if kick * (1.0 + gain) >= self.SEQUENCE_KICK:
            self.balancer = sequence
            self.stats.n_escalated += 1

    @property
    def _uses_correction(self):
        """The lookahead's and the balancer's predictions both use the online correction."""
        return super()._uses_correction or self.balancer is not None

    def _applied(self, x, index, t_start, c_start, kind):
        """Apply level ``index`` unless the track guard overrides it (then the guard's level
        is what the online correction and the stats record)."""
        if self.guard is not None:
            safe = self.guard(x, index)
            if safe != index:
                self.stats.n_guard += 1
                index = safe
        return super()._applied(x, index, t_start, c_start, kind)

    def _own_level(self, x):
        """The balancer's level near the upright (None elsewhere or without a balancer);
        at an episode's first step, the hand-over's side (``handover``)."""
        if self.handover and self.handover_side is None:
            self.handover_side = handover_side(self.balancer, x)
            self.reference[self.cart_index] = self.handover_side * self.handover
        if self.balancer is None:
            return None
        if self._escalation is not None:
            self._escalate()
        return self.balancer(x)
