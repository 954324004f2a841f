"""One interval of the multiple-shooting NLP, written once, and the NLP built from stage functions.

:class:`StageTerms` gives the constraint rows, their bounds, the cost terms and the Gauss-Newton
residuals of one control interval.  :class:`~lsindy_cas.control.shooting.MultipleShootingNLP`
writes its expanded (SX) NLP with it, stage after stage; :func:`staged_nlp` builds the *same*
NLP from three small functions -- the first interval (from the measured state), a middle one
(mapped over the ``N - 1`` others) and the terminal cost -- as a CasADi MX graph.

Why both: the SX NLP runs fastest in CasADi's virtual machine, but compiled to C (``jit=True``)
it is one function per derivative with the horizon unrolled (a 107,000-instruction Hessian on the
paper's plant): gcc needed 35-60 s for the first build of a model.  Generated from the staged
graph, the derivatives loop over one interval's code: the first build compiles in about 8 s and
the steps are as fast (``benchmarks/bench_mpc.py``).  Values and derivatives agree with
the SX NLP to rounding (about 1e-15 on the swing-up; ``tests/test_staged.py`` checks 1e-13).
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

__all__ = ["StageTerms", "staged_nlp"]


@dataclass(frozen=True, eq=False)
class StageTerms:
    """The terms of one interval of the NLP (see :class:`~lsindy_cas.control.shooting.OCP`).

    ``kind`` is ``"first"`` (interval 0: its start is the measured state, no slack, no state
    bounds), ``"mid"`` (intervals 1 .. N-1) or ``"terminal"`` (the cost of ``x_N`` only).
    """

    ocp: object
    levels: np.ndarray
    relaxation: str
    bounded: tuple
    n_slack: int
    slack_weight: float

    def terms(self, kind, x, c, s, xn, gain, ref, coef, negate_gap):
        """Rows, lower and upper bounds, cost terms (summed in order) and residuals of one
        interval: ``x`` its start, ``c`` its control vector, ``s`` its slack, ``xn`` the next
        state; ``negate_gap`` writes the shooting gap as ``F(x, u) - xn`` (HPIPM's sign)."""
        ocp, dt, weight = self.ocp, self.ocp.dt, self.ocp.input_weight
        if kind == "terminal":
            r = ocp.terminal_residual(x - ref)
            return [], [], [], [ca.sumsqr(r)], [r]
        rows, lb, ub, costs, residuals = [], [], [], [], []
        if self.relaxation == "poc":
            force = ca.dot(ca.DM(self.levels), c)
            penalty = ca.dot(c, ca.DM((self.levels / ocp.scale) ** 2))
        else:
            force = c[0]
            penalty = (c[0] / ocp.scale) ** 2
        u = ocp.full_input((1 + gain) * force)
        nxt = ocp.step(x, u) if ocp.param_ode is None else ocp.param_step(x, u, coef)
        gap = xn - nxt  # fatrop wants x_{k+1} - F, HPIPM F - x_{k+1}
        rows.append(-gap if negate_gap else gap)
        lb += [0.0] * ocp.n_state
        ub += [0.0] * ocp.n_state
        if self.relaxation == "poc":
            rows.append(ca.sum1(c) - 1)
            lb.append(0.0)
            ub.append(0.0)
        r = ocp.stage_residual(x - ref)
        costs.append(dt * (ca.sumsqr(r) + weight * penalty))
        if kind == "mid":
            residuals.append(np.sqrt(dt) * r)
            for i in self.bounded:  # soft bounds: lb_i <= x_i + s and x_i - s <= ub_i
                rows += [x[i] + s, x[i] - s]
                lb += [ocp.state_lb[i], -np.inf]
                ub += [np.inf, ocp.state_ub[i]]
        if self.relaxation == "continuous":
            residuals.append(np.sqrt(dt * weight) * c[0] / ocp.scale)
        if self.n_slack and kind == "mid":
            costs.append(self.slack_weight * (ca.sum1(s) + ca.sumsqr(s)))
            residuals.append(np.sqrt(self.slack_weight) * s)
        return rows, lb, ub, costs, residuals

    def function(self, kind, n_control, n_coef, negate_gap):
        """The interval as an SX function ``(x, c, s, xn, gain, ref, coef) -> (g, f)``, without
        the inputs that are empty or unused (called by name, see :func:`staged_nlp`): CasADi
        generates invalid C for an empty input of a mapped function."""
        n = self.ocp.n_state
        sizes = {"x": n, "c": n_control, "s": self.n_slack if kind == "mid" else 0, "xn": n,
                 "gain": 1, "ref": n, "coef": n_coef}
        if kind == "terminal":
            sizes.update(c=0, s=0, xn=0, gain=0, coef=0)
        args = {name: ca.SX.sym(name, size) for name, size in sizes.items()}
        rows, _, _, costs, _ = self.terms(kind, *args.values(), negate_gap=negate_gap)
        cost = 0
        for term in costs:
            cost += term
        names = [name for name, size in sizes.items() if size]
        return ca.Function(f"stage_{kind}", [args[a] for a in names],
                           [ca.vertcat(*rows), cost], names, ["g", "f"])


def staged_nlp(terms, n_var, n_control, horizon, n_coef, negate_gap):
    """The NLP ``{"x", "p", "f", "g"}`` as an MX graph of stage functions (see the module).

    The decision vector is ``[c_0, x_1, c_1, s_1, x_2, ..., c_{N-1}, s_{N-1}, x_N]`` and the
    parameter ``[x_0, gain, ref, coef]``, as in
    :class:`~lsindy_cas.control.shooting.MultipleShootingNLP`; the rows come stage by stage.
    """
    n, n_s = terms.ocp.n_state, terms.n_slack
    z = ca.MX.sym("z", n_var)
    p = ca.MX.sym("p", 2 * n + 1 + n_coef)
    shared = {"gain": p[n], "ref": p[n + 1:2 * n + 1], "coef": p[2 * n + 1:]}

    def call(function, **args):
        args = {name: value for name, value in dict(args, **shared).items()
                if name in function.name_in()}
        return function.call(args)

    w0 = n_control + n
    x1 = z[n_control:w0]
    first = terms.function("first", n_control, n_coef, negate_gap)
    out = call(first, x=p[:n], c=z[:n_control], xn=x1)
    g, f, x_last = [out["g"]], out["f"], x1
    if horizon > 1:
        w = n_control + n_s + n
        block = ca.reshape(z[w0:], w, horizon - 1)  # column k - 1: [c_k, s_k, x_{k+1}]
        nxt = block[n_control + n_s:, :]
        starts = ca.horzcat(x1, nxt[:, :horizon - 2]) if horizon > 2 else x1
        mid = terms.function("mid", n_control, n_coef, negate_gap).map(horizon - 1)
        out = call(mid, x=starts, c=block[:n_control, :], s=block[n_control:n_control + n_s, :],
                   xn=nxt)
        g.append(ca.vec(out["g"]))
        f = f + ca.sum2(out["f"])
        x_last = nxt[:, -1]
    f = f + call(terms.function("terminal", n_control, n_coef, negate_gap), x=x_last)["f"]
    return {"x": z, "p": p, "f": f, "g": ca.vertcat(*g)}
