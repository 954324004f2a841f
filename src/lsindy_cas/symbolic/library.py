"""Candidate-function libraries Θ(q, q̇) as CasADi SX expressions with readable names.

Each term is one sympy expression (what a person reads and what a saved model stores) and the SX
expression built from it (what is differentiated and evaluated).  Derivatives are exact:
Γ = ∇Θ · ẋ is a Jacobian-vector product, ∂Θ/∂q̇ and ∂²Θ/∂q̇² are CasADi Jacobians/Hessians, and every
quantity is evaluated for all samples at once through ``casadi.Function.map``.

sympy is imported only to parse or derive terms: a polynomial library seen before (names, CasADi
Functions and per-term facts in the disk cache, :mod:`.fcache`, :mod:`.template`) does without it.
"""
from __future__ import annotations

import itertools
from collections.abc import Sequence
from functools import cached_property

import casadi as ca
import numpy as np

from .._validate import check_int
from . import fcache
from .coords import Coordinates

_MAP = 512        # samples per evaluation of the mapped library functions

__all__ = ["Library"]


def _expanded(expr):
    """Expanded form, so that e.g. x*(x + y) and x**2 + x*y are recognised as one term."""
    import sympy as sp
    return sp.expand(expr)


class Library:
    """A list of candidate terms θ_j(q, q̇) over named generalized coordinates.

    Parameters
    ----------
    coords : list of str or Coordinates
        Generalized coordinate names, e.g. ``["x", "theta"]``; velocities are ``<q>_dot``.
    terms : list of str or sympy.Expr
        Candidate terms, e.g. ``["theta_dot**2", "cos(theta)"]``.  Duplicates are dropped.

    Notes
    -----
    Libraries compose: ``lib1 + lib2`` is their union (same coordinates required).
    """

    def __init__(self, coords, terms):
        import sympy as sp
        self.coords = coords if isinstance(coords, Coordinates) else Coordinates(coords)
        if isinstance(terms, (str, sp.Expr)):
            terms = [terms]
        exprs, index = [], {}
        for i, t in enumerate(terms):
            e = self.coords.parse(t, what=f"library term #{i + 1}")
            if e.is_number:
                raise ValueError(f"library term {t!r} is a constant; energy is defined up to a "
                                 "constant, so constants carry no information")
            if e not in index:          # sympy's canonical form: cos(a)*cos(b) == cos(b)*cos(a)
                index[e] = len(exprs)
                exprs.append(e)
        if not exprs:
            raise ValueError("a library needs at least one term")
        self.exprs = exprs
        self.names = [str(e) for e in exprs]
        self._index = index

    # ------------------------------------------------------------------ builders
    @classmethod
    def polynomial(cls, coords, features, degree: int):
        """All products of ``features`` of total degree 1..``degree`` (no constant term).

        Parameters
        ----------
        coords : list of str
            Generalized coordinate names.
        features : list of str or str
            Feature expressions, e.g. ``["cos(theta)", "sin(theta)", "theta_dot", "x", "x_dot"]``
            (a comma-separated string is accepted).
        degree : int
            Highest total degree of a product (≥ 1).
        """
        degree = check_int("degree", degree, low=1)
        c = coords if isinstance(coords, Coordinates) else Coordinates(coords)
        if isinstance(features, str):
            features = split_top_level(features)
        # the terms of a definition seen before: their names from the disk cache (.fcache)
        parts = [c.names, [f if isinstance(f, str) else None for f in features], int(degree)]
        cached = None if None in parts[1] else fcache.read("polynomial", parts)
        if cached is not None and cls is Library:
            try:
                return cls._from_names(c, cached["names"], cached["features"], int(degree))
            except (KeyError, TypeError, ValueError):
                pass                                   # a damaged record: build it again
        import sympy as sp
        feats = [c.parse(f, what=f"feature {f!r}") for f in features]
        if not feats:
            raise ValueError("features must list at least one expression")
        terms = []
        for d in range(1, int(degree) + 1):
            for combo in itertools.combinations_with_replacement(feats, d):
                terms.append(sp.Mul(*combo))
        lib = cls(c, terms)
        lib.spec = {"kind": "polynomial", "features": [str(f) for f in feats], "degree": int(degree)}
        # cached only if every name parses back to its term (what a cached library relies on)
        if None not in parts[1] and all(c.parse(n) == e for n, e in zip(lib.names, lib.exprs)):
            fcache.write("polynomial", parts, {"names": lib.names,
                                               "features": lib.spec["features"]})
        return lib

    @classmethod
    def _from_names(cls, coords: Coordinates, names, features, degree: int) -> "Library":
        """A polynomial library from its cached term names: each sympy term is parsed from its
        name when first used (:class:`_LazyTerms`); the names were checked when cached."""
        if not names or not all(isinstance(n, str) for n in names) or len(set(names)) != len(names):
            raise ValueError("bad cached library record")
        lib = cls.__new__(cls)
        lib.coords, lib.names = coords, list(names)
        lib.exprs = _LazyTerms(coords, lib.names)
        lib.spec = {"kind": "polynomial", "features": list(features), "degree": degree}
        return lib

    def __add__(self, other: "Library") -> "Library":
        if not isinstance(other, Library):
            return NotImplemented
        if other.coords.names != self.coords.names:
            raise ValueError(f"cannot join libraries over different coordinates "
                             f"{self.coords.names} and {other.coords.names}")
        return Library(self.coords, self.exprs + other.exprs)

    @property
    def spec(self) -> dict:
        """JSON-able description from which the library can be rebuilt."""
        return getattr(self, "_spec", None) or {"kind": "terms", "terms": list(self.names)}

    @spec.setter
    def spec(self, value):
        self._spec = value

    def to_dict(self) -> dict:
        return {"coords": list(self.coords.names), **self.spec}

    @classmethod
    def from_dict(cls, d: dict) -> "Library":
        if d.get("kind") == "polynomial":
            return cls.polynomial(d["coords"], d["features"], d["degree"])
        return cls(d["coords"], d["terms"])

    # ------------------------------------------------------------------ lookup
    def __len__(self) -> int:
        return len(self.exprs)

    def __repr__(self) -> str:
        return f"Library({len(self)} terms over {self.coords.names})"

    def index(self, term, what: str = "term") -> int:
        """Position of ``term`` (string or sympy) in the library; ``ValueError`` if absent."""
        if isinstance(term, str):          # a term's own name, or a plain coordinate/velocity name:
            j = self._name_index.get(term.strip())        # no parsing (nor sympy) needed
            if j is not None:
                return j
            if term.strip() in self.coords.state_names:   # a symbol that is no term's name
                raise ValueError(f"{what} {term!r} is not in the library ({len(self)} terms; "
                                 f"e.g. {', '.join(self.names[:4])}, ...)")
        e = self.coords.parse(term, what=what)
        j = self._name_index.get(str(e))       # by name first: parses no other term
        if j is not None and self.exprs[j] == e:
            return j
        j = self._index.get(e)
        if j is None:
            j = self._expanded_index.get(_expanded(e))
        if j is None:
            raise ValueError(f"{what} {str(term)!r} is not in the library ({len(self)} terms; "
                             f"e.g. {', '.join(self.names[:4])}, ...)")
        return j

    def coefficients(self, expr, what: str = "expression") -> np.ndarray:
        """Coefficient vector ξ (p,) with Θξ = ``expr``, after expanding products and trig sums.

        ``ValueError`` if ``expr`` is not a linear combination of library terms (constants are
        dropped: energy is defined up to one).
        """
        import sympy as sp
        e = sp.expand(sp.expand_trig(self.coords.parse(expr, what=what)))
        xi = np.zeros(len(self))
        for term, c in e.as_coefficients_dict().items():
            if term.is_number:
                continue
            xi[self.index(term, what=f"term of {what}")] += float(c)
        return xi

    @cached_property
    def _name_index(self) -> dict:
        return {n: j for j, n in enumerate(self.names)}

    @cached_property
    def _index(self) -> dict:
        """Term -> position (set by ``__init__``; built here for a library from cached names)."""
        return {e: j for j, e in enumerate(self.exprs)}

    @cached_property
    def _expanded_index(self) -> dict:
        return {_expanded(e): j for j, e in enumerate(self.exprs)}

    # ------------------------------------------------------------------ symbolic
    @cached_property
    def sx(self) -> ca.SX:
        """Θ as an SX row vector (1, p)."""
        return ca.horzcat(*[self.coords.to_casadi(e) for e in self.exprs])

    @cached_property
    def template(self):
        """The per-term facts and expanded Euler-Lagrange rows (:class:`.template.Template`)."""
        from .template import Template
        return Template(self)

    def sx_terms(self) -> ca.SX:
        """Θ as SX (p, 1) over ``coords.x`` from the (cached) Θ Function: no sympy needed."""
        return self._functions["theta"](self.coords.x)

    def velocity_degree(self, j: int) -> int | None:
        """Degree of homogeneity of term ``j`` in the velocities, or ``None`` if not homogeneous."""
        return self.template.degrees[j]

    def positions(self, j: int) -> list:
        """The coordinates whose position term ``j`` depends on (e.g. ``["theta"]``)."""
        return list(self.template.positions[j])

    # ------------------------------------------------------------------ numeric
    @cached_property
    def _functions(self) -> dict:
        """The CasADi Functions of Θ and its derivatives: from the disk cache
        (:mod:`.fcache`) when this library was built before, else built and cached."""
        n, p = self.coords.n, len(self)
        sizes = {"theta": p, "gamma": p, "grad": 2 * n * p, "dqd": n * p, "hess": n * n * p}

        def ok(funcs):
            return all(funcs[k].n_in() == (2 if k == "gamma" else 1) and funcs[k].n_out() == 1
                       and funcs[k].size1_in(0) == 2 * n and funcs[k].nnz_out(0) == sizes[k]
                       for k in sizes)
        funcs = fcache.load(self.coords.names, self.names, ok)
        if funcs is None:
            funcs = self._build_functions()
            fcache.save(self.coords.names, self.names, funcs)
        return funcs

    def _build_functions(self) -> dict:
        c = self.coords
        x, xd = c.x, ca.SX.sym("xd", 2 * c.n)
        theta = self.sx.T                                     # (p, 1)
        jac_x = ca.jacobian(theta, x)                         # (p, 2n)
        gamma = ca.mtimes(jac_x, xd)                          # exact ∇Θ·ẋ
        dqd = ca.jacobian(theta, c.qd)                        # (p, n)
        hess = [ca.jacobian(dqd[:, i], c.qd) for i in range(c.n)]   # n of (p, n)
        opts = {"cse": True}
        return {
            "theta": ca.Function("theta", [x], [theta], opts),
            "gamma": ca.Function("gamma", [x, xd], [gamma], opts),
            "grad": ca.Function("grad", [x], [ca.densify(ca.vec(jac_x))], opts),
            "dqd": ca.Function("dqd", [x], [ca.densify(ca.vec(dqd))], opts),
            "hess": ca.Function("theta_hess", [x],
                                [ca.densify(ca.vertcat(*[ca.vec(h) for h in hess]))], opts),
        }

    def _eval(self, name: str, *arrays) -> np.ndarray:
        """``name`` evaluated at every sample: (N, out_size).

        Samples go through one map of ``_MAP`` evaluations, built once per function (building a
        map costs time in proportion to its size), in blocks written straight into the output
        (``Function.buffer``: a C-ordered (N, k) array is CasADi's column-major (k, N)); the last
        block is padded with copies of the last sample.
        """
        f = self._functions[name]
        n_samples = arrays[0].shape[0]
        m = min(_MAP, n_samples)
        fm = self._maps.get((name, m))
        if fm is None:
            fm = self._maps[(name, m)] = f.map(m)
        buf, trigger = fm.buffer()
        ins = [np.empty((m, a.shape[1])) for a in arrays]
        res = np.empty((m, f.nnz_out(0)))
        for i, a in enumerate(ins):
            buf.set_arg(i, memoryview(a))
        buf.set_res(0, memoryview(res))
        out = np.empty((n_samples, f.nnz_out(0)))
        for lo in range(0, n_samples, m):
            hi = min(n_samples, lo + m)
            for a, src in zip(ins, arrays):
                a[:hi - lo] = src[lo:hi]
                a[hi - lo:] = src[hi - 1]
            trigger()
            out[lo:hi] = res[:hi - lo]
        return out

    @cached_property
    def _maps(self) -> dict:
        return {}

    def _states(self, X) -> np.ndarray:
        X = np.atleast_2d(np.asarray(X, dtype=float))
        if X.ndim != 2 or X.shape[1] != 2 * self.coords.n:
            raise ValueError(f"states must have shape (n_samples, {2 * self.coords.n}) "
                             f"= [q, q_dot] for coords {self.coords.names}, got {np.shape(X)}")
        return X

    def theta(self, X) -> np.ndarray:
        """Θ(X): (n_samples, p) for states X (n_samples, 2n) = [q, q̇]."""
        return self._eval("theta", self._states(X))

    def gamma(self, X, Xdot) -> np.ndarray:
        """Γ(X, Ẋ) = ∇Θ·ẋ = dΘ/dt along the data: (n_samples, p) (paper eq. 4)."""
        X, Xdot = self._states(X), self._states(Xdot)
        if X.shape != Xdot.shape:
            raise ValueError(f"X and Xdot must have the same shape, got {X.shape} and {Xdot.shape}")
        return self._eval("gamma", X, Xdot)

    def grad(self, X) -> np.ndarray:
        """∇_x Θ: (n_samples, 2n, p)."""
        X = self._states(X)
        p, m = len(self), 2 * self.coords.n
        return self._eval("grad", X).reshape(len(X), m, p)

    def dtheta_dqd(self, X) -> np.ndarray:
        """∂Θ/∂q̇: (n_samples, n, p)."""
        X = self._states(X)
        return self._eval("dqd", X).reshape(len(X), self.coords.n, len(self))

    def d2theta_dqd2(self, X) -> np.ndarray:
        """∂²Θ/∂q̇²: (n_samples, n, n, p); entry [s, i, k, j] = ∂²θ_j/∂q̇_i∂q̇_k."""
        X = self._states(X)
        n, p = self.coords.n, len(self)
        return self._eval("hess", X).reshape(len(X), n, n, p)


class _LazyTerms(Sequence):
    """The sympy terms of a library known by their names, each parsed when first used (a command
    that scores every support only ever reads the few terms of the winner)."""

    def __init__(self, coords: Coordinates, names):
        self._coords, self._names, self._done = coords, names, {}

    def __len__(self) -> int:
        return len(self._names)

    def __getitem__(self, j):
        if isinstance(j, slice):
            return [self[i] for i in range(*j.indices(len(self)))]
        j = range(len(self))[j]                        # negative indices, IndexError
        if j not in self._done:
            self._done[j] = self._coords.parse(self._names[j], what="library term")
        return self._done[j]

    def __add__(self, other):
        return list(self) + list(other)

    def __radd__(self, other):
        return list(other) + list(self)


def split_top_level(text: str) -> list[str]:
    """Split ``"cos(a),sin(a),b"`` at commas that are not inside parentheses."""
    parts, depth, cur = [], 0, ""
    for ch in text:
        if ch == "(":
            depth += 1
        elif ch == ")":
            depth -= 1
        if ch == "," and depth == 0:
            parts.append(cur.strip())
            cur = ""
        else:
            cur += ch
    if cur.strip():
        parts.append(cur.strip())
    return parts
