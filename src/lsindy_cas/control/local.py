"""The stabiliser near a target, built from the model's own linearisation there: :class:`LocalPolicy`.

The discrete map ``x⁺ = F(x, u)`` is linearised once at the target ``(x*, u*)`` (``u*`` the input
that holds it): ``z⁺ = A z + B v`` with ``z = x − x*`` (angles wrapped) and ``v = u − u*``.  The
discrete-time LQR gives the cost-to-go ``zᵀPz`` and the gain ``K``.

* continuous inputs: ``u = clip(u* − K z)``;
* discrete inputs: every sequence of ``depth`` inputs from the level sets is scored on the linear
  model by its stage costs plus the terminal ``zᵀPz``.  Each sequence's cost is a quadratic in
  ``z₀`` whose quadratic part is the same for all of them, so choosing the best is one
  matrix-vector product (:meth:`__call__`), not a simulation per sequence.

:meth:`region` finds, by simulating the nonlinear model from states on level sets of ``zᵀPz``,
the largest level from which the policy reaches the target band: the controller hands over to
this policy inside it.
"""
from __future__ import annotations

import itertools

import casadi as ca
import numpy as np

__all__ = ["LocalPolicy", "equilibrium_input"]

# sequences scored per decision at most: 3 levels give depth 6 (729); the product stays a
# ~1e-5 s matrix-vector product for the state sizes here
MAX_SEQUENCES = 729


def equilibrium_input(system, x_star, inputs):
    """The input that holds ``x_star`` at rest (least squares on q̈ = a + b u) and the residual
    acceleration it leaves (0 when the target is an equilibrium the inputs can hold)."""
    n = system.n // 2
    zero = np.zeros(system.m)
    a = np.asarray(system.ode(x_star, zero)).ravel()[n:]
    b = np.column_stack([np.asarray(system.ode(x_star, e)).ravel()[n:] - a
                         for e in np.eye(system.m)])
    u, *_ = np.linalg.lstsq(b, -a, rcond=None)
    residual = float(np.linalg.norm(a + b @ u))
    lo = np.array([i.low for i in inputs])
    hi = np.array([i.high for i in inputs])
    return u, residual, bool(np.all((lo - 1e-12 <= u) & (u <= hi + 1e-12)))


class LocalPolicy:
    """LQR (continuous inputs) or linear-model sequence search (discrete inputs) at a target.

    Parameters
    ----------
    system : ControlledSystem
    x_star, u_star : ndarray
        Target state and the input that holds it.
    inputs : list of Input
        The task's inputs (levels or bounds).
    Q, R : ndarray
        State and input weights (diagonal entries).
    depth : int
        Length of the scored sequences of discrete inputs (capped so that at most
        ``MAX_SEQUENCES`` are scored).
    ignore : ndarray of bool (n,), optional
        States whose error is taken as 0: cyclic positions the goal neither bands nor limits
        (the dynamics are the same wherever they are, and the user does not care).
    """

    def __init__(self, system, x_star, u_star, inputs, Q, R, depth=6, ignore=None):
        from scipy.linalg import solve_discrete_are
        self.system, self.x_star, self.u_star = system, np.asarray(x_star, float), u_star
        self.ignore = np.zeros(system.n, bool) if ignore is None else np.asarray(ignore, bool)
        x, u = ca.SX.sym("x", system.n), ca.SX.sym("u", system.m)
        nxt = system.step(x, u)
        jac = ca.Function("linearisation", [x, u], [ca.jacobian(nxt, x), ca.jacobian(nxt, u)])
        A, B = (np.asarray(M) for M in jac(self.x_star, u_star))
        self.A, self.B = A, B
        self.Q, self.R = np.diag(Q), np.diag(R)
        try:
            P = solve_discrete_are(A, B, self.Q, self.R)
        except (np.linalg.LinAlgError, ValueError):
            raise ValueError("the inputs cannot stabilise the target in the model (its "
                             "linearisation there is not stabilisable)") from None
        self.P = 0.5 * (P + P.T)
        self.K = np.linalg.solve(self.R + B.T @ P @ B, B.T @ P @ A)
        self.inputs = inputs
        self.lo = np.array([i.low for i in inputs])
        self.hi = np.array([i.high for i in inputs])
        self.discrete = any(i.discrete for i in inputs)
        if self.discrete:
            self._sequences(depth)

    def _sequences(self, depth):
        cands = [np.asarray(i.candidates()) for i in self.inputs]
        per_step = list(itertools.product(*cands))            # (k, m) input vectors
        k = len(per_step)
        depth = max(1, min(depth, int(np.floor(np.log(MAX_SEQUENCES) / np.log(max(k, 2))))))
        steps = np.asarray(per_step, float) - self.u_star      # v for each choice
        A, B, Q, R, P = self.A, self.B, self.Q, self.R, self.P
        n = A.shape[0]
        seqs = np.array(list(itertools.product(range(k), repeat=depth)))
        S = len(seqs)
        # z_j = A^j z0 + g_j;  cost = Σ_{j<d} (z_jᵀQ z_j + v_jᵀR v_j) + z_dᵀP z_d
        # = z0ᵀΦz0 + 2 z0ᵀ c_s + r_s: only c_s and r_s depend on the sequence
        c, r, g = np.zeros((S, n)), np.zeros(S), np.zeros((S, n))
        Apow = np.eye(n)
        for j in range(depth):
            v = steps[seqs[:, j]]                               # (S, m)
            c += g @ Q @ Apow if j else 0.0                     # g_0 = 0
            r += np.einsum("si,ij,sj->s", g, Q, g) + np.einsum("si,ij,sj->s", v, R, v)
            g = g @ A.T + v @ B.T
            Apow = A @ Apow
        c += g @ P @ Apow
        r += np.einsum("si,ij,sj->s", g, P, g)
        self.seq_c, self.seq_r = c, r
        self.first = np.asarray(per_step, float)[seqs[:, 0]]
        self.depth = depth

    def errors(self, X):
        """``z = x − x*`` with angles wrapped (ignored states 0), for rows of ``X``."""
        Z = self.system.wrap(np.atleast_2d(X) - self.x_star)
        Z[:, self.ignore] = 0.0
        return Z

    def value(self, X):
        """Cost-to-go ``zᵀPz`` of rows of ``X`` (n_rows,)."""
        Z = self.errors(X)
        return np.einsum("si,ij,sj->s", Z, self.P, Z)

    def inputs_for(self, X):
        """The policy's inputs for rows of ``X`` (n_rows, m)."""
        Z = self.errors(X)
        if self.discrete:
            best = np.argmin(2.0 * Z @ self.seq_c.T + self.seq_r, axis=1)
            return self.first[best]
        return np.clip(self.u_star - Z @ self.K.T, self.lo, self.hi)

    def __call__(self, x):
        return self.inputs_for(x)[0]

    def region(self, band, hold_steps, rng, n_dirs=96, limits=None):
        """Largest level ``c`` of ``zᵀPz`` from which the nonlinear model under this policy
        ends inside ``band`` (and within ``limits``) from every sampled state on the level set.

        Levels are tried from a small one upwards by doubling; sample states are random
        directions scaled onto the level set.  Returns 0 if even the smallest fails (the
        controller then never hands over: the swing-up search keeps control).
        """
        n = self.system.n
        D = rng.normal(size=(n_dirs, n))
        D /= np.sqrt(np.einsum("si,ij,sj->s", D, self.P, D))[:, None]   # unit level
        steps = max(hold_steps, int(np.ceil(3.0 / self.system.dt)))
        F = self.system.step.map(n_dirs)
        inner = np.min(band[np.isfinite(band)] ** 2) * np.min(np.linalg.eigvalsh(self.P))
        best, c = 0.0, max(inner, 1e-12) * 1e-2
        for _ in range(40):
            X = self.x_star + np.sqrt(c) * D
            ok = np.ones(n_dirs, bool)
            for _ in range(steps):
                U = self.inputs_for(X)
                X = np.asarray(F(X.T, U.T)).T
                if limits is not None:
                    ok &= np.all((X >= limits[0]) & (X <= limits[1]), axis=1)
                ok &= np.all(np.isfinite(X), axis=1)
                X[~np.isfinite(X)] = 0.0
            ok &= np.all(np.abs(self.errors(X)) <= band, axis=1)
            if not np.all(ok):
                break
            best, c = c, 2.0 * c
        return best
