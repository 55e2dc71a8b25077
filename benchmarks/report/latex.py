"""The tables of a results folder as LaTeX (``setobs-bench report DIR --latex``:
``DIR/report.tex`` beside ``report.md``): per scenario its table of relative RMS per state,
average, gap, times and verdicts (the published values beside ours where the Markdown report
has them), the absolute radii and the gap per state, each a booktabs ``tabular`` in a ``table``
with a caption naming the record and the reference of the ratios.

The cells are those of the Markdown report (:mod:`.tables`, the same :class:`~.numbers.Num`
values written in the same notation), the smallest value of each number column in bold
(among the rows that are neither unsound nor the exact reference).  Needs ``\\usepackage
{booktabs}`` in the document.
"""

from __future__ import annotations

import dataclasses
import re
from pathlib import Path
from typing import Any

import pandas as pd

from ..io import atomic_write_text, load_results
from ..verdicts import violating
from .aggregate import is_sweep
from .numbers import Num, format_columns
from .tables import (
    absolute_table_caption,
    absolute_table_cells,
    gap_table_caption,
    gap_table_data,
    scenario_table_caption,
    scenario_table_cells,
)

#: LaTeX's special characters in text and what writes them
_SPECIAL = {"\\": r"\textbackslash{}", "&": r"\&", "%": r"\%", "$": r"\$", "#": r"\#",
            "_": r"\_", "{": r"\{", "}": r"\}", "~": r"\textasciitilde{}",
            "^": r"\textasciicircum{}", "≤": r"$\le$", "<=": r"$\le$", "`": ""}
_SPECIAL_RE = re.compile("|".join(re.escape(k) for k in sorted(_SPECIAL, key=len,
                                                                reverse=True)))
_BOLD_RE = re.compile(r"\*\*(.+?)\*\*")


def escape(text: str) -> str:
    """``text`` with LaTeX's special characters escaped and Markdown bold (``**x**``) as
    ``\\textbf{x}``.

    Examples
    --------
    >>> escape("a_b 5% & #1 **no**")
    'a\\\\_b 5\\\\% \\\\& \\\\#1 \\\\textbf{no}'
    """
    parts = _BOLD_RE.split(str(text))  # odd entries: bold spans
    out = [_SPECIAL_RE.sub(lambda m: _SPECIAL[m.group(0)], p) for p in parts]
    return "".join(rf"\textbf{{{p}}}" if i % 2 else p for i, p in enumerate(out))


def bold_best(rows: list[list[Any]], skip: set[str]) -> list[list[Any]]:
    """``rows`` with the smallest value of each number column bold (ties all bold), taken
    over the rows whose first cell (the observer) is not in ``skip`` and is not marked bold
    (an unsound row)."""
    def eligible(r) -> bool:
        return isinstance(r[0], str) and r[0] not in skip and not r[0].startswith("**")

    width = max((len(r) for r in rows), default=0)
    best: dict[int, float] = {}
    for i in range(1, width):
        values = [c.value for r in rows if eligible(r) and i < len(r)
                  and isinstance(c := r[i], Num) and _finite(c.value)]
        if values:
            best[i] = min(float(v) for v in values)
    return [[dataclasses.replace(c, bold=True) if i in best and eligible(r)
             and isinstance(c, Num) and _finite(c.value) and float(c.value) == best[i] else c
             for i, c in enumerate(r)] for r in rows]


def _finite(value: Any) -> bool:
    try:
        return value is not None and pd.notna(value) and abs(float(value)) < float("inf")
    except (TypeError, ValueError):
        return False


def tabular(head: list[str], rows: list[list[Any]], skip: set[str]) -> str:
    """A booktabs ``tabular`` of a header and cells (the best value per column bold)."""
    cells = format_columns(bold_best(rows, skip))
    spec = "l" + "r" * (len(head) - 1)
    lines = [rf"\begin{{tabular}}{{{spec}}}", r"\toprule",
             " & ".join(escape(h) for h in head) + r" \\", r"\midrule"]
    lines += [" & ".join(escape(c) for c in r) + r" \\" for r in cells]
    return "\n".join([*lines, r"\bottomrule", r"\end{tabular}"])


def table(head: list[str], rows: list[list[Any]], caption: str, skip: set[str]) -> str:
    """A floating ``table`` holding :func:`tabular` and its caption."""
    return "\n".join([r"\begin{table}[htbp]", r"\centering", r"\small",
                      rf"\caption{{{escape(caption)}}}", tabular(head, rows, skip),
                      r"\end{table}", ""])


def _not_best(df: pd.DataFrame) -> set[str]:
    """The observers never bold as the best of a column: the exact reference and those that
    violate containment (:func:`benchmarks.verdicts.violating`)."""
    out = set(df.loc[violating(df), "observer"].astype(str))
    if "family" in df.columns:
        out |= set(df.loc[df["family"] == "reference", "observer"].astype(str))
    return out


def render_latex(summary: pd.DataFrame, meta: dict, name: str = "") -> str:
    """The LaTeX tables of a summary and its metadata, as text (see the module docstring)."""
    title = meta.get("config", {}).get("title", name)
    parts = [f"% {escape(title)}: tables of setobs-bench (needs \\usepackage{{booktabs}})", ""]
    if is_sweep(summary):
        return "\n".join([*parts, "% a sweep: its aggregated tables are in report.md only", ""])
    for sc, full in summary.groupby("scenario", sort=False):
        info = meta.get("scenarios", {}).get(sc, {})
        record = f"{sc}" + (f" ({info['description']})" if info.get("description") else "")
        skip = _not_best(full)
        head, rows = scenario_table_cells(full, meta)
        parts.append(table(head, rows, f"{record}. {scenario_table_caption(full, meta)}", skip))
        df = full[full["status"] != "unsupported"]
        absolute = absolute_table_cells(df, meta) if len(df) else None
        if absolute:
            parts.append(table(*absolute, f"{record}. {absolute_table_caption(df, meta)}",
                               skip))
        gaps = gap_table_data(df, meta) if len(df) else None
        if gaps:
            parts.append(table(*gaps, f"{record}. {gap_table_caption(df)}", skip))
    return "\n".join(parts)


def write_latex(results_dir: str | Path, out: str | Path, data: tuple | None = None) -> Path:
    """Write the LaTeX tables of a results folder (or of ``data``, ``(summary, meta)`` of a
    result store) to ``out``; returns its path."""
    summary, meta = data if data is not None else load_results(results_dir)
    out = Path(out)
    atomic_write_text(out, render_latex(summary, meta, Path(results_dir).name))
    return out


__all__ = ["bold_best", "escape", "render_latex", "table", "tabular", "write_latex"]
