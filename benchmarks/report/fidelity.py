"""``reports/fidelity.md``: every published cell beside ours, from the cells the fidelity gate
measured (:func:`benchmarks.gate.fidelity.measure`; this module only renders them).

A summary per table (how many average cells are within their tolerance, the claims and the
cells that fail the gate), then per table every cell: ours, published, the deviation, the
tolerance, the claim (``within``, ``explained``, ``open``) and what the stores measure, and the
reason of every explained or open cell, and what to cite (:mod:`.citation`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import pandas as pd

from .citation import citation_lines
from .numbers import Num, fmt, markdown_table

TITLE = "# Fidelity: our committed numbers against the published tables"
INTRO = (
    "Every published cell of the tables this project reproduces (`benchmarks/gate/"
    "fidelity.yaml`: ARCH 2021 Tables 3-6, Automatica 2021 Table 3, Alanwar et al. 2022) "
    "beside ours, read from the committed result stores (`results/<config>/`): v_i and their "
    "average against the smallest RMS radius among the observers the table compares, as in "
    "`reports/<config>.md`; `t_ms` the median time per step. Deviation: ours / published - 1. "
    "Claim: `within` (we reproduce it: `make check` fails when it leaves its tolerance), "
    "`explained` (not reproduced, for the measured reason below) or `open` (not reproduced, "
    "cause not established). Measured: `within` or `outside` the tolerance, `missing` where "
    "our row is not in the store; **within now** marks an explained or open cell that is "
    "within its tolerance (its claim can be updated). Tolerances: 10 % for an average, 15 % "
    "for a per-state cell unless the claims file gives its own. Rendered by `make reports` "
    "(`python -m benchmarks reports`) from the claims file and the stores; "
    "`python -m benchmarks fidelity` prints the failing cells.")


def _value(x: Any) -> Num | str:
    """A value cell: a number, or a status word (``noGain``, ``inf``; ``missing``)."""
    if x is None:
        return "missing"
    return x if isinstance(x, str) else Num(float(x))


def deviation_text(deviation: float) -> str:
    """``+3.4 %`` (``n/a`` where either side is not a number)."""
    if deviation is None or not math.isfinite(deviation):
        return fmt(None)
    if deviation == 0:
        return "0 %"
    return ("+" if deviation >= 0 else "") + fmt(100 * deviation, 3) + " %"


def _tol_text(tol: float) -> str:
    return fmt(100 * tol, 3) + " %"


def failure_line(r) -> str:
    """The one line of a cell claimed ``within`` that is not (a row of the measured cells)."""
    ours = "missing (not in the store)" if r.ours is None else (
        r.ours if isinstance(r.ours, str) else fmt(r.ours))
    pub = r.published if isinstance(r.published, str) else fmt(r.published)
    dev = deviation_text(r.deviation)
    return (f"FIDELITY: {r.table}, {r.row} (ours {r.ours_row}), {r.cell}: ours {ours} vs "
            f"published {pub} ({dev}, tolerance {_tol_text(r.tol)})")


def _measured_cell(r) -> str:
    if r.claim == "within" and r.measured != "within":
        return f"**{r.measured}: FAILS**"
    if r.claim != "within" and r.measured == "within":
        return "**within now**"
    return r.measured


def summary_counts(cells: pd.DataFrame) -> pd.DataFrame:
    """Per table: cells, average cells and how many are within, the claims, the failures."""
    rows = []
    for table, g in cells.groupby("table", sort=False):
        avg = g[g["kind"] == "avg"]
        rows.append({"table": table, "cells": len(g),
                     "within": int((g["measured"] == "within").sum()),
                     "avg_cells": len(avg),
                     "avg_within": int((avg["measured"] == "within").sum()),
                     "claimed": int((g["claim"] == "within").sum()),
                     "explained": int((g["claim"] == "explained").sum()),
                     "open": int((g["claim"] == "open").sum()),
                     "failing": int(((g["claim"] == "within")
                                     & (g["measured"] != "within")).sum())})
    return pd.DataFrame(rows)


def summary_line(cells: pd.DataFrame) -> str:
    """``average cells within tolerance: ARCH T3 12 of 15, ...``."""
    counts = summary_counts(cells)
    return "Average cells within tolerance (10 %): " + ", ".join(
        f"{r.table} {r.avg_within} of {r.avg_cells}" for r in counts.itertuples(index=False)
        if r.avg_cells) + "."


def _summary_table(cells: pd.DataFrame) -> str:
    head = ["table", "published cells", "within now", "average cells within", "claimed within",
            "explained", "open", "failing the gate"]
    rows = [[r.table, str(r.cells), str(r.within),
             f"{r.avg_within} of {r.avg_cells}" if r.avg_cells else "-", str(r.claimed),
             str(r.explained), str(r.open), f"**{r.failing}**" if r.failing else "0"]
            for r in summary_counts(cells).itertuples(index=False)]
    return markdown_table(head, rows)


def _cell_table(g: pd.DataFrame) -> str:
    head = ["published row", "ours", "cell", "ours value", "published", "deviation",
            "tolerance", "claim", "measured"]
    rows = [[r.row, r.ours_row, r.cell, _value(r.ours), _value(r.published),
             deviation_text(r.deviation), _tol_text(r.tol), r.claim, _measured_cell(r)]
            for r in g.itertuples(index=False)]
    return markdown_table(head, rows)


def _reasons(g: pd.DataFrame) -> list[str]:
    """One line per claim and reason of the explained and open cells, naming the rows (with
    ours where it differs) and their cells."""
    out = []
    rest = g[g["claim"] != "within"]
    for (claim, reason), h in rest.groupby(["claim", "reason"], sort=False):
        where = "; ".join(
            f"{row}" + (f" (`{ours}`)" if ours != row else "") + f" {', '.join(k['cell'])}"
            for (row, ours), k in h.groupby(["row", "ours_row"], sort=False))
        out.append(f"- {claim}: **{where}**: {reason}")
    return out


def render(cells: pd.DataFrame, tables: Mapping[str, Any]) -> str:
    """The Markdown text of ``reports/fidelity.md``.

    Parameters
    ----------
    cells : pandas.DataFrame
        The measured cells (:func:`benchmarks.gate.fidelity.measure`).
    tables : Mapping
        Table name -> its source (with a ``title``), in the report's order.

    Returns
    -------
    str
        The report, ending with a newline.
    """
    parts = [TITLE, "", INTRO, "", "## Summary", "", _summary_table(cells), "",
             summary_line(cells), ""]
    for table, src in tables.items():
        g = cells[cells["table"] == table]
        if g.empty:
            continue
        parts += [f"## {table}: {src.title}", "", f"Configuration `{src.config}`, "
                  f"store `results/{src.config}/`.", "", _cell_table(g), ""]
        reasons = _reasons(g)
        if reasons:
            parts += ["Not reproduced:", "", *reasons, ""]
    parts += ["\n".join(citation_lines("fidelity", (src.paper for src in tables.values())))]
    return "\n".join(parts).rstrip("\n") + "\n"
