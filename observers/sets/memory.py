"""The memory a set holds: the number of floating-point values that define it.

ReachTool (Silvestre 2023) reports it beside error, time and volume when it compares set
representations for estimation: a representation that is accurate only with ten thousand
generators costs what those generators cost at every step.  Counted from the arrays that define
each set type (caches such as a stored interval hull are not part of the set):

==========================  ==========================================
:class:`Interval`           ``2 n`` (``lo``, ``hi``)
:class:`Zonotope`           ``n + n r`` (centre, generators)
:class:`ConZonotope`        ``n + n r + nc r + nc`` (``c, G, A, b``)
:class:`Ellipsoid`          ``n + n^2`` (centre, shape matrix)
:class:`ZonotopeBundle`     the sum over its members
==========================  ==========================================

A set type of a plugin may say its own count with a ``doubles`` attribute; any other object
counts as unknown (NaN).
"""

from __future__ import annotations

from .bundle import ZonotopeBundle
from .conzonotope import ConZonotope
from .ellipsoid import Ellipsoid
from .interval import Interval
from .zonotope import Zonotope


def doubles(S) -> float:
    """The number of floating-point values that define the set ``S`` (NaN if unknown).

    Examples
    --------
    >>> import numpy as np
    >>> doubles(Zonotope(np.zeros(2), np.eye(2)))  # 2 + 2 * 2
    6
    """
    if isinstance(S, Zonotope):
        return S.c.size + S.G.size
    if isinstance(S, ConZonotope):
        return S.c.size + S.G.size + S.A.size + S.b.size
    if isinstance(S, Interval):
        return S.lo.size + S.hi.size
    if isinstance(S, Ellipsoid):
        return S.q.size + S.Q.size
    if isinstance(S, ZonotopeBundle):
        return sum(doubles(Z) for Z in S.members)
    own = getattr(S, "doubles", None)
    return float(own) if isinstance(own, (int, float)) else float("nan")
