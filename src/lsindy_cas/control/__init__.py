"""Step 5 — control with the equations: the optimal-control problem of one MPC step (``ocp.OCP``)
and its multiple-shooting transcription (``shooting``), the discrete-input MPC on any CasADi ODE
(``mpc``) with its force-choice rules (``rounding``, ``lookahead``) and counters (``stats``), the
online input-gain correction (``correction``), the balancer near the upright (``balancer``) and
the cart-pendulum swing-up controller (``cart_pendulum.SwingUpMPC``).

Rule: nothing here imports :mod:`lsindy_cas.identify`; a controller takes any object with an
``ode()`` (tests check it by reading the imports)."""
