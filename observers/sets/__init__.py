"""Set representations used by the observers (leaf package: imports nothing else of ours).

All sets are immutable value objects with the same small vocabulary:

========================  =====================================================
``S1 + S2``               Minkowski sum (exact, or outer for ellipsoids)
``S + v``                 translation by a vector
``M @ S``                 linear map
``S.interval()``          interval hull as an :class:`Interval`
``S.support(d)``          support function (sound upper bound for LP-based sets)
``S.contains(x, tol)``    membership of a point, up to ``tol``
========================  =====================================================

Zonotopes additionally offer ``Z.reduce(order, method)`` with the strategies of
:mod:`observers.sets.reduction`.  Matrix sets (:class:`MatrixZonotope`, :class:`IntervalMatrix`)
map vector sets with ``M @ Z`` (a sound enclosure, see :mod:`observers.sets.matrix_zonotope`).
Constrained zonotopes add the exact ``intersect`` and
``intersect_strips``, the lifted ``reduce``, ``rescale``, ``normalize_constraints`` and
``reduce_constraints`` / ``to_zonotope`` with the named constraint eliminations ``"fold"`` and
``"frobenius"`` (array kernels in :mod:`observers.sets.conzono_ops`); their 2n hull LPs are
solved together by a batched dual simplex with HiGHS as fallback, and can share one solver
object across sets (:class:`HullLP`, ``S.with_solver(lp)``).  Zonotope bundles
(:class:`ZonotopeBundle`, intersections of zonotopes kept implicitly) apply every operation
member by member and answer the hull and membership over the intersection by LP.
"""

from ..errors import EmptySet, SetError
from ..lp import HullLP, HullLPStats
from .bundle import ZonotopeBundle
from .conzonotope import ConZonotope
from .ellipsoid import Ellipsoid
from .interval import Interval
from .matrix_zonotope import IntervalMatrix, MatrixZonotope
from .memory import doubles
from .reduction import (
    PCA,
    CoraPCA,
    Girard,
    Reduction,
    get_reduction,
    reduction_names,
    register_reduction,
)
from .zonotope import Zonotope

__all__ = [
    "ConZonotope",
    "CoraPCA",
    "Ellipsoid",
    "EmptySet",
    "Girard",
    "HullLP",
    "HullLPStats",
    "Interval",
    "IntervalMatrix",
    "MatrixZonotope",
    "PCA",
    "Reduction",
    "SetError",
    "Zonotope",
    "ZonotopeBundle",
    "doubles",
    "get_reduction",
    "reduction_names",
    "register_reduction",
]
