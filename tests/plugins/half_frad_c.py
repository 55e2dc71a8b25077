"""``Test-Half-FRad-C``: FRad-C whose sets are scaled to half their size about their centre
(unsound on purpose: the nonlinear falsifier must catch it)."""

from __future__ import annotations

import observers
from observers.builtin.frad import FRadC
from observers.sets import Zonotope


@observers.register("Test-Half-FRad-C", family="propagation", set_type="zonotope",
                    ready_for_control=True)
class HalfFRadC(FRadC):
    """FRad-C with its sets shrunk to half about their centre (unsound, test only)."""

    def step(self, u_prev, y):
        Z = super().step(u_prev, y)
        return Zonotope(Z.c, 0.5 * Z.G)
