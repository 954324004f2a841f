"""Generalized coordinates: names -> CasADi SX and sympy symbols, and expression conversion.

A coordinate named ``theta`` gives the position symbol ``theta`` and the velocity symbol
``theta_dot``; an applied generalized force on it is written ``Q_theta``.  Expressions that people
write (features, prior terms, saved models) are sympy strings over these names; everything numeric
is CasADi SX built from the same sympy tree, so a term's name and its expression cannot drift apart.

sympy is imported only when a sympy symbol or expression is asked for (``q_sym``, ``parse``,
``to_casadi``): the numeric path (``q``, ``qd``, ``Q``, names) does without it (~0.5 s to import).
"""
from __future__ import annotations

import keyword
import re
from tokenize import TokenError
from dataclasses import dataclass, field

import casadi as ca

__all__ = ["Coordinates", "sympy_to_casadi"]

_NAME = re.compile(r"^[A-Za-z][A-Za-z0-9_]*$")


def _check_names(names) -> list[str]:
    if isinstance(names, str):
        names = [s.strip() for s in names.split(",") if s.strip()]
    try:
        names = list(names)
    except TypeError:
        raise TypeError(f"coords must be a list of coordinate names, got {type(names).__name__}") from None
    if not names:
        raise ValueError("coords must name at least one generalized coordinate")
    for n in names:
        if not isinstance(n, str):
            raise TypeError(f"coordinate names must be strings, got {n!r}")
        if not _NAME.match(n) or keyword.iskeyword(n) or n.endswith("_dot") or n.startswith("Q_"):
            raise ValueError(
                f"invalid coordinate name {n!r}: use a plain identifier that does not end in '_dot' "
                "or start with 'Q_'")
        if n in {"t", "E", "I", "S", "N", "O", "pi"}:
            raise ValueError(f"coordinate name {n!r} clashes with a reserved sympy name; choose another")
    if len(set(names)) != len(names):
        raise ValueError(f"coordinate names must be unique, got {names}")
    return names


_SX_NAMES = {"sin": ca.sin, "cos": ca.cos, "tan": ca.tan, "exp": ca.exp, "log": ca.log,
              "sinh": ca.sinh, "cosh": ca.cosh, "tanh": ca.tanh, "asin": ca.asin, "acos": ca.acos,
              "atan": ca.atan, "Abs": ca.fabs, "sign": ca.sign}


def _sx_funcs() -> dict:
    """sympy function class -> CasADi function (sympy imported on first use)."""
    global _SX_FUNCS_CACHE
    if _SX_FUNCS_CACHE is None:
        import sympy as sp
        _SX_FUNCS_CACHE = {getattr(sp, name): f for name, f in _SX_NAMES.items()}
    return _SX_FUNCS_CACHE


_SX_FUNCS_CACHE = None


def sympy_to_casadi(expr, table: dict) -> ca.SX:
    """Convert a sympy expression to CasADi SX.

    Parameters
    ----------
    expr : sympy.Expr
        Expression over the symbols in ``table``.
    table : dict
        Maps sympy Symbols to CasADi SX scalars.

    Returns
    -------
    casadi.SX
        A 1x1 SX expression.
    """
    import sympy as sp
    if expr.is_Symbol:
        if expr not in table:
            raise ValueError(f"unknown symbol {expr} in expression")
        return table[expr]
    if expr.is_Number or expr in (sp.pi, sp.E):
        return ca.SX(float(expr))
    if expr.is_Add:
        out = ca.SX(0)
        for a in expr.args:
            out = out + sympy_to_casadi(a, table)
        return out
    if expr.is_Mul:
        out = ca.SX(1)
        for a in expr.args:
            out = out * sympy_to_casadi(a, table)
        return out
    if expr.is_Pow:
        base, exp_ = expr.args
        b = sympy_to_casadi(base, table)
        if exp_.is_Integer:
            n = int(exp_)
            if n >= 0:
                return ca.constpow(b, n)
            return 1 / ca.constpow(b, -n)
        if exp_ == sp.Rational(1, 2):
            return ca.sqrt(b)
        return b ** sympy_to_casadi(exp_, table)
    fn = _sx_funcs().get(expr.func)
    if fn is not None:
        return fn(sympy_to_casadi(expr.args[0], table))
    raise ValueError(f"cannot convert {expr.func.__name__} in {expr} to CasADi")


@dataclass
class Coordinates:
    """Symbols for a set of generalized coordinates.

    Parameters
    ----------
    names : list of str
        Coordinate names, e.g. ``["x", "theta"]``.

    Attributes
    ----------
    q, qd, Q : casadi.SX
        Column vectors (n, 1) of positions, velocities (``<q>_dot``) and applied forces (``Q_<q>``).
    q_sym, qd_sym, Q_sym : list of sympy.Symbol
        The matching sympy symbols (real).
    """

    names: list
    q: ca.SX = field(init=False, repr=False)
    qd: ca.SX = field(init=False, repr=False)
    Q: ca.SX = field(init=False, repr=False)

    def __post_init__(self):
        self.names = _check_names(self.names)
        self.q = ca.vertcat(*[ca.SX.sym(n) for n in self.names])
        self.qd = ca.vertcat(*[ca.SX.sym(n + "_dot") for n in self.names])
        self.Q = ca.vertcat(*[ca.SX.sym("Q_" + n) for n in self.names])

    def _symbols(self, fmt: str) -> list:
        """Real sympy symbols named ``fmt.format(name)``, made once (sympy imported here)."""
        cache = self.__dict__.setdefault("_sym", {})
        if fmt not in cache:
            import sympy as sp
            cache[fmt] = [sp.Symbol(fmt.format(n), real=True) for n in self.names]
        return cache[fmt]

    @property
    def q_sym(self) -> list:
        """sympy symbols of the positions (real)."""
        return self._symbols("{}")

    @property
    def qd_sym(self) -> list:
        """sympy symbols of the velocities ``<q>_dot`` (real)."""
        return self._symbols("{}_dot")

    @property
    def Q_sym(self) -> list:
        """sympy symbols of the applied forces ``Q_<q>`` (real)."""
        return self._symbols("Q_{}")

    @property
    def n(self) -> int:
        """Number of generalized coordinates."""
        return len(self.names)

    @property
    def state_names(self) -> list[str]:
        """Names of the state ``x = [q, q_dot]``."""
        return self.names + [n + "_dot" for n in self.names]

    @property
    def x(self) -> ca.SX:
        """State vector ``[q; q_dot]`` as SX (2n, 1)."""
        return ca.vertcat(self.q, self.qd)

    def _sympy_locals(self, with_forces: bool) -> dict:
        syms = self.q_sym + self.qd_sym + (self.Q_sym if with_forces else [])
        return {str(s): s for s in syms}

    def parse(self, text, what: str = "expression", with_forces: bool = False):
        """Parse a string over the coordinate names into a sympy expression.

        Raises ``ValueError`` naming ``what`` if the text is not valid or uses an unknown name.
        """
        import sympy as sp
        if isinstance(text, sp.Expr):
            expr = text
        else:
            if not isinstance(text, str):
                raise TypeError(f"{what} must be a string, got {type(text).__name__}")
            if not text.strip():
                raise ValueError(f"{what} is empty")
            try:
                expr = sp.sympify(text, locals=self._sympy_locals(with_forces))
            except (sp.SympifyError, SyntaxError, TypeError, AttributeError, TokenError) as exc:
                raise ValueError(f"cannot parse {what} {text!r}: {exc}") from None
        if not isinstance(expr, sp.Expr):
            raise ValueError(f"{what} {text!r} is not an expression")
        allowed = set(self._sympy_locals(with_forces).values())
        unknown = sorted(str(s) for s in expr.free_symbols if s not in allowed)
        if unknown:
            known = ", ".join(self.state_names)
            raise ValueError(f"{what} {text!r} uses unknown name(s) {', '.join(unknown)}; "
                             f"known coordinates: {known}")
        funcs = _sx_funcs()
        if expr.atoms(sp.Function) and any(f.func not in funcs for f in expr.atoms(sp.Function)):
            bad = sorted({f.func.__name__ for f in expr.atoms(sp.Function) if f.func not in funcs})
            raise ValueError(f"{what} {text!r} uses unsupported function(s) {', '.join(bad)}")
        return expr

    def to_casadi(self, expr, with_forces: bool = False) -> ca.SX:
        """Convert a sympy expression over these coordinates to SX over ``q``, ``qd`` (and ``Q``)."""
        import sympy as sp
        table = dict(zip(self.q_sym, ca.vertsplit(self.q)))
        table.update(zip(self.qd_sym, ca.vertsplit(self.qd)))
        if with_forces:
            table.update(zip(self.Q_sym, ca.vertsplit(self.Q)))
        return sympy_to_casadi(sp.sympify(expr), table)
