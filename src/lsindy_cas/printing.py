"""What a person reads: H, L and the equations of motion, rounded, trig-simplified, pretty or LaTeX.

An identified model is a sum of library terms, so a Lagrangian that physics writes as
``θ̇1 θ̇2 cos(θ1 − θ2)`` comes out as ``θ̇1 θ̇2 cos θ1 cos θ2 + θ̇1 θ̇2 sin θ1 sin θ2``.  Here the
coefficients are first rounded to the chosen number of significant digits (so terms whose
coefficients agree at that precision can combine), then sympy's ``trigsimp`` folds the products back
into sums and differences of angles; the simplified form is kept only if it is not longer.

Symbols print as a physicist writes them: ``theta1_dot`` → θ̇₁ (``\\dot{\\theta}_{1}``),
``x_ddot`` → ẍ, ``Q_theta1`` → Q_θ₁.

>>> from lsindy_cas import printing
>>> printing.plain("1.0*a_dot*b_dot*cos(a)*cos(b) + 1.0*a_dot*b_dot*sin(a)*sin(b)")
'a_dot*b_dot*cos(a - b)'
"""
from __future__ import annotations

import numpy as np

from ._validate import relative_energy

__all__ = ["simplify", "plain", "pretty", "latex", "describe", "symbol_latex", "decimal_place",
           "format_pm", "round_coef"]



class _Sympy:
    """``sp.<name>`` imported on first use: what ``lsindy identify`` prints (:func:`model_text`)
    is assembled without sympy (~0.5 s to import); the renderers below need it."""

    def __getattr__(self, name):
        import sympy
        return getattr(sympy, name)


sp = _Sympy()

DIGITS = 4
# Most significant digits a coefficient is printed with when its standard error is tiny (exact
# fits on clean data) or unknown: beyond this the digits are round-off, not information.
MAX_DIGITS = 6


def _check_digits(digits) -> int:
    if isinstance(digits, bool) or not isinstance(digits, int) or not 1 <= digits <= 15:
        raise ValueError(f"digits must be an integer between 1 and 15, got {digits!r}")
    return digits


def _sympify(expr) -> sp.Basic:
    if isinstance(expr, sp.Basic):
        return expr
    if isinstance(expr, str):
        try:
            return sp.sympify(expr)
        except (sp.SympifyError, SyntaxError, TypeError) as exc:
            raise ValueError(f"cannot parse expression {expr!r}: {exc}") from None
    raise TypeError(f"expected a sympy expression or a string, got {type(expr).__name__}")


def _round(expr, digits: int):
    """Floats rounded to ``digits`` significant digits, as exact rationals (so identities are exact)."""
    floats = {f: sp.Rational(format(float(f), f".{digits - 1}e")) for f in expr.atoms(sp.Float)}
    return expr.xreplace(floats)


def _to_floats(expr, digits: int):
    """Non-integer rationals back to (double-precision) decimals; printers drop the zeros."""
    rats = {r: sp.Float(r, 15) for r in expr.atoms(sp.Rational) if not r.is_Integer}
    return expr.xreplace(rats)


def _trigsimp(expr):
    try:
        simpler = sp.trigsimp(expr)
    except (RecursionError, NotImplementedError, TypeError):   # trigsimp's heuristics can fail
        return expr
    return simpler if sp.count_ops(simpler) <= sp.count_ops(expr) else expr


def simplify(expr, digits: int = DIGITS):
    """Round coefficients to ``digits`` significant digits and fold trig products.

    Parameters
    ----------
    expr : sympy expression, ``Eq`` or str
    digits : int
        Significant digits of the coefficients (1–15).

    Returns
    -------
    sympy expression (or ``Eq``)
        E.g. ``0.5000*theta2_dot**2 + theta1_dot*theta2_dot*cos(theta1 - theta2)``.
    """
    digits = _check_digits(digits)
    expr = _sympify(expr)
    if isinstance(expr, sp.Equality):
        return sp.Eq(simplify(expr.lhs, digits), simplify(expr.rhs, digits), evaluate=False)
    exact = _round(sp.expand(expr), digits)
    return _to_floats(_trigsimp(exact), digits)


# ---------------------------------------------------------------------- values with errors
def decimal_place(value: float, std: float, max_digits: int = MAX_DIGITS) -> int:
    """Decimal exponent d to round ``value`` to (to a multiple of 10**d).

    Two significant digits of ``std`` (the usual convention for a standard error), but never more
    than ``max_digits`` significant digits of ``value``: ``(0.04903, 0.00021) -> -4``.
    """
    max_digits = _check_digits(max_digits)
    mag = abs(float(value))
    if mag > 0 and np.isfinite(mag):
        mag = float(f"{mag:.{max_digits - 1}e}")        # 0.09999999 counts as 0.1
    e = int(np.floor(np.log10(mag))) if mag > 0 and np.isfinite(mag) else 0
    floor = e - max_digits + 1
    std = float(std)
    if not (np.isfinite(std) and std > 0):
        return floor
    return max(int(np.floor(np.log10(std))) - 1, floor)


def round_coef(coef, std=None, max_digits: int = MAX_DIGITS) -> np.ndarray:
    """Each coefficient rounded to the decimal place its standard error allows (:func:`decimal_place`).

    Parameters
    ----------
    coef : array (p,)
    std : array (p,), optional
        Standard errors (None, 0 or nan: ``max_digits`` significant digits).
    """
    coef = np.asarray(coef, float)
    std = np.zeros_like(coef) if std is None else np.asarray(std, float)
    out = np.zeros_like(coef)
    for j in np.flatnonzero(coef):
        d = decimal_place(coef[j], std[j], max_digits)
        out[j] = float(round(coef[j] / 10.0 ** d) * 10.0 ** d) if d > 0 else round(coef[j], -d)
    return out


def format_pm(value: float, std: float, max_digits: int = MAX_DIGITS) -> str:
    """``value ± std`` with two significant digits of ``std`` and the value to the same place.

    >>> format_pm(0.049031, 0.000213)
    '0.04903 ± 0.00021'
    >>> format_pm(0.5, 3e-15)              # exact fit: at most six digits, the error as it is
    '0.500000 ± 3e-15'
    """
    value, std = float(value), float(std)
    d = decimal_place(value, std, max_digits)
    if not np.isfinite(std):
        err = "?"
    elif std == 0 or std < 0.5 * 10.0 ** d:      # below the last digit shown
        err = f"{std:.2g}"
    else:
        err = None
    mag = abs(value)
    e = int(np.floor(np.log10(float(f"{mag:.{max_digits - 1}e}")))) if mag > 0 else d
    if -4 <= e <= 6 and d >= -12:
        places = max(-d, 0)
        text = f"{round(value, -d) if d < 0 else round(value / 10.0 ** d) * 10.0 ** d:.{places}f}"
        return text + " ± " + (err if err is not None else f"{std:.{places}f}")
    # very small or large numbers: a common power of ten, (2.300 ± 0.010)e-08
    scale = 10.0 ** e
    places = max(e - d, 0)
    inner = f"{value / scale:.{places}f} ± " + (err if err is not None else
                                                f"{std / scale:.{places}f}")
    return f"({inner})e{e:+03d}"


# ---------------------------------------------------------------------- display symbols
def _dotted(name: str, dots: str):
    from sympy.printing.conventions import split_super_sub
    base, sups, subs = split_super_sub(name)
    out = base + dots
    if sups:
        out += "__" + "__".join(sups)
    if subs:
        out += "_" + "_".join(subs)
    return out


def symbol_latex(coord: str, dots: int = 0) -> str:
    r"""LaTeX of a coordinate or its derivative: ``("theta1", 2)`` -> ``\ddot{\theta}_{1}``."""
    if dots not in (0, 1, 2):
        raise ValueError(f"dots must be 0, 1 or 2, got {dots!r}")
    name = coord if dots == 0 else _dotted(coord, "d" * (dots - 1) + "dot")
    return sp.latex(sp.Symbol(name))


def _classify(name: str, coords):
    """(role, coordinate) for a symbol name: role in {"q", "dot", "ddot", "Q", None}."""
    if coords is not None:
        for c in coords:
            for role, form in (("q", c), ("dot", c + "_dot"), ("ddot", c + "_ddot"), ("Q", "Q_" + c)):
                if name == form:
                    return role, c
        return None, name
    for role, suffix in (("ddot", "_ddot"), ("dot", "_dot")):
        if name.endswith(suffix) and len(name) > len(suffix):
            return role, name[: -len(suffix)]
    if name.startswith("Q_") and len(name) > 2:
        return "Q", name[2:]
    return "q", name


def _display_names(expr, coords, for_latex: bool) -> dict:
    """Map each free symbol to its display Symbol (pretty) or LaTeX string."""
    out = {}
    for s in expr.free_symbols:
        role, c = _classify(s.name, coords)
        if role in (None, "q"):
            display = sp.Symbol(s.name)
        elif role == "dot":
            display = sp.Symbol(_dotted(c, "dot"))
        elif role == "ddot":
            display = sp.Symbol(_dotted(c, "ddot"))
        else:                                                       # applied force Q on c
            if for_latex:
                out[s] = f"Q_{{{sp.latex(sp.Symbol(c))}}}"
                continue
            display = sp.Symbol("Q_" + sp.pretty(sp.Symbol(c), use_unicode=True))
        out[s] = sp.latex(display) if for_latex else display
    return out


# ---------------------------------------------------------------------- renderers
def plain(expr, digits: int = DIGITS) -> str:
    """One line in sympy syntax (valid input again), rounded and trig-simplified."""
    return sp.sstr(simplify(expr, digits), full_prec=False)


def pretty(expr, digits: int = DIGITS, coords=None, wrap: int | None = 100) -> str:
    """Unicode 2-D rendering with θ̇-style symbols (``sympy.pretty``).

    Parameters
    ----------
    coords : list of str, optional
        Coordinate names, to tell ``<q>_dot`` velocities from coordinates that merely end in
        ``_dot``; inferred from the names when omitted.
    wrap : int or None
        Line width (None: no wrapping).
    """
    e = simplify(expr, digits)
    return sp.pretty(e.xreplace(_display_names(e, coords, for_latex=False)), use_unicode=True,
                     num_columns=wrap or 10_000, wrap_line=wrap is not None, full_prec=False)


def latex(expr, digits: int = DIGITS, coords=None) -> str:
    r"""LaTeX, e.g. ``\dot{\theta}_{1} \dot{\theta}_{2} \cos{\left(\theta_{1} - \theta_{2} \right)}``."""
    e = simplify(expr, digits)
    return sp.latex(e, symbol_names=_display_names(e, coords, for_latex=True), full_prec=False)


_STYLES = ("pretty", "latex", "plain")


def rounded(model):
    """``(H, L, equations of motion)`` of a fitted model with each coefficient rounded to the
    place its standard error allows (:func:`round_coef`; ``MAX_DIGITS`` significant digits when
    the model has no standard errors), the equations derived from the rounded L."""
    from .mechanics.euler_lagrange import EulerLagrange
    from .mechanics.linear import expression as combine
    lib = model.library
    coef_h = round_coef(model.coef_, getattr(model, "coef_std_", None))
    coef_l = round_coef(model.lagrangian_coef_, getattr(model, "lagrangian_coef_std_", None))
    L = combine(lib, coef_l)
    R = getattr(model, "rayleigh_", 0)          # friction forces −∂R/∂q̇ stay in the equations
    eoms = EulerLagrange(lib.coords, L, rayleigh=R if R != 0 else None).equations()
    return combine(lib, coef_h), L, eoms


def coefficient_table(model, indent: str = "  ") -> str:
    """The identified coefficients as ``value ± standard error``, one line per term of H and L.

    Returns "" for a model without standard errors (a model file written before they existed).
    """
    std_h = getattr(model, "coef_std_", None)
    if std_h is None:
        return ""
    names = model.library.names
    rows = [(part, names[j], format_pm(coef[j], std[j]))
            for part, coef, std in (("H", model.coef_, std_h),
                                    ("L", model.lagrangian_coef_, model.lagrangian_coef_std_))
            for j in np.flatnonzero(coef)]
    width = max((len(n) for _, n, _ in rows), default=0)
    how = getattr(model, "std_method_", None)
    head = "coefficients ± standard error" + (f" ({how})" if how else "") + ":"
    return "\n".join([head] + [f"{indent}{part}  {name:<{width}}  {pm}" for part, name, pm in rows])


def describe(model, digits: int | None = None, style: str = "pretty") -> str:
    """H, L and the equations of motion of a fitted ``LagrangianSINDy``, ready to print.

    Parameters
    ----------
    model : LagrangianSINDy
        A fitted (or loaded) model.
    digits : int, optional
        Significant digits of every coefficient.  None (default): each coefficient to the
        decimal place its standard error allows (two digits of the error, at most
        ``MAX_DIGITS`` significant digits; :func:`round_coef`).
    style : {"pretty", "latex", "plain"}
        Unicode 2-D, LaTeX (an ``align*`` block) or one line each in sympy syntax.
    """
    if style not in _STYLES:
        raise ValueError(f"style must be one of {_STYLES}, got {style!r}")
    if not hasattr(model, "hamiltonian_"):
        raise ValueError("the model is not fitted yet; call fit() or load()")
    coords = list(model.coords_)
    if digits is None:
        H, L, eoms = rounded(model)
        digits = MAX_DIGITS
    else:
        H, L = model.hamiltonian_, model.lagrangian_
        eoms = model.equations_of_motion()
    R = getattr(model, "rayleigh_", 0)         # friction: Rayleigh function, forces −∂R/∂q̇
    note = ([] if not relative_energy(model) else
            [f"(energy relative: H, L, R up to a constant factor; {model.normalised_by_} has "
             "coefficient 1)"])
    if style == "latex":
        rows = [rf"H &= {latex(H, digits, coords)}", rf"L &= {latex(L, digits, coords)}"]
        rows += [rf"R &= {latex(R, digits, coords)}"] if R != 0 else []
        rows += [rf"{latex(e.lhs, digits, coords)} &= {latex(e.rhs, digits, coords)}" for e in eoms]
        return "\n".join(["\\begin{align*}\n" + " \\\\\n".join(rows) + "\n\\end{align*}"]
                         + ["% " + n for n in note])
    if style == "plain":
        lines = [f"H = {plain(H, digits)}", f"L = {plain(L, digits)}"]
        lines += ([f"R = {plain(R, digits)}"] if R != 0 else []) + note + ["equations of motion:"]
        lines += [f"  {plain(e.lhs, digits)} = {plain(e.rhs, digits)}" for e in eoms]
        return "\n".join(lines)
    blocks = [_labelled("H = ", pretty(H, digits, coords)), _labelled("L = ", pretty(L, digits, coords))]
    blocks += [_labelled("R = ", pretty(R, digits, coords))] if R != 0 else []
    blocks += note + ["equations of motion (M q̈ = F):"]
    blocks += [_labelled("  ", pretty(e, digits, coords)) for e in eoms]
    return "\n".join(blocks)


def _labelled(label: str, block: str) -> str:
    """Prefix a (possibly multi-line) pretty block with a label on its baseline."""
    lines = block.split("\n")
    if len(lines) == 1:
        return label + block
    # the baseline of a sympy pretty block is its lowest line holding a main-level symbol; for
    # sums of fractions/powers that is where '+' / '=' appear
    base = next((i for i, ln in enumerate(lines) if " = " in ln or " + " in ln or " - " in ln),
                len(lines) // 2)
    pad = " " * len(label)
    return "\n".join((label if i == base else pad) + ln for i, ln in enumerate(lines))


def model_text(self) -> str:
    """What ``print(model)`` shows: H, L (R), the equations of motion, the coefficients ± errors.

    Each coefficient of H and L rounded to the place its standard error allows
    (:func:`round_coef`), the equations from the rounded L, R as fitted; ``MAX_DIGITS``
    significant digits at most.  Assembled from the library's templates (``model.texts``), so
    no sympy is needed."""
    if not hasattr(self, "coef_"):
        return "LagrangianSINDy(unfitted)"
    t = self.texts(MAX_DIGITS, round_coef(self.coef_, getattr(self, "coef_std_", None)),
                   round_coef(self.lagrangian_coef_, getattr(self, "lagrangian_coef_std_", None)))
    lines = [f"H = {t['hamiltonian']}", f"L = {t['lagrangian']}"]
    if self.has_friction_:
        lines.append(f"R = {t['rayleigh']}   (friction forces -dR/dq_dot)")
    if relative_energy(self):
        lines.append(f"energy relative: H, L and R up to a constant factor "
                     f"(normalised: coefficient of {self.normalised_by_} = 1)")
    lines.append("equations of motion:")
    lines += [f"  {lhs} = {rhs}" for lhs, rhs in t["equations"]]
    table = coefficient_table(self)
    if getattr(self, "refinement_", None) is not None:     # refine.py imports sympy: only then
        from .identify.refine import current_refinement, refinement_text
        if current_refinement(self) is not None:
            table = refinement_text(self.refinement_) + ("\n" + table if table else "")
    return "\n".join(lines + ([table] if table else []))
