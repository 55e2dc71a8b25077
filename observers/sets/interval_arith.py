"""Interval arithmetic with outward rounding, for sound enclosures of functions over a box.

:class:`Ival` is an immutable pair of float arrays ``lo <= hi`` (any common shape) with the
operators ``+ - * / **`` (integer and half-integer powers), unary minus and the elementary
functions of :data:`FUNCTIONS` (``sqrt, exp, log, sin, cos, tanh, arctan``).  Every result is
rounded outward by one unit in the last place (``np.nextafter``) on both ends, which encloses
the rounding error of a correctly rounded (or faithfully rounded, as numpy's elementary
functions are within 1 ulp) floating-point operation; for the transcendental functions, which
numpy computes to within a few ulp, two more units are added.  Expressions evaluated in this
arithmetic (e.g. sympy expressions through ``lambdify(..., modules=[FUNCTIONS])``) therefore
enclose the exact range of the expression over the box.

A function outside its domain (``sqrt`` or a fractional power of an interval reaching 0 or
below, ``log`` of a non-positive interval, division by an interval containing 0) raises
:class:`IntervalDomainError`, never returns NaN.
"""

from __future__ import annotations

import numpy as np

from ..errors import SetError

_INF = np.inf


class IntervalDomainError(SetError):
    """An interval operation left the domain of the function (e.g. ``sqrt([-1, 2])``)."""


def _down(x: np.ndarray, ulps: int = 1) -> np.ndarray:
    for _ in range(ulps):
        x = np.nextafter(x, -_INF)
    return x


def _up(x: np.ndarray, ulps: int = 1) -> np.ndarray:
    for _ in range(ulps):
        x = np.nextafter(x, _INF)
    return x


class Ival:
    """Interval value(s) ``[lo, hi]`` with outward-rounded arithmetic (see module docstring).

    Parameters
    ----------
    lo, hi : array_like
        Bounds of equal shape (or broadcastable scalars) with ``lo <= hi``; ``hi`` defaults to
        ``lo`` (a point interval).
    """

    __slots__ = ("lo", "hi")
    __array_ufunc__ = None  # ``ndarray * Ival`` defers to Ival.__rmul__

    def __init__(self, lo, hi=None):
        lo = np.asarray(lo, dtype=float)
        hi = lo if hi is None else np.asarray(hi, dtype=float)
        if np.any(lo > hi):
            raise SetError("empty interval: a lower bound exceeds its upper bound")
        object.__setattr__(self, "lo", lo)
        object.__setattr__(self, "hi", hi)

    def __setattr__(self, name, value):  # immutable value
        raise AttributeError("Ival is immutable")

    @staticmethod
    def of(x) -> Ival:
        return x if isinstance(x, Ival) else Ival(x)

    # -- magnitude ------------------------------------------------------------------------
    def mag(self) -> np.ndarray:
        """``max(|lo|, |hi|)``: the largest absolute value in the interval."""
        return np.maximum(np.abs(self.lo), np.abs(self.hi))

    # -- arithmetic -----------------------------------------------------------------------
    def __neg__(self) -> Ival:
        return Ival(-self.hi, -self.lo)

    def __pos__(self) -> Ival:
        return self

    def __add__(self, other) -> Ival:
        o = Ival.of(other)
        return Ival(_down(self.lo + o.lo), _up(self.hi + o.hi))

    __radd__ = __add__

    def __sub__(self, other) -> Ival:
        return self + (-Ival.of(other))

    def __rsub__(self, other) -> Ival:
        return Ival.of(other) + (-self)

    def __mul__(self, other) -> Ival:
        o = Ival.of(other)
        p = np.stack(np.broadcast_arrays(self.lo * o.lo, self.lo * o.hi,
                                         self.hi * o.lo, self.hi * o.hi))
        p = np.where(np.isnan(p), 0.0, p)  # 0 * inf: the product of a zero bound is 0
        return Ival(_down(p.min(axis=0)), _up(p.max(axis=0)))

    __rmul__ = __mul__

    def reciprocal(self) -> Ival:
        """``1 / self``; refuses an interval containing 0."""
        if np.any((self.lo <= 0) & (self.hi >= 0)):
            raise IntervalDomainError("division by an interval containing 0")
        return Ival(_down(1.0 / self.hi), _up(1.0 / self.lo))

    def __truediv__(self, other) -> Ival:
        return self * Ival.of(other).reciprocal()

    def __rtruediv__(self, other) -> Ival:
        return Ival.of(other) * self.reciprocal()

    def __pow__(self, p) -> Ival:
        p = float(p)
        if p == int(p):
            k = int(p)
            if k == 0:
                return Ival(np.ones_like(self.lo))
            if k < 0:
                return (self ** (-k)).reciprocal()
            lo, hi = self.lo, self.hi
            if k % 2:  # odd power: monotone
                return Ival(_down(lo**k, 2), _up(hi**k, 2))
            a, b = np.abs(lo) ** k, np.abs(hi) ** k
            low = np.where((lo <= 0) & (hi >= 0), 0.0, np.minimum(a, b))
            return Ival(_down(low, 2), _up(np.maximum(a, b), 2))
        if 2 * p == int(2 * p):  # half-integer power: sqrt(x)^(2p)
            return sqrt(self) ** int(2 * p)
        if np.any(self.lo <= 0):
            raise IntervalDomainError(f"power {p} of an interval reaching 0 or below")
        return exp(p * log(self))

    def __repr__(self) -> str:
        return f"Ival(lo={self.lo!r}, hi={self.hi!r})"


def _elementary(fn, *, monotone: bool = True, ulps: int = 3, domain=None):
    def apply(x):
        if not isinstance(x, Ival):
            return fn(x)
        if domain is not None:
            domain(x)
        return Ival(_down(fn(x.lo), ulps), _up(fn(x.hi), ulps))
    apply.__name__ = fn.__name__
    return apply


def _positive(what: str):
    def check(x: Ival) -> None:
        if np.any(x.lo <= 0):
            raise IntervalDomainError(f"{what} of an interval reaching 0 or below "
                                      f"(lower bound {float(np.min(x.lo)):.6g})")
    return check


def sqrt(x):
    """Square root; refuses an interval reaching 0 or below (its derivatives blow up there)."""
    if not isinstance(x, Ival):
        return np.sqrt(x)
    _positive("sqrt")(x)
    return Ival(_down(np.sqrt(x.lo)), _up(np.sqrt(x.hi)))


exp = _elementary(np.exp)
log = _elementary(np.log, domain=_positive("log"))
tanh = _elementary(np.tanh)
arctan = _elementary(np.arctan)


def _periodic(fn, shift: float):
    """sin/cos: exact extrema where the interval contains a maximum or minimum."""
    def apply(x):
        if not isinstance(x, Ival):
            return fn(x)
        a, b = fn(x.lo), fn(x.hi)
        lo, hi = np.minimum(a, b), np.maximum(a, b)
        # maxima of fn at shift + 2 pi k, minima at shift + pi + 2 pi k
        k_max = np.ceil((x.lo - shift) / (2 * np.pi))
        has_max = shift + 2 * np.pi * k_max <= x.hi
        k_min = np.ceil((x.lo - shift - np.pi) / (2 * np.pi))
        has_min = shift + np.pi + 2 * np.pi * k_min <= x.hi
        wide = (x.hi - x.lo) >= 2 * np.pi
        hi = np.where(has_max | wide, 1.0, _up(hi, 3))
        lo = np.where(has_min | wide, -1.0, _down(lo, 3))
        return Ival(np.maximum(lo, -1.0), np.minimum(hi, 1.0))
    apply.__name__ = fn.__name__
    return apply


sin = _periodic(np.sin, np.pi / 2)
cos = _periodic(np.cos, 0.0)

#: namespace for ``sympy.lambdify(..., modules=[FUNCTIONS])``: interval elementary functions
FUNCTIONS = {"sqrt": sqrt, "exp": exp, "log": log, "sin": sin, "cos": cos, "tanh": tanh,
             "atan": arctan, "arctan": arctan}
