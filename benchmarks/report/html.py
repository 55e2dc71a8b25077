"""The HTML report of a results folder (``DIR/index.html``) and the index of all reports.

The page renders the same table data as the Markdown report (:func:`benchmarks.report.
tables.scenario_table_data`, :func:`~benchmarks.report.tables.absolute_table_data`): one source
of the cells, two renderers. Per scenario it states the record length and the noise bounds,
names the reference of every table and figure, and shows every state's bounds and interval
radius (log scale) over time with the true state and the steps of any violation
(:func:`~benchmarks.report.figures.bounds_and_radii`, inline SVG whose observers are shown and
hidden with the legend's check boxes), a heat map of the table's ratios and the per-step times
beside the papers' times; then a ranking summary, the configuration, environment and git
commit of the run, and last what to cite (:mod:`.citation`). Everything is inline (CSS and
small scripts for sorting and for the layers, no network at view time); the heat map and time
figures are matplotlib PNG files beside the page, every figure with PNG and PDF copies to
download.

:func:`write_index` links every report; it writes into the results folder, and rewrites the
committed ``reports/index.html`` (from the committed Markdown reports only) just when asked.
"""

from __future__ import annotations

import html
import os
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
import yaml

from observers.registry import table_order

from ..errors import ConfigError
from ..io import atomic_write_text, environment, load_results, load_runs, path_component
from ..metrics import timed_in_parallel
from .aggregate import is_sweep, sweep_tables
from .citation import citation_html, citation_lines
from .figures import BoundsView, LayeredFigure, bounds_and_radii, heat_map, step_times
from .markdown import shown_tables
from .numbers import MISSING, Num, format_columns
from .paper import paper_rows, paper_title
from .tables import (
    INTRO,
    PHASE_CAPTION,
    absolute_table_caption,
    absolute_table_data,
    gap_table_caption,
    gap_table_data,
    phase_table_data,
    relative_values,
    scenario_facts,
    scenario_notes,
    scenario_table_caption,
    scenario_table_data,
)

FIGURE_DIR = "html_figures"

CSS = """
body{font-family:system-ui,sans-serif;margin:1.5em auto;max-width:1500px;padding:0 1em;
color:#222}
h1{font-size:1.5em}h2{font-size:1.25em;border-bottom:1px solid #ccc;margin-top:2em}
h3{font-size:1.05em}
table.sortable{border-collapse:collapse;font-size:.85em;margin:.5em 0}
table.sortable th,table.sortable td{border:1px solid #ccc;padding:2px 6px;text-align:right;
white-space:nowrap}
table.env td{text-align:left}
table.sortable td:first-child,table.sortable th:first-child,table.sortable td.text{text-align:left}
table.sortable th{background:#eef;cursor:pointer;user-select:none;white-space:nowrap}
table.sortable th[aria-sort=ascending]::after{content:" \\25B2"}
table.sortable th[aria-sort=descending]::after{content:" \\25BC"}
table.sortable tr:nth-child(even) td{background:#fafafa}
figure{display:inline-block;margin:.5em 1em .5em 0;vertical-align:top;max-width:100%}
figure img{max-width:100%;border:1px solid #ddd}
figure.layered{display:block;margin:.5em 0}
figure.layered .svgfig svg{display:block;width:100%;height:auto;border:1px solid #ddd}
figcaption{font-size:.8em}
p.caption{font-size:.85em;color:#444;margin:.3em 0}
p.facts{font-size:.9em}
code{background:#f4f4f4;padding:0 .2em}
.legend{font-size:.8em;margin:.4em 0;line-height:1.9}
.legend label{display:inline-block;margin-right:1em;cursor:pointer;white-space:nowrap}
.legend label.violating{color:#b00}
.legend svg{vertical-align:middle;margin-right:.2em}
.legend button{font-size:.9em;margin-right:.4em}
pre{background:#f4f4f4;padding:.6em;overflow-x:auto;font-size:.8em}
.notes{font-size:.85em;color:#633}
nav a{margin-right:1em}
"""

#: click a header to sort (numbers by the value before any parenthesis; "-" and words last)
SORT_JS = """
function cellKey(td){var t=td.textContent.trim().replace(/^<=\\s*/,'');
var m=t.match(/^[-+]?\\d*\\.?\\d+(e[-+]?\\d+)?/i);
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

#: show and hide the layers of a figure with the check boxes of its legend (no network)
LAYER_JS = """
function showLayer(fig,key,on){fig.querySelectorAll('g.layer.'+key).forEach(function(g){
g.style.display=on?'':'none'})}
function syncLegend(legend){var fig=document.getElementById(legend.dataset.figure);
legend.querySelectorAll('input[data-layer]').forEach(function(cb){
showLayer(fig,cb.dataset.layer,cb.checked)})}
document.addEventListener('DOMContentLoaded',function(){
document.querySelectorAll('.legend[data-figure]').forEach(function(legend){
legend.querySelectorAll('input[data-layer]').forEach(function(cb){
cb.addEventListener('change',function(){syncLegend(legend)})});
legend.querySelectorAll('button[data-select]').forEach(function(b){
b.addEventListener('click',function(){var how=b.dataset.select;
legend.querySelectorAll('input[data-layer]').forEach(function(cb){
cb.checked=how==='all'?true:how==='none'?cb.dataset.kind!=='observer':cb.defaultChecked});
syncLegend(legend)})})})});
"""


def inline(text: str) -> str:
    """Escape a line of text; Markdown bold (``**x**``) becomes ``<strong>``, code
    (```x```) ``<code>``."""
    out = re.sub(r"\*\*(.+?)\*\*", r"<strong>\1</strong>", html.escape(str(text)))
    return re.sub(r"`([^`]+)`", r"<code>\1</code>", out)


_cell = inline


_NUMBER = re.compile(r"^\**(<= )?[-+]?(\d|\.\d)")


def html_table(head: list[str], rows: list[list[str]], table_id: str = "") -> str:
    """A sortable HTML table of cell strings (the same cells as the Markdown tables); columns
    without any number are left-aligned (class ``text``)."""
    ident = f' id="{html.escape(table_id)}"' if table_id else ""
    out = [f'<table class="sortable"{ident}><thead><tr>']
    out += [f"<th>{html.escape(h)}</th>" for h in head]
    out.append("</tr></thead><tbody>")
    text = [i > 0 and not any(_NUMBER.match(str(r[i])) for r in rows if i < len(r))
            for i in range(len(head))]
    for cells in rows:
        out.append("<tr>" + "".join(
            f'<td class="text">{_cell(c)}</td>' if i < len(text) and text[i]
            else f"<td>{_cell(c)}</td>" for i, c in enumerate(cells)) + "</tr>")
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
    tightest), the mean rank over the scenarios where it ran, the mean over the linear records
    of its mean gap to the exact floor (1 = optimal; also over the steady steps, after the
    first 20 % of each record), the median over the scenarios of the memory of its set, and
    its containment violations.
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
    exact = df[(df["status"] == "ok") & (df["gap_kind"] == "exact")] if "gap_kind" in \
        df.columns else df.iloc[:0]
    for column, name in (("gap", "mean_gap"), ("gap_steady", "mean_gap_steady")):
        # the mean over the linear scenarios of the observer's mean gap to the exact floor
        if column in exact.columns:
            gap = exact.assign(v=pd.to_numeric(exact[column], errors="coerce")).groupby(
                ["scenario", "observer"])["v"].mean().groupby("observer").mean()
            out[name] = gap.reindex(out.index)
        else:
            out[name] = np.nan
    if "memory" in df.columns:  # the median over the scenarios of the set's memory
        mem = df[df["status"] == "ok"].drop_duplicates(["scenario", "observer"])
        out["memory"] = pd.to_numeric(mem["memory"], errors="coerce").groupby(
            mem["observer"]).median().reindex(out.index)
    else:
        out["memory"] = np.nan
    return out.sort_values(["mean_rank", "mean_rel_rms"], na_position="last")


def ranking_table(summary: pd.DataFrame) -> tuple[list[str], list[list[str]]]:
    """Header and rows of :func:`ranking` (each number column in one notation)."""
    rk = ranking(summary)
    head = ["Observer", "mean rank", "mean rel. RMS", "mean gap (exact floor)",
            "mean gap steady", "memory (median)", "scenarios ranked", "failed", "violations"]
    rows = [[obs, Num(r.mean_rank), Num(r.mean_rel_rms), Num(r.mean_gap),
             Num(r.mean_gap_steady), Num(r.memory),
             str(int(r.ranked)) if pd.notna(r.ranked) else "0", str(int(r.failed)),
             MISSING if pd.isna(r.violations) else str(int(r.violations))]
            for obs, r in rk.iterrows()]
    return head, format_columns(rows)


def gap_heat_map(df: pd.DataFrame, scenario: str, names: list[str], base: Path
                 ) -> tuple[list[Path] | None, str]:
    """The gap to the floor per observer and state as a heat map, and its caption; nothing
    without a floor."""
    if "gap" not in df.columns:
        return None, ""
    ok = df[(df["status"] == "ok")].assign(gap=lambda d: pd.to_numeric(d["gap"],
                                                                       errors="coerce"))
    mat = ok.pivot_table(index="observer", columns="state", values="gap")
    if mat.empty or not np.isfinite(mat.to_numpy(float)).any():
        return None, ""
    mat = mat.reindex(table_order(mat.index))
    mat.columns = [names[i] if i < len(names) else f"x{i + 1}" for i in mat.columns]
    upper = ok["gap_kind"].astype(str).str.startswith("upper").any()
    reference = ("reference: an inner box of the consistent set (falsifier), so each value is "
                 "an upper bound of the gap" if upper else
                 "reference: the exact consistent set of the record (Exact), filtered or "
                 "predicted as each observer's floor")
    paths = heat_map(mat, f"{scenario}: gap to the floor per observer and state (1 = optimal)",
                     reference, base, label="log10 gap")
    return paths, (f"gap of the table above per observer and state, log colour scale; "
                   f"{reference}")


def time_figure(df: pd.DataFrame, scenario: str, meta: dict,
                base: Path) -> tuple[list[Path] | None, str]:
    """Per-step time (median ms, log scale) of every observer, beside the paper's time where
    one is published; returns the figure's paths and its caption."""
    pairs = df[df["status"] != "unsupported"].drop_duplicates("observer").set_index("observer")
    pairs = pairs.reindex(table_order(pairs.index))
    info = meta.get("scenarios", {}).get(scenario, {})
    n = int(df["state"].max()) + 1
    variant = "nonlinear" if "nonlinear" in scenario else "linear"
    key = info.get("paper_table")
    paper = paper_rows(key, n, variant)
    theirs = np.array([paper[o.split("[")[0]].t_ms
                       if o.split("[")[0] in paper and paper[o.split("[")[0]].t_ms else np.nan
                       for o in pairs.index], float)
    source = paper_title(key, variant)
    parallel = timed_in_parallel(df)
    paths = step_times(list(pairs.index), pairs["step_ms"].to_numpy(float), theirs,
                       scenario, parallel, base, source)
    caption = "per-step time (median ms, log scale) on this machine" + (
        " with jobs running in parallel (indicative only)" if parallel else "")
    caption += (f", beside the published times of {source} (MATLAB, i7-8565U)"
                if np.isfinite(theirs).any() else "; no published times for this scenario")
    return paths, caption


def figure_html(paths: list[Path] | None, page_dir: Path, caption: str) -> str:
    """A ``<figure>`` showing the PNG of ``paths`` with download links to the PNG and the PDF
    (relative to ``page_dir``); ``""`` without a figure."""
    if not paths:
        return ""
    png, pdf = (p.relative_to(page_dir).as_posix() for p in paths)
    return (f'<figure><img src="{html.escape(png)}" alt="{html.escape(caption)}">'
            f"<figcaption>{inline(caption)} — download "
            f'<a href="{html.escape(png)}" download>PNG</a> '
            f'<a href="{html.escape(pdf)}" download>PDF</a></figcaption></figure>')


def _swatch(color: str, dash: str, kind: str) -> str:
    if kind == "band":
        return (f'<svg width="28" height="10"><rect x="1" y="1" width="26" height="8" '
                f'fill="{color}" fill-opacity="0.4"/></svg>')
    dasharray = f' stroke-dasharray="{dash}"' if dash else ""
    return (f'<svg width="28" height="10"><line x1="1" y1="5" x2="27" y2="5" '
            f'stroke="{color}" stroke-width="2"{dasharray}/></svg>')


def layered_figure_html(fig: LayeredFigure | None, fig_id: str, page_dir: Path,
                        caption: str) -> str:
    """A figure of selectable layers: a legend of check boxes (click a name or a box to show
    or hide that observer's curves; buttons for all, none and the first view), the inline
    SVG and download links to the PNG and PDF of the first view."""
    if fig is None:
        return ""
    items = []
    for la in fig.layers:
        checked = " checked" if la.visible else ""
        note = f" ({html.escape(la.note)})" if la.note else ""
        cls = ' class="violating"' if la.note else ""
        items.append(f'<label{cls} data-name="{html.escape(la.name)}"><input type="checkbox" '
                     f'data-layer="{la.key}" data-kind="{la.kind}"{checked}>'
                     f"{_swatch(la.color, la.dash, la.kind)}{html.escape(la.name)}{note}"
                     "</label>")
    buttons = "".join(f'<button type="button" data-select="{k}">{t}</button>'
                      for k, t in (("all", "all observers"), ("none", "no observer"),
                                   ("first", "first view")))
    png, pdf = (p.relative_to(page_dir).as_posix() for p in fig.paths)
    return (f'<figure class="layered"><div class="legend" data-figure="{fig_id}">{buttons}'
            + "".join(items) + f'</div><div class="svgfig" id="{fig_id}">{fig.svg}</div>'
            f"<figcaption>{inline(caption)} — download the first view: "
            f'<a href="{html.escape(png)}" download>PNG</a> '
            f'<a href="{html.escape(pdf)}" download>PDF</a></figcaption></figure>')


#: observers shown at first in the bounds figure (the tightest by average ratio; observers
#: with a violation are always shown)
FIRST_VIEW = 6


def floor_bands(runs: pd.DataFrame, df: pd.DataFrame, scenario: str
                ) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """The exact floors of a linear record as bands of the bounds figure (``floor_lo`` and
    ``floor_hi`` of ``runs.csv`` on the rows of an observer held against each floor);
    nothing for a record without an exact floor."""
    if "floor_lo" not in runs.columns or "gap_kind" not in df.columns:
        return {}
    out = {}
    for floor, label in (("filtered", "exact set (after y_k)"),
                         ("predicted", "exact set (before y_k)")):
        who = df[(df["floor"] == floor) & (df["gap_kind"] == "exact")]["observer"]
        if who.empty:
            continue
        g = runs[(runs["scenario"] == scenario) & (runs["observer"] == who.iloc[0])]
        lo = g.pivot_table(index="step", columns="state", values="floor_lo", dropna=False)
        hi = g.pivot_table(index="step", columns="state", values="floor_hi", dropna=False)
        if np.isfinite(lo.to_numpy(float)).any():
            out[label] = (lo.to_numpy(float), hi.to_numpy(float))
    return out


def bounds_figure(runs: pd.DataFrame, df: pd.DataFrame, scenario: str, info: dict,
                  meta: dict, base: Path, bands: dict | None = None
                  ) -> tuple[LayeredFigure | None, str]:
    """The bounds-and-radius figure of one scenario (every observer a layer, the
    :data:`FIRST_VIEW` tightest shown at first) and its caption."""
    rel, reference = relative_values(df, meta)
    ok = df.assign(_rel=rel)
    ok = ok[(ok["status"] == "ok") & ok["_rel"].notna()]
    order = ok.groupby("observer")["_rel"].mean().sort_values()
    names = table_order(df[df["status"] != "unsupported"]["observer"].unique())
    view = BoundsView(visible=set(order.index[:FIRST_VIEW]), bands=bands,
                      title=f"{scenario}: bounds and interval radius of every state")
    fig = bounds_and_radii(runs, scenario, names, info.get("state_names") or [], base, view)
    truth = runs.loc[runs["scenario"] == scenario, "x_true"].notna().any()
    caption = ("every state's interval bounds (left) and radius on a log scale (right) over "
               "time, " + ("with the true state (dashed black) and the steps where a set "
                           "missed it (red x)" if truth else
                           "(the record has no true state, so no containment check)")
               + (f"; filled bands: {', '.join(bands)}" if bands else "")
               + f"; shown at first: the {FIRST_VIEW} observers of smallest average v_i "
               f"({reference}) and any observer with a violation; tick a name to show it")
    return fig, caption


def html_page(title: str, body: list[str]) -> str:
    """A complete page with the inline style sheet and scripts (no external file)."""
    return ("<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
            f"<title>{html.escape(title)}</title><style>{CSS}</style>"
            f"<script>{SORT_JS}{LAYER_JS}</script></head><body>\n" + "\n".join(body)
            + "\n</body></html>\n")


def _definition_table(items: dict) -> str:
    rows = "".join(f"<tr><td>{html.escape(str(k))}</td><td>{html.escape(str(v))}</td></tr>"
                   for k, v in items.items())
    return f'<table class="sortable env"><thead><tr><th>key</th><th>value</th></tr></thead>' \
           f"<tbody>{rows}</tbody></table>"


#: the built documentation site (``make docs``), linked from every page when present
DOCS_INDEX = Path(__file__).resolve().parents[2] / "docs" / "_build" / "html" / "index.html"


def docs_link(page_dir: Path) -> str:
    """A paragraph linking the documentation site (relative link when it is built, else how
    to build it)."""
    if DOCS_INDEX.is_file():
        rel = _relpath(DOCS_INDEX, page_dir)
        return (f'<p class="caption">Documentation: <a href="{html.escape(Path(rel).as_posix())}">'
                "the setobs-bench documentation site</a> (observers, configs, records, "
                "plugins, the gate and the audit).</p>")
    return ('<p class="caption">Documentation: the setobs-bench documentation site, built by '
            "<code>make docs</code> into <code>docs/_build/html/</code> of the repository "
            "(observers, configs, records, plugins, the gate and the audit).</p>")


def write_html(results_dir: str | Path, out: str | Path | None = None,
               figures: bool = True, bands: dict | None = None,
               data: tuple | None = None) -> Path:
    """Write the HTML report of a results folder (default ``DIR/index.html``).

    Parameters
    ----------
    results_dir : str or Path
        A folder written by ``setobs-bench run`` (``summary.csv``, optionally
        ``runs.csv`` and ``meta.json``).
    out : str or Path, optional
        The HTML file; its figures go to ``html_figures/`` beside it.
    figures : bool
        Draw the figures (``False``: tables, ranking and environment only).
    bands : dict, optional
        Extra bands of the bounds figures per scenario:
        ``{scenario: {name: (lo, hi)}}`` with arrays of shape (steps, states)
        (:func:`~benchmarks.report.figures.bounds_and_radii`).
    data : (DataFrame, dict), optional
        ``(summary, meta)`` already read (a result store's view); the figures then come from
        the store's last local run, ``DIR/run/runs.csv``, where it exists.

    Returns
    -------
    Path
        The page written.
    """
    results_dir = Path(results_dir)
    summary, meta = data if data is not None else load_results(results_dir)
    out = Path(out) if out else results_dir / "index.html"
    page_dir = out.parent
    fig_dir = page_dir / FIGURE_DIR
    runs = None
    runs_dir = results_dir / "run" if data is not None else results_dir
    if figures and (runs_dir / "runs.csv").is_file():
        runs = load_runs(runs_dir)
    title = meta.get("config", {}).get("title", results_dir.name)
    sweep = is_sweep(summary)
    scenarios = [] if sweep else list(dict.fromkeys(summary["scenario"]))
    body = [f"<h1>{html.escape(title)}</h1>",
            "<nav>" + "".join(f'<a href="#sc-{html.escape(s)}">{html.escape(s)}</a>'
                              for s in scenarios)
            + '<a href="#ranking">ranking</a><a href="#environment">configuration</a></nav>',
            f"<p>{inline(INTRO)} Click a column header to sort.</p>", docs_link(page_dir)]
    if sweep:  # several seeds or option variants: the aggregated tables of the Markdown report
        body += ["<p>Sweep: relative RMS radius over the seeds (mean, std, min, max over the "
                 "successful runs; reference: the best observer of the same scenario and "
                 "seed), as in report.md.</p>"]
        body += markdown_to_html(sweep_tables(summary))
    page = _Page(page_dir, fig_dir, runs if figures else None, bands or {}, figures)
    for sc in scenarios:
        body += _scenario_section(summary, meta, sc, page)
    body += _ranking_section(summary) if not sweep else []
    body += _environment_section(summary, meta, results_dir.name)
    atomic_write_text(out, html_page(title, body))
    return out


@dataclass(frozen=True)
class _Page:
    """Where a page of :func:`write_html` goes and what its figures draw from."""

    page_dir: Path
    fig_dir: Path
    runs: pd.DataFrame | None
    bands: dict
    figures: bool


def _scenario_section(summary: pd.DataFrame, meta: dict, sc: str, page: _Page) -> list[str]:
    """The section of scenario ``sc``: its tables, notes and figures."""
    full = summary[summary["scenario"] == sc]
    info = meta.get("scenarios", {}).get(sc, {})
    df = full[full["status"] != "unsupported"]
    body = [f'<h2 id="sc-{html.escape(sc)}">{html.escape(sc)}</h2>',
            f"<p>{inline(info.get('description', ''))}</p>"]
    facts = scenario_facts(info)
    if facts:
        body.append(f'<p class="facts">{inline(facts[0].upper() + facts[1:])}</p>')
    body += [f'<p class="caption">{inline(scenario_table_caption(full, meta))}</p>',
             html_table(*scenario_table_data(full, meta), table_id=f"table-{sc}")]
    body += _scenario_tables(df, meta, sc)
    notes = scenario_notes(full)
    if notes:
        body.append('<ul class="notes">' + "".join(f"<li>{html.escape(n)}</li>"
                                                  for n in notes) + "</ul>")
    if page.figures and len(df):
        body += _scenario_figures(full, df, (sc, info, meta), page)
    return body


def _scenario_tables(df: pd.DataFrame, meta: dict, sc: str) -> list[str]:
    """The absolute radii, the gap to the exact floor and the phases of scenario ``sc``
    (those with rows)."""
    body: list[str] = []
    absolute = absolute_table_data(df, meta) if len(df) else None
    if absolute:
        body += ["<h3>Absolute RMS radii</h3>",
                 f'<p class="caption">{inline(absolute_table_caption(df, meta))}</p>',
                 html_table(*absolute, table_id=f"absolute-{sc}")]
    gaps = gap_table_data(df, meta) if len(df) else None
    if gaps:
        body += ["<h3>Gap to the exact floor</h3>",
                 f'<p class="caption">{inline(gap_table_caption(df))}</p>',
                 html_table(gaps[0], format_columns(gaps[1]), table_id=f"gap-{sc}")]
    phases = phase_table_data(df) if len(df) else None
    if phases:
        body += ["<h3>Time per phase of a step</h3>",
                 f'<p class="caption">{inline(PHASE_CAPTION)}</p>',
                 html_table(phases[0], format_columns(phases[1]), table_id=f"phases-{sc}")]
    return body


def _scenario_figures(full: pd.DataFrame, df: pd.DataFrame, about: tuple, page: _Page
                      ) -> list[str]:
    """The figures of one scenario (``about``: its name, its ``meta.json`` entry and the
    run's meta data): the bounds figure where the run has ``runs.csv``, the heat maps of
    v_i and of the gap, and the step times."""
    sc, info, meta = about
    body: list[str] = []
    base = page.fig_dir / path_component(sc)  # a name, never a path
    page_dir = page.page_dir
    if page.runs is not None:
        sc_bands = {**floor_bands(page.runs, df, sc), **page.bands.get(sc, {})}
        fig, caption = bounds_figure(page.runs, df, sc, info, meta, base / "bounds",
                                     sc_bands or None)
        body.append(layered_figure_html(fig, f"bounds-{sc}", page_dir, caption))
    rel, reference = relative_values(df, meta)
    mat = (df.assign(_rel=rel)[df["status"] == "ok"]
           .pivot_table(index="observer", columns="state", values="_rel"))
    mat = mat.reindex(table_order(mat.index))
    names = info.get("state_names") or []
    mat.columns = [names[i] if i < len(names) else f"x{i + 1}" for i in mat.columns]
    heat = heat_map(mat, f"{sc}: v_i per observer and state (1 = the reference)",
                    reference, base / "rel_rms_heatmap") if len(mat) else None
    gap_heat, gap_caption = gap_heat_map(df, sc, names, base / "gap_heatmap")
    times, time_caption = time_figure(full, sc, meta, base / "step_time")
    figs = [figure_html(heat, page_dir, f"v_i of the table above, per observer and "
                        f"state, log colour scale; {reference}"),
            figure_html(gap_heat, page_dir, gap_caption),
            figure_html(times, page_dir, time_caption)]
    body.append('<div class="figures">' + "".join(f for f in figs if f) + "</div>")
    return body


def _ranking_section(summary: pd.DataFrame) -> list[str]:
    """The ranking over the scenarios (not of a sweep)."""
    return ['<h2 id="ranking">Ranking summary</h2>',
            "<p>Mean over the scenarios of each observer's average relative RMS (reference: "
            "eq. 9 against all guaranteed observers of the run, <code>rel_rms</code> of "
            "summary.csv, not a paper's observers) and of its rank in each scenario "
            "(1 = tightest); failed runs are not ranked. Violations: steps whose true state "
            "lay outside the set, summed over the scenarios where containment was checked "
            "(n/a: checked in none).</p>",
            html_table(*ranking_table(summary), table_id="ranking-table")]


def _environment_section(summary: pd.DataFrame, meta: dict, folder: str) -> list[str]:
    """The configuration, the environments of the run and of the report, and what to cite
    (``folder``: the results folder's name, the configuration's name by default)."""
    raw = meta.get("config", {}).get("raw")
    env = {"run_id": meta.get("run_id", "?"), "created": meta.get("created", "?"),
           **meta.get("versions", {})}
    now = environment()
    return ['<h2 id="environment">Configuration and environment</h2>',
            f"<p>git commit of the run: <code>{html.escape(env.get('git') or 'unknown')}</code>"
            f"; report written at commit <code>{html.escape(now.get('git') or 'unknown')}"
            "</code>.</p>",
            "<h3>Configuration</h3>",
            "<pre>" + html.escape(yaml.safe_dump(raw, sort_keys=False) if raw else
                                  "(no meta.json)") + "</pre>",
            "<h3>Environment of the run</h3>", _definition_table(env),
            "<h3>Environment of this report</h3>", _definition_table(now),
            '<h2 id="cite">What to cite</h2>',
            citation_html(meta.get("config", {}).get("name") or folder,
                          shown_tables(summary, meta))]


def _title(path: Path) -> str:
    for line in path.read_text(encoding="utf-8").splitlines():
        if line.startswith("# "):
            return line[2:].strip()
    return path.stem


_STORE_LINE = re.compile(r"Rendered from the result store `(results/[^`]+)`")
_STAMP = re.compile(r"<!-- (?:freshness|measured): .*?(?:config=(\S+) )?command=(.*?) -->")


def _made_by(path: Path) -> str:
    """How a report was made: its result store, else its configuration file or the command
    of its stamp (:mod:`.freshness`)."""
    text = path.read_text(encoding="utf-8", errors="replace")
    store = _STORE_LINE.search(text)
    if store:
        return f"{store.group(1)} (result store)"
    found = _STAMP.findall(text)
    if not found:
        return ""
    config, command = found[-1]
    return Path(config).name if config and config != "-" else command


def write_index(reports_dir: str | Path, results_root: str | Path | None = None,
                out: str | Path | None = None) -> Path:
    """Write an index page linking every Markdown report of ``reports_dir`` and, where
    ``results_root`` is given, the HTML report ``RESULTS/<name>/index.html`` of the same name
    where it exists; the page ends with the project's citation line (:mod:`.citation`).

    Parameters
    ----------
    reports_dir : str or Path
        The folder of the Markdown reports (``reports``).
    results_root : str or Path, optional
        The folder of the runs (``results``); without it the page links the Markdown reports
        only (the committed ``reports/index.html``: its content depends on the committed
        reports alone, so rewriting it leaves the repository clean).
    out : str or Path, optional
        The page to write; default ``RESULTS/index.html`` with ``results_root`` (the local
        runs never enter a committed file), else ``REPORTS/index.html``.

    Returns
    -------
    Path
        The page written.
    """
    reports_dir = Path(reports_dir)
    if not reports_dir.is_dir():
        raise ConfigError(f"no folder {reports_dir}")
    if out is None:
        out = (Path(results_root) if results_root is not None else reports_dir) / "index.html"
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    files = [md for md in sorted(reports_dir.glob("*.md")) if md.name.lower() != "readme.md"]
    titles = {md: _title(md) for md in files}
    counts = pd.Series(list(titles.values())).value_counts() if titles else pd.Series()
    rows = []
    for md in files:
        title = titles[md] + (f" ({md.stem})" if counts.get(titles[md], 0) > 1 else "")
        rel_md = Path(_relpath(md, out.parent)).as_posix()
        links = f'<a href="{html.escape(rel_md)}">{html.escape(md.name)}</a>'
        if results_root is not None:
            page = Path(results_root) / md.stem / "index.html"
            if page.is_file():
                rel = Path(_relpath(page, out.parent))
                links += f' · <a href="{html.escape(rel.as_posix())}">HTML report</a>'
        rows.append(f"<tr><td>{html.escape(title)}</td><td>{html.escape(_made_by(md))}</td>"
                    f"<td>{links}</td></tr>")
    local = ("and, where the run is present in this checkout's results folder, its HTML "
             "report" if results_root is not None else
             "(the HTML reports of local runs: <code>setobs-bench index</code> writes "
             "<code>results/index.html</code>)")
    body = ["<h1>setobs-bench reports</h1>",
            f"<p>Every committed report (Markdown, published values in parentheses) {local}."
            "</p>", docs_link(out.parent),
            '<table class="sortable" id="reports"><thead><tr><th>report</th><th>made by</th>'
            "<th>files</th></tr></thead><tbody>" + "".join(rows) + "</tbody></table>",
            '<p class="cite">' + html.escape(citation_lines(None)[0]) + " Each report ends "
            "with the paper whose table it reproduces.</p>"]
    atomic_write_text(out, html_page("setobs-bench reports", body))
    return out


def _relpath(target: Path, start: Path) -> str:
    return os.path.relpath(target.resolve(), start.resolve())
