"""What a report says about a scenario's model besides its record: the bounds of the noise
sets and of the initial set, stored in ``meta.json`` (``scenarios.<name>.sets``) by the runner
and stated in the scenario headers of the reports."""

from __future__ import annotations

from typing import Any

import numpy as np

#: the sets of a system that the reports state, with the symbol of their elements
SETS = {"W": "w", "V": "v", "X0": "x0"}


def set_bounds(system: Any) -> dict[str, dict[str, Any]]:
    """Per set of :data:`SETS` the system has: the centre and the radii of its interval hull,
    whether it is that box (``box``: a zonotope whose generators are axis-aligned, at most one
    per coordinate), and its number of generators.

    Examples
    --------
    >>> from systems import alamo2d
    >>> set_bounds(alamo2d())["V"]["radius"]
    [0.2]
    """
    out: dict[str, dict[str, Any]] = {}
    for name in SETS:
        S = getattr(system, name, None)
        if S is None or not hasattr(S, "interval"):
            continue
        hull = S.interval()
        lo, hi = np.asarray(hull.lo, float), np.asarray(hull.hi, float)
        G = getattr(S, "G", None)
        box = False
        if G is not None:
            G = np.asarray(G, float)
            nonzero = np.count_nonzero(G, axis=0)
            rows = np.count_nonzero(G, axis=1)
            box = bool(np.all(nonzero <= 1) and np.all(rows <= 1))
        out[name] = {"center": ((lo + hi) / 2).tolist(), "radius": ((hi - lo) / 2).tolist(),
                     "box": box, "generators": None if G is None else int(G.shape[1])}
    return out
