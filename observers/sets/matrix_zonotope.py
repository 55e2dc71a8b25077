"""Matrix sets: interval matrices and matrix zonotopes (Althoff, PhD thesis 2010, Sec. 4.4).

A matrix zonotope is ``{C + sum_i beta_i G_i : |beta_i| <= 1}`` with an r x c centre ``C`` and
generator matrices ``G_i`` (stored as an array of shape (h, r, c)); an interval matrix is the
box ``{M : lo <= M <= hi}`` (entry-wise).

Products with vector sets are *sound enclosures*: the image of a zonotope under a matrix set is
in general not a zonotope (it contains the bilinear terms ``beta_i xi_j G_i g_j``), so

``M @ Z`` (matrix zonotope times zonotope)
    returns the zonotope with centre ``C c``, generators ``[C G, G_1 c, ..., G_h c]`` and the
    bilinear terms enclosed by their interval hull, i.e. one box with half-widths
    ``sum_{i,j} |G_i g_j|``.  Every point ``(C + sum beta_i G_i)(c + G xi)`` is
    ``C c + C G xi + sum_i beta_i G_i c + sum_{ij} (beta_i xi_j) G_i g_j`` with all factors and
    products in [-1, 1], hence in the result.
``M @ CZ`` (matrix zonotope times constrained zonotope)
    the same construction; the factors ``xi`` of the constrained zonotope keep their
    constraints ``A xi = b``, the new factors are unconstrained, so the result is a constrained
    zonotope that contains the image.
``I @ Z`` (interval matrix times zonotope)
    Althoff's theorem: centre ``T c``, generators ``[T G, diag(S (|c| + sum_j |g_j|))]`` with
    ``T`` the midpoint and ``S`` the radius matrix of ``I``.
"""

from __future__ import annotations

import numpy as np

from ..errors import SetError
from ..lp import box_feasible
from ._arrays import frozen, matrix
from .conzonotope import ConZonotope
from .reduction import Reduction, check_order, get_reduction
from .zonotope import Zonotope

_EPS = np.finfo(float).eps


def _generators(G, shape: tuple[int, int]) -> np.ndarray:
    """Validate generator matrices as an (h, r, c) array (a list of r x c matrices)."""
    if G is None:
        return np.zeros((0, *shape))
    try:
        a = np.asarray(G, dtype=float)
    except (TypeError, ValueError) as exc:
        raise SetError(f"matrix zonotope generators must be numeric ({exc})") from None
    if a.size == 0:
        return np.zeros((0, *shape))
    if a.ndim == 2 and a.shape == shape:
        a = a[None]
    if a.ndim != 3 or a.shape[1:] != shape:
        raise SetError(f"matrix zonotope generators must have shape (h, {shape[0]}, {shape[1]}),"
                       f" got {a.shape}")
    if not np.all(np.isfinite(a)):
        raise SetError("matrix zonotope generators contain non-finite values")
    return a


class IntervalMatrix:
    """The set of matrices ``lo <= M <= hi`` (entry-wise)."""

    __slots__ = ("_lo", "_hi")
    __array_ufunc__ = None

    def __init__(self, lo, hi):
        lo = matrix(lo, "interval matrix lower bound")
        hi = matrix(hi, "interval matrix upper bound", rows=lo.shape[0], cols=lo.shape[1])
        if np.any(lo > hi):
            raise SetError("interval matrix is empty (some lower bound exceeds its upper bound)")
        self._lo, self._hi = frozen(lo), frozen(hi)

    @classmethod
    def from_center_radius(cls, center, radius) -> IntervalMatrix:
        """``[center - radius, center + radius]`` (radius >= 0 entry-wise)."""
        c = matrix(center, "interval matrix centre")
        r = matrix(radius, "interval matrix radius", rows=c.shape[0], cols=c.shape[1])
        if np.any(r < 0):
            raise SetError("interval matrix radius must be non-negative")
        return cls(c - r, c + r)

    lo = property(lambda self: self._lo, doc="Entry-wise lower bounds.")
    hi = property(lambda self: self._hi, doc="Entry-wise upper bounds.")

    @property
    def shape(self) -> tuple[int, int]:
        """Shape (r, c) of the member matrices."""
        return self._lo.shape

    def center(self) -> np.ndarray:
        """Midpoint matrix."""
        return 0.5 * (self._lo + self._hi)

    def radius(self) -> np.ndarray:
        """Entry-wise half-widths."""
        return 0.5 * (self._hi - self._lo)

    def width(self) -> np.ndarray:
        """Entry-wise widths ``hi - lo``."""
        return self._hi - self._lo

    def contains(self, M, tol: float = 0.0) -> bool:
        """Whether ``lo - tol <= M <= hi + tol`` entry-wise."""
        M = matrix(M, "matrix", rows=self.shape[0], cols=self.shape[1])
        return bool(np.all(M >= self._lo - tol) and np.all(M <= self._hi + tol))

    def to_matrix_zonotope(self) -> MatrixZonotope:
        """The same box as a matrix zonotope (one generator per entry of non-zero width)."""
        r = self.radius()
        idx = np.flatnonzero(r)
        G = np.zeros((idx.size, *self.shape))
        G.reshape(idx.size, -1)[np.arange(idx.size), idx] = r.reshape(-1)[idx]
        return MatrixZonotope(self.center(), G)

    def __add__(self, other) -> IntervalMatrix:
        if isinstance(other, IntervalMatrix):
            if other.shape != self.shape:
                raise SetError(f"cannot add interval matrices of shapes {self.shape} and "
                               f"{other.shape}")
            return IntervalMatrix(self._lo + other._lo, self._hi + other._hi)
        if isinstance(other, MatrixZonotope):
            return NotImplemented
        M = matrix(other, "matrix", rows=self.shape[0], cols=self.shape[1])
        return IntervalMatrix(self._lo + M, self._hi + M)

    __radd__ = __add__

    def __neg__(self) -> IntervalMatrix:
        return IntervalMatrix(-self._hi, -self._lo)

    def __sub__(self, other) -> IntervalMatrix:
        return self + (-other)

    def __matmul__(self, other):
        """``I @ J`` (interval matrices or a numeric matrix), or ``I @ Z`` (zonotope)."""
        Tc, S = self.center(), self.radius()
        if isinstance(other, Zonotope):
            if other.dim != self.shape[1]:
                raise SetError(f"cannot map a set of dimension {other.dim} with an interval "
                               f"matrix of shape {self.shape}")
            box = S @ (np.abs(other.c) + np.abs(other.G).sum(axis=1))
            return Zonotope(Tc @ other.c, np.hstack([Tc @ other.G, np.diag(box)]))
        if isinstance(other, IntervalMatrix):
            Jc, Jr = other.center(), other.radius()
        else:
            Jc = matrix(other, "matrix", rows=self.shape[1])
            Jr = np.zeros_like(Jc)
        if Jc.shape[0] != self.shape[1]:
            raise SetError(f"cannot multiply interval matrices of shapes {self.shape} and "
                           f"{Jc.shape}")
        # midpoint-radius product (Rump): an enclosure of {M N}; widened for rounding errors
        c = Tc @ Jc
        r = np.abs(Tc) @ Jr + S @ (np.abs(Jc) + Jr)
        r = r + 4 * _EPS * (np.abs(Tc) @ np.abs(Jc) + r) * Tc.shape[1]
        return IntervalMatrix(c - r, c + r)

    def __rmatmul__(self, M) -> IntervalMatrix:
        M = matrix(M, "matrix", cols=self.shape[0])
        c = M @ self.center()
        r = np.abs(M) @ self.radius()
        r = r + 4 * _EPS * (np.abs(M) @ np.abs(self.center()) + r) * M.shape[1]
        return IntervalMatrix(c - r, c + r)

    def __repr__(self) -> str:
        return f"IntervalMatrix(shape={self.shape}, max width={self.width().max(initial=0):.4g})"


class MatrixZonotope:
    """Matrix zonotope ``<C, G_1, ..., G_h>`` (immutable value object).

    Parameters
    ----------
    C : (r, c) array_like
        Centre matrix.
    G : (h, r, c) array_like, optional
        Generator matrices.

    Examples
    --------
    >>> import numpy as np
    >>> M = MatrixZonotope(np.eye(2), [0.1 * np.eye(2)])
    >>> M.interval_matrix().hi
    array([[1.1, 0. ],
           [0. , 1.1]])
    """

    __slots__ = ("_C", "_G")
    __array_ufunc__ = None

    def __init__(self, C, G=None):
        C = matrix(C, "matrix zonotope centre")
        self._C = frozen(C)
        self._G = frozen(_generators(G, C.shape))

    @classmethod
    def trusted(cls, C: np.ndarray, G: np.ndarray) -> MatrixZonotope:
        obj = object.__new__(cls)
        C.setflags(write=False)
        G.setflags(write=False)
        obj._C, obj._G = C, G
        return obj

    @classmethod
    def from_sequence(cls, Z: Zonotope, T: int) -> MatrixZonotope:
        """All n x T matrices whose columns lie in ``Z`` independently (the paper's ``M_w``).

        Centre ``[c ... c]``; one generator per generator ``g`` of ``Z`` and column ``k``,
        with ``g`` in column ``k`` and zeros elsewhere (``xi * T`` generators).
        """
        T = int(T)
        if T < 1:
            raise SetError(f"a sequence needs at least one column, got T={T}")
        n, xi = Z.G.shape
        G = np.zeros((xi, T, n, T))
        for i in range(xi):
            G[i, np.arange(T), :, np.arange(T)] = Z.G[:, i]
        return cls(np.tile(Z.c.reshape(-1, 1), (1, T)), G.reshape(xi * T, n, T))

    # -- data -----------------------------------------------------------------------------
    C = property(lambda self: self._C, doc="Centre matrix.")
    G = property(lambda self: self._G, doc="Generator matrices, shape (h, r, c).")

    @property
    def shape(self) -> tuple[int, int]:
        """Shape (r, c) of the member matrices."""
        return self._C.shape

    @property
    def num_generators(self) -> int:
        """Number h of generator matrices."""
        return self._G.shape[0]

    def center(self) -> np.ndarray:
        """Centre matrix (alias of :attr:`C`)."""
        return self._C

    def radius(self) -> np.ndarray:
        """Entry-wise half-widths of the interval hull, ``sum_i |G_i|``."""
        return np.abs(self._G).sum(axis=0)

    def width(self) -> np.ndarray:
        """Entry-wise widths of the interval hull."""
        return 2.0 * self.radius()

    def interval_matrix(self) -> IntervalMatrix:
        """Interval hull ``C +- sum_i |G_i|`` (exact, entry-wise)."""
        r = self.radius()
        return IntervalMatrix(self._C - r, self._C + r)

    def vectorize(self) -> Zonotope:
        """The zonotope of ``vec(M)`` (row-major) in R^(r c)."""
        return Zonotope(self._C.reshape(-1), self._G.reshape(self.num_generators, -1).T)

    @classmethod
    def from_vector(cls, Z: Zonotope, shape: tuple[int, int]) -> MatrixZonotope:
        """Inverse of :meth:`vectorize`."""
        if Z.dim != shape[0] * shape[1]:
            raise SetError(f"a zonotope of dimension {Z.dim} is no {shape} matrix set")
        return cls(Z.c.reshape(shape), Z.G.T.reshape(-1, *shape))

    def sample(self, k: int, rng: np.random.Generator) -> np.ndarray:
        """``k`` random members (k x r x c), half of the factors at +-1."""
        beta = rng.uniform(-1.0, 1.0, size=(k, self.num_generators))
        beta = np.where(rng.random(beta.shape) < 0.5, np.sign(beta), beta)
        return self._C + np.einsum("kh,hrc->krc", beta, self._G)

    def contains(self, M, tol: float = 0.0) -> bool:
        """Exact membership of the matrix ``M`` up to ``tol`` per entry (one LP)."""
        M = matrix(M, "matrix", rows=self.shape[0], cols=self.shape[1])
        if not self.interval_matrix().contains(M, tol):
            return False
        return box_feasible(self._G.reshape(self.num_generators, -1).T,
                            (M - self._C).reshape(-1), tol)

    def reduce(self, order: float, method: str | Reduction = "girard") -> MatrixZonotope:
        """Enclosing matrix zonotope with at most ``order * r * c`` generators (the
        reduction strategy acts on the vectorised zonotope)."""
        check_order(order)
        G = get_reduction(method).reduce(self._G.reshape(self.num_generators, -1).T, order)
        return MatrixZonotope(self._C, G.T.reshape(-1, *self.shape))

    # -- operations -------------------------------------------------------------------------
    def __add__(self, other) -> MatrixZonotope:
        if isinstance(other, IntervalMatrix):
            other = other.to_matrix_zonotope()
        if isinstance(other, MatrixZonotope):
            if other.shape != self.shape:
                raise SetError(f"cannot add matrix sets of shapes {self.shape} and "
                               f"{other.shape}")
            return MatrixZonotope(self._C + other._C, np.concatenate([self._G, other._G]))
        M = matrix(other, "matrix", rows=self.shape[0], cols=self.shape[1])
        return MatrixZonotope(self._C + M, self._G)

    __radd__ = __add__

    def __neg__(self) -> MatrixZonotope:
        return MatrixZonotope(-self._C, -self._G)

    def __sub__(self, other) -> MatrixZonotope:
        return self + (-other)

    def __mul__(self, s) -> MatrixZonotope:
        if not np.isscalar(s):
            return NotImplemented
        return MatrixZonotope(float(s) * self._C, float(s) * self._G)

    __rmul__ = __mul__

    def __rmatmul__(self, L) -> MatrixZonotope:
        """``L @ M`` for a numeric matrix ``L`` (exact)."""
        L = matrix(L, "matrix", cols=self.shape[0])
        return MatrixZonotope(L @ self._C, np.matmul(L, self._G))

    def __matmul__(self, other):
        """``M @ R`` (numeric matrix, exact), ``M @ Z`` (zonotope) or ``M @ CZ``
        (constrained zonotope); the set products are sound enclosures (module docstring)."""
        if isinstance(other, Zonotope):
            c, Gx, bil = self._image(other.c, other.G)
            return Zonotope.trusted(c, np.hstack([Gx, np.diag(bil)]))
        if isinstance(other, ConZonotope):
            c, Gx, bil = self._image(other.c, other.G)
            G = np.hstack([Gx, np.diag(bil)])
            nc, r = other.A.shape
            A = np.hstack([other.A, np.zeros((nc, G.shape[1] - r))])
            return ConZonotope(c, G, A, other.b)
        if hasattr(other, "interval") and not isinstance(other, np.ndarray):
            return NotImplemented
        R = matrix(other, "matrix", rows=self.shape[1])
        return MatrixZonotope(self._C @ R, np.matmul(self._G, R))

    def _image(self, c: np.ndarray, G: np.ndarray):
        """Centre, generators ``[C G, G_i c]`` (the factors of the set first) and the box
        half-widths of the bilinear terms of ``M (c + G xi)``."""
        if c.shape[0] != self.shape[1]:
            raise SetError(f"cannot map a set of dimension {c.shape[0]} with a matrix set of "
                           f"shape {self.shape}")
        Gc = self._G @ c  # (h, r)
        bil = np.abs(np.matmul(self._G, G)).sum(axis=(0, 2)) if G.size else np.zeros(
            self.shape[0])
        Gx = np.hstack([self._C @ G, Gc.T])
        # outward rounding of the bilinear box covers floating-point error of all products
        scale = np.abs(self._C) @ (np.abs(c) + np.abs(G).sum(axis=1)) + np.abs(Gc).sum(axis=0)
        bil = bil + 4 * _EPS * (bil + scale) * max(1, self.shape[1])
        return self._C @ c, Gx, bil

    # -- value semantics --------------------------------------------------------------------
    def __eq__(self, other) -> bool:
        return (isinstance(other, MatrixZonotope) and np.array_equal(self._C, other._C)
                and self._G.shape == other._G.shape and np.array_equal(self._G, other._G))

    def __hash__(self) -> int:
        return hash((self._C.tobytes(), self._G.shape, self._G.tobytes()))

    def __repr__(self) -> str:
        return f"MatrixZonotope(shape={self.shape}, generators={self.num_generators})"
