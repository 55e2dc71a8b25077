"""Accuracy history: the golden summaries of ``results/baseline/`` across the git history.

Every commit that changed the golden files is read back with ``git show REV:path``; per
observer and scenario the average relative RMS (eq. 9) over the states and the number of
containment violations are drawn over the commits (one line per observer), like asv does for
timings, so that one sees when and where a bound got looser. The page
(``OUT/index.html``) also lists, per commit, the observers whose average moved by more than
their regression tolerance.
"""

from __future__ import annotations

import html
import io
import subprocess
from pathlib import Path

import numpy as np
import pandas as pd

from ..errors import ConfigError
from ..io import atomic_write_csv, atomic_write_text, path_component
from ..report import figures
from ..report.html import figure_html, html_page, html_table

HISTORY_COLUMNS = ["commit", "date", "subject", "scenario", "observer", "rel_rms",
                   "violations", "status"]


def _git(args: list[str], cwd: Path) -> str:
    try:
        proc = subprocess.run(["git", *args], cwd=cwd, capture_output=True, text=True,
                              timeout=60)
    except (OSError, subprocess.SubprocessError) as exc:
        raise ConfigError(f"history: git failed: {exc}") from None
    if proc.returncode != 0:
        raise ConfigError(f"history: git {' '.join(args[:2])} failed: "
                          f"{proc.stderr.strip().splitlines()[0] if proc.stderr.strip() else ''}")
    return proc.stdout


def baseline_commits(baseline: Path) -> list[tuple[str, str, str]]:
    """``(hash, ISO date, subject)`` of every commit that changed ``baseline``, oldest first."""
    cwd = baseline if baseline.is_dir() else Path.cwd()
    log = _git(["log", "--format=%H%x09%cI%x09%s", "--", str(baseline.resolve())], cwd)
    rows = [tuple(line.split("\t", 2)) for line in log.splitlines() if line.strip()]
    return [(h, d, s) for h, d, s in reversed(rows)]


def summaries_at(rev: str, baseline: Path) -> pd.DataFrame:
    """Per scenario and observer at commit ``rev``: average ``rel_rms`` over the states, the
    violations and the status, read from the golden CSV files of that commit."""
    top = Path(_git(["rev-parse", "--show-toplevel"], baseline).strip())
    rel = baseline.resolve().relative_to(top).as_posix()
    names = _git(["ls-tree", "--name-only", f"{rev}:{rel}"], top).split()
    frames = []
    for name in names:
        if not name.endswith(".csv"):
            continue
        df = pd.read_csv(io.StringIO(_git(["show", f"{rev}:{rel}/{name}"], top)))
        if not {"scenario", "observer", "rel_rms", "status"} <= set(df.columns):
            continue
        if "violations" not in df.columns:
            df["violations"] = np.nan
        frames.append(df.groupby(["scenario", "observer"], sort=False).agg(
            rel_rms=("rel_rms", "mean"), violations=("violations", "max"),
            status=("status", "first")).reset_index())
    if not frames:
        return pd.DataFrame(columns=["scenario", "observer", "rel_rms", "violations", "status"])
    return pd.concat(frames, ignore_index=True)


def collect(baseline: str | Path) -> pd.DataFrame:
    """The history table: one row per commit, scenario and observer (:data:`HISTORY_COLUMNS`)."""
    baseline = Path(baseline)
    if not baseline.is_dir():
        raise ConfigError(f"history: no folder {baseline}")
    commits = baseline_commits(baseline)
    if not commits:
        raise ConfigError(f"history: no commit in the git history changed {baseline}")
    frames = []
    for rev, date, subject in commits:
        df = summaries_at(rev, baseline)
        frames.append(df.assign(commit=rev[:10], date=date, subject=subject))
    table = pd.concat(frames, ignore_index=True)
    return table[HISTORY_COLUMNS]


def changes(table: pd.DataFrame, rtol: float = 1e-6) -> pd.DataFrame:
    """Rows where an observer's average relative RMS or its violations changed from the
    previous commit that had it (relative change above ``rtol``), or its status did."""
    out = []
    for (_sc, _obs), g in table.groupby(["scenario", "observer"], sort=False):
        prev = None
        for r in g.itertuples(index=False):
            if prev is not None:
                a, b = prev.rel_rms, r.rel_rms
                moved = (np.isfinite(a) and np.isfinite(b) and abs(b - a) > rtol * abs(a))
                viol = not (pd.isna(prev.violations) and pd.isna(r.violations)) and \
                    prev.violations != r.violations
                if moved or viol or prev.status != r.status:
                    out.append({"commit": r.commit, "date": r.date[:10], "scenario": r.scenario,
                                "observer": r.observer, "before": a, "after": b,
                                "status": f"{prev.status} -> {r.status}"
                                if prev.status != r.status else r.status,
                                "violations": r.violations})
            prev = r
    return pd.DataFrame(out, columns=["commit", "date", "scenario", "observer", "before",
                                      "after", "status", "violations"])


def write_history(baseline: str | Path = "results/baseline", out: str | Path = "results/history"
                  ) -> tuple[Path, pd.DataFrame]:
    """Write ``OUT/index.html`` (figures per scenario, changes per commit) and
    ``OUT/history.csv``; returns the page and the history table."""
    table = collect(baseline)
    out = Path(out)
    atomic_write_csv(out / "history.csv", table)
    commits = table.drop_duplicates("commit")
    body = ["<h1>Accuracy history of the golden summaries</h1>",
            f"<p>{len(commits)} commits changed <code>{html.escape(str(baseline))}</code>. "
            "Per scenario: the average relative RMS (eq. 9, over the states) of every "
            "observer and its containment violations at each of these commits. A rising line "
            "is a looser bound.</p>"]
    for sc in dict.fromkeys(table["scenario"]):
        paths = figures.history(table, sc, out / "figures" / f"{path_component(sc)}_history")
        body += [f"<h2>{html.escape(sc)}</h2>",
                 figure_html(paths, out, f"{sc}: relative RMS and violations over commits")]
    ch = changes(table)
    rows = [[r.commit, r.date, r.scenario, r.observer, f"{r.before:.6g}", f"{r.after:.6g}",
             r.status, "n/a" if pd.isna(r.violations) else str(int(r.violations))]
            for r in ch.itertuples(index=False)]
    body += ["<h2>Changes per commit</h2>",
             html_table(["commit", "date", "scenario", "observer", "avg rel. RMS before",
                         "after", "status", "violations"], rows, "changes")
             if rows else "<p>No value changed.</p>",
             "<h2>Commits</h2>",
             html_table(["commit", "date", "subject"],
                        [[c.commit, c.date, c.subject] for c in commits.itertuples()],
                        "commits")]
    page = out / "index.html"
    atomic_write_text(page, html_page("Accuracy history", body))
    return page, table
