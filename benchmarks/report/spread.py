"""The measured BLAS-kernel spread printed beside the cells of observers whose design is
undetermined (issue 37: a table never shows a bare number that another machine would not
reproduce).

Every built-in observer gives the same numbers under every OpenBLAS kernel to 1e-4 or better
(``results/baseline/SENSITIVITY.md``).  An observer listed in :data:`CHAOTIC_BY_NATURE` would
keep a published row whose design is not a defined point: its cells carry the spread measured
by ``baseline --update`` on the same scenario (the golden files' ``kernel_spread``), or say
that none was measured there.  The list is empty since PRad-A's design became the unique
Riccati point (it held PRad-A on the 6-tank, whose SDP returned a point within its
tolerance: a 394 % spread).
"""

from __future__ import annotations

import functools
import math
from pathlib import Path

import pandas as pd

from .freshness import ROOT
from .numbers import fmt

#: observers whose published rows rest on an undetermined design (see the module docstring)
CHAOTIC_BY_NATURE: tuple[str, ...] = ()
#: a measured spread above this (relative) is printed beside the value
SHOWN_ABOVE = 1e-4
#: the golden files of the regression gate (their ``kernel_spread`` column)
BASELINE = ROOT / "results" / "baseline"


@functools.lru_cache(maxsize=32)
def _golden(path: Path) -> pd.DataFrame | None:
    try:
        return pd.read_csv(path)
    except (OSError, ValueError):
        return None


def measured_spread(observer: str, scenario: str, baseline: Path = BASELINE
                    ) -> list[float] | None:
    """Per state, the relative spread of the RMS radius of ``observer`` on ``scenario``
    under the OpenBLAS kernels ``baseline --update`` compared; ``None`` where the golden
    files have no such row."""
    frame = _golden(Path(baseline) / f"{scenario}.csv")
    if frame is None or "kernel_spread" not in frame.columns:
        return None
    rows = frame[frame["observer"] == observer].sort_values("state")
    if rows.empty:
        return None
    return [float(x) for x in pd.to_numeric(rows["kernel_spread"], errors="coerce")]


def spread_note(observer: str, scenario: str, state: int, baseline: Path = BASELINE
                ) -> str | None:
    """The text printed beside a cell of ``observer`` (a labelled variant ``NAME[tag]``
    counts as ``NAME``) on ``scenario``: ``None`` for an observer not chaotic by nature or a
    spread up to :data:`SHOWN_ABOVE`, else the measured spread, or that none was measured."""
    name = observer.split("[")[0]
    if name not in CHAOTIC_BY_NATURE:
        return None
    spread = measured_spread(name, scenario, baseline)
    if spread is None or state >= len(spread) or not math.isfinite(spread[state]):
        return "kernel spread not measured; design undetermined"
    if spread[state] <= SHOWN_ABOVE:
        return None
    return f"±{fmt(100 * spread[state], 3)} % across BLAS kernels"
