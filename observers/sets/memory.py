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

Each set type says its own count (a ``doubles`` property), and so may the set type of a plugin;
any other object counts as unknown (NaN).  This module imports none of the set types: what a
row records about its sets depends on the code of the set types its observer uses, and no
more (:mod:`benchmarks.store.fingerprint`).
"""

from __future__ import annotations


def doubles(S) -> int | float:
    """The number of floating-point values that define the set ``S`` (NaN if unknown).

    Examples
    --------
    >>> import numpy as np
    >>> from observers.sets import Zonotope
    >>> doubles(Zonotope(np.zeros(2), np.eye(2)))  # 2 + 2 * 2
    6
    """
    own = getattr(S, "doubles", None)
    if isinstance(own, bool) or not isinstance(own, (int, float)):
        return float("nan")
    return own
