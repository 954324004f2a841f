"""Step 4 — from an energy to motion: the Legendre transform H → L (``legendre``, paper eq. 7) and
the Euler–Lagrange equations M(q) q̈ = F as a CasADi ODE and sympy equations (``euler_lagrange``)."""
