"""The measured BLAS-kernel spread printed beside a table cell that another machine would not
reproduce (issue 37: a table never shows such a number bare).

Two measurements feed it.  The paper tables' own: ``python -m benchmarks.studies.kernels``
(``make kernels``) re-runs each published configuration under every other OpenBLAS kernel of
the CPU and writes the spread of every accuracy cell to ``results/kernels/kernel_spread.csv``
(:data:`KERNEL_SPREAD`); a cell above :data:`SHOWN_ABOVE` carries it
(:func:`measured_cell_spread`).  And the regression gate's, for the observers below.

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

import numpy as np
import pandas as pd

from .freshness import ROOT
from .numbers import fmt

#: observers whose published rows rest on an undetermined design (see the module docstring)
CHAOTIC_BY_NATURE: tuple[str, ...] = ()
#: a measured spread above this (relative) is printed beside the value
SHOWN_ABOVE = 1e-4
#: the golden files of the regression gate (their ``kernel_spread`` column)
BASELINE = ROOT / "results" / "baseline"
#: the configurations of the published tables, whose cells the kernel study measures
PAPER_CONFIGS = ("arch2021_table3", "arch2021_table4", "arch2021_table5", "arch2021_table6",
                 "arch2021_table6_12tanks", "automatica2021_table3", "alanwar2022")
#: the configurations the kernel study measures: the published tables and the textbook plants
#: (whose CZN rows on the bus suspension move by up to 1 % with the rounding of one sum: a
#: ranking beyond the papers must say so too)
KERNEL_CONFIGS = (*PAPER_CONFIGS, "textbook")
#: the kernel study's table, relative to the checkout (``python -m benchmarks.studies.kernels``;
#: committed, and ``setobs-bench stale`` checks its fingerprints)
KERNEL_TABLE = Path("results") / "kernels" / "kernel_spread.csv"
#: the measured tables' per-cell spread in this checkout
KERNEL_SPREAD = ROOT / KERNEL_TABLE


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


def measured_cell_spread(observer: str, scenario: str, state: int, config: str | None = None,
                         table: Path = KERNEL_SPREAD) -> float | None:
    """The kernel spread of one accuracy cell of the configuration ``config`` (``observer``
    as labelled in its table, a variant ``NAME[tag]`` included) measured by the kernel study;
    ``None`` where it has no such cell (another configuration's cells are never borrowed) and
    ``inf`` where the status differs between kernels."""
    cells = _cells(Path(table))
    if cells is None or config is None:
        return None
    return cells.get((config, observer, scenario, state))


#: the index of each table read by :func:`_golden`, by the identity of its frame (a new read
#: of the file, after ``_golden.cache_clear()``, is a new frame and gets a new index)
_INDEXES: dict[int, tuple[pd.DataFrame, dict[tuple, float]]] = {}


def _cells(table: Path) -> dict[tuple, float] | None:
    """The kernel study's table as ``{(config, observer, scenario, state): spread}``: the
    largest spread of the key's rows (NaN if none is a number), ``inf`` where a row records
    another status under another kernel; ``None`` without a readable table.  Indexed once
    per read: a report renders thousands of cells."""
    frame = _golden(table)
    if frame is None or "spread" not in frame.columns:
        return None
    held = _INDEXES.get(id(frame))
    if held is None or held[0] is not frame:
        if len(_INDEXES) >= 32:  # as many as _golden keeps
            _INDEXES.clear()
        held = _INDEXES[id(frame)] = (frame, _index(frame))
    return held[1]


def _index(frame: pd.DataFrame) -> dict[tuple, float]:
    """The dictionary of :func:`_cells` for one read of the kernel study's table."""
    other = frame.get("status_other", pd.Series(math.nan, index=frame.index))
    cells = frame.assign(spread=pd.to_numeric(frame["spread"], errors="coerce"),
                         differs=other.notna() & (other.astype(str).str.len() > 0)).groupby(
        ["config", "observer", "scenario", "state"], sort=False).agg(
        spread=("spread", "max"), differs=("differs", "any"))
    return dict(zip(cells.index, np.where(cells["differs"], math.inf, cells["spread"]),
                    strict=True))


def row_spread_note(observer: str, scenario: str, states: int, config: str | None = None,
                    table: Path = KERNEL_SPREAD) -> str | None:
    """The text printed beside a value over the ``states`` states of a row (its average):
    the largest per-state spread the kernel study measured where it exceeds
    :data:`SHOWN_ABOVE` (a bound: the relative spread of a sum of positive radii is at most
    the largest relative spread of its terms), else ``None``.  A table too wide to show its
    states (more than 8) prints this beside the average, so a kernel-dependent row is never
    shown bare."""
    cells = [measured_cell_spread(observer, scenario, i, config, table) for i in range(states)]
    worst = max((c for c in cells if c is not None), default=None)
    if worst is None or worst <= SHOWN_ABOVE:
        return None
    if math.isinf(worst):
        return "status differs across BLAS kernels"
    return f"up to ±{fmt(100 * worst, 3)} % across BLAS kernels"


def spread_note(observer: str, scenario: str, state: int, config: str | None = None,
                baseline: Path = BASELINE, table: Path = KERNEL_SPREAD) -> str | None:
    """The text printed beside a cell of ``observer`` on ``scenario`` in the table of the
    configuration ``config``: the spread the kernel study measured for this very cell where
    it exceeds :data:`SHOWN_ABOVE`; else, for an
    observer chaotic by nature (a labelled variant ``NAME[tag]`` counts as ``NAME``), the
    regression gate's measured spread or that none was measured; else ``None``."""
    cell = measured_cell_spread(observer, scenario, state, config, table)
    if cell is not None and cell > SHOWN_ABOVE:
        if math.isinf(cell):
            return "status differs across BLAS kernels"
        return f"±{fmt(100 * cell, 3)} % across BLAS kernels"
    name = observer.split("[")[0]
    if name not in CHAOTIC_BY_NATURE:
        return None
    spread = measured_spread(name, scenario, baseline)
    if spread is None or state >= len(spread) or not math.isfinite(spread[state]):
        return "kernel spread not measured; design undetermined"
    if spread[state] <= SHOWN_ABOVE:
        return None
    return f"±{fmt(100 * spread[state], 3)} % across BLAS kernels"
