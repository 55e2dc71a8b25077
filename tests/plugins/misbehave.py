"""Misbehaving observer plugins (test only), registered when imported (``tests.plugins.X`` is
importable by worker processes, as an installed plugin package would be):

``Test-Hang``
    FRad-A whose ``step`` never returns from step 3 on (a plugin stuck in a loop);
``Test-Exit``
    FRad-A whose ``step`` ends its process with ``os._exit(9)`` at step 2;
``Test-Leak``
    FRad-A that keeps 200 MB more at every step (up to 4 GB, so that a broken limit cannot
    take the machine);
``Test-Lie``
    FRad-A with its sets scaled to 0.95 about their centres (tighter, and unsound).
"""

from __future__ import annotations

import os
import time

import numpy as np

import observers
from observers.builtin.frad import FRadA
from observers.sets import Zonotope

NAMES = ("Test-Hang", "Test-Exit", "Test-Leak", "Test-Lie")
_KEPT: list[np.ndarray] = []


@observers.register("Test-Hang", family="strip", set_type="zonotope", ready_for_control=False)
class Hang(FRadA):
    """FRad-A that hangs at step 3 (test only)."""

    def step(self, u_prev, y):
        if self.k == 3:
            flag = os.environ.get("SETOBS_TEST_HANG_FLAG")
            if flag:  # tell a test that the run is inside its jobs now
                open(flag, "a").close()
            while True:
                time.sleep(0.05)
        return super().step(u_prev, y)


@observers.register("Test-Exit", family="strip", set_type="zonotope", ready_for_control=False)
class Exit(FRadA):
    """FRad-A that ends its process with exit code 9 at step 2 (test only)."""

    def step(self, u_prev, y):
        if self.k == 2:
            os._exit(9)
        return super().step(u_prev, y)


@observers.register("Test-Leak", family="strip", set_type="zonotope", ready_for_control=False)
class Leak(FRadA):
    """FRad-A that leaks 200 MB per step, at most 4 GB (test only)."""

    def step(self, u_prev, y):
        if len(_KEPT) < 20:
            _KEPT.append(np.ones(25_000_000))  # 200 MB, written (resident)
        return super().step(u_prev, y)


@observers.register("Test-Lie", family="strip", set_type="zonotope", ready_for_control=False)
class Lie(FRadA):
    """FRad-A with its sets scaled to 0.95 about their centres (unsound, test only)."""

    def step(self, u_prev, y):
        Z = super().step(u_prev, y)
        return Zonotope(Z.c, 0.95 * Z.G)
