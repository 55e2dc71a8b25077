"""The soundness audit as a report: ``reports/soundness.md`` rendered from the audit's result
store, or a direct run's report (the short audit of CI, chosen scenarios or observers)."""

from __future__ import annotations

from datetime import datetime, timezone
from pathlib import Path

import pandas as pd

from systems import edge as edge_cases

from ..io import atomic_write_csv, atomic_write_text, environment
from ..report.citation import citation_lines
from ..report.markdown import store_footer
from ..report.numbers import fmt, markdown_table
from .audit import aggregate


def _table(agg: pd.DataFrame) -> str:
    """Markdown table of the aggregated audit (:func:`aggregate`)."""
    head = ["observer", "scenario", "runs", "steps", "violations", "worst violation",
            "undecided", "floor steps", "uncovered", "failed runs", "LP tests", "time s"]
    rows = [[r.observer, r.scenario, str(r.runs), str(r.steps),
             f"**{r.violations}**" if r.violations else "0",
             "-" if r.violations == 0 else f"{fmt(r.worst_violation, 3)} ({r.worst_at})",
             str(r.undecided), str(r.floor_steps),
             f"**{r.uncovered}** ({r.uncovered_at})" if r.uncovered else "0",
             r.failed or "-", str(r.lp_tests), fmt(r.seconds, 3)]
            for r in agg.itertuples(index=False)]
    return markdown_table(head, rows)


def soundness_report(df: pd.DataFrame, count: int, provenance: str,
                     footer: list[str] | None = None) -> str:
    """The Markdown report of an audit: ``reports/soundness.md`` (from its store,
    :func:`render_store`) or a direct run's (:func:`write_audit`); ``provenance`` is the line
    saying how the rows were made, ``footer`` the closing lines, after which come the lines
    saying what to cite (the project: the audit reproduces no paper's table)."""
    agg = aggregate(df)
    guaranteed = agg[agg["guaranteed"]]
    baselines = agg[~agg["guaranteed"]]
    bad = guaranteed[(guaranteed["violations"] > 0) | (guaranteed["uncovered"] > 0)]
    verdict = ("**Zero violations for every guaranteed observer: every true state inside, no "
               "consistent state found outside.**" if bad.empty else
               "**VIOLATIONS by guaranteed observers: " + ", ".join(
                   f"{r.observer} on {r.scenario} ({r.violations} steps missing the true state, "
                   f"{r.uncovered} missing the floor)"
                   for r in bad.itertuples(index=False)) + "** (bugs to fix or to explain)")
    first = df[(df["observer"] == df["observer"].iloc[0])
               & (df["scenario"] == df["scenario"].iloc[0])] if len(df) else df
    kinds = ", ".join(f"{r.kind} {r.runs}" for r in first.itertuples(index=False))
    used = int(first["runs"].sum()) if len(first) else 0
    parts = [
        "# Soundness audit",
        "",
        provenance,
        "",
        "Every observer runs on seeded realisations of each scenario; at every step the true "
        "state is tested for membership in the estimated set with an exact test per set type "
        "(interval hull rejection, a verified factor-vector certificate, else an LP whose "
        "primal and dual points give certified bounds of the distance; see "
        "`benchmarks/run/membership.py`). Tolerance: max(scenario tolerance, "
        "1e-8 max(1, |x|_inf)). "
        "*Violations*: steps at which the true state is certified to lie outside the set; "
        "*worst violation*: the largest certified infinity-norm distance from the true state "
        "to the set (Euclidean for ellipsoids); *undecided*: steps the LP could not decide "
        "within its precision (counted, not hidden): the true state lies within the rounding "
        "level of the set's own floating-point data, e.g. on the boundary of a badly scaled "
        "set, or inside a diverging estimate whose generators reach 1e10, where double "
        "precision cannot resolve 1e-8; *failed runs*: realisations without an "
        "estimate (noGain: no gain found; unsupported: the observer does not apply, e.g. a "
        "data-driven observer on a scenario without training data) or ending early "
        "(diverged: its earlier steps are still checked; empty: the estimate became empty, "
        "which also counts as a violation). *Floor steps*: steps of the first realisations of "
        "each scenario whose interval hulls were also held against the record's floor (the "
        "exact consistent set of a linear record by `Exact`; the verified consistent states "
        "the falsifier found at ten steps of a nonlinear record; `benchmarks/run/floor.py`); "
        "*uncovered*: steps where the hull misses a state consistent with the data, a "
        "violation whatever the true state did.",
        "",
        f"Realisations per observer and scenario: {used} of the first {count} (realisation "
        f"i has seed i and kind i mod 5: {kinds}). `vertex`, `vertex-hold` and "
        "`worst-input` are adversarial: "
        "noise at the vertices of W and V (redrawn every step, or held for random dwell "
        "times) and bang-bang inputs at the bounds of the nominal input range that swing the "
        "state between extremes; see `benchmarks/gate/audit.py`.",
        "",
        verdict,
        "",
        "## Guaranteed observers",
        "",
        _table(guaranteed) if len(guaranteed) else "(none)",
        "",
        "## Non-guaranteed baselines (counted separately)",
        "",
        _table(baselines) if len(baselines) else "(none registered)",
        "",
        *(footer or []),
        *citation_lines("soundness"),
        "",
    ]
    return "\n".join(parts)


def edge_sections(df: pd.DataFrame) -> list[str]:
    """The edge-case audit's own sections (:mod:`systems.edge`): the cases, and per observer
    and case every run that refused the system, failed or ended early, with its reasons."""
    agg = aggregate(df)
    cases = [[c.name, c.property,
              f"none: {c.no_floor}" if c.no_floor else "held on the short record"]
             for c in edge_cases.CASES]
    failed = agg[agg["failed"] != ""]
    rows = [[r.observer, r.scenario, r.failed,
             (r.reasons or "-").replace(" | ", "; ").replace("|", "\\|")]
            for r in failed.itertuples(index=False)]
    per = agg.groupby("observer", sort=False).agg(
        runs=("runs", "sum"), violations=("violations", "sum"), uncovered=("uncovered", "sum"),
        failed=("failed", lambda f: sum(1 for x in f if x)))
    summary = [[obs, str(int(r.runs)), f"**{int(r.violations)}**" if r.violations else "0",
                f"**{int(r.uncovered)}**" if r.uncovered else "0", str(int(r.failed))]
               for obs, r in per.iterrows()]
    return [
        "## The edge cases",
        "",
        "Each case is the 3-state plant of `systems/edge.py` (or its unicycle) with one "
        f"degenerate property; a `-long` case is the same on {edge_cases.LONG_STEPS} steps "
        f"(the others: {edge_cases.SHORT_STEPS}); the estimates on a `-long` case are held "
        "to the true state only, those on the short one to its floor too "
        f"({edge_cases.LONG_FLOOR_COST}).",
        "",
        markdown_table(["case", "what is degenerate", "floor"], cases),
        "",
        "## Per observer",
        "",
        "Runs, steps missing the true state (an empty estimate counts), steps missing the "
        "floor, and the cases it refused or failed on (below, with the reasons).",
        "",
        markdown_table(["observer", "runs", "violations", "uncovered", "cases refused or "
                        "failed"], summary),
        "",
        "## Refusals and failures, with their reasons",
        "",
        markdown_table(["observer", "case", "runs", "reasons"], rows) if rows else
        "(none: every observer accepted every case and ended every run)",
        "",
    ]


def write_audit(df: pd.DataFrame, out: str | Path, report: str | Path, count: int,
                elapsed: float, jobs: int, command: str, edge: bool = False
                ) -> tuple[Path, Path]:
    """Write a direct run's ``soundness.csv`` (per kind) and its Markdown report, each
    atomically (the short audit of CI, the edge-case audits, or an audit of chosen scenarios
    or observers; ``edge``: with :func:`edge_sections`)."""
    csv_path = Path(out) / "soundness.csv"
    atomic_write_csv(csv_path, df)
    report = Path(report)
    versions = environment()
    provenance = (f"Generated by `{command}` on "
                  f"{datetime.now(timezone.utc).isoformat(timespec='seconds')} (git "
                  f"{versions.get('git', '?')}); {elapsed:.0f} s wall time with {jobs} "
                  "worker(s).")
    text = soundness_report(df, count, provenance, edge_sections(df) if edge else None)
    atomic_write_text(report, text.rstrip("\n") + "\n")
    return csv_path, report


def render_store(summary: pd.DataFrame, meta: dict) -> str:
    """``reports/soundness.md`` rendered from the audit's result store."""
    count = meta.get("audit", {}).get("realisations", "?")
    seconds = float(summary["seconds"].sum()) if len(summary) else 0.0
    provenance = (f"Rendered from the result store `results/soundness/` "
                  f"(`make audit`: {count} realisations per observer and scenario; the rows' "
                  f"audit took {seconds:.0f} s of worker time in all).")
    return soundness_report(summary, count, provenance, store_footer(meta))
