"""``Test-Crash``: an observer whose design ends its process (a worker that dies mid-sweep)."""

from __future__ import annotations

import os

import observers
from observers.builtin.frad import FRadA


@observers.register("Test-Crash", family="strip", set_type="zonotope",
                    ready_for_control=False)
class Crash(FRadA):
    """FRad-A whose design kills its process with exit code 7 (test only)."""

    def design(self):
        os._exit(7)
