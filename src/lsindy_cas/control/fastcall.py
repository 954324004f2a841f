"""Calling a small CasADi function from Python without its per-call conversions.

``f(x, u)`` on numpy arrays converts every argument to a ``DM`` and every result back, which
costs about 0.1 ms per call on a 2-core machine; the evaluation of a one-step RK4 map of a
two-coordinate model's ODE (176 instructions) takes about 2 microseconds.  A controller step near the
upright calls such functions a few times (the online correction, the track guard), so the
conversions were a fifth of the median control step.  :class:`NumericFunction` evaluates
through CasADi's buffer interface (``Function.buffer``, CasADi >= 3.5.1): preallocated numpy
arrays bound once to the function's inputs and outputs.  It runs the same evaluation, so its
results equal those of ``f(...)`` bit for bit (``tests/test_fastcall.py``).
"""

from __future__ import annotations

import numpy as np

__all__ = ["NumericFunction"]


class NumericFunction:
    """Evaluate the CasADi function ``f`` on numbers through preallocated buffers.

    ``NumericFunction(f)(a, b, ...)`` returns what ``f(a, b, ...)`` returns, as numpy arrays of
    the outputs' shapes (a list when ``f`` has several outputs, like CasADi's).  Arguments are
    anything ``np.asarray`` takes with the input's number of entries (stored column-major, as
    CasADi does).  Functions with a sparse input or output are called the ordinary way.
    Not re-entrant: one evaluation at a time per instance (the buffers are shared).
    """

    def __init__(self, f):
        self.f = f
        self._shapes_in = [f.size_in(i) for i in range(f.n_in())]
        self._shapes_out = [f.size_out(i) for i in range(f.n_out())]
        dense = all(f.sparsity_in(i).is_dense() for i in range(f.n_in())) and all(
            f.sparsity_out(i).is_dense() for i in range(f.n_out()))
        self._eval = None
        if dense and hasattr(f, "buffer"):
            buf, self._eval = f.buffer()
            self._buf = buf  # keep the buffer object alive with the views bound to it
            self._args = [np.zeros(r * c) for r, c in self._shapes_in]
            self._res = [np.zeros(r * c) for r, c in self._shapes_out]
            for i, a in enumerate(self._args):
                buf.set_arg(i, memoryview(a))
            for i, r in enumerate(self._res):
                buf.set_res(i, memoryview(r))

    def __call__(self, *args):
        if len(args) != len(self._shapes_in):
            raise TypeError(f"{self.f.name()} takes {len(self._shapes_in)} arguments, got "
                            f"{len(args)}.")
        if self._eval is None:
            out = self.f(*args)
            out = out if isinstance(out, (list, tuple)) else [out]
            res = [np.asarray(o, dtype=float) for o in out]
        else:
            for a, v, shape in zip(self._args, args, self._shapes_in):
                v = np.asarray(v, dtype=float)
                if v.size != a.size:
                    raise ValueError(f"{self.f.name()}: argument of shape {v.shape} for an "
                                     f"input of shape {shape}.")
                a[:] = v.ravel(order="F") if v.ndim == 2 else v.ravel()
            self._eval()
            res = [r.reshape(shape, order="F").copy()
                   for r, shape in zip(self._res, self._shapes_out)]
        return res[0] if len(res) == 1 else res
