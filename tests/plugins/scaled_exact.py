"""``Test-Exact-098``: the exact reference's hulls scaled by 0.98 about their centres
(unsound on purpose: the exact floor must flag it, whatever the true state does)."""

from __future__ import annotations

import observers
from observers.builtin.exact import Exact
from observers.sets import Interval


@observers.register("Test-Exact-098", family="strip", set_type="interval",
                    ready_for_control=False)
class ScaledExact(Exact):
    """``Exact`` whose hulls are scaled by 0.98 about their centres (test only)."""

    def step(self, u_prev, y):
        S = super().step(u_prev, y).interval()
        c, r = 0.5 * (S.lo + S.hi), 0.5 * (S.hi - S.lo)
        return Interval(c - 0.98 * r, c + 0.98 * r)
