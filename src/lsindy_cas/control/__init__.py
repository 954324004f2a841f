"""Step 5 — control with the equations: a multiple-shooting optimal-control problem (``ocp``), the
discrete-input MPC on any CasADi ODE (``mpc``) with its force-choice rules (``rounding``,
``lookahead``), the online input-gain correction, the balancer near the upright (``balancer``) and
the cart-pendulum swing-up controller (``cart_pendulum.SwingUpMPC``).

Rule: nothing here imports :mod:`lsindy_cas.identify`; a controller takes any object with an
``ode()`` (tests check it by reading the imports)."""
