"""What the choice of k and support records: :class:`Step` (one k's best admissible support
and its held-out error), :class:`Unscored` (a k without a model, and why) and
:class:`Selection` (the outcome of :func:`~lsindy_cas.identify.selection.select`)."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .search import SearchResult

__all__ = ["Step", "Selection", "Unscored"]


@dataclass
class Step:
    """The best admissible support of one size k and its held-out error."""

    k: int
    support: tuple
    coef: np.ndarray = field(repr=False)
    score: float
    cv: float
    cv_folds: np.ndarray = field(repr=False)
    search: SearchResult | None = field(default=None, repr=False)
    beam: bool = False          # found by the beam or branch and bound (not every support scored)
    chi: float = float("nan")


@dataclass
class Selection:
    """Outcome of :func:`select`.

    Attributes
    ----------
    k : int
    support : tuple of int
    coef : array (p,)
    search : SearchResult
        The search at the chosen k (candidates for the diagnostics).
    steps : list of Step
        Every k scored, in order (one entry when k was given).
    automatic : bool
    excluded : list of int
        Library terms left out of the search (see ``exclude``).
    unscored : list of Unscored
        Automatic k: every k of the scan without a model, with the reason (module notes).
    """

    k: int
    support: tuple
    coef: np.ndarray
    search: SearchResult
    steps: list
    automatic: bool
    excluded: list
    unscored: list = field(default_factory=list)

    @property
    def undecided(self) -> list:
        """The k below the chosen one whose search stopped before finding a model or proving
        there is none."""
        return [u for u in self.unscored if not u.proven and u.k < self.k]


@dataclass
class Unscored:
    """A k of the automatic scan without a model: ``proven`` if no admissible k-term model
    exists, otherwise undecided (its search stopped first); ``seconds`` and ``work`` it spent."""

    k: int
    reason: str
    proven: bool
    seconds: float = 0.0
    work: float = 0.0

    def __str__(self) -> str:
        what = "no admissible model" if self.proven else "undecided"
        return f"k = {self.k}: {what} ({self.reason}; {self.seconds:.1f} s)"
