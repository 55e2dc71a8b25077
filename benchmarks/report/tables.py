"""The cells of the report tables, rendered by both the Markdown report
(:mod:`.markdown`) and the HTML page (:mod:`.html`): one source of the cells, two renderers.

* :func:`scenario_table_data` -- relative RMS per state (eq. 9, the published value beside it),
  average, times and the containment verdict of every observer on one scenario;
* :func:`absolute_table_data` -- absolute RMS radii with the published ones;
* :func:`scenario_notes` -- failures and observers that do not apply;
* :data:`INTRO` -- the paragraph that opens both reports;
* :func:`design_times_table` -- the offline designs' times (``setobs-bench designs``).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from observers.registry import table_order

from ..metrics import timed_in_parallel
from ..verdicts import NA, NO, contained_column, reference_rows, violating
from .numbers import fmt, fmt_pair, markdown_table, text_table
from .paper import paper_rows, paper_status

#: the paragraph that opens the Markdown and the HTML report
INTRO = ("Relative RMS interval radius v_i (eq. 9 of Althoff & Rath 2021) per state; the "
         "published value is in parentheses where a paper table exists, and then our ratios "
         "are taken against the best of the observers that table compares (so both share "
         "their reference; observers the paper did not run, e.g. CZN in ARCH 2021, can be "
         "below 1). `rel_rms` in summary.csv is against all observers of the run. Times "
         "are medians "
         "per step on this machine (the papers' times: MATLAB, i7-8565U). `contained`: "
         "`yes` if the true state lies in every estimated set (exact membership test; "
         "`contained (hull only)`: in every interval hull), `no` with the number of "
         "violating steps, `n/a` where it was not checked (no true state in the record). "
         "A row marked (unsound) violates containment and is never the reference of a "
         "ratio. `(n/a)` after the average and the time: the observer is not part of the "
         "published comparison (the paper has no row for it, e.g. ROPO, CZN, the data-driven "
         "observers), so there is no published value to deviate from.")


def _contained_col(df: pd.DataFrame) -> str:
    hull = contained_column("hull")
    return hull if hull in df.columns else contained_column("exact")


def _status_cell(g: pd.DataFrame) -> str:
    """The ``contained`` cell: ``yes``, ``n/a`` (nothing to check it against, or not
    checked to the end), the number of violations, or the failure status; a row that is not
    guaranteed (a labelled CORA variant) says so, with its violations counted."""
    status, verdict = g["status"].iloc[0], g[_contained_col(g)].iloc[0]
    if not bool(g["guaranteed"].iloc[0]) and status == "ok":
        viol = g["violations"].iloc[0]
        return "not guaranteed" + ("" if pd.isna(viol) else f": {int(viol)} violations")
    if verdict == NO:
        return f"**no: {int(g['violations'].iloc[0])} violations**"
    if status == "ok":
        return NA if pd.isna(verdict) else str(verdict)
    step = g["failed_step"].iloc[0]
    return f"{status}" + (f" (step {int(step)})" if pd.notna(step) else "")


def paper_relative(df: pd.DataFrame, paper_names) -> pd.Series:
    """Eq. (9) with the minimum taken over the observers the published table compares (so
    that our ratios and the paper's share their reference); NaN where none of them ran."""
    ok = reference_rows(df) & df["observer"].isin(list(paper_names))
    best = df[ok].groupby("state")["rms_radius"].min()
    return df["rms_radius"] / df["state"].map(best)


def scenario_table(df: pd.DataFrame, meta: dict) -> str:
    """Markdown table of one scenario (:func:`scenario_table_data`)."""
    return markdown_table(*scenario_table_data(df, meta))


def scenario_table_data(df: pd.DataFrame, meta: dict) -> tuple[list[str], list[list[str]]]:
    """Header and rows (cell strings) of one scenario's table: relative RMS per state (paper
    value in parentheses), average, per-step time, design time and containment.

    Where a paper table exists, the ratios are taken against the best of the observers that
    table compares (:func:`paper_relative`), like the paper's own;
    otherwise against all observers of the run (``rel_rms``). The Markdown and the HTML
    report both render these cells."""
    sc = df["scenario"].iloc[0]
    info = meta.get("scenarios", {}).get(sc, {})
    n = int(df["state"].max()) + 1
    key = info.get("paper_table")
    variant = "nonlinear" if "nonlinear" in sc else "linear"
    paper = paper_rows(key, n, variant)
    names = info.get("state_names") or [f"x{i + 1}" for i in range(n)]
    show = list(range(n)) if n <= 8 else []
    contained = "contained" if _contained_col(df) == contained_column("exact") else (
        "contained (hull only)")
    # times of jobs that ran concurrently (``run --jobs``) are marked in the header itself
    par = " (parallel)" if timed_in_parallel(df) else ""
    head = (["Observer"] + [f"v{i + 1} {names[i]}" for i in show]
            + ["avg", f"step ms{par}", f"hull ms{par}", f"design s{par}", contained])
    rows = []
    df = df.assign(_rel=paper_relative(df, paper) if paper else df["rel_rms"],
                   _bad=violating(df))
    for obs in table_order(df["observer"].unique()):
        g = df[df["observer"] == obs].sort_values("state")
        p = paper.get(obs.split("[")[0])  # a labelled variant NAME[tag]: NAME's published row
        rel = g["_rel"].to_numpy(float)
        cells = [f"**{obs}** (unsound)" if g["_bad"].any() else obs]
        for i in show:
            cells.append(fmt_pair(rel[i], p.v[i] if p and p.v else None))
        avg = float(np.mean(rel)) if g["status"].iloc[0] == "ok" else float("nan")
        pstat = paper_status(key, n, obs, variant)
        if paper and p is None and not pstat:  # not part of the published comparison
            cells += [f"{fmt(avg)} ({NA})", f"{fmt(g['step_ms'].iloc[0])} ({NA})"]
        else:
            cells.append(fmt_pair(avg, p.avg if p else None) if not pstat
                         else f"{fmt(avg)} ({pstat})")
            cells.append(fmt_pair(g["step_ms"].iloc[0], p.t_ms if p else None))
        cells += [fmt(g["hull_ms"].iloc[0]), fmt(g["design_s"].iloc[0]), _status_cell(g)]
        rows.append(cells)
    return head, rows


def absolute_table(df: pd.DataFrame, meta: dict) -> str:
    """Markdown table of absolute RMS radii (:func:`absolute_table_data`); ``""`` if none."""
    data = absolute_table_data(df, meta)
    return markdown_table(*data) if data else ""


def absolute_table_data(df: pd.DataFrame, meta: dict) -> tuple[list[str], list[list[str]]] | None:
    """Header and rows of the absolute RMS radii (paper: relative value times its smallest
    absolute radius); ``None`` above 8 states."""
    sc = df["scenario"].iloc[0]
    info = meta.get("scenarios", {}).get(sc, {})
    n = int(df["state"].max()) + 1
    if n > 8:
        return None
    paper = paper_rows(info.get("paper_table"), n)
    head = ["Observer"] + [f"r{i + 1}" for i in range(n)]
    rows = []
    for obs in table_order(df["observer"].unique()):
        g = df[df["observer"] == obs].sort_values("state")
        p = paper.get(obs)
        r = g["rms_radius"].to_numpy(float)
        rows.append([obs] + [fmt_pair(r[i], p.absolute[i] if p and p.absolute else None)
                             for i in range(n)])
    return head, rows


def scenario_notes(full: pd.DataFrame) -> list[str]:
    """One line per observer that failed on a scenario (status and reason), and one listing
    the observers that do not apply to it (``unsupported``, left out of the tables)."""
    unsupported = full[full["status"] == "unsupported"].drop_duplicates("observer")
    failures = full[~full["status"].isin(["ok", "unsupported"])].drop_duplicates("observer")
    notes = [f"{r['observer']}: {r['status']}: {r['message']}" for _, r in failures.iterrows()]
    if len(unsupported):
        notes.append("not applicable here (unsupported): " + ", ".join(
            f"{r['observer']} ({r['message']})" for _, r in unsupported.iterrows()))
    return notes


def design_times_table(done: list[tuple[str, str, str, float]], top: int | None = None) -> str:
    """The per-design times of :func:`benchmarks.run.designs.prewarm`, slowest first, as a
    plain-text table.

    A design shared by several observers (e.g. the PRad-C/D centre) is computed by the first
    worker that needs it; the others wait for it on the cache lock, so their time is the
    wait.  A cached design shows the time of loading it.
    """
    rows = sorted(done, key=lambda r: -r[3])[:top]
    return text_table(["design", "status", "seconds"],
                      [[f"{s}: {o}", st, fmt(t, 3)] for s, o, st, t in rows],
                      right=[False, False, True])
