"""Axis-aligned boxes ``[lo, hi]`` as immutable value objects."""

from __future__ import annotations

import numpy as np

from ..errors import SetError
from ._arrays import direction, frozen, linear_map_matrix, vector


class Interval:
    """The box ``{x : lo <= x <= hi}`` (interval vector).

    Parameters
    ----------
    lo, hi : array_like
        Lower and upper bounds of equal length with ``lo <= hi``.

    Examples
    --------
    >>> import numpy as np
    >>> I = Interval([-1, 0], [1, 2])
    >>> (np.array([[1, 1], [0, 1]]) @ I).hi
    array([3., 2.])
    """

    __slots__ = ("_lo", "_hi")
    __array_ufunc__ = None  # let ``ndarray @ Interval`` defer to __rmatmul__

    def __init__(self, lo, hi):
        lo = vector(lo, "interval lower bound")
        hi = vector(hi, "interval upper bound", dim=lo.shape[0])
        if np.any(lo > hi):
            i = int(np.argmax(lo > hi))
            raise SetError(f"empty interval: lower bound {lo[i]} > upper bound {hi[i]} (entry {i})")
        self._lo = frozen(lo)
        self._hi = frozen(hi)

    # -- data -----------------------------------------------------------------------------
    @property
    def lo(self) -> np.ndarray:
        """Lower bounds."""
        return self._lo

    @property
    def hi(self) -> np.ndarray:
        """Upper bounds."""
        return self._hi

    @property
    def doubles(self) -> int:
        """Floating-point values that define the set: ``lo`` and ``hi`` (memory)."""
        return self.lo.size + self.hi.size

    @property
    def dim(self) -> int:
        """Dimension of the ambient space."""
        return self._lo.shape[0]

    def center(self) -> np.ndarray:
        """Midpoint of the box."""
        return 0.5 * (self._lo + self._hi)

    def radius(self) -> np.ndarray:
        """Half-widths of the box."""
        return 0.5 * (self._hi - self._lo)

    # -- operations -------------------------------------------------------------------------
    def interval(self) -> Interval:
        """The interval hull (the box itself)."""
        return self

    def __add__(self, other) -> Interval:
        if isinstance(other, Interval):
            if other.dim != self.dim:
                raise SetError(f"cannot add intervals of dimensions {self.dim} and {other.dim}")
            return Interval(self._lo + other._lo, self._hi + other._hi)
        if hasattr(other, "interval") and not isinstance(other, np.ndarray):
            return NotImplemented
        v = vector(other, "translation vector", dim=self.dim)
        return Interval(self._lo + v, self._hi + v)

    __radd__ = __add__

    def __rmatmul__(self, M) -> Interval:
        M = linear_map_matrix(M, self.dim)
        c = M @ self.center()
        r = np.abs(M) @ self.radius()
        return Interval(c - r, c + r)

    def __neg__(self) -> Interval:
        return Interval(-self._hi, -self._lo)

    def support(self, d) -> float | np.ndarray:
        """Support function ``max_{x in I} d'x`` (vector ``d``, or one value per column)."""
        d = direction(d, self.dim)
        return d.T @ self.center() + np.abs(d).T @ self.radius()

    def contains(self, x, tol: float = 0.0) -> bool:
        """Whether ``lo - tol <= x <= hi + tol`` holds component-wise."""
        x = vector(x, "point", dim=self.dim)
        return bool(np.all(x >= self._lo - tol) and np.all(x <= self._hi + tol))

    # -- value semantics --------------------------------------------------------------------
    def __eq__(self, other) -> bool:
        return (
            isinstance(other, Interval)
            and np.array_equal(self._lo, other._lo)
            and np.array_equal(self._hi, other._hi)
        )

    def __hash__(self) -> int:
        return hash((self._lo.tobytes(), self._hi.tobytes()))

    def __repr__(self) -> str:
        return f"Interval(lo={self._lo.tolist()}, hi={self._hi.tolist()})"
