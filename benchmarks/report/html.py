"""The HTML report of a results folder (``DIR/index.html``) and the index of all reports.

The page renders the same table data as the Markdown report (:func:`benchmarks.report.
scenario_table_data`, :func:`~benchmarks.report.tables.absolute_table_data`): one source of the
cells, two renderers. It adds a ranking summary, per scenario the bounds of the tightest
observers over time for one state with the true state, a heat map of the relative RMS
(observer x state) and the per-step times on a log scale beside the papers' times, and the
configuration, environment and git commit of the run. Everything is inline (CSS and a small
sorting script, no network at view time); figures are matplotlib PNG files beside the page,
each with a PDF copy to download.
"""

from __future__ import annotations

import html
import os
import re
from pathlib import Path

import numpy as np
import pandas as pd
import yaml

from observers.registry import table_order

from ..errors import ConfigError
from ..io import atomic_write_text, environment, load_results, load_runs, path_component
from ..metrics import timed_in_parallel
from .aggregate import is_sweep, sweep_tables
from .figures import bounds_over_time, heat_map, step_times
from .numbers import MISSING, fmt
from .paper import paper_rows
from .tables import INTRO, absolute_table_data, scenario_notes, scenario_table_data

FIGURE_DIR = "html_figures"

CSS = """
body{font-family:system-ui,sans-serif;margin:1.5em auto;max-width:1200px;padding:0 1em;
color:#222}
h1{font-size:1.5em}h2{font-size:1.25em;border-bottom:1px solid #ccc;margin-top:2em}
h3{font-size:1.05em}
table.sortable{border-collapse:collapse;font-size:.85em;margin:.5em 0}
table.sortable th,table.sortable td{border:1px solid #ccc;padding:2px 6px;text-align:right;
white-space:nowrap}
table.env td{text-align:left}
table.sortable td:first-child,table.sortable th:first-child{text-align:left}
table.sortable th{background:#eef;cursor:pointer;user-select:none;white-space:nowrap}
table.sortable th[aria-sort=ascending]::after{content:" \\25B2"}
table.sortable th[aria-sort=descending]::after{content:" \\25BC"}
table.sortable tr:nth-child(even) td{background:#fafafa}
figure{display:inline-block;margin:.5em 1em .5em 0;vertical-align:top}
figure img{max-width:560px;border:1px solid #ddd}
figcaption{font-size:.8em}
pre{background:#f4f4f4;padding:.6em;overflow-x:auto;font-size:.8em}
.notes{font-size:.85em;color:#633}
nav a{margin-right:1em}
"""

#: click a header to sort (numbers by the value before any parenthesis; "-" and words last)
SORT_JS = """
function cellKey(td){var t=td.textContent.trim();var m=t.match(/^[-+]?\\d*\\.?\\d+(e[-+]?\\d+)?/i);
return m?parseFloat(m[0]):null}
function sortTable(th){var table=th.closest('table');var body=table.tBodies[0];
var idx=Array.prototype.indexOf.call(th.parentNode.children,th);
var asc=th.getAttribute('aria-sort')!=='ascending';
Array.prototype.forEach.call(th.parentNode.children,function(h){h.removeAttribute('aria-sort')});
th.setAttribute('aria-sort',asc?'ascending':'descending');
var rows=Array.prototype.slice.call(body.rows);
rows.sort(function(a,b){var x=cellKey(a.cells[idx]),y=cellKey(b.cells[idx]);
if(x===null&&y===null){var s=a.cells[idx].textContent.localeCompare(b.cells[idx].textContent);
return asc?s:-s}
if(x===null)return 1;if(y===null)return -1;return asc?x-y:y-x});
rows.forEach(function(r){body.appendChild(r)})}
document.addEventListener('DOMContentLoaded',function(){
document.querySelectorAll('table.sortable th').forEach(function(th){
th.addEventListener('click',function(){sortTable(th)})})});
"""


def _cell(text: str) -> str:
    """Escape a table cell; Markdown bold (``**x**``) becomes ``<strong>``."""
    return re.sub(r"\*\*(.+?)\*\*", r"<strong>\1</strong>", html.escape(str(text)))


def html_table(head: list[str], rows: list[list[str]], table_id: str = "") -> str:
    """A sortable HTML table of cell strings (the same cells as the Markdown tables)."""
    ident = f' id="{html.escape(table_id)}"' if table_id else ""
    out = [f'<table class="sortable"{ident}><thead><tr>']
    out += [f"<th>{html.escape(h)}</th>" for h in head]
    out.append("</tr></thead><tbody>")
    for cells in rows:
        out.append("<tr>" + "".join(f"<td>{_cell(c)}</td>" for c in cells) + "</tr>")
    out.append("</tbody></table>")
    return "".join(out)


def markdown_to_html(lines: list[str]) -> list[str]:
    """Render Markdown headings (``## x``), tables and paragraphs (as produced by
    :func:`benchmarks.report.aggregate.sweep_tables`) as HTML, tables sortable."""
    out: list[str] = []
    table: list[list[str]] = []

    def flush() -> None:
        if table:
            out.append(html_table(table[0], table[1:]))
            table.clear()

    for line in lines:
        if line.startswith("|"):
            cells = [c.strip() for c in line.strip().strip("|").split("|")]
            if not all(set(c) <= set("-:") for c in cells):  # not the separator row
                table.append(cells)
            continue
        flush()
        if line.startswith("## "):
            out.append(f"<h2>{html.escape(line[3:])}</h2>")
        elif line.strip():
            out.append(f"<p>{_cell(line)}</p>")
    flush()
    return out


def ranking(summary: pd.DataFrame) -> pd.DataFrame:
    """Ranking summary over the scenarios of a run: per observer the mean relative RMS per
    scenario (eq. 9 against all observers of the run), its rank in each scenario (1 = the
    tightest), the mean rank over the scenarios where it ran, and its containment violations.
    Observers that failed or do not apply in a scenario are not ranked there."""
    df = summary[summary["status"] != "unsupported"]
    per = (df[df["status"] == "ok"].groupby(["scenario", "observer"])["rel_rms"].mean()
           .rename("avg").reset_index())
    per["rank"] = per.groupby("scenario")["avg"].rank(method="min")
    pairs = df.drop_duplicates(["scenario", "observer"])
    failed = pairs[pairs["status"] != "ok"].groupby("observer").size()
    viol = pairs.groupby("observer")["violations"].sum(min_count=1)
    out = per.groupby("observer").agg(mean_rank=("rank", "mean"), mean_rel_rms=("avg", "mean"),
                                      ranked=("rank", "size"))
    out = out.reindex(table_order(pairs["observer"].unique()))
    out["failed"] = failed.reindex(out.index).fillna(0).astype(int)
    out["violations"] = viol.reindex(out.index)
    return out.sort_values(["mean_rank", "mean_rel_rms"], na_position="last")


def ranking_table(summary: pd.DataFrame) -> tuple[list[str], list[list[str]]]:
    """Header and rows of :func:`ranking`."""
    rk = ranking(summary)
    head = ["Observer", "mean rank", "mean rel. RMS", "scenarios ranked", "failed",
            "violations"]
    rows = [[obs, fmt(r.mean_rank, 3), fmt(r.mean_rel_rms), str(int(r.ranked))
             if pd.notna(r.ranked) else "0", str(int(r.failed)),
             MISSING if pd.isna(r.violations) else str(int(r.violations))]
            for obs, r in rk.iterrows()]
    return head, rows


def time_figure(df: pd.DataFrame, scenario: str, meta: dict, base: Path) -> list[Path] | None:
    """Per-step time (median ms, log scale) of every observer, beside the paper's time."""
    pairs = df.drop_duplicates("observer").set_index("observer")
    pairs = pairs.reindex(table_order(pairs.index))
    info = meta.get("scenarios", {}).get(scenario, {})
    n = int(df["state"].max()) + 1
    variant = "nonlinear" if "nonlinear" in scenario else "linear"
    paper = paper_rows(info.get("paper_table"), n, variant)
    theirs = np.array([paper[o].t_ms if o in paper and paper[o].t_ms else np.nan
                       for o in pairs.index], float)
    return step_times(list(pairs.index), pairs["step_ms"].to_numpy(float), theirs,
                              scenario, timed_in_parallel(df), base)


def figure_html(paths: list[Path] | None, page_dir: Path, caption: str) -> str:
    """A ``<figure>`` showing the PNG of ``paths`` with download links to the PNG and the PDF
    (relative to ``page_dir``); ``""`` without a figure."""
    if not paths:
        return ""
    png, pdf = (p.relative_to(page_dir).as_posix() for p in paths)
    return (f'<figure><img src="{html.escape(png)}" alt="{html.escape(caption)}">'
            f"<figcaption>{html.escape(caption)} — download "
            f'<a href="{html.escape(png)}" download>PNG</a> '
            f'<a href="{html.escape(pdf)}" download>PDF</a></figcaption></figure>')


def html_page(title: str, body: list[str]) -> str:
    """A complete page with the inline style sheet and sorting script (no external file)."""
    return ("<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
            f"<title>{html.escape(title)}</title><style>{CSS}</style>"
            f"<script>{SORT_JS}</script></head><body>\n" + "\n".join(body)
            + "\n</body></html>\n")


def _definition_table(items: dict) -> str:
    rows = "".join(f"<tr><td>{html.escape(str(k))}</td><td>{html.escape(str(v))}</td></tr>"
                   for k, v in items.items())
    return f'<table class="sortable env"><thead><tr><th>key</th><th>value</th></tr></thead>' \
           f"<tbody>{rows}</tbody></table>"


def write_html(results_dir: str | Path, out: str | Path | None = None,
               figures: bool = True) -> Path:
    """Write the HTML report of a results folder (default ``DIR/index.html``).

    Parameters
    ----------
    results_dir : str or Path
        A folder written by ``python -m benchmarks run`` (``summary.csv``, optionally
        ``runs.csv`` and ``meta.json``).
    out : str or Path, optional
        The HTML file; its figures go to ``html_figures/`` beside it.
    figures : bool
        Draw the figures (``False``: tables, ranking and environment only).

    Returns
    -------
    Path
        The page written.
    """
    results_dir = Path(results_dir)
    summary, meta = load_results(results_dir)
    out = Path(out) if out else results_dir / "index.html"
    page_dir = out.parent
    fig_dir = page_dir / FIGURE_DIR
    runs = None
    if figures and (results_dir / "runs.csv").is_file():
        runs = load_runs(results_dir)
    title = meta.get("config", {}).get("title", results_dir.name)
    sweep = is_sweep(summary)
    scenarios = [] if sweep else list(dict.fromkeys(summary["scenario"]))
    body = [f"<h1>{html.escape(title)}</h1>",
            "<nav>" + "".join(f'<a href="#sc-{html.escape(s)}">{html.escape(s)}</a>'
                              for s in scenarios)
            + '<a href="#ranking">ranking</a><a href="#environment">configuration</a></nav>',
            f"<p>{html.escape(INTRO)} Click a column header to sort.</p>"]
    if sweep:  # several seeds or option variants: the aggregated tables of the Markdown report
        body += ["<p>Sweep: relative RMS radius over the seeds (mean, std, min, max over the "
                 "successful runs), as in report.md.</p>"]
        body += markdown_to_html(sweep_tables(summary))
    for sc in scenarios:
        full = summary[summary["scenario"] == sc]
        info = meta.get("scenarios", {}).get(sc, {})
        df = full[full["status"] != "unsupported"]
        body += [f'<h2 id="sc-{html.escape(sc)}">{html.escape(sc)}</h2>',
                 f"<p>{html.escape(info.get('description', ''))}</p>",
                 html_table(*scenario_table_data(df, meta), table_id=f"table-{sc}")]
        absolute = absolute_table_data(df, meta)
        if absolute:
            body += ["<h3>Absolute RMS radii (published: relative value x smallest radius)</h3>",
                     html_table(*absolute, table_id=f"absolute-{sc}")]
        notes = scenario_notes(full)
        if notes:
            body.append('<ul class="notes">' + "".join(f"<li>{html.escape(n)}</li>"
                                                      for n in notes) + "</ul>")
        if figures:
            names = info.get("state_names") or []
            label = names[0] if names else "x1"
            sc_dir = fig_dir / path_component(sc)  # a name, never a path
            figs = [figure_html(heat_map(df, sc, sc_dir / "rel_rms_heatmap"), page_dir,
                            "relative RMS, observer x state"),
                    figure_html(time_figure(df, sc, meta, sc_dir / "step_time"), page_dir,
                            "per-step time, log scale, with the paper's")]
            if runs is not None:
                truth = runs.loc[runs["scenario"] == sc, "x_true"].notna().any()
                figs.insert(0, figure_html(bounds_over_time(
                    runs, df, sc, 0, sc_dir / "bounds_x1", label), page_dir,
                    f"bounds of {label} over time "
                    + ("with the true state" if truth else "(the record has no true state)")))
            body.append('<div class="figures">' + "".join(f for f in figs if f) + "</div>")
    body += ['<h2 id="ranking">Ranking summary</h2>',
             "<p>Mean over the scenarios of each observer's average relative RMS (eq. 9 against "
             "all observers of the run) and of its rank in each scenario (1 = tightest); "
             "failed runs are not ranked. Violations: steps whose true state lay outside the "
             "set, summed over the scenarios where containment was checked (n/a: checked in "
             "none).</p>",
             html_table(*ranking_table(summary), table_id="ranking-table")] if not sweep else []
    raw = meta.get("config", {}).get("raw")
    env = {"run_id": meta.get("run_id", "?"), "created": meta.get("created", "?"),
           **meta.get("versions", {})}
    now = environment()
    body += ['<h2 id="environment">Configuration and environment</h2>',
             f"<p>git commit of the run: <code>{html.escape(env.get('git') or 'unknown')}</code>"
             f"; report written at commit <code>{html.escape(now.get('git') or 'unknown')}"
             "</code>.</p>",
             "<h3>Configuration</h3>",
             "<pre>" + html.escape(yaml.safe_dump(raw, sort_keys=False) if raw else
                                   "(no meta.json)") + "</pre>",
             "<h3>Environment of the run</h3>", _definition_table(env),
             "<h3>Environment of this report</h3>", _definition_table(now)]
    atomic_write_text(out, html_page(title, body))
    return out


def _title(path: Path) -> str:
    for line in path.read_text(encoding="utf-8").splitlines():
        if line.startswith("# "):
            return line[2:].strip()
    return path.stem


def write_index(reports_dir: str | Path, results_root: str | Path | None = None) -> Path:
    """Write ``REPORTS/index.html`` linking every Markdown report of ``reports_dir`` and, where
    it exists, the HTML report ``RESULTS/<name>/index.html`` of the same name."""
    reports_dir = Path(reports_dir)
    if not reports_dir.is_dir():
        raise ConfigError(f"no folder {reports_dir}")
    rows = []
    for md in sorted(reports_dir.glob("*.md")):
        if md.name.lower() == "readme.md":
            continue
        links = f'<a href="{html.escape(md.name)}">{html.escape(md.name)}</a>'
        if results_root is not None:
            page = Path(results_root) / md.stem / "index.html"
            if page.is_file():
                rel = Path(_relpath(page, reports_dir))
                links += f' · <a href="{html.escape(rel.as_posix())}">HTML report</a>'
        rows.append(f"<tr><td>{html.escape(_title(md))}</td><td>{links}</td></tr>")
    body = ["<h1>setobs-bench reports</h1>",
            "<p>Every table of <code>make bench</code> (Markdown, published values in "
            "parentheses) and, where the run is present, its HTML report.</p>",
            '<table class="sortable" id="reports"><thead><tr><th>report</th><th>files</th>'
            "</tr></thead><tbody>" + "".join(rows) + "</tbody></table>"]
    out = reports_dir / "index.html"
    atomic_write_text(out, html_page("setobs-bench reports", body))
    return out


def _relpath(target: Path, start: Path) -> str:
    return os.path.relpath(target.resolve(), start.resolve())
