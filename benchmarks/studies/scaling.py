"""Scaling study: how the observers' costs and accuracy grow with the number of states.

``python -m benchmarks.studies.scaling`` (run by ``make bench``) runs every observer of the
harness (all but the stochastic and data-driven families) on the linear and the nonlinear
n-tank system (``tank<n>-linear``, ``tank<n>-nonlinear``) for n in :data:`SIZES` and writes
``reports/scaling.md``, a log-log figure beside it and the tidy table
``results/scaling/scaling.csv``:

* per-step time of ``step()``, interval-hull time, offline design time and relative RMS
  radius (mean over the states of eq. 9, against the best observer at the same n) per
  observer and size;
* a fitted cost exponent per observer: the slope ``p`` of ``log(step + hull) = a + p log n``
  (least squares over the sizes it ran at, at least 3);
* the budget: each offline design runs in a worker process with a budget of ``--design-budget``
  seconds and each run of ``--steps`` steps with ``--run-budget`` seconds; one over it is
  stopped (its worker ended) and reported ``timeout``, a run as soon as the steps it ran
  project it over the budget (:func:`observers.run`: the time spent plus the steps left at
  the cost of the last steps; the message names the step and the projection), so that a run
  that cannot finish does not use up its whole budget; larger sizes of that observer are then
  not attempted (``not run``, with the reason).  A scenario that does not exist (yet) is
  listed as ``not run: scenario not available``.

Jobs run one at a time (honest single-threaded timing, see :mod:`benchmarks`); the offline
designs come from the design cache when present (the design time is then that of the cache
read, marked ``cached``).  The real-time limit is the sampling time of the tank model
(:data:`REALTIME_MS`).
"""

from __future__ import annotations

import argparse
import functools
import json
import sys
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
import pandas as pd

import observers
from observers import offline
from observers.base import BUDGET_WINDOW
from observers.registry import table_order
from systems import ModelError

from ..io import (
    atomic_write_csv,
    atomic_write_json,
    atomic_write_text,
    environment,
)
from ..metrics import add_relative_rms, warmup_steps
from ..report import figures, freshness
from ..report.citation import citation_lines
from ..report.numbers import MISSING, fmt, markdown_table
from ..run.executors import JobFailure, ProcessExecutor
from ..run.rows import Job, design_observer, execute_job
from ..run.specs import build_scenario

SIZES = (6, 12, 30, 60, 100, 200)
VARIANTS = ("linear", "nonlinear")
REALTIME_MS = 500.0  # sampling time of the tank model
DESIGN_BUDGET_S = 60.0
RUN_BUDGET_S = 30.0
STEPS = 40
#: design times below this are no offline design (nothing to fit an exponent to)
MIN_DESIGN_S = 1e-2
COLUMNS = ["variant", "n", "observer", "set_type", "status", "message", "design_s",
           "design_cached", "step_ms", "hull_ms", "total_ms", "rel_rms", "violations"]


def default_observers() -> list[str]:
    """Every registered observer except the stochastic, data-driven, reference and
    moving-horizon families (the exact reference is timed in reports/speed.md, the
    moving-horizon estimators in the frontier study, reports/frontier.md)."""
    return [i.name for i in observers.available()
            if i.family not in ("stochastic", "data-driven", "reference", "moving-horizon")]


def design_only(job: Job) -> dict:
    """The offline design of ``job`` alone (in a worker): status, message, seconds, and
    whether it was read from the design cache."""
    sc, options = job.inputs()
    observers.available()  # the plugin imports are not part of a design's time
    loads = sum(offline.CACHE_LOADS.values())
    t0 = time.perf_counter()
    obs, status, message = design_observer(job.observer, sc, options)
    seconds = time.perf_counter() - t0
    return {"status": status, "message": message, "design_s": seconds,
            "design_cached": sum(offline.CACHE_LOADS.values()) > loads}


def _job(variant: str, n: int, name: str, steps: int) -> Job:
    spec = {"name": f"tank{n}-{variant}", "steps": steps}
    return Job(spec=spec, base=None, observer=name, module=observers.get(name).cls.__module__,
               options={}, observer_options={}, containment="hull", seed=None, variant="")


def _row(variant, n, name, status, message="", **values) -> dict:
    row = dict.fromkeys(COLUMNS, np.nan)
    row.update(variant=variant, n=n, observer=name, set_type=observers.get(name).set_type,
               status=status, message=message, design_cached=False, violations=np.nan)
    row.update(values)
    return row


def run_study(sizes=SIZES, names=None, variants=VARIANTS, steps: int = STEPS,
              design_budget: float = DESIGN_BUDGET_S, run_budget: float = RUN_BUDGET_S,
              log=print) -> pd.DataFrame:
    """Run the study; one row per variant, size and observer (see :data:`COLUMNS`)."""
    names = names or default_observers()
    design_ex = ProcessExecutor(1, timeout=design_budget)
    run_ex = ProcessExecutor(1, timeout=run_budget)
    rows = []
    try:
        for variant in variants:
            available = {}
            for n in sizes:
                try:
                    build_scenario({"name": f"tank{n}-{variant}", "steps": steps}, None)
                    available[n] = True
                except Exception as exc:  # noqa: BLE001 - any failure: not available
                    available[n] = f"{type(exc).__name__}: {exc}"
            for name in names:
                stopped = ""
                for n in sizes:
                    if available[n] is not True:
                        rows.append(_row(variant, n, name, "not run",
                                         f"scenario not available ({available[n]})"))
                        continue
                    if stopped:
                        rows.append(_row(variant, n, name, "not run", stopped))
                        continue
                    rows.append(_one(variant, n, name, steps, design_ex, run_ex))
                    r = rows[-1]
                    log(f"{variant} n={n} {name}: {r['status']} "
                        f"(design {r['design_s']:.3g} s, step {r['total_ms']:.3g} ms)")
                    if r["status"] == "timeout":
                        stopped = f"not attempted: timeout at n={n}"
    finally:
        design_ex.close()
        run_ex.close()
    return relative(pd.DataFrame(rows))


def _one(variant, n, name, steps, design_ex, run_ex) -> dict:
    job = _job(variant, n, name, steps)
    (_, d), = design_ex.map(design_only, [job])
    if isinstance(d, JobFailure):
        what = "design " if d.status == "timeout" else ""
        return _row(variant, n, name, d.status, what + d.message)
    if d["status"] != "ok":
        return _row(variant, n, name, d["status"], d["message"], design_s=d["design_s"])
    (_, out), = run_ex.map(functools.partial(execute_job, budget=run_ex.timeout), [job])
    design = {"design_s": d["design_s"], "design_cached": d["design_cached"]}
    if isinstance(out, JobFailure):
        what = f"run of {steps} steps " if out.status == "timeout" else ""
        return _row(variant, n, name, out.status, what + out.message, **design)
    s = out[1]
    first = s.iloc[0]
    return _row(variant, n, name, first["status"], first["message"] or "", **design,
                step_ms=first["step_ms"], hull_ms=first["hull_ms"],
                total_ms=first["step_ms"] + first["hull_ms"],
                violations=first["violations"], _rms=s["rms_radius"].to_numpy(float),
                guaranteed=bool(first["guaranteed"]))


def relative(df: pd.DataFrame) -> pd.DataFrame:
    """``rel_rms``: per run, the mean over the states of its RMS radius divided by the
    smallest among the successful guaranteed observers of the same variant and size."""
    if "_rms" not in df.columns:
        return df[COLUMNS]
    per_state = []
    for r in df.to_dict("records"):
        rms = r["_rms"]
        if isinstance(rms, np.ndarray):
            per_state.append(pd.DataFrame({
                "scenario": f"{r['variant']}/{r['n']}", "observer": r["observer"],
                "state": np.arange(rms.size), "rms_radius": rms, "status": r["status"],
                "guaranteed": bool(r["guaranteed"])}))
    out = df.drop(columns=[c for c in ("_rms", "guaranteed") if c in df.columns])
    if per_state:
        rel = add_relative_rms(pd.concat(per_state, ignore_index=True))
        mean = rel.groupby(["scenario", "observer"])["rel_rms"].mean()
        key = out["variant"] + "/" + out["n"].astype(str)
        out["rel_rms"] = [mean.get((k, o), np.nan) for k, o in zip(key, out["observer"],
                                                                     strict=True)]
    return out[COLUMNS]


def exponents(df: pd.DataFrame) -> pd.DataFrame:
    """Fitted cost exponents per variant and observer: slope of log(step + hull time) and of
    log(design time, computed not cached) against log n (NaN below 3 sizes)."""
    rows = []
    for (variant, name), g in df.groupby(["variant", "observer"], sort=False):
        row = {"variant": variant, "observer": name}
        ok = g[(g["status"] == "ok") & (g["total_ms"] > 0)]
        row["step_exponent"] = _slope(ok["n"], ok["total_ms"])
        d = g[(g["status"] == "ok") & ~g["design_cached"].astype(bool)
              & (g["design_s"] >= MIN_DESIGN_S)]
        row["design_exponent"] = _slope(d["n"], d["design_s"])
        row["largest_n"] = int(ok["n"].max()) if len(ok) else np.nan
        fast = ok[ok["total_ms"] <= REALTIME_MS]
        row["largest_realtime_n"] = int(fast["n"].max()) if len(fast) else np.nan
        rows.append(row)
    return pd.DataFrame(rows)


def _slope(n, t) -> float:
    n, t = np.asarray(n, float), np.asarray(t, float)
    if n.size < 3:
        return float("nan")
    return float(np.polyfit(np.log(n), np.log(t), 1)[0])


def _result_cell(r, value: str) -> str:
    if r.status == "ok":
        return value + ("" if not r.violations or pd.isna(r.violations)
                        else f" (**{int(r.violations)} violations**)")
    return {"timeout": "timeout", "not run": "not run"}.get(r.status, r.status)


def _split(r) -> bool:
    """Whether row ``r`` has a measured ``step()`` and hull time (a run stopped by its
    budget has them for the steps it ran; a run stopped from outside has none)."""
    return bool(np.isfinite(r.step_ms) and np.isfinite(r.hull_ms))


def stop_cost(r, steps: int = STEPS) -> str:
    """What a run of ``steps`` steps stopped by its budget spent per step (medians over the
    steps it ran after the warm-up), and which of ``step()`` and the interval hull is the
    larger part; where it stopped within the warm-up, that it could not be split ("" for
    other statuses)."""
    if r.status != "timeout":
        return ""
    if not _split(r):  # stopped by its projection within the warm-up steps, or from outside
        return ("; `step()` and interval hull not timed apart: it stopped within the first "
                f"{warmup_steps(steps)} steps, which the medians leave out"
                if str(r.message).startswith("stopped after step") else "")
    larger = "the interval hull" if r.hull_ms > r.step_ms else "`step()`"
    return (f"; per step over the steps run: `step()` {fmt(r.step_ms, 3)} ms + interval hull "
            f"{fmt(r.hull_ms, 3)} ms (medians), most of it {larger}")


def _size_table(df: pd.DataFrame, variant: str, sizes, what: str) -> list[str]:
    """Markdown lines: one row per observer, one column per size, of ``what`` (time, design or
    rms)."""
    head = ["Observer"] + [f"n={n}" for n in sizes]
    rows = []
    g = df[df["variant"] == variant]
    for name in table_order(g["observer"].unique()):
        cells = [name]
        for n in sizes:
            r = g[(g["observer"] == name) & (g["n"] == n)]
            if not len(r):
                cells.append(MISSING)
                continue
            r = next(r.itertuples(index=False))
            if what == "time":
                value = f"{fmt(r.step_ms, 3)} + {fmt(r.hull_ms, 3)}"
                if r.status == "timeout" and _split(r):  # the steps it ran, before it stopped
                    cells.append(f"timeout ({value})")
                    continue
            elif what == "design":
                value = fmt(r.design_s, 3) + (" (cached)" if r.design_cached else "")
            else:
                value = fmt(r.rel_rms, 3)
            cells.append(_result_cell(r, value))
        rows.append(cells)
    return markdown_table(head, rows).splitlines()


def failures(g: pd.DataFrame, steps: int = STEPS) -> list[str]:
    """Markdown list: per observer, each status other than ok with its sizes and the message
    (of the smallest size; for a run of ``steps`` steps stopped by its budget, what its steps
    cost, :func:`stop_cost`)."""
    bad = g[g["status"] != "ok"]
    if not len(bad):
        return []
    out = ["What did not run, and why:", ""]
    for name in table_order(bad["observer"].unique()):
        h = bad[bad["observer"] == name]
        for status, k in h.groupby("status", sort=False):
            sizes = ", ".join(str(n) for n in k["n"])
            first = next(k.itertuples(index=False))
            out.append(f"- {name}, {status} at n = {sizes}: {first.message}"
                       + stop_cost(first, steps))
    return out + [""]


@dataclass(frozen=True)
class StudyRun:
    """How the study ran (``scaling.json`` beside ``scaling.csv``): the sizes n, the simulated
    steps, the design and run budgets (seconds) and the wall time of the whole study."""

    sizes: list
    steps: int
    design_budget: float
    run_budget: float
    elapsed: float


def report(df: pd.DataFrame, fig: Path, out: Path, run: StudyRun) -> str:
    """The Markdown report of the study that ran as ``run``; it ends with what to cite
    (:mod:`benchmarks.report.citation`)."""
    sizes, steps, elapsed = run.sizes, run.steps, run.elapsed
    design_budget, run_budget = run.design_budget, run.run_budget
    env = environment()
    exp = exponents(df)
    parts = [
        "# Scaling study: linear and nonlinear n-tank, n = " + ", ".join(map(str, sizes)), "",
        f"Every observer (all but the stochastic and data-driven ones) on `tank<n>-linear` and "
        f"`tank<n>-nonlinear` ({steps} simulated steps, seed 0), one job at a time "
        "(single-threaded BLAS). Budget: offline design "
        f"{design_budget:g} s, run {run_budget:g} s ({steps} steps, i.e. "
        f"{1e3 * run_budget / steps:.0f} ms per step including the interval hull and the "
        "containment check); a design or run over it is stopped and marked `timeout`, a run "
        "as soon as the steps it ran project it over the budget (the time spent plus the steps "
        f"left at the median cost of its last {BUDGET_WINDOW} steps; its message below names "
        "the step), and the larger sizes of that observer are then `not run`. Real-time "
        f"limit: the sampling time, {REALTIME_MS:g} ms per step. Produced by "
        "`python -m benchmarks.studies.scaling` "
        f"in {elapsed / 60:.0f} min (git {env.get('git', '?')}); timings on a shared 2-core "
        "machine are indicative.", "",
        f"![step time against n]({fig.relative_to(out.parent).as_posix()})", "",
        "## Fitted cost exponents", "",
        "Slope p of log(step + hull time) against log n (time ~ n^p) over the sizes each "
        "observer ran at (at least 3), of the offline design time likewise (computed designs "
        f"of at least {MIN_DESIGN_S:g} s only, not cache reads), the largest n that ran and "
        "the largest within the real-time limit.", "",
        "| Observer | variant | p (step) | p (design) | largest n | largest n in real time |",
        "|---|---|---|---|---|---|",
    ]
    for variant in df["variant"].unique():
        e = exp[exp["variant"] == variant]
        for name in table_order(e["observer"].unique()):
            r = next(e[e["observer"] == name].itertuples(index=False))
            if pd.isna(r.largest_n):
                continue  # never ran: see the tables below
            parts.append(f"| {name} | {variant} | {fmt(r.step_exponent, 3)} | "
                         f"{fmt(r.design_exponent, 3)} | {fmt(r.largest_n, 3)} | "
                         f"{fmt(r.largest_realtime_n, 3)} |")
    parts.append("")
    for variant in df["variant"].unique():
        g = df[df["variant"] == variant]
        if len(g) and (g["status"] == g["status"].iloc[0]).all() and g["status"].iloc[0] != "ok":
            r = g.iloc[0]
            parts += [f"## {variant} n-tank", "", f"No observer ran: every one is "
                      f"`{r['status']}` at every size, e.g. {r['observer']}: {r['message']}", ""]
            continue
        parts += [f"## {variant} n-tank", "", "Per-step time, `step()` + interval hull (ms, "
                  "medians; after `timeout`, over the steps the run did before it stopped):",
                  ""] + _size_table(df, variant, sizes, "time") + [
            "", "Offline design time (s):", ""] + _size_table(df, variant, sizes, "design") + [
            "", "Relative RMS radius (mean over the states, against the best observer at the "
            "same n):", ""] + _size_table(df, variant, sizes, "rms") + [""]
        parts += failures(g, steps)
    parts += ["---", ", ".join(f"{k} {v}" for k, v in env.items()), "",
              *citation_lines("scaling"), ""]
    return "\n".join(parts)


def main(argv: list[str] | None = None) -> int:
    """Command line of the study."""
    p = argparse.ArgumentParser(prog="python -m benchmarks.studies.scaling",
                                description=__doc__.splitlines()[0])
    p.add_argument("--sizes", type=int, nargs="+", default=list(SIZES))
    p.add_argument("--observers", nargs="+", help="observer names (default: see the docstring)")
    p.add_argument("--variants", nargs="+", default=list(VARIANTS), choices=VARIANTS)
    p.add_argument("--steps", type=int, default=STEPS)
    p.add_argument("--design-budget", type=float, default=DESIGN_BUDGET_S, metavar="S")
    p.add_argument("--run-budget", type=float, default=RUN_BUDGET_S, metavar="S")
    p.add_argument("--out", default="reports/scaling.md", help="Markdown report")
    p.add_argument("--results", default="results/scaling", help="folder of scaling.csv")
    p.add_argument("--report-only", action="store_true",
                   help="rewrite the report and figure from the results of an earlier run")
    args = p.parse_args(argv)
    if min(args.sizes) < 2 or args.steps < 2 or args.design_budget <= 0 or args.run_budget <= 0:
        print("error: sizes must be >= 2, steps >= 2 and the budgets positive", file=sys.stderr)
        return 2
    try:
        names = [observers.get(n).name for n in args.observers] if args.observers else None
    except (observers.UnknownObserver, ModelError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    results = Path(args.results)
    if args.report_only:  # rewrite the report from an earlier run's table
        try:
            df = pd.read_csv(results / "scaling.csv", keep_default_na=False,
                             na_values=[""]).fillna({"message": ""})
            run = StudyRun(**json.loads((results / "scaling.json").read_text()))
        except (OSError, ValueError, TypeError) as exc:
            print(f"error: no earlier study in {results}: {exc}", file=sys.stderr)
            return 2
    else:
        t0 = time.perf_counter()
        df = run_study(args.sizes, names, args.variants, args.steps, args.design_budget,
                       args.run_budget, log=lambda m: print(m, file=sys.stderr))
        run = StudyRun(args.sizes, args.steps, args.design_budget, args.run_budget,
                       time.perf_counter() - t0)
        atomic_write_csv(results / "scaling.csv", df)
        atomic_write_json(results / "scaling.json", asdict(run))
    out = Path(args.out)
    fig, _ = figures.scaling(df, list(df["variant"].unique()), REALTIME_MS,
                             out.parent / out.stem)
    text = report(df, fig, out, run).rstrip("\n")
    regen = f"python -m benchmarks.studies.scaling --out {out} --results results/scaling"
    atomic_write_text(out, f"{text}\n\n{freshness.measured(regen)}\n")
    print(f"wrote {out}, {fig} and {Path(args.results) / 'scaling.csv'}")
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
