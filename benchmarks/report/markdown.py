"""The Markdown report of a results folder (``DIR/report.md``): the papers' tables with
the published values beside ours (cells from :mod:`benchmarks.report.tables`), links to the
bounds figures (:func:`.figures.observer_bounds`) and, last, what to cite (:mod:`.citation`)."""

from __future__ import annotations

from pathlib import Path

from observers.registry import table_order

from ..io import atomic_write_text, load_results, load_runs, path_component
from ..metrics import timed_in_parallel
from . import freshness
from .aggregate import is_sweep, sweep_tables
from .citation import citation_lines
from .figures import observer_bounds
from .numbers import markdown_table
from .tables import (
    INTRO,
    PHASE_CAPTION,
    absolute_table,
    absolute_table_caption,
    gap_table_caption,
    gap_table_data,
    phase_table_data,
    published_table,
    scenario_facts,
    scenario_notes,
    scenario_table,
    scenario_table_caption,
)


def write_report(results_dir: str | Path, out: str | Path | None = None,
                 figures: bool = True, data: tuple | None = None) -> Path:
    """Write the Markdown report (and figures) for a results folder; returns its path.

    ``data``: ``(summary, meta)`` already read (a result store's view); the figures then come
    from the store's last local run, ``DIR/run/runs.csv``, where it exists."""
    results_dir = Path(results_dir)
    # one complete generation, or ConfigError
    summary, meta = data if data is not None else load_results(results_dir)
    out = Path(out) if out else results_dir / "report.md"
    runs = None
    runs_dir = results_dir / "run" if data is not None else results_dir
    if figures and (runs_dir / "runs.csv").is_file() and len(summary):
        runs = load_runs(runs_dir)
    atomic_write_text(out, render_report(summary, meta, out, runs, results_dir.name))
    return out


def store_footer(meta: dict) -> list[str]:
    """The closing lines of a report rendered from a result store: the runs its rows come
    from (when, commit, machine, BLAS kernel, versions) and how it is kept fresh."""
    runs = meta.get("runs", {})
    counts: dict[str, int] = {}
    for rec in meta.get("rows", {}).values():
        counts[rec.get("run", "?")] = counts.get(rec.get("run", "?"), 0) + 1
    lines = ["---", f"Rendered from the result store `results/{meta['config']['name']}/` "
             f"({len(meta.get('rows', {}))} rows, each with the fingerprint of the code, data "
             "and configuration entry that produced it; `setobs-bench stale` names the rows a "
             "change touched, `make bench` re-runs just those and `make reports` renders this "
             "page again). Rows by run:", ""]
    for run_id, run in sorted(runs.items(), key=lambda kv: (kv[1].get("created", ""), kv[0])):
        m, v = run.get("machine", {}), run.get("versions", {})
        ex = run.get("executor", {})
        lines.append(
            f"- run {run_id}: {counts.get(run_id, 0)} rows, {run.get('created', '?')}, commit "
            f"{run.get('commit') or '?'}; {m.get('cpu', '?')} ({m.get('cores', '?')} cores, "
            f"OpenBLAS kernel {m.get('blas_coretype', '?')}); {ex.get('workers', '?')} "
            f"worker(s); " + ", ".join(f"{k} {val}" for k, val in sorted(v.items())
                                       if k not in ("blas_coretype",)))
    return [*lines, ""]


def shown_tables(summary, meta: dict) -> list[str]:
    """The published tables whose values a report of ``summary`` shows in parentheses (none for
    a sweep, whose tables are aggregated over the seeds), in the scenarios' order."""
    if not len(summary) or is_sweep(summary):
        return []
    keys = (published_table(full, meta) for _, full in summary.groupby("scenario", sort=False))
    return list(dict.fromkeys(k for k in keys if k))


def render_report(summary, meta: dict, out: Path, runs=None, name: str = "") -> str:
    """The Markdown report of a summary and its metadata (a run's or a store's), as text.

    Its last lines (before the provenance comment of a run's report) say what to cite: the
    paper whose table the configuration reproduces and those whose published values it shows,
    then the project with its version (:func:`.citation.citation_lines`).

    Parameters
    ----------
    summary : DataFrame
        The summary rows.
    meta : dict
        ``meta.json`` of a run, or of a result store (it has ``runs``).
    out : Path
        Where the report goes (figures are linked relative to it).
    runs : DataFrame, optional
        ``runs.csv`` rows, to draw the bounds figures (beside ``out``).
    name : str
        Title to use if ``meta`` has none.
    """
    out = Path(out)
    fig_dir = out.parent / (out.stem + "_figures")
    title = meta.get("config", {}).get("title", name)
    parts = [f"# {title}", "", INTRO, ""]
    if timed_in_parallel(summary):
        ex = meta.get("executor", {})
        parts += [f"Times marked *(parallel)* were measured while {ex.get('workers', 'several')}"
                  f" jobs ran concurrently ({ex.get('name', 'parallel')} executor): indicative "
                  "only; a serial run (`run` without `--jobs`) gives the comparable per-step "
                  "times, and `reports/speed.md` is always timed serially.", ""]
    cite = [*citation_lines(meta.get("config", {}).get("name") or name,
                            shown_tables(summary, meta)), ""]
    if is_sweep(summary):  # aggregated over the seeds, one row per observer and variant
        parts += ["Sweep: relative RMS radius (mean over the states of eq. 9, against the "
                  "best observer of the same seed) over the seeds: mean, standard deviation, "
                  "min and max over the successful runs; times are medians over them.", ""]
        parts += sweep_tables(summary)
        summary = summary.iloc[0:0]  # no per-seed tables
    if not len(summary):
        runs = None
    for sc, full in summary.groupby("scenario", sort=False):
        info = meta.get("scenarios", {}).get(sc, {})
        df = full[full["status"] != "unsupported"]  # status rows of the scenario table only
        facts = scenario_facts(info)
        parts += [f"## {sc}", "", info.get("description", ""), ""]
        if facts:
            parts += [facts[0].upper() + facts[1:], ""]
        parts += [scenario_table_caption(full, meta), "", scenario_table(full, meta), ""]
        abs_table = absolute_table(df, meta) if len(df) else ""
        if abs_table:
            parts += [absolute_table_caption(df, meta), "", abs_table, ""]
        gaps = gap_table_data(df, meta) if len(df) else None
        if gaps:
            parts += [gap_table_caption(df), "", markdown_table(*gaps), ""]
        phases = phase_table_data(df) if len(df) else None
        if phases:
            parts += [PHASE_CAPTION, "", markdown_table(*phases), ""]
        notes = scenario_notes(full)
        parts += [f"- {note}" for note in notes] + ([""] if notes else [])
        if runs is not None:
            links = []
            names = info.get("state_names") or []
            for obs in table_order(df["observer"].unique()):
                base = fig_dir / path_component(sc) / path_component(obs)  # names, not paths
                paths = observer_bounds(runs, sc, obs, names, base)
                if paths is not None:
                    links.append(f"[{obs}]({paths[0].relative_to(out.parent).as_posix()})")
            if links:
                parts += ["Figures (bounds over time with the true state): " + ", ".join(links),
                          ""]
    if "runs" in meta:  # a result store: its runs, no code stamp (the rows carry theirs)
        parts += store_footer(meta) + cite
        return "\n".join(parts)
    versions = meta.get("versions", {})
    if versions:
        parts += ["---", f"Run {meta.get('run_id', '?')} of " + meta.get("created", "") + "; "
                  + ", ".join(
            f"{k} {v}" for k, v in versions.items()), ""]
    parts += cite  # the last visible lines: the stamp below is a comment
    config = freshness.config_of(meta.get("config", {}).get("name"))
    parts.append(freshness.stamp(freshness.report_command(config, out), config))
    return "\n".join(parts) + "\n"
