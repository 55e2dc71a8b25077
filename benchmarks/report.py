"""Markdown tables in the papers' layout (our value beside the published one) and figures of
the bounds over time with the true state."""

from __future__ import annotations

import math
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from observers.registry import table_order  # noqa: E402

from . import freshness  # noqa: E402
from .aggregate import is_sweep, sweep_tables  # noqa: E402
from .io import atomic_savefig, atomic_write_text, load_results  # noqa: E402
from .metrics import timed_in_parallel  # noqa: E402
from .paper import paper_rows, paper_status  # noqa: E402
from .verdicts import NA, NO, contained_column, reference_rows, violating  # noqa: E402

MAX_FIGURE_STATES = 6
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


def _fmt(x, digits: int = 4) -> str:
    if x is None or (isinstance(x, float) and math.isnan(x)):
        return "-"
    x = float(x)
    if x == 0:
        return "0"
    if abs(x) >= 1e4 or abs(x) < 1e-3:
        return f"{x:.{digits - 1}e}"
    return f"{x:.{digits}g}"


def _pair(ours, paper) -> str:
    return _fmt(ours) if paper is None else f"{_fmt(ours)} ({_fmt(paper)})"


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


def markdown_table(head: list[str], rows: list[list[str]]) -> str:
    """Render a header and rows of cell strings as a Markdown table."""
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    return "\n".join(lines + ["| " + " | ".join(cells) + " |" for cells in rows])


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
            cells.append(_pair(rel[i], p.v[i] if p and p.v else None))
        avg = float(np.mean(rel)) if g["status"].iloc[0] == "ok" else float("nan")
        pstat = paper_status(key, n, obs, variant)
        if paper and p is None and not pstat:  # not part of the published comparison
            cells += [f"{_fmt(avg)} ({NA})", f"{_fmt(g['step_ms'].iloc[0])} ({NA})"]
        else:
            cells.append(_pair(avg, p.avg if p else None) if not pstat
                         else f"{_fmt(avg)} ({pstat})")
            cells.append(_pair(g["step_ms"].iloc[0], p.t_ms if p else None))
        cells += [_fmt(g["hull_ms"].iloc[0]), _fmt(g["design_s"].iloc[0]), _status_cell(g)]
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
        rows.append([obs] + [_pair(r[i], p.absolute[i] if p and p.absolute else None)
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


def bounds_figure(runs: pd.DataFrame, scenario: str, observer: str, meta: dict, path: Path):
    """Interval bounds over time with the true state, one panel per state (first six)."""
    g = runs[(runs["scenario"] == scenario) & (runs["observer"] == observer)]
    if g.empty or not np.isfinite(g["lo"]).any():
        return None
    n = int(g["state"].max()) + 1
    names = meta.get("scenarios", {}).get(scenario, {}).get("state_names") or []
    k = min(n, MAX_FIGURE_STATES)
    fig, axes = plt.subplots(k, 1, figsize=(7, 1.6 * k + 0.6), sharex=True, squeeze=False)
    for i, ax in enumerate(axes[:, 0]):
        s = g[g["state"] == i]
        ax.fill_between(s["t"], s["lo"], s["hi"], color="tab:blue", alpha=0.3, lw=0,
                        label="estimated interval")
        if np.isfinite(s["x_true"]).any():
            ax.plot(s["t"], s["x_true"], color="k", lw=0.8, label="true state")
            bad = s[s["contained"] == 0]
            if len(bad):
                ax.plot(bad["t"], bad["x_true"], "rx", ms=4, label="outside")
        ax.set_ylabel(names[i] if i < len(names) else f"x{i + 1}", fontsize=8)
        ax.tick_params(labelsize=7)
    axes[0, 0].set_title(f"{observer} on {scenario}", fontsize=9)
    axes[0, 0].legend(fontsize=7, loc="upper right")
    axes[-1, 0].set_xlabel("t [s]", fontsize=8)
    fig.tight_layout()
    atomic_savefig(fig, path, dpi=90)
    plt.close(fig)
    return path


def write_report(results_dir: str | Path, out: str | Path | None = None,
                 figures: bool = True) -> Path:
    """Write the Markdown report (and figures) for a results folder; returns its path."""
    results_dir = Path(results_dir)
    summary, meta = load_results(results_dir)  # one complete generation, or ConfigError
    out = Path(out) if out else results_dir / "report.md"
    fig_dir = out.parent / (out.stem + "_figures")
    title = meta.get("config", {}).get("title", results_dir.name)
    parts = [f"# {title}", "", INTRO, ""]
    if timed_in_parallel(summary):
        ex = meta.get("executor", {})
        parts += [f"Times marked *(parallel)* were measured while {ex.get('workers', 'several')}"
                  f" jobs ran concurrently ({ex.get('name', 'parallel')} executor): indicative "
                  "only; a serial run (`run` without `--jobs`) gives the comparable per-step "
                  "times, and `reports/speed.md` is always timed serially.", ""]
    if is_sweep(summary):  # aggregated over the seeds, one row per observer and variant
        parts += ["Sweep: relative RMS radius (mean over the states of eq. 9, against the "
                  "best observer of the same seed) over the seeds: mean, standard deviation, "
                  "min and max over the successful runs; times are medians over them.", ""]
        parts += sweep_tables(summary, _fmt)
        summary = summary.iloc[0:0]  # no per-seed tables
    runs = None
    if figures and (results_dir / "runs.csv").is_file() and len(summary):
        runs = pd.read_csv(results_dir / "runs.csv")
    for sc, full in summary.groupby("scenario", sort=False):
        info = meta.get("scenarios", {}).get(sc, {})
        df = full[full["status"] != "unsupported"]  # listed below the tables instead
        parts += [f"## {sc}", "", info.get("description", ""), "", scenario_table(df, meta), ""]
        abs_table = absolute_table(df, meta)
        if abs_table:
            parts += ["Absolute RMS radii (published: relative value x smallest radius):", "",
                      abs_table, ""]
        notes = scenario_notes(full)
        parts += [f"- {note}" for note in notes] + ([""] if notes else [])
        if runs is not None:
            links = []
            for obs in table_order(df["observer"].unique()):
                p = bounds_figure(runs, sc, obs, meta, fig_dir / sc / f"{obs}.png")
                if p is not None:
                    links.append(f"[{obs}]({p.relative_to(out.parent).as_posix()})")
            if links:
                parts += ["Figures (bounds over time with the true state): " + ", ".join(links),
                          ""]
    versions = meta.get("versions", {})
    if versions:
        parts += ["---", "Run " + meta.get("created", "") + "; " + ", ".join(
            f"{k} {v}" for k, v in versions.items()), ""]
    config = freshness.config_of(meta.get("config", {}).get("name"))
    parts.append(freshness.stamp(freshness.report_command(config, out), config))
    atomic_write_text(out, "\n".join(parts) + "\n")
    return out
