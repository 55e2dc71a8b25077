"""Constrained zonotopes ``{c + G xi : A xi = b, ||xi||_inf <= 1}`` (Scott et al., 2016)."""

from __future__ import annotations

import numpy as np

from ._arrays import direction, frozen, linear_map_matrix, matrix, vector
from ._lp import BoxLP, box_feasible
from .errors import SetError
from .interval import Interval
from .zonotope import Zonotope


class ConZonotope:
    """Constrained zonotope with centre ``c`` (n), generators ``G`` (n x r) and constraints
    ``A xi = b`` (``A``: nc x r, ``b``: nc).

    Interval hulls and support values are computed by linear programs (HiGHS) and are
    guaranteed outer bounds: they are evaluated from a dual point, never from the primal
    objective value (see :mod:`observers.sets._lp`).
    """

    __slots__ = ("_c", "_G", "_A", "_b")
    __array_ufunc__ = None

    def __init__(self, c, G=None, A=None, b=None):
        c = vector(c, "constrained zonotope centre")
        n = c.shape[0]
        G = np.zeros((n, 0)) if G is None else matrix(G, "constrained zonotope generators", rows=n)
        r = G.shape[1]
        if A is None:
            if b is not None and np.size(b) > 0:
                raise SetError("constraint offsets b given without constraint matrix A")
            A, b = np.zeros((0, r)), np.zeros(0)
        else:
            A = matrix(A, "constraint matrix A", cols=r)
            b = np.zeros(0) if b is None and A.shape[0] == 0 else b
            if b is None:
                raise SetError("constraint matrix A given without offsets b")
            b = vector(b, "constraint offsets b", dim=A.shape[0]) if A.shape[0] else np.zeros(0)
        self._c, self._G, self._A, self._b = frozen(c), frozen(G), frozen(A), frozen(b)

    @classmethod
    def from_zonotope(cls, Z: Zonotope) -> ConZonotope:
        """The zonotope ``Z`` without constraints."""
        return cls(Z.c, Z.G)

    # -- data -----------------------------------------------------------------------------
    c = property(lambda self: self._c, doc="Centre.")
    G = property(lambda self: self._G, doc="Generator matrix (n x r).")
    A = property(lambda self: self._A, doc="Constraint matrix (nc x r).")
    b = property(lambda self: self._b, doc="Constraint offsets (nc).")

    @property
    def dim(self) -> int:
        """Dimension n of the ambient space."""
        return self._c.shape[0]

    @property
    def num_generators(self) -> int:
        """Number r of generators."""
        return self._G.shape[1]

    @property
    def num_constraints(self) -> int:
        """Number nc of equality constraints."""
        return self._A.shape[0]

    def center(self) -> np.ndarray:
        """Centre ``c`` (not necessarily a point of the set)."""
        return self._c

    # -- operations -------------------------------------------------------------------------
    def __add__(self, other) -> ConZonotope:
        if isinstance(other, Interval):
            other = Zonotope.from_interval(other)
        if isinstance(other, Zonotope):
            other = ConZonotope.from_zonotope(other)
        if isinstance(other, ConZonotope):
            if other.dim != self.dim:
                raise SetError(f"cannot add sets of dimensions {self.dim} and {other.dim}")
            A = np.block(
                [
                    [self._A, np.zeros((self.num_constraints, other.num_generators))],
                    [np.zeros((other.num_constraints, self.num_generators)), other._A],
                ]
            )
            return ConZonotope(
                self._c + other._c, np.hstack([self._G, other._G]), A,
                np.concatenate([self._b, other._b]),
            )
        if hasattr(other, "interval") and not isinstance(other, np.ndarray):
            return NotImplemented
        v = vector(other, "translation vector", dim=self.dim)
        return ConZonotope(self._c + v, self._G, self._A, self._b)

    __radd__ = __add__

    def __rmatmul__(self, M) -> ConZonotope:
        M = linear_map_matrix(M, self.dim)
        return ConZonotope(M @ self._c, M @ self._G, self._A, self._b)

    def __neg__(self) -> ConZonotope:
        return ConZonotope(-self._c, -self._G, self._A, self._b)

    def interval(self) -> Interval:
        """Guaranteed interval hull from 2n LPs sharing one feasible set."""
        if self.num_constraints == 0:
            return Zonotope(self._c, self._G).interval()
        lp = BoxLP(self._A, self._b)
        hi = np.array([lp.maximize(g) for g in self._G])
        lo = np.array([-lp.maximize(-g) for g in self._G])
        return Interval(self._c + lo, self._c + hi)

    def support(self, d) -> float | np.ndarray:
        """Guaranteed upper bound of the support function (vector ``d`` or one per column)."""
        d = direction(d, self.dim)
        D = d.reshape(self.dim, -1)
        if self.num_constraints == 0:
            vals = D.T @ self._c + np.abs(self._G.T @ D).sum(axis=0)
        else:
            lp = BoxLP(self._A, self._b)
            vals = np.array([di @ self._c + lp.maximize(self._G.T @ di) for di in D.T])
        return float(vals[0]) if d.ndim == 1 else vals

    def contains(self, x, tol: float = 0.0) -> bool:
        """Membership of ``x`` up to ``tol`` (infinity norm in state space); one LP."""
        x = vector(x, "point", dim=self.dim)
        M = np.vstack([self._G, self._A])
        t = np.concatenate([x - self._c, self._b])
        tols = np.concatenate([np.full(self.dim, tol), np.zeros(self.num_constraints)])
        return box_feasible(M, t, tols)

    def to_zonotope(self) -> Zonotope:
        """Outer approximation obtained by dropping the constraints."""
        return Zonotope(self._c, self._G)

    # -- value semantics --------------------------------------------------------------------
    def __eq__(self, other) -> bool:
        return isinstance(other, ConZonotope) and all(
            a.shape == b.shape and np.array_equal(a, b)
            for a, b in zip(
                (self._c, self._G, self._A, self._b),
                (other._c, other._G, other._A, other._b),
                strict=True,
            )
        )

    def __hash__(self) -> int:
        return hash(tuple((a.shape, a.tobytes()) for a in (self._c, self._G, self._A, self._b)))

    def __repr__(self) -> str:
        return (
            f"ConZonotope(dim={self.dim}, generators={self.num_generators}, "
            f"constraints={self.num_constraints})"
        )
