"""The fidelity gate: our committed numbers against the published tables.

The regression gate (:mod:`.regression`) compares our numbers with our own golden files; this
one compares the committed result stores (``results/<config>/``) with the published cells,
as the claims file says (:mod:`.fidelity_claims`, ``benchmarks/gate/fidelity.yaml``):

* :func:`measure` classifies every published cell: ``within`` its tolerance, ``outside`` it,
  or ``missing`` (our row is not in the store), beside the claim (``within``, ``explained``,
  ``open``);
* :func:`failures` are the cells claimed ``within`` that are not: ``check`` fails on them,
  one line each naming the table, the row, the cell, ours and the published value;
* :func:`render` is ``reports/fidelity.md`` (:mod:`benchmarks.report.fidelity`), rendered by
  ``make reports`` and stale (``setobs-bench stale``, ``make check``) when it differs from its
  rendering now.

Ours is the value of the committed report: v_i against the smallest RMS radius among the
observers the published table compares (:func:`benchmarks.report.tables.relative_values`),
``avg`` their mean, ``t_ms`` the median time per step.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd

from ..io import atomic_write_text
from ..report import fidelity as fidelity_report
from ..report.tables import relative_values
from ..store.store import load_store
from .fidelity_claims import CLAIMS_FILE, TABLES, Claim, load_claims

#: the report this module renders (in the folder of the committed reports)
REPORT_NAME = "fidelity.md"
#: the columns of :func:`measure`
COLUMNS = ["table", "row", "cell", "kind", "ours_row", "ours", "published", "deviation", "tol",
           "claim", "measured", "reason"]
#: our statuses that match a published "diverged" (Inf) or "failed" (NaN)
FAILED = ("diverged", "error")


class _Stores:
    """The committed stores under ``results``, each read once, and the ratios of each
    scenario's table computed once."""

    def __init__(self, results: Path):
        self.results = Path(results)
        self._views: dict[str, tuple[pd.DataFrame, dict] | None] = {}
        self._tables: dict[tuple[str, str], pd.DataFrame | None] = {}

    def _table(self, config: str, scenario: str) -> pd.DataFrame | None:
        """The rows of ``scenario`` in the store of ``config`` with their ratio ``_rel`` (the
        report's v_i); ``None`` without a store."""
        if config not in self._views:
            store = load_store(self.results / config)
            self._views[config] = store.view() if store is not None else None
        key = (config, scenario)
        if key not in self._tables:
            view = self._views[config]
            if view is None:
                self._tables[key] = None
            else:
                summary, meta = view
                df = summary[summary["scenario"] == scenario]
                rel = relative_values(df, meta)[0] if len(df) else df.get("rel_rms")
                self._tables[key] = df.assign(_rel=rel)
        return self._tables[key]

    def ours(self, claim: Claim) -> float | str | None:
        """Our value of a claim's cell: a number, our status where the row has no estimate
        (``noGain``, ``diverged``, ...), ``None`` where the row is not in the store."""
        src = TABLES[claim.table]
        column = claim.cell if claim.cell in src.scenarios else ""
        df = self._table(src.config, src.scenarios[column])
        if df is None:
            return None
        g = df[df["observer"] == claim.ours].sort_values("state")
        if g.empty:
            return None
        status = str(g["status"].iloc[0])
        if status != "ok":
            return status
        if claim.kind == "time":
            return float(g["step_ms"].iloc[0])
        values = g["_rel"].to_numpy(float)
        if claim.cell.startswith("v"):
            return float(values[int(claim.cell[1:]) - 1])
        return float(np.mean(values))


def _compare(ours: float | str | None, published: float | str, tol: float
             ) -> tuple[str, float]:
    """``(measured, deviation)`` of one cell: ``within``/``outside``/``missing`` and
    ours / published - 1 (NaN where either is not a number)."""
    if ours is None:
        return "missing", math.nan
    if isinstance(published, str):  # noGain, inf (diverged), nan (failed)
        same = (ours == "noGain") if published == "noGain" else ours in FAILED
        return ("within" if same else "outside"), math.nan
    if isinstance(ours, str) or not math.isfinite(ours):
        return "outside", math.nan
    deviation = ours / published - 1.0
    return ("within" if abs(deviation) <= tol else "outside"), deviation


def measure(results: str | Path = "results", claims: str | Path = CLAIMS_FILE) -> pd.DataFrame:
    """Every published cell with ours, the deviation, the claim and what the stores measure.

    Parameters
    ----------
    results : str or Path
        The folder of the committed result stores.
    claims : str or Path
        The claims file (default the shipped ``benchmarks/gate/fidelity.yaml``).

    Returns
    -------
    pandas.DataFrame
        One row per published cell, columns :data:`COLUMNS` (``measured``: ``within``,
        ``outside`` or ``missing``).
    """
    stores = _Stores(Path(results))
    rows = []
    for c in load_claims(claims):
        ours = stores.ours(c)
        measured, deviation = _compare(ours, c.published, c.tol)
        rows.append([c.table, c.row, c.cell, c.kind, c.ours, ours, c.published, deviation,
                     c.tol, c.status, measured, c.reason])
    # object columns: a value is a number, a status word or None (missing), never coerced
    return pd.DataFrame({name: pd.Series([r[i] for r in rows], dtype=object)
                         for i, name in enumerate(COLUMNS)}).infer_objects().astype(
        {"ours": object, "published": object})


def failures(cells: pd.DataFrame) -> list[str]:
    """One line per cell claimed ``within`` that is not: table, row, cell, ours, published."""
    bad = cells[(cells["claim"] == "within") & (cells["measured"] != "within")]
    return [fidelity_report.failure_line(r) for r in bad.itertuples(index=False)]


def now_within(cells: pd.DataFrame) -> pd.DataFrame:
    """The ``explained`` or ``open`` cells that are within their tolerance now (their claim
    can be updated)."""
    return cells[(cells["claim"] != "within") & (cells["measured"] == "within")]


def render(results: str | Path = "results", claims: str | Path = CLAIMS_FILE) -> str:
    """The text of ``reports/fidelity.md`` from the stores under ``results``."""
    return fidelity_report.render(measure(results, claims), TABLES)


def summary(cells: pd.DataFrame) -> str:
    """``average cells within tolerance (10 %): ARCH T3 11 of 15, ...``."""
    return fidelity_report.summary_line(cells)


def rerender(results: str | Path, reports: str | Path) -> bool:
    """Write ``REPORTS/fidelity.md`` if it differs from its rendering now; whether it did."""
    path = Path(reports) / REPORT_NAME
    text = render(results)
    if path.is_file() and path.read_text(encoding="utf-8") == text:
        return False
    atomic_write_text(path, text)
    return True


def stale_line(results: str | Path, reports: str | Path) -> str | None:
    """Why ``REPORTS/fidelity.md`` is out of date (missing, or different from its rendering
    now), ``None`` if it is current."""
    path = Path(reports) / REPORT_NAME
    if not path.is_file():
        return f"{path} is missing (`make reports` renders it)"
    if path.read_text(encoding="utf-8") != render(results):
        return (f"{path} differs from the claims and the stores rendered now (`make reports` "
                "renders it)")
    return None
