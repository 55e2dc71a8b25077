"""Ellipsoids ``{x : (x - q)' Q^+ (x - q) <= 1, x - q in range(Q)}`` as immutable value objects.

The shape matrix ``Q`` is symmetric positive semi-definite (degenerate ellipsoids are allowed,
as CORA allows them for rank-deficient disturbance sets).

Besides the :class:`Ellipsoid` class this module holds the array kernels of the ellipsoidal
observers, so that they can run on plain arrays in their hot loops:

* :func:`outer_sum`: outer ellipsoid of a Minkowski sum, a member of the family
  ``Q1 / (1 - p) + Q2 / p`` chosen by a named weight strategy (:data:`SUM_WEIGHTS`);
* :func:`quadratic_update`: outer ellipsoid of an ellipsoid intersected with the measurement
  set ``{x : ||y - C x||^2 <= rho}``, a member of the family of convex combinations of the two
  quadratic constraints (Schweppe 1968; Fogel & Huang 1982);
* :func:`obe_weight`: the combination weight that minimises the upper bound of the new level
  ``sigma^2`` (the "optimal bounding ellipsoid" rule of Dasgupta & Huang 1987, used by
  Gollamudi et al. 1996 and Liu et al. 2016).
"""

from __future__ import annotations

from collections.abc import Callable
from itertools import product

import numpy as np

from ..errors import SetError
from ._arrays import direction, frozen, linear_map_matrix, matrix, vector
from .interval import Interval
from .zonotope import Zonotope

_PSD_TOL = 1e-10

#: conversions of a zonotope ``c + G xi`` (r generators) into an ellipsoid
CONVERSIONS = ("inner:norm", "outer:norm")


# -- array kernels ----------------------------------------------------------------------------
def min_trace_weight(Q1: np.ndarray, Q2: np.ndarray) -> float:
    """Weight ``p = sqrt(tr Q2) / (sqrt(tr Q1) + sqrt(tr Q2))`` minimising the trace of
    ``Q1 / (1 - p) + Q2 / p`` (Kurzhanski & Valyi 1997; Liu et al. 2016, eq. (21))."""
    s1, s2 = np.sqrt(max(np.trace(Q1), 0.0)), np.sqrt(max(np.trace(Q2), 0.0))
    return float(s2 / (s1 + s2))


#: named strategies choosing the weight ``p`` of :func:`outer_sum`
SUM_WEIGHTS: dict[str, Callable[[np.ndarray, np.ndarray], float]] = {
    "min-trace": min_trace_weight,
}


def outer_sum(Q1: np.ndarray, Q2: np.ndarray, weight: str | float = "min-trace") -> np.ndarray:
    """Shape matrix of an ellipsoid enclosing ``E(0, Q1) + E(0, Q2)``.

    Every member ``Q1 / (1 - p) + Q2 / p`` with ``0 < p < 1`` of this family is an outer
    ellipsoid of the Minkowski sum (Kurzhanski & Valyi 1997, Sec. 2.2); ``weight`` is either a
    number ``p`` or the name of a strategy in :data:`SUM_WEIGHTS` (``"min-trace"``: the member
    of minimal trace, touching the sum in every coordinate-free sense used by Liu et al.).
    If one of the two ellipsoids is a single point, the sum is exact.
    """
    if not np.any(Q2):
        return Q1.copy()
    if not np.any(Q1):
        return Q2.copy()
    if isinstance(weight, str):
        try:
            p = SUM_WEIGHTS[weight](Q1, Q2)
        except KeyError:
            known = ", ".join(sorted(SUM_WEIGHTS))
            raise SetError(f"unknown Minkowski-sum weight '{weight}' (known: {known})") from None
    else:
        p = float(weight)
    if not 0.0 < p < 1.0:
        raise SetError(f"Minkowski-sum weight must lie in (0, 1), got {p!r}")
    Q = Q1 / (1.0 - p) + Q2 / p
    return 0.5 * (Q + Q.T)


def quadratic_update(
    q: np.ndarray, P: np.ndarray, s2: float, C: np.ndarray, rho: float, y: np.ndarray,
    lam: float,
) -> tuple[np.ndarray, np.ndarray, float]:
    """Outer ellipsoid of ``{x : (x-q)' P^-1 (x-q) <= s2}`` intersected with
    ``{x : ||y - C x||^2 <= rho}``, for the combination weight ``0 < lam < 1``.

    Every point of the intersection satisfies the convex combination
    ``(1-lam) (x-q)' P^-1 (x-q) + lam ||y - C x||^2 <= (1-lam) s2 + lam rho``, which is the
    ellipsoid ``{x : (x-q+)' P+^-1 (x-q+) <= s2+}`` with (``delta = y - C q``)

    * ``P+^-1 = (1-lam) P^-1 + lam C'C``, i.e. ``P+ = (P - K C P) / (1-lam)``,
      ``K = P C' (C P C' + (1-lam)/lam I)^-1`` (no inverse of ``P`` is needed);
    * ``q+ = q + K delta``;
    * ``s2+ = (1-lam) s2 + lam rho - delta' (C P C'/(1-lam) + I/lam)^-1 delta``.

    Returns ``(q+, P+, s2+)``; ``s2+ < 0`` means that the intersection is empty.  A weighted
    measurement set ``(y - C x)' R^-1 (y - C x) <= rho`` is handled by whitening ``C`` and
    ``y`` with a factor ``T`` of ``R^-1 = T'T`` before the call.
    """
    PCt = P @ C.T
    delta = y - C @ q
    Qt = (C @ PCt) / (1.0 - lam) + np.eye(C.shape[0]) / lam
    X = np.linalg.solve(Qt, np.column_stack([delta, PCt.T]))
    q_new = q + (PCt @ X[:, 0]) / (1.0 - lam)
    P_new = (P - (PCt @ X[:, 1:]) / (1.0 - lam)) / (1.0 - lam)
    s2_new = (1.0 - lam) * s2 + lam * rho - float(delta @ X[:, 0])
    return q_new, 0.5 * (P_new + P_new.T), s2_new


def obe_weight(g: float, beta: float) -> float:
    """Weight ``nu`` minimising the upper bound of ``s2+`` in :func:`quadratic_update`.

    With ``g`` the largest eigenvalue of ``C P C'`` and ``beta = (rho - s2) / ||delta||^2``
    (Dasgupta & Huang 1987; Gollamudi et al. 1996; Liu et al. 2016):
    ``nu = (1 - sqrt(g / (1 + beta (g - 1)))) / (1 - g)``, or ``(1 - beta) / 2`` for
    ``g = 1``.  Returns ``1.0`` when ``1 + beta (g - 1) <= 0``: the bound then decreases on
    all of ``(0, 1)`` and the caller must cap the weight.
    """
    if abs(g - 1.0) <= 1e-8 * max(1.0, abs(g)):
        return 0.5 * (1.0 - beta)
    omega = 1.0 + beta * (g - 1.0)
    if omega <= 0.0:
        return 1.0
    return float((1.0 - np.sqrt(g / omega)) / (1.0 - g))


def max_quadratic_on_zonotope(M: np.ndarray, G: np.ndarray, exact_up_to: int = 16) -> float:
    """Upper bound of ``max (G xi)' M (G xi)`` over ``||xi||_inf <= 1`` (``M`` PSD).

    Exact (maximum over the ``2^r`` vertices, where a convex function attains its maximum)
    for ``r <= exact_up_to`` generators, else ``min(r lambda_max(H), sum |H_ij|)`` with
    ``H = G' M G``, both valid since ``||xi||_2^2 <= r`` and ``|xi_i xi_j| <= 1``.
    """
    H = G.T @ M @ G
    r = H.shape[0]
    if r == 0:
        return 0.0
    if r <= exact_up_to:
        signs = np.array(list(product((-1.0, 1.0), repeat=r - 1)))
        signs = np.hstack([np.ones((signs.shape[0], 1)), signs])  # xi and -xi give the same
        return float(max(np.einsum("ki,ij,kj->k", signs, H, signs).max(), 0.0))
    return float(min(r * np.linalg.eigvalsh(0.5 * (H + H.T))[-1], np.abs(H).sum()))


# -- the set class ----------------------------------------------------------------------------
class Ellipsoid:
    """Ellipsoid with centre ``q`` and shape matrix ``Q`` (CORA's ``ellipsoid(Q, q)``).

    ``E1 + E2`` is the minimal-trace outer ellipsoid of the Minkowski sum,
    ``Q = (1 + 1/p) Q1 + (1 + p) Q2`` with ``p = sqrt(tr Q1 / tr Q2)`` (Kurzhanski & Valyi);
    :meth:`plus` offers the other members of that family.  ``E + v`` translates and ``M @ E``
    is exact.
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

    @classmethod
    def trusted(cls, q: np.ndarray, Q: np.ndarray) -> Ellipsoid:
        """Build from fresh float arrays (``q``: n, ``Q``: symmetric PSD n x n) without
        validation or copies, for hot loops; the arrays are frozen in place."""
        obj = object.__new__(cls)
        q.setflags(write=False)
        Q.setflags(write=False)
        obj._q, obj._Q = q, Q
        return obj

    @classmethod
    def from_zonotope(cls, Z, mode: str = "outer:norm") -> Ellipsoid:
        """Ellipsoid inside or around the zonotope ``Z = c + G xi`` (or an :class:`Interval`).

        ``mode``:

        * ``"inner:norm"``: ``Q = G G'``, the image ``{G xi : ||xi||_2 <= 1}`` of the unit
          ball, which lies in ``Z`` because ``||xi||_inf <= ||xi||_2``;
        * ``"outer:norm"``: ``Q = r G G'`` with ``r`` the number of non-zero generators, the
          image of the ball of radius ``sqrt(r)``, which contains ``Z`` because
          ``||xi||_2 <= sqrt(r)`` on the unit cube.

        For parallelotopes (``r = n``) these are CORA's ``ellipsoid(Z, 'inner:norm')`` and
        ``ellipsoid(Z, 'outer:norm')`` (``G G'`` and ``n G G'``); degenerate zonotopes give
        rank-deficient shape matrices.
        """
        if isinstance(Z, Interval):
            Z = Zonotope.from_interval(Z)
        if not isinstance(Z, Zonotope):
            raise SetError(f"from_zonotope needs a Zonotope or an Interval, got {type(Z).__name__}")
        if mode not in CONVERSIONS:
            raise SetError(f"unknown conversion mode '{mode}' (known: {', '.join(CONVERSIONS)})")
        G = Z.G[:, np.any(Z.G != 0.0, axis=0)]
        fac = 1.0 if mode == "inner:norm" else float(G.shape[1])
        Q = fac * (G @ G.T)
        return cls.trusted(np.array(Z.c, dtype=float), 0.5 * (Q + Q.T))

    q = property(lambda self: self._q, doc="Centre.")
    Q = property(lambda self: self._Q, doc="Shape matrix (symmetric PSD).")

    @property
    def doubles(self) -> int:
        """Floating-point values that define the set: centre and shape matrix (memory)."""
        return self.q.size + self.Q.size

    @property
    def dim(self) -> int:
        """Dimension n of the ambient space."""
        return self._q.shape[0]

    def center(self) -> np.ndarray:
        """Centre ``q``."""
        return self._q

    # -- operations -------------------------------------------------------------------------
    def plus(self, other: Ellipsoid, weight: str | float = "min-trace") -> Ellipsoid:
        """Outer ellipsoid of the Minkowski sum, ``Q1 / (1 - p) + Q2 / p`` (see
        :func:`outer_sum`; ``weight`` is a strategy name or the number ``p``)."""
        if not isinstance(other, Ellipsoid):
            raise SetError(f"can only add an Ellipsoid to an Ellipsoid, got {type(other).__name__}")
        if other.dim != self.dim:
            raise SetError(f"cannot add ellipsoids of dimensions {self.dim} and {other.dim}")
        return Ellipsoid(self._q + other._q, outer_sum(self._Q, other._Q, weight))

    def __add__(self, other) -> Ellipsoid:
        if isinstance(other, Ellipsoid):
            return self.plus(other)
        if hasattr(other, "interval") and not isinstance(other, np.ndarray):
            return NotImplemented
        return Ellipsoid(self._q + vector(other, "translation vector", dim=self.dim), self._Q)

    __radd__ = __add__

    def __rmatmul__(self, M) -> Ellipsoid:
        M = linear_map_matrix(M, self.dim)
        return Ellipsoid(M @ self._q, M @ self._Q @ M.T)

    def __neg__(self) -> Ellipsoid:
        return Ellipsoid(-self._q, self._Q)

    def intersect_strip(self, C, y, V, lam: str | float = "min-trace") -> Ellipsoid:
        """Outer ellipsoid of the intersection with the measurement set of ``y``,
        ``{x : y - C x in E(0, V)}`` (for one output and ``V = sigma^2`` the strip
        ``|C x - y| <= sigma``).

        A member of the family of :func:`quadratic_update` (prior level 1, measurement set
        whitened with ``V``), chosen by ``lam``: a number in ``(0, 1)``, ``"min-trace"`` (the
        member of smallest trace, by a bounded scalar search) or ``"obe"`` (the rule of
        :func:`obe_weight`, which leaves the set unchanged when the level cannot decrease,
        e.g. when ``y`` is the centre's output).  Raises :class:`SetError` if the
        intersection is empty.
        """
        m = np.atleast_2d(np.asarray(V, dtype=float)).shape[0]
        C = matrix(C, "output matrix", rows=m, cols=self.dim)
        y = vector(y, "measurement", dim=m)
        V = matrix(V, "noise shape matrix", rows=m, cols=m)
        try:
            T = np.linalg.inv(np.linalg.cholesky(0.5 * (V + V.T)))  # T'T = V^-1
        except np.linalg.LinAlgError:
            raise SetError("noise shape matrix V must be positive definite") from None
        Ct, yt, P = T @ C, T @ y, np.array(self._Q)

        def member(w: float) -> tuple[np.ndarray, np.ndarray, float]:
            return quadratic_update(self._q, P, 1.0, Ct, 1.0, yt, w)

        if lam == "obe":
            delta = yt - Ct @ self._q
            g = float(np.linalg.eigvalsh(Ct @ P @ Ct.T)[-1])
            if not (delta @ delta > 0.0 and g > 0.0):
                return self
            lam = obe_weight(g, 0.0)
        elif lam == "min-trace":
            from scipy.optimize import minimize_scalar

            def size(w: float) -> float:
                _, Pw, s2 = member(w)
                return max(s2, 0.0) * float(np.trace(Pw))

            lam = float(minimize_scalar(size, bounds=(1e-9, 1 - 1e-9), method="bounded",
                                        options={"xatol": 1e-10}).x)
        elif isinstance(lam, str):
            raise SetError(f"unknown intersection weight '{lam}' (known: min-trace, obe, "
                           "or a number)")
        lam = float(lam)
        if not 0.0 < lam < 1.0:
            raise SetError(f"intersection weight must lie in (0, 1), got {lam!r}")
        q, P_new, s2 = member(lam)
        if s2 < 0.0:
            raise SetError("the ellipsoid does not intersect the measurement set")
        return Ellipsoid(q, s2 * P_new)

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
        # the range of Q relative to its largest eigenvalue: an absolute floor of 1e-10 put the
        # whole of an ellipsoid of radius 5e-7 (a system in units of 1e-6) outside its range
        pos = lam > _PSD_TOL * lam.max(initial=0.0)
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

    def sample(self, k: int, rng: np.random.Generator) -> np.ndarray:
        """``k`` random points of the set (k x n), half of them on the boundary."""
        lam, V = np.linalg.eigh(self._Q)
        L = V * np.sqrt(np.maximum(lam, 0.0))
        d = rng.normal(size=(k, self.dim))
        d /= np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-300)
        r = np.where(rng.random(k) < 0.5, 1.0, rng.random(k) ** (1.0 / max(self.dim, 1)))
        return self._q + (d * r[:, None]) @ L.T

    # -- value semantics --------------------------------------------------------------------
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
