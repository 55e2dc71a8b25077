"""A dependency-free progress bar on stderr (silent when stderr is not a terminal unless
forced)."""

from __future__ import annotations

import sys
import time


class Progress:
    """``with Progress(total, "label") as p: ... p.advance(note)``."""

    def __init__(self, total: int, label: str = "", enabled: bool | None = None, width: int = 28):
        self.total = max(int(total), 1)
        self.label = label
        self.width = width
        self.done = 0
        self.enabled = sys.stderr.isatty() if enabled is None else enabled
        self._t0 = time.perf_counter()

    def __enter__(self) -> Progress:
        self._draw("")
        return self

    def advance(self, note: str = "") -> None:
        """Count one unit of work as done and redraw."""
        self.done += 1
        self._draw(note)

    def _draw(self, note: str) -> None:
        if not self.enabled:
            return
        frac = self.done / self.total
        bar = "#" * int(frac * self.width)
        elapsed = time.perf_counter() - self._t0
        eta = elapsed / frac - elapsed if frac > 0 else 0.0
        line = (f"\r{self.label} [{bar:<{self.width}}] {self.done}/{self.total} "
                f"{elapsed:5.1f}s eta {eta:5.1f}s {note[:40]:<40}")
        sys.stderr.write(line)
        sys.stderr.flush()

    def __exit__(self, *exc) -> None:
        if self.enabled:
            sys.stderr.write("\n")
            sys.stderr.flush()
