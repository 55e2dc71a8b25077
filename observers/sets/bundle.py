"""Zonotope bundles: the intersection ``Z_1 & ... & Z_k`` of zonotopes, kept implicitly.

After Althoff & Krogh, "Zonotope bundles for the efficient computation of reachable sets"
(IEEE CDC-ECC 2011): a set is represented by several zonotopes whose intersection it is, and
every operation acts on each member.  A linear map and a Minkowski sum with a zonotope
distribute over the members as outer bounds (``M (Z_1 & Z_2) subset M Z_1 & M Z_2``,
``(Z_1 & Z_2) + Z subset (Z_1 + Z) & (Z_2 + Z)``; exact for an invertible map), so do the
intersection with a strip (each member with its own gain) and the order reduction (each
member on its own).  What the intersection is worth appears in the two questions that look
at all members at once:

* the **interval hull**, by linear programs over the intersection written as a constrained
  zonotope (``x = c_1 + G_1 xi_1`` with ``G_1 xi_1 - G_i xi_i = c_i - c_1``, Scott et al.
  2016), every bound evaluated from a dual point (:mod:`observers.lp.hull`), hence sound,
  and intersected with the members' own hulls;
* **membership**, exact by one LP per member (a point is in the bundle iff it is in every
  member).
"""

from __future__ import annotations

import numpy as np

from ..errors import EmptySet, SetError
from ..lp import HullLP
from ._arrays import linear_map_matrix, matrix, strips, vector
from .conzonotope import ConZonotope
from .interval import Interval
from .reduction import Reduction, check_order, get_reduction
from .zonotope import Zonotope, strip_generators

#: relative rounding margin of a member's interval hull ``c +- sum |G|``: members' hulls that
#: cross by less than this times their magnitude meet (a flat intersection)
HULL_ROUNDING = 64 * np.finfo(float).eps


class ZonotopeBundle:
    """The intersection of the zonotopes ``members`` (all of one dimension, at least one).

    Parameters
    ----------
    members : sequence of Zonotope or Interval

    Examples
    --------
    >>> import numpy as np
    >>> B = ZonotopeBundle([Zonotope([0, 0], [[1, 0], [0, 1]]),
    ...                     Zonotope([1, 0], [[0.5, 0.5], [0.5, -0.5]])])
    >>> B.contains([0.6, 0.0]), B.contains([0.0, 0.8])
    (True, False)
    """

    __slots__ = ("_members", "_hull", "_solver")
    __array_ufunc__ = None

    def __init__(self, members):
        members = [Zonotope.from_interval(Z) if isinstance(Z, Interval) else Z
                   for Z in members]
        if not members:
            raise SetError("a zonotope bundle needs at least one member")
        for Z in members:
            if not isinstance(Z, Zonotope):
                raise SetError(f"bundle members must be zonotopes, got {type(Z).__name__}")
        if len({Z.dim for Z in members}) != 1:
            raise SetError("bundle members have different dimensions: "
                           f"{sorted({Z.dim for Z in members})}")
        self._members = tuple(members)
        self._hull: Interval | None = None
        self._solver: HullLP | None = None

    @classmethod
    def trusted(cls, members, solver: HullLP | None = None) -> ZonotopeBundle:
        """Build from zonotopes of one dimension without checks (hot loops)."""
        obj = object.__new__(cls)
        obj._members, obj._hull, obj._solver = tuple(members), None, solver
        return obj

    def with_solver(self, solver: HullLP) -> ZonotopeBundle:
        """The same set, computing its hull LPs with the shared solver ``solver``."""
        if not isinstance(solver, HullLP):
            raise SetError(f"solver must be a HullLP, got {type(solver).__name__}")
        return ZonotopeBundle.trusted(self._members, solver)

    # -- data -----------------------------------------------------------------------------
    @property
    def members(self) -> tuple[Zonotope, ...]:
        """The zonotopes whose intersection the set is."""
        return self._members

    @property
    def doubles(self) -> int:
        """Floating-point values that define the set: the sum over the members (memory)."""
        return sum(Z.doubles for Z in self.members)

    @property
    def dim(self) -> int:
        """Dimension n of the ambient space."""
        return self._members[0].dim

    @property
    def size(self) -> int:
        """Number of members."""
        return len(self._members)

    def center(self) -> np.ndarray:
        """Midpoint of the interval hull."""
        return self.interval().center()

    # -- operations (member by member) --------------------------------------------------------
    def __rmatmul__(self, M) -> ZonotopeBundle:
        M = linear_map_matrix(M, self.dim)
        return ZonotopeBundle.trusted([M @ Z for Z in self._members], self._solver)

    def __add__(self, other) -> ZonotopeBundle:
        if isinstance(other, ZonotopeBundle):
            raise SetError("the Minkowski sum of two bundles is not a bundle operation "
                           "(add a zonotope)")
        if isinstance(other, Interval):
            other = Zonotope.from_interval(other)
        if isinstance(other, Zonotope):
            if other.dim != self.dim:
                raise SetError(f"cannot add a zonotope of dimension {other.dim} to a bundle "
                               f"of dimension {self.dim}")
        elif hasattr(other, "interval") and not isinstance(other, np.ndarray):
            return NotImplemented
        else:
            other = vector(other, "translation vector", dim=self.dim)
        return ZonotopeBundle.trusted([Z + other for Z in self._members], self._solver)

    __radd__ = __add__

    def intersect_strips(self, C, y, sigma, gains) -> ZonotopeBundle:
        """Outer bound of the intersection with the strips ``|C x - y| <= sigma``: each member
        ``(c, G)`` becomes ``c + L (y - C c)`` with generators ``[(I - L C) G, L diag(sigma)]``
        (the family of Alamo et al. 2005, Property 3, valid for every gain ``L``); ``gains``
        is one n x m gain per member (the bundle observer's choices:
        :func:`observers.numerics.bundle.member_gain`)."""
        C, y, sigma = strips(C, y, sigma, self.dim)
        m = C.shape[0]
        if len(gains) != self.size:
            raise SetError(f"{len(gains)} gains for {self.size} bundle members")
        out = []
        for Z, L in zip(self._members, gains, strict=True):
            L = matrix(L, "strip gain", rows=self.dim, cols=m)
            c = Z.c + L @ (y - C @ Z.c)
            out.append(Zonotope.trusted(c, strip_generators(Z.G, L, C, sigma)))
        return ZonotopeBundle.trusted(out, self._solver)

    def reduce(self, order: float, method: str | Reduction = "girard") -> ZonotopeBundle:
        """Every member reduced to order at most ``order`` with the named strategy."""
        check_order(order)
        strategy = get_reduction(method)
        return ZonotopeBundle.trusted(
            [Zonotope.trusted(Z.c.copy(), strategy.reduce(Z.G, order)) for Z in self._members],
            self._solver)

    # -- questions about the intersection -------------------------------------------------------
    def as_conzonotope(self) -> ConZonotope:
        """The intersection as a constrained zonotope in the factors of all members:
        ``c_1 + [G_1, 0, ...] xi`` with ``G_1 xi_1 - G_i xi_i = c_i - c_1`` (i >= 2)."""
        Z1 = self._members[0]
        n, k = self.dim, self.size
        widths = [Z.num_generators for Z in self._members]
        r = sum(widths)
        G = np.zeros((n, r))
        G[:, : widths[0]] = Z1.G
        A = np.zeros(((k - 1) * n, r))
        b = np.zeros((k - 1) * n)
        start = widths[0]
        for i, Z in enumerate(self._members[1:]):
            rows = slice(i * n, (i + 1) * n)
            A[rows, : widths[0]] = Z1.G
            A[rows, start : start + widths[i + 1]] = -Z.G
            b[rows] = Z.c - Z1.c
            start += widths[i + 1]
        return ConZonotope.trusted(Z1.c.copy(), G, A, b, self._solver)

    def _member_box(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The intersection of the members' hulls and its rounding margin (per coordinate,
        :data:`HULL_ROUNDING` times the largest ``|c| + sum |G|`` of a member)."""
        his = [Z.interval() for Z in self._members]
        lo = np.max([H.lo for H in his], axis=0)
        hi = np.min([H.hi for H in his], axis=0)
        scale = np.max([np.abs(Z.c) + np.abs(Z.G).sum(axis=1) for Z in self._members], axis=0)
        return lo, hi, HULL_ROUNDING * scale

    def interval(self) -> Interval:
        """Interval hull of the intersection by LP (bounds from dual points, sound), within
        the intersection of the members' hulls; :class:`EmptySet` if those are disjoint.
        Where the LP reports the intersection empty (which rounding can fake on a thin
        intersection) the members' hulls are kept.  Bounds that cross by no more than the
        rounding margin of the members' hulls (:data:`HULL_ROUNDING`) are a flat
        intersection, not an empty one: its hull is the crossed interval, taken outward (a
        coordinate measured without noise pins every member to the same value up to the
        rounding of its own update; such crossings of 1e-16 ended ZB-A with ``empty``)."""
        if self._hull is not None:
            return self._hull
        lo, hi, margin = self._member_box()
        if np.any(lo > hi + margin):
            raise EmptySet("the members of the zonotope bundle do not intersect")
        if self.size > 1:
            try:
                H = self.as_conzonotope().interval()
            except EmptySet:
                H = None
            if H is not None:
                lo, hi = np.maximum(lo, H.lo), np.minimum(hi, H.hi)
                if np.any(lo > hi + margin):  # two sound bounds crossed beyond rounding
                    raise EmptySet("the members of the zonotope bundle do not intersect")
        self._hull = Interval(np.minimum(lo, hi), np.maximum(lo, hi))
        return self._hull

    def support(self, d) -> float | np.ndarray:
        """Sound upper bound of ``max d'x`` over the intersection: the least of the members'
        support values and the LP bound over the intersection."""
        best = np.min([np.asarray(Z.support(d), float) for Z in self._members], axis=0)
        if self.size > 1:
            try:
                best = np.minimum(best, np.asarray(self.as_conzonotope().support(d), float))
            except EmptySet:
                pass
        return best if np.ndim(best) else float(best)

    def contains(self, x, tol: float = 0.0) -> bool:
        """Exact membership up to ``tol`` (infinity norm) in every member (one LP each)."""
        x = vector(x, "point", dim=self.dim)
        return all(Z.contains(x, tol) for Z in self._members)

    # -- value semantics --------------------------------------------------------------------
    def __eq__(self, other) -> bool:
        return isinstance(other, ZonotopeBundle) and self._members == other._members

    def __hash__(self) -> int:
        return hash(self._members)

    def __repr__(self) -> str:
        gens = ", ".join(str(Z.num_generators) for Z in self._members)
        return f"ZonotopeBundle(dim={self.dim}, members={self.size}, generators=[{gens}])"
