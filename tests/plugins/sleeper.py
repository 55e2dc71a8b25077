"""``Test-Sleep``: an observer plugin whose ``step()`` sleeps for ever (test only; the gate's
time budget per job, ``tests/test_gate_budget.py``)."""

from __future__ import annotations

import time

import observers
from observers.builtin.frad import FRadA


@observers.register("Test-Sleep", family="strip", set_type="zonotope", ready_for_control=False)
class Sleep(FRadA):
    """FRad-A whose first ``step`` never returns (test only)."""

    def step(self, u_prev, y):
        while True:
            time.sleep(3600)
