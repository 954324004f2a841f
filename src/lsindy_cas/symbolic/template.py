"""What a fitted model prints, as templates linear in its coefficients, computed once per library.

Everything a fit prints and writes is linear in the fitted coefficients: H = Σ c_j θ_j,
L = Σ c^L_j θ_j, and row i of the equations of motion is Σ_j c^L_j EL_i[θ_j] = Q_i − ∂R/∂q̇_i with
the Euler–Lagrange operator applied to one term,

    EL_i[θ] = Σ_k ∂²θ/∂q̇_i∂q̇_k q̈_k + Σ_k ∂²θ/∂q̇_i∂q_k q̇_k − ∂θ/∂q_i,

and R = Σ ρ_j R_j likewise.  So sympy is needed once per library: for every term j its velocity
degree, the positions it depends on, and θ_j, EL_i[θ_j] and ∂θ_j/∂q̇_i expanded into
(coefficient, monomial) pairs, the monomials printed by sympy (canonical strings: equal monomials
of different terms are equal strings and merge).  The record is kept in the disk cache
(:mod:`.fcache`), so a library seen before prints and writes its models without importing sympy:
:func:`format_float` and :func:`text` turn ``{monomial: coefficient}`` into sympy syntax.
"""
from __future__ import annotations

import re

import numpy as np

from . import fcache

__all__ = ["Template", "format_float", "text"]

FORMAT = 1          # bump when the record's content changes


class Template:
    """The per-term facts of a library (see the module text), from the cache or built with sympy.

    The velocity degrees and positions of every term form one record (the search's admissibility
    needs them all); the expanded rows (θ_j, EL_i[θ_j], ∂θ_j/∂q̇_i) are derived only for the terms
    a model uses and added to a second record, so a library of hundreds of terms pays sympy for
    the few terms of its models only, once.

    Parameters
    ----------
    library : Library
        The library; only its coordinates, names and (on a cache miss) sympy terms are used.
    """

    def __init__(self, library):
        self.library = library
        self.coords, self.names = list(library.coords.names), list(library.names)
        self._parts = [FORMAT, self.coords, self.names]
        rec = fcache.read("template", self._parts)
        if not _valid(rec, len(self.names)):
            rec = _facts(library)
            fcache.write("template", self._parts, rec)
        self.degrees = rec["degrees"]          # velocity degree per term (None: not homogeneous)
        self.positions = rec["positions"]      # per term: the coordinates whose position it uses
        self._rows = None

    def rows(self, indices) -> list:
        """For each term in ``indices``: {"self": pairs, "el": [pairs per coordinate], "dqd":
        [pairs per coordinate]}, pairs = [[coefficient, monomial string], ...]."""
        if self._rows is None:
            rec = fcache.read("rows", self._parts)
            self._rows = dict(rec["terms"]) if rec is not None and isinstance(
                rec.get("terms"), dict) else {}
        missing = [int(j) for j in indices if self.names[int(j)] not in self._rows
                   or not _valid_rows(self._rows[self.names[int(j)]], len(self.coords))]
        if missing:
            for j in missing:
                self._rows[self.names[j]] = _term_rows(self.library, j)
            rec = fcache.read("rows", self._parts)          # others may have added terms
            terms = dict(rec["terms"]) if rec is not None and isinstance(
                rec.get("terms"), dict) else {}
            terms.update(self._rows)
            fcache.write("rows", self._parts, {"terms": terms})
        return [self._rows[self.names[int(j)]] for j in indices]

    def combine(self, coef, rows: str = "self", i: int | None = None) -> dict:
        """``{monomial: Σ_j coef_j a_jm}`` over the non-zero coefficients, in first-seen order.

        ``rows``: "self" (the terms themselves), "el" (EL_i of each term) or "dqd" (∂θ/∂q̇_i).
        """
        active = np.flatnonzero(coef)
        out: dict = {}
        for j, r in zip(active, self.rows(active)):
            for a, mono in (r[rows] if rows == "self" else r[rows][i]):
                out[mono] = out.get(mono, 0.0) + float(coef[j]) * a
        return out

    def equations(self, coef_l, dps: int, friction=None) -> list:
        """Equations of motion as ``(lhs, rhs)`` strings in sympy syntax, one per coordinate:
        lhs the monomials with an acceleration ``<q>_ddot``, rhs ``Q_<q>`` minus the rest (and
        minus the friction force ∂R/∂q̇_i: ``friction = (template of R's terms, ρ)``)."""
        accel = re.compile(r"\b(" + "|".join(re.escape(c + "_ddot") for c in self.coords) + r")\b")
        out = []
        for i, c in enumerate(self.coords):
            row = self.combine(coef_l, "el", i)
            lhs = {m: a for m, a in row.items() if accel.search(m)}
            rhs = {m: -a for m, a in row.items() if not accel.search(m)}
            if friction is not None and np.any(friction[1]):
                for m, a in friction[0].combine(friction[1], "dqd", i).items():
                    rhs[m] = rhs.get(m, 0.0) - a
            out.append((text(lhs, dps), text(rhs, dps, lead=f"Q_{c}")))
        return out


def format_float(x: float, dps: int) -> str:
    """``x`` as sympy prints a Float of ``dps`` digits inside an expression: ``9.81``, ``1.0``,
    ``1.0e-5`` (mpmath's layout: fixed point for exponents in (min(−dps//3, −5), dps))."""
    x = float(x)
    if x == 0:
        return "0.0"
    if not np.isfinite(x):
        return {"inf": "oo", "-inf": "-oo"}.get(repr(x), "nan")
    mant, exp = format(abs(x), f".{dps - 1}e").split("e")
    digits, exp = mant.replace(".", ""), int(exp)
    sign = "-" if x < 0 else ""
    if min(-(dps // 3), -5) < exp < dps:
        if exp < 0:
            digits, split = "0" * -exp + digits, 1
        else:
            split = exp + 1
        exp = 0
    else:
        split = 1
    body = (digits[:split] + "." + digits[split:]).rstrip("0")
    body += "0" if body.endswith(".") else ""
    if exp == 0:
        return sign + body
    return f"{sign}{body}e{'+' if exp > 0 else ''}{exp}"


def text(terms: dict, dps: int, lead: str | None = None) -> str:
    """``{monomial: coefficient}`` as one sympy-syntax sum (``lead``, e.g. ``Q_x``, first with
    coefficient 1); coefficients printed with ``dps`` significant digits, zeros dropped."""
    parts = [] if lead is None else [(False, lead)]
    for mono, a in _ordered(terms):
        if a == 0:
            continue
        num = format_float(abs(a), dps)
        parts.append((a < 0, num if mono == "1" else f"{num}*{mono}"))
    if not parts:
        return "0"
    out = ("-" if parts[0][0] else "") + parts[0][1]
    for neg, s in parts[1:]:
        out += (" - " if neg else " + ") + s
    return out


def _factors(mono: str) -> dict | None:
    """``"phi_dot**2*sin(theta)**2"`` -> {"phi_dot": 2, "sin(theta)": 2}; None if not a plain
    product of powers (e.g. a quotient)."""
    pieces, depth, start, k = [], 0, 0, 0
    while k < len(mono):
        ch = mono[k]
        depth += (ch == "(") - (ch == ")")
        if ch == "*" and depth == 0:
            if mono[k + 1:k + 2] == "*":           # a power: skip "**"
                k += 2
                continue
            pieces.append(mono[start:k])
            start = k + 1
        k += 1
    pieces.append(mono[start:])
    out = {}
    for piece in pieces:
        base, _, exp = piece.partition("**")
        if "/" in piece or not base or (exp and not exp.isdigit()):
            return None
        out[base] = out.get(base, 0) + (int(exp) if exp else 1)
    return out


# sympy's order of functions among the generators of a sum (its Function.class_key)
_FUNC_ORDER = {"exp": 10, "log": 11, "sin": 20, "cos": 21, "tan": 22, "cot": 23, "sinh": 30,
               "cosh": 31, "tanh": 32, "coth": 33}
_CALL = re.compile(r"^([A-Za-z_]\w*)\((.*)\)$")


def _gen_key(g: str) -> tuple:
    """Symbols alphabetically, then functions in sympy's order, then anything else."""
    if g.isidentifier():
        return (0, 0, g, "")
    call = _CALL.match(g)
    if call:
        return (1, _FUNC_ORDER.get(call.group(1), 10000), call.group(1), call.group(2))
    return (2, 0, g, "")


def _ordered(terms: dict) -> list:
    """The terms in the order sympy prints a sum (lexicographic in the exponents, the symbols
    alphabetically, then the functions), as far as it can be read from the strings; the rest in
    their given order after them."""
    facs = {m: ({} if m == "1" else _factors(m)) for m in terms}
    gens = sorted({g for f in facs.values() if f for g in f}, key=_gen_key)
    key = {m: tuple(-f.get(g, 0) for g in gens) for m, f in facs.items() if f is not None}
    plain = sorted((m for m in terms if m in key), key=lambda m: key[m])
    return [(m, terms[m]) for m in plain + [m for m in terms if m not in key]]


def _valid(rec, p: int) -> bool:
    try:
        return (len(rec["degrees"]) == p and len(rec["positions"]) == p
                and all(d is None or isinstance(d, int) for d in rec["degrees"]))
    except (KeyError, TypeError):
        return False


def _valid_rows(r, n: int) -> bool:
    try:
        return (isinstance(r["self"], list) and len(r["el"]) == n and len(r["dqd"]) == n
                and all(len(pair) == 2 for rows in (r["el"], r["dqd"]) for row in rows
                        for pair in row))
    except (KeyError, TypeError):
        return False


def _facts(library) -> dict:
    """Velocity degree and positions of every term (sympy)."""
    c = library.coords
    return {"degrees": [_velocity_degree(e, c.qd_sym) for e in library.exprs],
            "positions": [[n for n, s in zip(c.names, c.q_sym) if s in e.free_symbols]
                          for e in library.exprs]}


def _add(out: dict, expr, factor=None, sign: float = 1.0) -> None:
    """Add the expanded ``expr`` (times the symbol ``factor``) to ``{monomial: coefficient}``."""
    import sympy as sp
    if expr == 0:
        return
    for mono, a in sp.expand(expr).as_coefficients_dict().items():
        key = str(mono if factor is None else mono * factor)
        out[key] = out.get(key, 0.0) + sign * float(a)


def _pairs(out: dict) -> list:
    return [[a, m] for m, a in out.items() if a != 0]


def _term_rows(library, j: int) -> dict:
    """θ_j, EL_i[θ_j] and ∂θ_j/∂q̇_i of one term, expanded (sympy)."""
    import sympy as sp
    c = library.coords
    qdd = [sp.Symbol(n + "_ddot", real=True) for n in c.names]
    e = library.exprs[j]
    own: dict = {}
    _add(own, e)
    el, dqd = [], []
    for v_i, q_i in zip(c.qd_sym, c.q_sym):
        p, row, d = sp.diff(e, v_i), {}, {}
        _add(d, p)
        for v, a in zip(c.qd_sym, qdd):          # d/dt ∂θ/∂q̇_i: the accelerations' part ...
            _add(row, sp.diff(p, v), a)
        for q, v in zip(c.q_sym, c.qd_sym):      # ... and the positions' part
            _add(row, sp.diff(p, q), v)
        _add(row, sp.diff(e, q_i), sign=-1.0)    # − ∂θ/∂q_i
        el.append(_pairs(row))
        dqd.append(_pairs(d))
    return {"self": _pairs(own), "el": el, "dqd": dqd}


def _velocity_degree(expr, qd_sym):
    import sympy as sp
    try:
        poly = sp.Poly(expr, *qd_sym)
    except sp.PolynomialError:
        return None
    degs = {sum(m) for m in poly.monoms()}
    return degs.pop() if len(degs) == 1 else None
