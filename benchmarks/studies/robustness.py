"""Rankings that hold: every guaranteed observer over many noise realisations.

``python -m benchmarks.studies.robustness`` (``make robustness``) runs every guaranteed
observer (the reference and the non-guaranteed baseline aside) on the first
:data:`REALISATIONS` realisations of each scenario of the soundness audit (the simulated
versions of the papers' records: :data:`benchmarks.gate.audit.AUDIT_SCENARIOS`), the same
realisations the audit draws (:func:`benchmarks.gate.audit.realisation`: uniform,
truncated-Gaussian and vertex noise, vertex noise held for random dwell times, a bang-bang
worst-case input), holds each record's rows against its floor (the exact consistent set of a
linear record; on a nonlinear one the falsifier's inner box of verified consistent states,
within a budget of :data:`FALSIFIER_BUDGET` simplex iterations, so a gap upper bound) and
writes ``reports/robustness.md``, a figure of the rank distributions beside it and the tidy
table ``results/robustness/robustness.csv`` (a row per scenario, realisation and observer).
The records of ARCH 2021 Tables 5 and 6 (the n-tank scaling, 12 to 30 tanks:
:data:`SCALING_TABLES`) are realised the same way with the observers those tables compare
(their rankings only: no floor, whose exact hulls at 30 states would cost more than the
rest of the study).  Reported:

* per observer and scenario, the mean and the 10/50/90 % quantiles over the realisations of
  its **relative RMS** (its mean RMS radius over the smallest sound one of the same
  realisation) and of its **gap** and **gap steady** to the floor;
* its **rank** per realisation (1 = the tightest sound observer) and the distribution of the
  ranks;
* a **pairwise win table** of the observers of each scenario with the best median rank: how
  often the row is tighter than the column over the realisations where both ran soundly;
* per paper table, one sentence on whether its single-record ranking (the committed result
  store) holds over the realisations;
* the **containment violations** of the true state over all runs (interval hulls).

Every (scenario, realisation) is one task (its floor and every observer) run in ``--jobs``
processes; the exact floors are cached on disk, so those the audit computed are reused.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pandas as pd

import observers

from ..errors import ConfigError
from ..gate import audit, dated
from ..io import atomic_write_text, environment, read_table
from ..metrics import rms_radius
from ..report import figures
from ..report.citation import citation_lines
from ..report.numbers import MISSING, fmt, markdown_table
from ..report.paper import paper_rows
from ..run.executors import run_tasks
from ..run.floor import floor_columns, observer_floor
from ..run.floor_inner import FALSIFIER_STEPS
from ..run.floors import compute_floor
from ..run.rows import merge_options, run_observer
from .cli import log, refuse, require_positive, study_parser, table_of, wrote

#: realisations per scenario (the audit's first ones)
REALISATIONS = 20
#: observers with the best median rank shown in a scenario's pairwise win table
WIN_TABLE_SIZE = 8
#: the published tables (committed result stores) whose record the audit simulates:
#: (store, its scenario = the audit's scenario)
PAPER_TABLES = (
    ("arch2021_table3", ("tank6-linear",)),
    ("arch2021_table4", ("tank6-nonlinear",)),
    ("automatica2021_table3", ("vehicle6d-sim",)),
    ("nonlinear_comparison", ("tank6-nonlinear",)),
    ("nonlinear_comparison", ("vanderpol-sim",)),
)
#: the n-tank scaling tables of ARCH 2021 (Table 5 linear, Table 6 nonlinear and its 12-tank
#: column): (store, its records, the published table's variant); each record is realised
#: with the observers the published table compares
SCALING_TABLES = (
    ("arch2021_table5", ("tank12-linear", "tank18-linear", "tank24-linear", "tank30-linear"),
     "linear"),
    ("arch2021_table6_12tanks", ("tank12-nonlinear",), "nonlinear"),
    ("arch2021_table6", ("tank18-nonlinear", "tank24-nonlinear", "tank30-nonlinear"),
     "nonlinear"),
)
#: the published table of the n-tank scaling (both variants, every column)
SCALING_KEY = "arch2021_table5_6_tank_scaling"
#: the falsifier's work budget per nonlinear realisation, in simplex iterations (a count, so
#: the same floor on every machine): a uniform-noise tank6-nonlinear record takes about
#: 18,000, a vertex-noise one 40,000-120,000 (degenerate LPs; each LP is also capped, at
#: ``search.LP_ITERATION_LIMIT``); vertex realisation 7 needed 1.9 million without the caps,
#: and its last step is left out (the report names it)
FALSIFIER_BUDGET = 150_000
COLUMNS = ["scenario", "realisation", "kind", "observer", "status", "violations", "rms",
           "rel_rms", "rank", "gap", "gap_steady", "floor", "floor_steps"]


def study_observers() -> list[str]:
    """Every guaranteed observer but the exact reference, in table order."""
    return [i.name for i in observers.available() if i.guaranteed and i.family != "reference"]


def scaling_observers(scenario: str, variant: str) -> tuple[str, ...]:
    """The observers with a published value in the column of ``scenario``'s record of the
    n-tank scaling table (``variant``: its linear or nonlinear table), in registry order."""
    published = paper_rows(SCALING_KEY, int(scenario.split("-")[0].removeprefix("tank")),
                           variant)
    return tuple(n for n in study_observers()
                 if n in published and published[n].avg is not None)


def study_tasks(count: int, names: tuple[str, ...] | None = None,
                scenarios=audit.AUDIT_SCENARIOS, scaling: bool = True
                ) -> list[tuple[str, int, tuple[str, ...], bool]]:
    """``(scenario, realisation, observers, with floor)`` of every run of the study: every
    observer of ``names`` (default: :func:`study_observers`) on the audit's ``scenarios``,
    with their floors; with ``scaling``, the observers of each n-tank scaling table on its
    records, without floors."""
    names = tuple(study_observers() if names is None else names)
    tasks = [(s, i, names, True) for s in scenarios for i in range(count)]
    if scaling:
        tasks += [(s, i, scaling_observers(s, variant), False)
                  for _, records, variant in SCALING_TABLES for s in records
                  for i in range(count)]
    return tasks


def run_realisation(task: tuple[str, int, tuple[str, ...], bool]) -> list[dict]:
    """Every observer of ``names`` on realisation ``index`` of ``scenario``, held against the
    record's floor if ``with_floor``."""
    scenario, index, names, with_floor = task
    kind, sc = audit.realisation(scenario, index)
    floor = compute_floor(sc, with_floor, budget=FALSIFIER_BUDGET)
    searched = (0 if not floor.usable else sc.N if floor.steps is None
                else int(np.isfinite(floor.lo["filtered"]).all(axis=1).sum()))
    rows = []
    for name in names:
        row = {"scenario": scenario, "realisation": index, "kind": kind, "observer": name,
               "status": "ok", "violations": np.nan, "rms": np.nan, "gap": np.nan,
               "gap_steady": np.nan, "floor": floor.kind, "floor_steps": searched}
        run = run_observer(name, sc, merge_options(name, sc), "hull")
        row["status"] = run.status
        res = run.result
        if run.in_set is not None:
            row["violations"] = int((~run.in_set).sum())
        if run.status == "ok" and res is not None:
            row["rms"] = float(np.mean(rms_radius(res.radius)))
            if floor.usable:
                cols = floor_columns(floor, observer_floor(name), res.lo, res.hi, True,
                                     sc.tolerance)
                missed = cols["covers_exact"] == "no"
                if missed and floor.kind == "exact":  # re-solved from scratch, as the audit
                    N, n = sc.N, sc.system.n
                    lo, hi = np.full((N, n), np.nan), np.full((N, n), np.nan)
                    lo[: len(res.lo)], hi[: len(res.hi)] = res.lo, res.hi
                    missed = audit.recheck_exact_misses(observer_floor(name), floor, lo, hi,
                                                        sc)[0] > 0
                if missed:
                    row["violations"] = max(int(row["violations"] or 0), 1)
                row["gap"] = float(np.mean(cols["gap"]))
                row["gap_steady"] = float(np.mean(cols["gap_steady"]))
        rows.append(row)
    return rows


def sound(df: pd.DataFrame) -> pd.Series:
    """The rows that may be ranked: run to the end without a violation."""
    return (df["status"] == "ok") & (df["violations"].fillna(0) == 0) & np.isfinite(df["rms"])


def add_ranks(df: pd.DataFrame) -> pd.DataFrame:
    """``rel_rms`` (over the smallest sound ``rms`` of the same realisation) and ``rank``
    (1 = the tightest sound row of the realisation; ties share the smaller rank)."""
    out = df.copy()
    ok = sound(out)
    keys = ["scenario", "realisation"]
    best = out[ok].groupby(keys)["rms"].min().rename("_best")
    out = out.join(best, on=keys)
    out["rel_rms"] = np.where(ok, out["rms"] / out["_best"], np.nan)
    out["rank"] = np.nan
    out.loc[ok, "rank"] = out[ok].groupby(keys)["rms"].rank(method="min")
    return out.drop(columns="_best")


def per_observer(df: pd.DataFrame, scenario: str) -> pd.DataFrame:
    """Per observer of ``scenario``: realisations run soundly, mean and quantiles of the
    relative RMS, of the gap and of the gap steady, the median and mean rank, failures and
    violations; sorted by median rank."""
    g = df[df["scenario"] == scenario]
    rows = []
    for name, h in g.groupby("observer", sort=False):
        ok = h[sound(h)]
        r = ok["rel_rms"].to_numpy(float)
        gap = ok["gap"].dropna().to_numpy(float)
        steady = ok["gap_steady"].dropna().to_numpy(float)

        def q(a, p):
            return float(np.quantile(a, p)) if a.size else np.nan

        rows.append({"observer": name, "runs": len(h), "sound": len(ok),
                     "failed": int((h["status"] != "ok").sum()),
                     "violations": int(h["violations"].fillna(0).sum()),
                     "rel_mean": float(r.mean()) if r.size else np.nan,
                     "rel_q10": q(r, 0.1), "rel_q50": q(r, 0.5), "rel_q90": q(r, 0.9),
                     "gap_mean": float(gap.mean()) if gap.size else np.nan,
                     "gap_q10": q(gap, 0.1), "gap_q90": q(gap, 0.9),
                     "steady_mean": float(steady.mean()) if steady.size else np.nan,
                     "rank_median": q(ok["rank"].to_numpy(float), 0.5),
                     "rank_mean": float(ok["rank"].mean()) if len(ok) else np.nan})
    out = pd.DataFrame(rows)
    return out.sort_values(["rank_median", "rank_mean", "observer"], na_position="last")


def win_table(df: pd.DataFrame, scenario: str, names: list[str]) -> pd.DataFrame:
    """``W[a, b]``: the fraction of the realisations of ``scenario`` where both ran soundly in
    which ``a``'s mean RMS radius is smaller than ``b``'s (NaN where they never both did)."""
    g = df[(df["scenario"] == scenario) & sound(df)]
    rms = g.pivot_table(index="realisation", columns="observer", values="rms")
    out = pd.DataFrame(np.nan, index=names, columns=names)
    for a in names:
        for b in names:
            if a == b or a not in rms or b not in rms:
                continue
            both = rms[[a, b]].dropna()
            if len(both):
                out.loc[a, b] = float((both[a] < both[b]).mean())
    return out


def single_record_order(store: Path, scenario: str) -> pd.Series:
    """The mean relative RMS per observer of ``scenario`` in a committed result store (its
    ``summary.csv``; sound rows only): the single-record ranking of a paper table."""
    s = read_table(store / "summary.csv")
    col = "contained" if "contained" in s.columns else s.columns[s.columns.str.startswith(
        "contained")][0]
    s = s[(s["scenario"] == scenario) & (s["status"] == "ok")
          & (s[col].astype(str) != "no") & s["variant"].isna()]
    return s.groupby("observer")["rms_radius"].mean().sort_values()


def holds_sentence(table: str, scenarios: tuple[str, ...], df: pd.DataFrame,
                   results: Path) -> str:
    """Whether the single-record ranking of a paper table (over each of its records) holds
    over the realisations."""
    store = results / table
    if not (store / "summary.csv").is_file():
        return f"{table}: no committed store to compare with."
    kept = total = 0
    shares, observed, realised = [], set(), 0
    for scenario in scenarios:
        single = single_record_order(store, scenario)
        g = df[(df["scenario"] == scenario) & sound(df)]
        rms = g.pivot_table(index="realisation", columns="observer", values="rms")
        names = [n for n in single.index if n in rms.columns]
        if len(names) < 2:
            continue
        observed.update(names)
        realised = max(realised, len(rms))
        for i, a in enumerate(names):
            for b in names[i + 1:]:  # the record ranks a above (tighter than) b
                both = rms[[a, b]].dropna()
                if len(both):
                    total += 1
                    kept += int((both[a] < both[b]).mean() > 0.5)
        top = rms[names].idxmin(axis=1)
        share = float((top == names[0]).mean()) if len(top) else np.nan
        shares.append(f"{names[0]} on {scenario} in {fmt(100 * share, 3)} %")
    if total == 0:
        return f"{table}: fewer than two observers in common."
    verdict = ("holds" if kept >= 0.9 * total else
               "holds in the main" if kept >= 0.75 * total else "does not hold")
    where = ", ".join(scenarios)
    return (f"**{table}** ({where}, {len(observed)} observers): the single-record "
            f"ranking {verdict} over {realised} realisations: {kept} of {total} pairs keep "
            f"their order in most realisations; its best observer is the tightest of them "
            f"in a share of the realisations: {'; '.join(shares)}.")


def floor_sentence(df: pd.DataFrame, scenario: str) -> str:
    """What the gap columns of ``scenario`` are measured against, per realisation."""
    g = df[df["scenario"] == scenario].drop_duplicates("realisation")
    kinds = set(g["floor"].astype(str))
    if kinds <= {"none", "nan"}:
        return "Floor: none (a ranking record; gap columns n/a)."
    if kinds == {"exact"}:
        return f"Floor: the exact consistent set of each of the {len(g)} realisations."
    full = int(g["floor_steps"].max())
    short = g[g["floor_steps"] < full]
    text = (f"Floor: the falsifier's inner box (verified consistent states at {full} steps "
            "per realisation; the gap columns are upper bounds)")
    if len(short):
        text += "; the budget left steps out in realisation " + ", ".join(
            f"{int(r.realisation)} ({int(r.floor_steps)} of {full} steps)"
            for r in short.itertuples())
    return text + "."


def report(df: pd.DataFrame, fig: Path | None, out: Path, results: Path,
           elapsed: float) -> str:
    """The Markdown report (see the module docstring)."""
    env = environment()
    viol = int(df["violations"].fillna(0).sum())
    runs = len(df)
    parts = [
        "# Rankings that hold: every guaranteed observer over many noise realisations", "",
        f"Every guaranteed observer on the first {df['realisation'].nunique()} realisations of "
        "each scenario of the soundness audit (uniform, truncated-Gaussian and vertex noise, "
        "vertex noise held for random dwell times, a bang-bang worst-case input; the same "
        "records the audit draws). **rel. RMS**: the observer's mean RMS radius over the "
        "smallest sound one of the same realisation; **gap**, **gap steady**: to the floor, "
        "over the whole record and after its first 20 % (the exact consistent set on a linear "
        "record; on a nonlinear one the falsifier's inner box of verified consistent states "
        f"at {FALSIFIER_STEPS} steps, searched within {FALSIFIER_BUDGET:,} simplex iterations, "
        "so an upper bound of the gap); **rank**: 1 = the tightest sound observer of the "
        "realisation; quantiles q10/q50/q90 over the realisations. The records of ARCH 2021 "
        "Tables 5 and 6 (12 to 30 tanks) are realised the same way with the observers those "
        "tables compare, for their rankings (no floor). "
        f"{runs} runs; **containment violations: {viol}** (the true state in the interval "
        "hull at every step; every hull covering the floor: the exact set, or every verified "
        "consistent state of the falsifier). "
        "Produced by `python -m benchmarks.studies.robustness`"
        + (f" in {elapsed / 60:.1f} min" if np.isfinite(elapsed) else "")
        + f" (git {env.get('git', '?')}).", "",
        "## Do the paper tables' rankings hold?", "",
    ]
    present = set(df["scenario"])
    tables = [(t, r) for t, r in PAPER_TABLES] + [(t, r) for t, r, _ in SCALING_TABLES]
    parts += [f"- {holds_sentence(t, r, df, results)}" for t, r in tables
              if set(r) <= present]
    parts += ["- **alanwar2022** (rotating-target): its record and offline experiment are "
              "re-drawn over 20 seeds by the data-driven study, whose section 6 says whether "
              "the single-record ranking holds (`reports/datadriven.md`).", ""]
    if fig is not None:
        parts += [f"![rank distributions]({fig.relative_to(out.parent).as_posix()})", ""]
    for scenario in dict.fromkeys(df["scenario"]):
        per = per_observer(df, scenario)
        parts += [f"## {scenario}", "", floor_sentence(df, scenario), ""]
        head = ["observer", "sound / runs", "rel. RMS mean", "q10", "q50", "q90", "gap mean",
                "gap q10", "gap q90", "gap steady mean", "median rank", "failed",
                "violations"]
        rows = [[r.observer, f"{r.sound} / {r.runs}", fmt(r.rel_mean, 3), fmt(r.rel_q10, 3),
                 fmt(r.rel_q50, 3), fmt(r.rel_q90, 3), fmt(r.gap_mean, 3), fmt(r.gap_q10, 3),
                 fmt(r.gap_q90, 3), fmt(r.steady_mean, 3), fmt(r.rank_median),
                 str(r.failed), str(r.violations)] for r in per.itertuples()]
        parts += markdown_table(head, rows).splitlines() + [""]
        names = [n for n in per["observer"] if per.set_index("observer").loc[n, "sound"]]
        names = names[:WIN_TABLE_SIZE]
        if len(names) >= 2:
            w = win_table(df, scenario, names)
            parts += [f"How often the row is tighter than the column ({scenario}, the "
                      f"{len(names)} best by median rank):", ""]
            rows = [[a, *(MISSING if np.isnan(w.loc[a, b]) else fmt(w.loc[a, b], 2)
                          for b in names)] for a in names]
            parts += markdown_table(["", *names], rows).splitlines() + [""]
    parts += ["---", ", ".join(f"{k} {v}" for k, v in env.items()), "",
              *citation_lines("robustness"), ""]
    return "\n".join(parts)


def run_study(jobs: int = 1, scenarios=audit.AUDIT_SCENARIOS, count: int = REALISATIONS,
              names=None, scaling: bool = True, log=lambda m: None) -> pd.DataFrame:
    """Every task of :func:`study_tasks` in ``jobs`` processes, as one table."""
    tasks = [t for t in study_tasks(count, names, scenarios, scaling) if t[2]]
    outs = run_tasks(run_realisation, tasks, jobs,
                     lambda task, _: log(f"{task[0]} realisation {task[1]}: done"))
    return add_ranks(pd.DataFrame([row for out in outs for row in out]))[COLUMNS]


def run_changed(old: pd.DataFrame, changed: list[str], jobs: int = 1,
                count: int = REALISATIONS, log=lambda m: None) -> pd.DataFrame:
    """The table ``old`` with the rows of the observers ``changed`` measured again (every
    realisation of theirs; the ranks of every realisation recomputed over the merged rows):
    the study's incremental run (``make robustness``)."""
    if not changed:
        return old
    return merge_changed(old, run_study(jobs, count=count, names=tuple(changed), log=log),
                         changed)


def merge_changed(old: pd.DataFrame, new: pd.DataFrame, changed: list[str]) -> pd.DataFrame:
    """``old`` with the rows of the observers ``changed`` replaced by ``new``'s, in the order
    of a full run (scenario, realisation, table order), ranks recomputed."""
    kept = old[~old["observer"].isin(changed)]
    merged = pd.concat([kept, new], ignore_index=True).drop(columns=["rank"])
    position = {n: i for i, n in enumerate(study_observers())}
    scenarios = {s: i for i, s in enumerate(dict.fromkeys(old["scenario"]))}
    merged = merged.assign(_s=merged["scenario"].map(scenarios), _o=merged["observer"].map(
        position)).sort_values(["_s", "realisation", "_o"], kind="stable")
    return add_ranks(merged.drop(columns=["_s", "_o"]).reset_index(drop=True))[COLUMNS]


def changed_observers() -> list[str]:
    """The observers of the study whose code changed since the committed table was measured
    (:func:`benchmarks.gate.dated.changed_rows`); every one if it has no record."""
    changed = dated.changed_rows("robustness")
    return study_observers() if changed is None else [
        n for n in study_observers() if n in changed]


def render(df: pd.DataFrame, out: Path, results: Path, elapsed: float) -> None:
    """The figure and the report of the table ``df``."""
    ranks = df[sound(df)][["scenario", "observer", "rank"]]
    fig = figures.rank_distributions(ranks, out.parent / "figures" / "robustness_ranks")[0] \
        if len(ranks) else None
    atomic_write_text(out, report(df, fig, out, results, elapsed))


def main(argv: list[str] | None = None) -> int:
    """Command line of the study."""
    p = study_parser("benchmarks.studies.robustness", __doc__, out="reports/robustness.md",
                     results="results", results_help="folder of the stores (the paper "
                     "tables' single records) and of robustness/robustness.csv",
                     render_help="no run: the report and figure from the table in --results")
    p.add_argument("--realisations", type=int, default=REALISATIONS,
                   help=f"per scenario (default {REALISATIONS})")
    p.add_argument("--changed", action="store_true",
                   help="measure again only the observers whose code changed since the "
                        "committed table was measured (reports/robustness.md's dated block; "
                        "everything where there is no table)")
    args = p.parse_args(argv)
    results, out = Path(args.results), Path(args.out)
    table = results / "robustness" / "robustness.csv"
    try:
        require_positive(jobs=args.jobs, realisations=args.realisations)
        changed = changed_observers() if args.changed and table.is_file() else None
        if changed is not None:
            log(f"robustness: measuring again {len(changed)} observer(s): "
                f"{', '.join(changed) or 'none'}")
        df, elapsed = table_of(table, args.render, lambda: run_study(
            args.jobs, count=args.realisations, log=log) if changed is None else run_changed(
            read_table(table), changed, args.jobs, args.realisations, log=log))
    except ConfigError as exc:
        return refuse(exc)
    render(df, out, results, elapsed)
    return wrote(out, table)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
