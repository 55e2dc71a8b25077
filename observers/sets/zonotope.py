"""Zonotopes ``{c + G xi : ||xi||_inf <= 1}`` as immutable value objects."""

from __future__ import annotations

import numpy as np

from ..errors import SetError
from ..lp import box_feasible
from ._arrays import CentreGenerators, direction, frozen, linear_map_matrix, matrix, vector
from .interval import Interval
from .reduction import Reduction, check_order, get_reduction


def strip_generators(G: np.ndarray, Lam: np.ndarray, C: np.ndarray,
                     sigma: np.ndarray) -> np.ndarray:
    r"""The generators ``[(I - Lam C) G, Lam diag(sigma)]`` of a zonotope with generators
    ``G`` intersected with the strips ``|C x - y| <= sigma`` by the gain ``Lam`` (n x m; the
    family of Alamo et al. 2005, Property 3, sound for every gain).

    Computed as ``G - Lam (C G)`` when ``2 m < n`` (2 m n r flops), else with ``I - Lam C``
    formed first (n^2 r flops), in one allocation.  The one formula of the strip updates
    (:func:`observers.families.strip_update`, FRad-A's
    :func:`observers.numerics.frad.alamo_frad_strips`, the bundle members'
    :meth:`ZonotopeBundle.intersect_strips <observers.sets.ZonotopeBundle.intersect_strips>`).
    """
    n, r = G.shape
    m = Lam.shape[1]
    out = np.empty((n, r + m))
    if 2 * m < n:
        np.subtract(G, Lam @ (C @ G), out=out[:, :r])
    else:
        T = -(Lam @ C)
        T[np.diag_indices(n)] += 1.0
        np.matmul(T, G, out=out[:, :r])
    np.multiply(Lam, sigma, out=out[:, r:])
    return out


class Zonotope(CentreGenerators):
    """Zonotope with centre ``c`` (length n) and generator matrix ``G`` (n x r).

    Operators: ``Z1 + Z2`` is the Minkowski sum (generators concatenated in this order,
    which matters for tie-breaking in reduction), ``Z + v`` a translation, ``M @ Z`` a linear
    map and ``-Z`` the point reflection.

    Examples
    --------
    >>> import numpy as np
    >>> Z = Zonotope([0, 0], np.eye(2))
    >>> W = Zonotope([0, 0], [[0.1], [0.2]])
    >>> (np.array([[2, 0], [0, 1]]) @ Z + W).interval().hi
    array([2.1, 1.2])
    """

    __slots__ = ("_c", "_G")
    __array_ufunc__ = None  # let ``ndarray @ Zonotope`` defer to __rmatmul__

    def __init__(self, c, G=None):
        c = vector(c, "zonotope centre")
        n = c.shape[0]
        G = np.zeros((n, 0)) if G is None else matrix(G, "zonotope generators", rows=n)
        self._c = frozen(c)
        self._G = frozen(G)

    @classmethod
    def trusted(cls, c: np.ndarray, G: np.ndarray) -> Zonotope:
        """Build from float arrays of the right shapes without validation or copies.

        For hot loops that have just computed fresh arrays; the arrays are frozen in place.
        """
        obj = object.__new__(cls)
        c.setflags(write=False)
        G.setflags(write=False)
        obj._c, obj._G = c, G
        return obj

    @classmethod
    def box(cls, radius, center=None) -> Zonotope:
        """Axis-aligned box with half-widths ``radius`` (a vector) around ``center``."""
        r = vector(radius, "box radius")
        if np.any(r < 0):
            raise SetError("box radius must be non-negative")
        c = np.zeros_like(r) if center is None else vector(center, "box centre", dim=r.shape[0])
        return cls(c, np.diag(r))

    @classmethod
    def from_interval(cls, interval: Interval) -> Zonotope:
        """The box ``interval`` as a zonotope."""
        return cls(interval.center(), np.diag(interval.radius()))

    # -- data -----------------------------------------------------------------------------
    @property
    def c(self) -> np.ndarray:
        """Centre."""
        return self._c

    @property
    def G(self) -> np.ndarray:
        """Generator matrix (n x r)."""
        return self._G

    @property
    def doubles(self) -> int:
        """Floating-point values that define the set: centre and generators (memory)."""
        return self._c.size + self._G.size

    def box_form(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """``(c, G, A, b)`` of the set as ``{c + G xi : A xi = b, |xi|_inf <= 1}``: here no
        constraint (``A`` has no rows); a constrained zonotope gives its own.  The one form in
        which the harness tests membership in both (:mod:`benchmarks.run.membership`)."""
        r = self._G.shape[1]
        return self._c, self._G, np.zeros((0, r)), np.zeros(0)

    @property
    def order(self) -> float:
        """Order ``r / n`` (CORA's definition)."""
        return self.num_generators / self.dim

    # -- operations -------------------------------------------------------------------------
    def __add__(self, other) -> Zonotope:
        if isinstance(other, Zonotope):
            if other.dim != self.dim:
                raise SetError(f"cannot add zonotopes of dimensions {self.dim} and {other.dim}")
            return Zonotope(self._c + other._c, np.hstack([self._G, other._G]))
        if isinstance(other, Interval):
            return self + Zonotope.from_interval(other)
        if hasattr(other, "interval") and not isinstance(other, np.ndarray):
            return NotImplemented
        return Zonotope(self._c + vector(other, "translation vector", dim=self.dim), self._G)

    def __radd__(self, other) -> Zonotope:
        if isinstance(other, Interval):
            return Zonotope.from_interval(other) + self
        return self + other

    def __rmatmul__(self, M) -> Zonotope:
        M = linear_map_matrix(M, self.dim)
        return Zonotope(M @ self._c, M @ self._G)

    def __neg__(self) -> Zonotope:
        return Zonotope(-self._c, -self._G)

    def __mul__(self, s) -> Zonotope:
        if not np.isscalar(s):
            return NotImplemented
        return Zonotope(float(s) * self._c, float(s) * self._G)

    __rmul__ = __mul__

    def interval(self) -> Interval:
        """Interval hull ``c +- sum(|G|, 2)`` (exact)."""
        r = np.abs(self._G).sum(axis=1)
        return Interval(self._c - r, self._c + r)

    def support(self, d) -> float | np.ndarray:
        """Support function ``d'c + ||G'd||_1`` (vector ``d``, or one value per column)."""
        d = direction(d, self.dim)
        return d.T @ self._c + np.abs(self._G.T @ d).sum(axis=0)

    def contains(self, x, tol: float = 0.0) -> bool:
        """Exact membership of ``x`` up to ``tol`` in the infinity norm (one LP via HiGHS)."""
        x = vector(x, "point", dim=self.dim)
        if not self.interval().contains(x, tol):
            return False
        return box_feasible(self._G, x - self._c, tol)

    def reduce(self, order: float, method: str | Reduction = "girard") -> Zonotope:
        """Enclosing zonotope of order at most ``order`` using the named strategy."""
        check_order(order)
        return Zonotope(self._c, get_reduction(method).reduce(self._G, order))

    def compact(self) -> Zonotope:
        """The same set without all-zero generator columns."""
        return Zonotope(self._c, self._G[:, np.any(self._G != 0.0, axis=0)])

    def sample(self, k: int, rng: np.random.Generator) -> np.ndarray:
        """``k`` random points of the set (k x n): vertices' mix of box samples and corners."""
        xi = rng.uniform(-1.0, 1.0, size=(k, self.num_generators))
        corners = rng.random(size=xi.shape) < 0.5
        xi = np.where(corners, np.sign(xi), xi)
        return self._c + xi @ self._G.T

    # -- value semantics --------------------------------------------------------------------
    def __eq__(self, other) -> bool:
        return (
            isinstance(other, Zonotope)
            and np.array_equal(self._c, other._c)
            and self._G.shape == other._G.shape
            and np.array_equal(self._G, other._G)
        )

    def __hash__(self) -> int:
        return hash((self._c.tobytes(), self._G.shape, self._G.tobytes()))

    def __repr__(self) -> str:
        return f"Zonotope(dim={self.dim}, generators={self.num_generators})"
