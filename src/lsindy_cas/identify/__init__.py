"""Step 3 — the energy from data: the energy balance (``balance``), the best-subset search
(``search``, ``subset_tree``), physical admissibility (``admissibility``), the choice of k
(``selection``), the noise model and errors-in-variables correction (``uncertainty``), the report
(``diagnostics``) and the estimator that runs them in order (``estimator.LagrangianSINDy``).

Rule: nothing here imports :mod:`lsindy_cas.paper` (tests check it by reading the imports)."""
