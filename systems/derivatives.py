"""Automatic derivatives of nonlinear dynamics for conservative linearisation.

A user writes the dynamics once as ``f(x, u, m)``, where ``m`` is the math namespace:
``numpy`` for numerical evaluation and :data:`SYMBOLIC` (elementwise sympy functions) for the
derivation, e.g.::

    def f(x, u, m):
        return np.array([x[0] + 0.1 * x[1], x[1] + 0.1 * (m.sin(x[0]) + u[0])], dtype=object)

:class:`SymbolicDerivatives` then builds, with sympy, the Jacobian ``df/dx`` and ``df/du``
(compiled to numpy) and the non-zero second derivatives ``d^2 f_i / dx_j dx_k`` (the input
is known exactly, so only state directions matter), compiled to the outward-rounded interval
arithmetic of :mod:`observers.sets.interval_arith`: :meth:`SymbolicDerivatives.hessian_bounds`
returns rigorous bounds of each over a box, from which :mod:`observers.prediction` encloses
the Lagrange remainder of the linearisation.
"""

from __future__ import annotations

from collections.abc import Callable
from types import SimpleNamespace

import numpy as np

from observers.sets.interval_arith import FUNCTIONS, Ival

from .errors import ModelError


def _elementwise(fn):
    def apply(x):
        if isinstance(x, np.ndarray):
            return np.vectorize(fn, otypes=[object])(x)
        return fn(x)
    return apply


def _symbolic_namespace():
    import sympy

    names = {"sqrt": sympy.sqrt, "exp": sympy.exp, "log": sympy.log, "sin": sympy.sin,
             "cos": sympy.cos, "tanh": sympy.tanh, "arctan": sympy.atan}
    return SimpleNamespace(**{k: _elementwise(v) for k, v in names.items()})


class _LazySymbolic:
    """:data:`SYMBOLIC` imports sympy on first use only."""

    _ns = None

    def __getattr__(self, name):
        if _LazySymbolic._ns is None:
            _LazySymbolic._ns = _symbolic_namespace()
        return getattr(_LazySymbolic._ns, name)


#: elementwise sympy versions of ``sqrt, exp, log, sin, cos, tanh, arctan`` (the ``m`` of f)
SYMBOLIC = _LazySymbolic()


class SymbolicDerivatives:
    """Jacobian and Lagrange-remainder enclosure of ``f(x, u, m)``, derived with sympy.

    Parameters
    ----------
    f : callable
        ``f(x, u, m) -> (n,) array``; called once with arrays of sympy symbols and
        ``m = SYMBOLIC`` to derive the expressions.
    n, nu : int
        State and input dimensions.
    outputs : int, optional
        Number of values ``f`` returns (default ``n``: dynamics; an output function
        ``h(x)`` of ``ny`` values is derived as ``f(x, u, m) = h(x, m)`` with ``nu = 0``).
    what : str
        Name of the function in error messages (``"f"`` or ``"h"``).
    """

    def __init__(self, f: Callable, n: int, nu: int, outputs: int | None = None,
                 what: str = "f"):
        import sympy

        xs = sympy.symbols(f"x0:{n}", real=True)
        us = sympy.symbols(f"u0:{nu}", real=True) if nu else ()
        try:
            out = f(np.array(xs, dtype=object), np.array(us, dtype=object), SYMBOLIC)
            exprs = [sympy.sympify(e) for e in np.asarray(out, dtype=object).ravel()]
        except Exception as exc:  # a user's f that sympy cannot trace
            raise ModelError(f"cannot derive {what} symbolically ({type(exc).__name__}: {exc}); "
                             f"write {what} with m.sqrt, m.sin, ... or pass its derivatives "
                             "by hand") from None
        m = n if outputs is None else int(outputs)
        if len(exprs) != m:
            raise ModelError(f"{what} returns {len(exprs)} values, expected {m}")
        self.n, self.nu, self.m = n, nu, m
        self.symbols = (xs, us)
        self.expressions = exprs
        self._value_interval = sympy.lambdify((xs, us), exprs, modules=[FUNCTIONS])
        Jx = sympy.Matrix(exprs).jacobian(xs)
        Ju = sympy.Matrix(exprs).jacobian(us) if nu else sympy.zeros(m, 0)
        self.jacobian_expressions = (Jx, Ju)
        self._jx = sympy.lambdify((xs, us), Jx, modules="numpy")
        self._jx_entries = [(i, j) for i in range(m) for j in range(n) if Jx[i, j] != 0]
        self._jx_interval = sympy.lambdify(
            (xs, us), [Jx[i, j] for i, j in self._jx_entries], modules=[FUNCTIONS])
        self._ju = sympy.lambdify((xs, us), Ju, modules="numpy")
        # second derivatives in x (u enters with dz_u = 0): keep the non-zero ones, j <= k
        entries, exprs2 = [], []
        pos = {x: j for j, x in enumerate(xs)}
        for i, e in enumerate(exprs):
            for j in sorted(pos[x] for x in e.free_symbols if x in pos):
                dj = sympy.diff(e, xs[j])
                for k in sorted(pos[x] for x in dj.free_symbols if x in pos):
                    if k < j:
                        continue
                    h = sympy.diff(dj, xs[k])
                    if h != 0:
                        entries.append((i, j, k))
                        exprs2.append(h)
        self.hessian_entries = entries
        self.hessian_index = np.array(entries, dtype=int).reshape(-1, 3)
        self._hess = sympy.lambdify((xs, us), exprs2, modules=[FUNCTIONS])

    def jacobian(self, x: np.ndarray, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(df/dx, df/du)`` at ``(x, u)``."""
        Jx = np.array(self._jx(tuple(x), tuple(u)), dtype=float).reshape(self.m, self.n)
        Ju = np.array(self._ju(tuple(x), tuple(u)), dtype=float).reshape(self.m, self.nu)
        return Jx, Ju

    def value_bounds(self, lo: np.ndarray, hi: np.ndarray, u: np.ndarray) -> Ival:
        """Enclosure of the values over the box ``[lo, hi]`` (outward-rounded interval
        arithmetic); ``lo`` and ``hi`` may carry a trailing axis of boxes (or points, with
        ``lo == hi``), evaluated all at once."""
        xs = tuple(Ival(a, b) for a, b in zip(lo, hi, strict=True))
        vals = [Ival.of(v) for v in self._value_interval(xs, tuple(float(v) for v in u))]
        shape = np.broadcast(np.asarray(lo[0]), np.asarray(hi[0])).shape
        return Ival(np.array([np.broadcast_to(v.lo, shape) for v in vals], dtype=float),
                    np.array([np.broadcast_to(v.hi, shape) for v in vals], dtype=float))

    def hessian_bounds(self, lo: np.ndarray, hi: np.ndarray, u: np.ndarray) -> Ival:
        """Enclosures of the non-zero ``d^2 f_i / dx_j dx_k`` (j <= k) over the box."""
        if not self.hessian_entries:
            return Ival(np.zeros(0))
        xs = tuple(Ival(a, b) for a, b in zip(lo, hi, strict=True))
        vals = [Ival.of(v) for v in self._hess(xs, tuple(float(v) for v in u))]
        return Ival(np.array([v.lo for v in vals], dtype=float),
                    np.array([v.hi for v in vals], dtype=float))

    def jacobian_bounds(self, lo: np.ndarray, hi: np.ndarray,
                        u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Bounds ``(Jlo, Jhi)`` of ``df/dx`` over the box ``[lo, hi]`` (interval arithmetic)."""
        Jlo, Jhi = np.zeros((self.m, self.n)), np.zeros((self.m, self.n))
        xs = tuple(Ival(a, b) for a, b in zip(lo, hi, strict=True))
        vals = self._jx_interval(xs, tuple(float(v) for v in u))
        for (i, j), v in zip(self._jx_entries, vals, strict=True):
            v = Ival.of(v)
            Jlo[i, j], Jhi[i, j] = v.lo, v.hi
        return Jlo, Jhi
