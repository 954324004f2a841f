"""Typed findings: a message for the user together with a stable code for the program.

The diagnostics' warnings and traps, the admissibility rules' rejection reasons and the status'
reasons are :class:`Finding` objects.  The text is what users read (printed, written to the model
file) and may be reworded freely; decisions — which warnings the status drops, which rejected
supports count as rival energies — read only :attr:`Finding.code` (and :attr:`Finding.numbers`).

A :class:`Finding` *is* its message (a ``str`` subclass), so everything that prints, joins,
compares, sorts or JSON-encodes the messages keeps working unchanged; the code and the numbers
travel along (also through pickling, e.g. to Dask workers).  A plain string where a finding is
expected (a user's own admissibility rule) has no code: :func:`code_of` gives ``None``.
"""
from __future__ import annotations

from types import MappingProxyType

__all__ = ["Finding", "UndeterminedError", "code_of", "CODES",
           # diagnostics: warnings
           "WORK_UNEXPLAINED", "NULL_SPACE", "NEAR_TIE",
           # diagnostics: traps and near-tie reasons
           "CONSTANT_INPUT", "CONSERVED_QUANTITIES", "NO_COEFFICIENTS",
           # search and admissibility: why a support is rejected (or that it is admissible)
           "REDUCIBLE", "NO_SCALE", "EXCLUDED_COORDINATE", "VELOCITY_LINEAR", "NOT_SIGNIFICANT",
           "ALL_ZERO", "PRIOR_ZERO", "COEFFICIENT_ZERO", "NOT_POSITIVE_DEFINITE", "ADMISSIBLE",
           # status: why a fit is undetermined
           "STD_PROPAGATED", "STD_JACKKNIFE", "RESIDUAL_ABOVE_NOISE", "ILL_CONDITIONED",
           "INADMISSIBLE_RIVAL", "CONSERVED_UNRESOLVED", "SIMULATION_DRIFT", "K_UNDECIDED"]

# diagnostics.py: warnings
WORK_UNEXPLAINED = "work_unexplained"      # the best model leaves > half of the work unexplained
NULL_SPACE = "null_space"                  # a combination of the chosen terms is not determined
NEAR_TIE = "near_tie"                      # other admissible supports fit about as well
# diagnostics.py: traps, and the reason of a near tie that could not be fitted
CONSTANT_INPUT = "constant_input"          # a constant force acts like a linear potential
CONSERVED_QUANTITIES = "conserved_quantities"  # passive data conserve more than the energy
NO_COEFFICIENTS = "no_coefficients"        # a near tie whose coefficients could not be fitted
# search.py / bnb.py / admissibility.py: rejection reasons
REDUCIBLE = "reducible"                    # rule 0: a smaller support plus round-off
NO_SCALE = "no_scale"                      # rule 0': the scale trial cannot fix the scale
EXCLUDED_COORDINATE = "excluded_coordinate"  # rule 1: a term a constant input leaves open
VELOCITY_LINEAR = "velocity_linear"        # rule 2: a momentum-like term
PRIOR_ZERO = "prior_zero"                  # rule 3: a prior term came out zero
ALL_ZERO = "all_zero"                      # rules 3-4: every coefficient is zero
COEFFICIENT_ZERO = "coefficient_zero"      # rule 4: a support term came out zero
NOT_POSITIVE_DEFINITE = "not_positive_definite"  # rule 5: the kinetic part is not ≻ 0
NOT_SIGNIFICANT = "not_significant"        # rule 6: a term is not significantly non-zero
ADMISSIBLE = "admissible"                  # passed every rule
# status.py: reasons added to the warnings
STD_PROPAGATED = "std_propagated"          # rule 7, propagated standard error too large
STD_JACKKNIFE = "std_jackknife"            # rule 7, jackknife standard error too large
RESIDUAL_ABOVE_NOISE = "residual_above_noise"  # rule 1, χ > CHI_BAD
ILL_CONDITIONED = "ill_conditioned"        # rule 6
INADMISSIBLE_RIVAL = "inadmissible_rival"  # rule 5
CONSERVED_UNRESOLVED = "conserved_unresolved"  # rule 4, passive
SIMULATION_DRIFT = "simulation_drift"      # rule 2
K_UNDECIDED = "k_undecided"                # rule 8: a smaller k's search stopped undecided

CODES = frozenset(v for k, v in globals().items() if k.isupper() and isinstance(v, str))


class Finding(str):
    """A message (the ``str`` itself) with a stable ``code`` and the ``numbers`` behind it.

    ``str(finding)`` and ``finding.message`` are the message; equality and hashing are those of
    the message, so a finding compares equal to its text.  Immutable.
    """

    __slots__ = ("_code", "_numbers")   # set once in __new__

    def __new__(cls, message: str, code: str, numbers: dict | None = None):
        if code not in CODES:
            raise ValueError(f"unknown finding code {code!r}")
        self = super().__new__(cls, message)
        object.__setattr__(self, "_code", code)
        object.__setattr__(self, "_numbers", MappingProxyType(dict(numbers or {})))
        return self

    @property
    def code(self) -> str:
        return self._code

    @property
    def message(self) -> str:
        return str.__str__(self)

    @property
    def numbers(self):
        """The quantities the message states (read-only mapping)."""
        return self._numbers

    def __str__(self) -> str:
        return str.__str__(self)

    def __repr__(self) -> str:
        return f"Finding({self.message!r}, code={self.code!r})"

    def __setattr__(self, name, value):
        raise AttributeError("a Finding is immutable")

    def __delattr__(self, name):
        raise AttributeError("a Finding is immutable")

    def __reduce__(self):
        return Finding, (self.message, self.code, dict(self.numbers))


def code_of(item) -> str | None:
    """The code of a finding; None for a plain string (or anything else)."""
    return item.code if isinstance(item, Finding) else None


class UndeterminedError(ValueError):
    """The data (with this library and these options) do not determine the model: automatic
    selection found no admissible model for any number of terms, or the fitted friction creates
    energy.  A :class:`ValueError`, raised after the search, not for unusable arguments;
    ``lsindy identify`` exits with code 3 on it, as for a fitted model whose status is
    "undetermined" (the same pure-noise data give either answer depending on the noise draw)."""
