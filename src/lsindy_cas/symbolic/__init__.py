"""Step 1 of the pipeline — the symbols: coordinate names → CasADi/sympy symbols (``coords``) and
the candidate library Θ(q, q̇) as named CasADi SX terms with exact derivatives (``library``)."""
