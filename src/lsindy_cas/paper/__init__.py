"""The paper's experiments, built on the library: benchmark systems with known Lagrangians
(``systems``), Table I (``table1``), the baselines SINDy/KRONIC (``baselines``), Figs. 3–4
(``figures``) and the Fig. 5 swing-up experiment (``swingup``, ``swingup_figures``)."""
