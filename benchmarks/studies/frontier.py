"""Frontier study: accuracy against cost of the observers' complexity knobs.

``python -m benchmarks.studies.frontier`` (``make frontier``) runs, on
``tank6-linear``, ``vehicle6d-cora``, the first :data:`STEPS_30` steps of the 30-state
record ``tank30-linear-cora`` and the nonlinear records ``tank6-nonlinear`` and
``vanderpol-sim``, every setting of :data:`SETTINGS` (the zonotope order of FRad-A/B and
VolMin-B with the scenario's PCA reduction and of FRad-A with Girard's, the constraint budget
of CZN-A/B/MV/FO, the window L of the moving-horizon estimators MHE in both formulations and
MHE-PR, the members of the zonotope bundle ZB-A, ...), and writes
``reports/frontier.md``, a log-log figure beside it and the tidy table
``results/frontier/frontier.csv``:

* **gap**: the mean over the states of the observer's RMS radius over the exact floor's
  (:mod:`benchmarks.run.floor`; 1 is optimal), with ``covers_exact`` and the containment
  violations of the true state; on a nonlinear record the floor is the falsifier's verified
  inner box and the gap an upper bound (printed ``<=``);
* **cost**: the median per-step time of ``step()`` plus the interval hull (warm-up steps
  dropped), in ms and as a ratio to the median step of a plain Kalman filter on the same
  record (:func:`benchmarks.timing.steps.kalman_step_times`; the extended Kalman filter on a
  nonlinear record), so that the figure reads the
  same on any machine;
* the **Pareto front** of each record: the settings that no other setting beats on both
  axes (no other is at most as costly and at most as wide, and strictly better in one).
  Only sound settings (``covers_exact`` not ``no``, no violation) count.

Budget: ``--budget`` seconds in all (default :data:`BUDGET_S`, a few minutes); the settings
run in the order of :data:`SETTINGS` (cheap ones first, fewer on the 30-state record), one at
a time in this process (honest single-threaded timing), and those left when the budget is
spent are listed as ``not run: budget``.  The exact floors come from ``Exact``'s on-disk
cache when present (the first computation of the three floors costs about a minute).
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pandas as pd

import observers
from observers.errors import ObserverError
from systems import ModelError

from ..io import atomic_write_csv, atomic_write_text, environment
from ..metrics import memory_columns, warmup_steps
from ..report import figures, freshness
from ..report.citation import citation_lines
from ..report.numbers import MISSING, fmt, markdown_table
from ..run.floor import GAP_UPPER, floor_columns, observer_floor
from ..run.floors import compute_floor
from ..timing.steps import first_steps, kalman_step_times

#: total time budget of a run of the study (seconds)
BUDGET_S = 480.0
#: steps of the 30-state record (its exact floor grows faster than linearly with the steps)
STEPS_30 = 60
#: records and the number of steps used (None: the whole record)
RECORDS = {"tank6-linear": None, "vehicle6d-cora": None, "tank30-linear-cora": STEPS_30,
           "tank6-nonlinear": None, "vanderpol-sim": None}

_ORDERS = (5, 20, 100, 200)
_WINDOWS = (1, 2, 3, 5, 10, 20)
#: (observer, knob, values) per record, cheap settings first
SETTINGS: dict[str, list[tuple[str, str, tuple]]] = {
    "tank6-linear": [
        ("MHE", "window", _WINDOWS), ("FRad-A", "order", _ORDERS),
        ("FRad-B", "order", _ORDERS), ("VolMin-B", "order", (5, 20, 100)),
        ("CZN-B", "max_constraints", (3, 6, 12, 24)), ("CZN-A", "max_constraints", (3, 6, 12)),
        ("CZN-MV", "max_constraints", (3, 6, 12)), ("FRad-A[girard]", "order", (5, 20, 100)),
        ("MHE[lp]", "window", (5, 20)), ("ROPO", "basis", ("min-volume",)),
        ("ZB-A", "members", (1, 2)),
    ],
    "vehicle6d-cora": [
        ("MHE", "window", _WINDOWS), ("FRad-A", "order", _ORDERS),
        ("FRad-B", "order", _ORDERS), ("VolMin-B", "order", (5, 20, 100)),
        ("CZN-B", "max_constraints", (4, 8, 16, 32)), ("CZN-A", "max_constraints", (4, 8, 16)),
        ("CZN-MV", "max_constraints", (4, 8, 16)), ("FRad-A[girard]", "order", (5, 20, 100)),
        ("MHE[lp]", "window", (5, 20)), ("ROPO", "basis", ("min-volume",)),
        ("ZB-A", "members", (1, 2)),
    ],
    "tank30-linear-cora": [
        ("MHE", "window", (1, 3, 5)), ("FRad-A", "order", (5, 20, 100)),
        ("FRad-B", "order", (5, 20)), ("CZN-B", "max_constraints", (30, 60)),
        ("MHE[lp]", "window", (5,)),
    ],
    # nonlinear records: the floor is the falsifier's inner box, so every gap is an upper
    # bound; the Kalman step is the extended Kalman filter's
    "tank6-nonlinear": [
        ("MHE-PR", "window", (1, 2, 3, 5, 10)), ("FRad-A", "order", (5, 20, 100)),
        ("CZN-FO", "max_constraints", (6, 12, 24)), ("MHE-PR[sweeps]", "window", (5,)),
    ],
    "vanderpol-sim": [
        ("MHE-PR", "window", (1, 2, 3, 5, 10, 20)), ("FRad-A", "order", (5, 20, 100)),
        ("CZN-FO", "max_constraints", (4, 8, 16)), ("MHE-PR[sweeps]", "window", (5, 10)),
    ],
}
#: fixed options of a labelled variant ``NAME[tag]``
VARIANTS = {"MHE[lp]": {"formulation": "lp"}, "FRad-A[girard]": {"reduction": "girard"},
            "MHE-PR[sweeps]": {"sweeps": 2}}
COLUMNS = ["record", "steps", "observer", "knob", "value", "status", "message", "gap",
           "gap_steady", "gap_kind", "cost_ms", "kalman_ms", "cost_ratio", "memory", "covers_exact",
           "violations", "pareto"]


def _options(sc, name: str, knob: str, value) -> dict:
    """The scenario's options the observer accepts, its variant's, and the knob's value."""
    base = name.split("[")[0]
    info = observers.get(base)
    accepted = info.option_defaults()
    allowed = info.scenario_options
    opts = {k: v for k, v in (sc.options or {}).items()
            if k in accepted and (allowed is None or k in allowed)}
    opts.update(VARIANTS.get(name, {}))
    opts[knob] = value
    return opts


def run_setting(sc, floor, kalman_ms: float, name: str, knob: str, value) -> dict:
    """One observer setting on one record: status, gap, cost, soundness."""
    row = {"observer": name, "knob": knob, "value": str(value), "status": "ok", "message": "",
           "gap": np.nan, "gap_steady": np.nan, "gap_kind": "n/a", "cost_ms": np.nan,
           "kalman_ms": kalman_ms,
           "cost_ratio": np.nan, "memory": np.nan, "covers_exact": "n/a",
           "violations": np.nan}
    base = name.split("[")[0]
    try:
        obs = observers.create(base, sc.system, **_options(sc, name, knob, value))
        res = observers.run(obs, sc.u, sc.y, keep_sets=False, on_error="status")
    except (ObserverError, ModelError, ValueError) as exc:
        row.update(status="error", message=str(exc).splitlines()[0])
        return row
    if res.status != "ok":
        row.update(status=res.status, message=str(res.message).splitlines()[0])
        return row
    w = warmup_steps(sc.N)
    t = (np.asarray(res.step_times) + np.asarray(res.hull_times))[w:]
    cost = float(np.median(t) * 1e3)
    tol = float(getattr(sc, "tolerance", 0.0) or 0.0)
    cols = floor_columns(floor, observer_floor(base), res.lo, res.hi, True, tol)
    viol = int((((res.lo > sc.x_true + tol) | (sc.x_true > res.hi + tol)).any(axis=1)).sum()
               ) if sc.x_true is not None else np.nan
    row.update(gap=float(np.mean(cols["gap"])), gap_steady=float(np.mean(cols["gap_steady"])),
               gap_kind=cols["gap_kind"], cost_ms=cost, cost_ratio=cost / kalman_ms,
               memory=memory_columns(res.doubles)["memory"],
               covers_exact=cols["covers_exact"], violations=viol)
    return row


def pareto(g: pd.DataFrame) -> pd.Series:
    """Whether each row is on the Pareto front of its record: sound and run, and no other
    such row at most as costly and at most as wide with one of them strictly smaller."""
    ok = (g["status"] == "ok") & (g["covers_exact"] != "no") & (g["violations"].fillna(0) == 0)
    ok &= np.isfinite(g["gap"]) & np.isfinite(g["cost_ratio"])
    c, q = g["cost_ratio"].to_numpy(float), g["gap"].to_numpy(float)
    front = np.zeros(len(g), bool)
    idx = np.flatnonzero(ok.to_numpy())
    for i in idx:
        j = idx[idx != i]
        beaten = (c[j] <= c[i]) & (q[j] <= q[i]) & ((c[j] < c[i]) | (q[j] < q[i]))
        front[i] = not beaten.any()
    return pd.Series(front, index=g.index)


def run_study(records: dict[str, int | None] | None = None, budget: float = BUDGET_S,
              settings: dict | None = None, log: Callable[[str], None] = lambda m: None
              ) -> pd.DataFrame:
    """Every setting on every record within ``budget`` seconds (see the module docstring)."""
    records = RECORDS if records is None else records
    settings = SETTINGS if settings is None else settings
    t0 = time.perf_counter()
    rows = []
    for record, steps in records.items():
        sc = systems_scenario(record)
        sc = first_steps(sc, steps) if steps else sc
        todo = [(n, k, v) for n, k, vals in settings.get(record, []) for v in vals]
        if time.perf_counter() - t0 > budget:
            rows += [{"record": record, "steps": sc.N, "observer": n, "knob": k,
                      "value": str(v), "status": "not run", "message": "budget"}
                     for n, k, v in todo]
            continue
        log(f"{record}: floor ({sc.N} steps)")
        floor = compute_floor(sc)
        kal = kalman_step_times(sc.system, sc.u, sc.y)[warmup_steps(sc.N):]
        kalman_ms = float(np.median(kal) * 1e3)
        for n, k, v in todo:
            if time.perf_counter() - t0 > budget:
                row = {"observer": n, "knob": k, "value": str(v), "status": "not run",
                       "message": "budget"}
            elif not floor.usable:
                row = {"observer": n, "knob": k, "value": str(v), "status": "not run",
                       "message": f"no floor: {floor.message}"}
            else:
                log(f"{record}: {n} {k}={v}")
                row = run_setting(sc, floor, kalman_ms, n, k, v)
            rows.append({"record": record, "steps": sc.N, **row})
    df = pd.DataFrame(rows, columns=COLUMNS[:-1])
    df["pareto"] = False
    for _, g in df.groupby("record", sort=False):
        df.loc[g.index, "pareto"] = pareto(g)
    return df


def systems_scenario(name: str):
    """The shipped scenario ``name`` (imported here: ``systems`` is only needed to run)."""
    import systems

    return systems.scenario(name)


def _label(r) -> str:
    return f"{r.observer} {r.knob}={r.value}"


def _gap(r, value: float) -> str:
    """A gap as printed: ``<= x`` where the floor is the falsifier's inner box (an upper
    bound of the gap), else the gap itself."""
    text = fmt(value, 3)
    return f"<= {text}" if getattr(r, "gap_kind", "") == GAP_UPPER and text != MISSING \
        else text


def front_sentence(g: pd.DataFrame) -> str:
    """One sentence naming the Pareto front of a record, cheapest first."""
    f = g[g["pareto"]].sort_values("cost_ratio")
    if not len(f):
        return "No setting ran soundly: no Pareto front."
    parts = [f"{_label(r)} (gap {_gap(r, r.gap)} at {fmt(r.cost_ratio, 3)}x Kalman)"
             for r in f.itertuples(index=False)]
    return "Pareto front, cheapest first: " + "; ".join(parts) + "."


def report(df: pd.DataFrame, fig: Path, out: Path, *, budget: float, elapsed: float,
           fig_memory: Path | None = None) -> str:
    """The Markdown report; it ends with what to cite (:mod:`benchmarks.report.citation`)."""
    env = environment()
    parts = [
        "# Frontier study: accuracy against cost of the complexity knobs", "",
        "Each observer setting on each record: **gap** = mean over the states of the RMS "
        "radius over the exact floor's (1 is optimal: no guaranteed observer can be tighter; "
        "on a nonlinear record, `<=`: an upper bound, over the falsifier's verified inner box), "
        "**cost** = median per-step time of `step()` plus the interval hull, in ms and as a "
        "ratio to a plain Kalman step on the same record (the extended Kalman filter's on a "
        "nonlinear record; timed in the same process). The "
        "**Pareto front** (`*`) are the sound settings that no other setting beats on both "
        "axes. Settings run one at a time, cheap ones first, within a budget of "
        f"{budget:g} s ({elapsed / 60:.1f} min used); timings on a shared 2-core machine are "
        "indicative, the ratios less so. Produced by `python -m benchmarks.studies.frontier` "
        f"(git {env.get('git', '?')}).", "",
        f"![gap against cost]({fig.relative_to(out.parent).as_posix()})", "",
    ]
    if fig_memory is not None:
        parts += ["**Memory**: the floating-point values of the estimated set at steady state "
                  "(median over the steps after the first 20 % of the record); **gap steady**: "
                  "the gap over the same steps.", "",
                  f"![gap against memory]({fig_memory.relative_to(out.parent).as_posix()})",
                  ""]
    head = ["observer", "setting", "gap", "gap steady", "ms / step", "x Kalman", "memory",
            "covers exact", "violations", "Pareto"]
    for record, g in df.groupby("record", sort=False):
        kal = g["kalman_ms"].dropna()
        parts += [f"## {record} ({int(g['steps'].iloc[0])} steps, Kalman step "
                  f"{fmt(kal.iloc[0] if len(kal) else np.nan, 3)} ms)",
                  "", front_sentence(g), ""]
        rows = []
        for r in g.itertuples(index=False):
            if r.status != "ok":
                rows.append([r.observer, f"{r.knob}={r.value}", f"{r.status}: {r.message}",
                             MISSING, MISSING, MISSING, MISSING, MISSING, MISSING, ""])
                continue
            rows.append([r.observer, f"{r.knob}={r.value}", _gap(r, r.gap),
                         _gap(r, getattr(r, "gap_steady", np.nan)), fmt(r.cost_ms, 3),
                         fmt(r.cost_ratio, 3), fmt(getattr(r, "memory", np.nan)),
                         r.covers_exact, fmt(r.violations), "*" if r.pareto else ""])
        parts += markdown_table(head, rows).splitlines() + [""]
    parts += ["---", ", ".join(f"{k} {v}" for k, v in env.items()), "",
              *citation_lines("frontier"), ""]
    return "\n".join(parts)


def main(argv: list[str] | None = None) -> int:
    """Command line of the study."""
    p = argparse.ArgumentParser(prog="python -m benchmarks.studies.frontier",
                                description=__doc__.splitlines()[0])
    p.add_argument("--budget", type=float, default=BUDGET_S, metavar="S",
                   help=f"total seconds (default {BUDGET_S:g})")
    p.add_argument("--records", nargs="+", default=list(RECORDS), choices=list(RECORDS))
    p.add_argument("--out", default="reports/frontier.md", help="Markdown report")
    p.add_argument("--results", default="results/frontier", help="folder of frontier.csv")
    args = p.parse_args(argv)
    if args.budget <= 0:
        print("error: the budget must be positive", file=sys.stderr)
        return 2
    t0 = time.perf_counter()
    df = run_study({r: RECORDS[r] for r in args.records}, args.budget,
                   log=lambda m: print(m, file=sys.stderr))
    elapsed = time.perf_counter() - t0
    atomic_write_csv(Path(args.results) / "frontier.csv", df)
    out = Path(args.out)
    fig = figures.frontier(df, out.parent / out.stem)[0]
    fig_memory = figures.frontier(df, out.parent / f"{out.stem}_memory", x="memory")[0]
    text = report(df, fig, out, budget=args.budget, elapsed=elapsed,
                  fig_memory=fig_memory).rstrip("\n")
    regen = f"python -m benchmarks.studies.frontier --out {out} --results {args.results}"
    atomic_write_text(out, f"{text}\n\n{freshness.measured(regen)}\n")
    print(f"wrote {out}, {fig} and {Path(args.results) / 'frontier.csv'}")
    return 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
