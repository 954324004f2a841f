"""The linear system of the energy balance, A ξ = b, as the forms build it: :class:`EnergyBalance`
(with the stacked states and gradients the search and the admissibility rules read)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["EnergyBalance", "is_passive"]


@dataclass
class EnergyBalance:
    """``A ξ = b`` (or ``A ξ = 0`` when ``b`` is None), plus what the search needs to judge supports.

    Attributes
    ----------
    A : array (n_rows, p)
    b : array (n_rows,) or None
    D : array (n_samples * 2n, p)
        Stacked state gradients ∇Θ at the samples.
    X : array (n_samples, 2n)
        Sample states.
    form : str
        ``"derivative"`` or ``"integral"``.
    groups : int array (n_rows,), optional
        Index of the trajectory each row comes from (rows of one trajectory are in time order).
    weights : array (n_rows,), optional
        Row weights already applied (rows are scaled by √w); None means all ones.
    centred : bool
        Rows are deviations from their trajectory's weighted mean (the all-windows integral form);
        then row i belongs to sample i, so ``X``, ``D`` and the rows line up.
    work_rules : list of str, optional
        Integral form, per trajectory: how its work integral was computed — "increments"
        (held force × position increments), "quadrature" (held force × trapezoid of q̇),
        "spline" (smooth force) or "none" (no power) — which the noise model needs.
    dissipation : array (n_rows, r), optional
        Rayleigh dissipation columns (:mod:`lsindy_cas.identify.dissipation`), rows as ``A``'s.
        When set, ``A`` and ``b`` are projected off their span and ``raw`` holds the unprojected
        ``(A, b)``.
    intercept : array (n_rows,), optional
        Compressed (streamed) balance: the rows' entries of the per-trajectory intercept column
        that centred rows are orthogonal to (dense centred rows: √w, see ``intercept_column``).
    n_data_rows : int, optional
        Compressed (streamed) balance (:mod:`lsindy_cas.identify.stream`): the number of rows
        of the uncompressed balance; ``A``, ``b`` then hold block-wise R factors with the same
        Gram matrices, and ``X``, ``D`` a subsample of the states.
    quadrature : float
        Integral form: the squared error of ``b`` expected from the work integral's own
        discretisation (J², rows weighted and centred as ``b``; :func:`work_error`).  On
        noise-free data it is what a correct model leaves; 0 for position increments.
    dissipation_error : array (n_rows, r), optional
        Estimated quadrature error of each entry of ``dissipation`` (integral form).
    """

    A: np.ndarray
    b: np.ndarray | None
    D: np.ndarray
    X: np.ndarray
    form: str
    groups: np.ndarray | None = None
    weights: np.ndarray | None = None
    centred: bool = False
    work_rules: list | None = None
    dissipation: np.ndarray | None = None
    raw: tuple | None = None
    intercept: np.ndarray | None = None
    n_data_rows: int | None = None
    quadrature: float = 0.0
    dissipation_error: np.ndarray | None = None

    @property
    def passive(self) -> bool:
        return self.b is None

    @property
    def compressed(self) -> bool:
        """Rows are block-wise R factors of the balance (streamed), not one row per sample."""
        return self.n_data_rows is not None

    @property
    def n_rows(self) -> int:
        """Rows of the (uncompressed) balance: windows or samples."""
        return len(self.A) if self.n_data_rows is None else int(self.n_data_rows)

    @property
    def per_sample(self) -> bool:
        """Row i belongs to sample i (dense all-windows form): per-sample noise model and EIV."""
        return self.centred and not self.compressed

    def intercept_column(self) -> np.ndarray:
        """(n_rows,): the per-trajectory constant column of centred rows (√w per dense row)."""
        if self.intercept is not None:
            return self.intercept
        return np.sqrt(np.ones(len(self.A)) if self.weights is None else self.weights)

    @property
    def n_groups(self) -> int:
        return 1 if self.groups is None else int(self.groups.max()) + 1


def is_passive(trajectories) -> bool:
    return all(not np.any(tr.power) for tr in trajectories)
