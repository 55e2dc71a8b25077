"""Ellipsoids ``{x : (x - q)' Q^+ (x - q) <= 1, x - q in range(Q)}`` as immutable value objects.

The shape matrix ``Q`` is symmetric positive semi-definite (degenerate ellipsoids are allowed,
as CORA allows them for rank-deficient disturbance sets).
"""

from __future__ import annotations

import numpy as np

from ._arrays import direction, frozen, linear_map_matrix, matrix, vector
from .errors import SetError
from .interval import Interval

_PSD_TOL = 1e-10


class Ellipsoid:
    """Ellipsoid with centre ``q`` and shape matrix ``Q`` (CORA's ``ellipsoid(Q, q)``).

    ``E1 + E2`` is the minimal-trace outer ellipsoid of the Minkowski sum,
    ``Q = (1 + 1/p) Q1 + (1 + p) Q2`` with ``p = sqrt(tr Q1 / tr Q2)`` (Kurzhanski & Valyi);
    ``E + v`` translates and ``M @ E`` is exact.
    """

    __slots__ = ("_q", "_Q")
    __array_ufunc__ = None

    def __init__(self, q, Q):
        q = vector(q, "ellipsoid centre")
        n = q.shape[0]
        Q = matrix(Q, "ellipsoid shape matrix", rows=n, cols=n)
        scale = max(1.0, float(np.abs(Q).max(initial=0.0)))
        if np.abs(Q - Q.T).max(initial=0.0) > 1e-9 * scale:
            raise SetError("ellipsoid shape matrix must be symmetric")
        Q = 0.5 * (Q + Q.T)
        if n and np.linalg.eigvalsh(Q)[0] < -_PSD_TOL * scale:
            raise SetError("ellipsoid shape matrix must be positive semi-definite")
        self._q = frozen(q)
        self._Q = frozen(Q)

    q = property(lambda self: self._q, doc="Centre.")
    Q = property(lambda self: self._Q, doc="Shape matrix (symmetric PSD).")

    @property
    def dim(self) -> int:
        """Dimension n of the ambient space."""
        return self._q.shape[0]

    def center(self) -> np.ndarray:
        """Centre ``q``."""
        return self._q

    def __add__(self, other) -> Ellipsoid:
        if isinstance(other, Ellipsoid):
            if other.dim != self.dim:
                raise SetError(f"cannot add ellipsoids of dimensions {self.dim} and {other.dim}")
            t1, t2 = float(np.trace(self._Q)), float(np.trace(other._Q))
            if t1 == 0.0 or t2 == 0.0:
                return Ellipsoid(self._q + other._q, self._Q + other._Q)
            p = np.sqrt(t1 / t2)
            return Ellipsoid(self._q + other._q, (1 + 1 / p) * self._Q + (1 + p) * other._Q)
        if hasattr(other, "interval") and not isinstance(other, np.ndarray):
            return NotImplemented
        return Ellipsoid(self._q + vector(other, "translation vector", dim=self.dim), self._Q)

    __radd__ = __add__

    def __rmatmul__(self, M) -> Ellipsoid:
        M = linear_map_matrix(M, self.dim)
        return Ellipsoid(M @ self._q, M @ self._Q @ M.T)

    def __neg__(self) -> Ellipsoid:
        return Ellipsoid(-self._q, self._Q)

    def interval(self) -> Interval:
        """Interval hull ``q +- sqrt(diag(Q))`` (exact)."""
        r = np.sqrt(np.maximum(np.diag(self._Q), 0.0))
        return Interval(self._q - r, self._q + r)

    def support(self, d) -> float | np.ndarray:
        """Support function ``d'q + sqrt(d'Qd)`` (vector ``d``, or one value per column)."""
        d = direction(d, self.dim)
        quad = np.einsum("i...,ij,j...->...", d, self._Q, d)
        return d.T @ self._q + np.sqrt(np.maximum(quad, 0.0))

    def distance(self, x) -> float:
        """Euclidean distance from ``x`` to the ellipsoid (0 inside)."""
        x = vector(x, "point", dim=self.dim)
        lam, V = np.linalg.eigh(self._Q)
        lam = np.maximum(lam, 0.0)
        z = V.T @ (x - self._q)
        pos = lam > _PSD_TOL * max(1.0, lam.max(initial=0.0))
        # components outside the range of Q must be travelled in full
        off = float(np.sum(z[~pos] ** 2))
        zp, lp = z[pos], lam[pos]
        if np.sum(zp**2 / lp) <= 1.0:
            return float(np.sqrt(off))
        # projection onto the boundary: p_i = lp_i z_i / (lp_i + mu), sum p_i^2 / lp_i = 1
        def excess(mu: float) -> float:
            return float(np.sum(lp * zp**2 / (lp + mu) ** 2)) - 1.0

        lo, hi = 0.0, max(1.0, float(np.sqrt(lp.max()) * np.abs(zp).max()))
        while excess(hi) > 0:
            hi *= 2.0
        for _ in range(200):
            mid = 0.5 * (lo + hi)
            if excess(mid) > 0:
                lo = mid
            else:
                hi = mid
        p = lp * zp / (lp + hi)
        return float(np.sqrt(off + np.sum((zp - p) ** 2)))

    def contains(self, x, tol: float = 0.0) -> bool:
        """Whether ``x`` lies within Euclidean distance ``tol`` of the ellipsoid."""
        return self.distance(x) <= max(tol, 1e-12 * max(1.0, float(np.abs(self._q).max())))

    def __eq__(self, other) -> bool:
        return (
            isinstance(other, Ellipsoid)
            and np.array_equal(self._q, other._q)
            and np.array_equal(self._Q, other._Q)
        )

    def __hash__(self) -> int:
        return hash((self._q.tobytes(), self._Q.tobytes()))

    def __repr__(self) -> str:
        return f"Ellipsoid(dim={self.dim})"
