"""The speed report ``reports/speed.md`` (``python -m benchmarks speed``, part of ``make bench``).

Times the cases of the speed table (:data:`CASES`: per-step cost on the 6-state vehicle as a
ratio to a numpy Kalman step, milliseconds per step on 100 and 200 tanks) with
:func:`benchmarks.timing.steps.time_observers` at steady state (the steps from which the set
has reached its order; a row whose steady state lies beyond the steps run says ``growing``),
and writes one Markdown table with

* the measured value and the case's target,
* the ratio of our median step time to the per-step time published with MATLAB + CORA
  (``systems/data/paper_tables``; ``n/a`` where the paper has no time for that system),
* the ratio to the previous measurement, read from the JSON this command wrote last time
  (``reports/speed.json``, committed with the report, so it holds a previous commit's numbers)
  before it is overwritten with the new measurement.

A second section times the exact reference (the accuracy floor) cold on the records and
budgets of :data:`benchmarks.timing.exact_cost.EXACT_CASES`; a third profiles where a
constrained zonotope's step spends its time (:mod:`benchmarks.timing.step_profile`), a fourth
where its interval hull does (:mod:`benchmarks.timing.hull_profile`).

Every time is a median over repeated runs in one process; the ratio to the Kalman step is
measured right after the observer in the same process, so it survives a busy machine better
than the milliseconds do.  Read the table as indicative; no test asserts on it.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..errors import ConfigError
from ..io import atomic_write_json, atomic_write_text, environment
from ..report import freshness
from ..report.citation import citation_lines
from ..report.numbers import MISSING, fmt
from ..report.paper import paper_rows
from ..run.progress import announced
from .exact_cost import EXACT_CASES, ExactCase, measure_exact, render_exact
from .hull_profile import HULL_CASES, HullCase, measure_hulls, render_hulls
from .step_profile import STEP_CASES, StepCase, measure_steps, render_steps
from .steps import TimingPlan, TimingRow, time_observers

DEFAULT_REPORT = Path("reports") / "speed.md"
DEFAULT_JSON = Path("reports") / "speed.json"
#: the published tables of the *paper ms* column (vehicle: Althoff & Rath 2021, Table 3;
#: tanks: ARCH 2021, Tables 5/6), cited at the end of the report
PAPER_TABLES = ("automatica2021_table3_vehicle6", "arch2021_table5_6_tank_scaling")


@dataclass(frozen=True)
class Case:
    """One row group of the speed table.

    Attributes
    ----------
    label : str
        Text of the table's case column.
    scenario : str
        Scenario timed.
    observers : tuple of str
        Observers timed (one table row each).
    metric : str
        ``"ratio"`` (median step / Kalman step), ``"ratio_hull"`` (median step + interval hull
        / Kalman step), ``"ms"`` (median step, ms) or ``"ms_hull"`` (median step + hull, ms).
    target : float
        The value to reach (at most).
    repeat, steps, warmup : int
        Runs over the record, steps of the record run (``0``: all) and steps not timed (at
        least).
    steady : bool
        Time only the steady state (:func:`benchmarks.timing.steps.steady_from`: the steps
        from which the set size stays constant); where the ``steps`` run do not reach it the
        report says so (``growing``).
    fast_forward : int
        If positive: step to the steady state without hulls (untimed), then time this many
        steps with their hulls (:func:`benchmarks.timing.steps.time_observer_fast_forward`;
        for the large constrained zonotopes, whose way to the steady state would cost
        minutes of hulls).
    hulls : bool
        With ``fast_forward``: time the hulls of the timed steps too (else ``step()`` alone).
    options : tuple of (str, value) pairs
        Options of the observers timed, over the scenario's defaults (e.g. MHE's window).
    """

    label: str
    scenario: str
    observers: tuple[str, ...]
    metric: str
    target: float
    repeat: int = 3
    steps: int = 0
    warmup: int = 5
    steady: bool = True
    fast_forward: int = 0
    hulls: bool = True
    options: tuple[tuple[str, Any], ...] = ()


VEHICLE = "vehicle6d-cora"
CASES: tuple[Case, ...] = (
    Case("FRad-A, vehicle-6, step / Kalman step", VEHICLE, ("FRad-A",), "ratio", 3.0),
    Case("FRad-B, FRad-C, PRad-*, Nom-G, vehicle-6, step / Kalman step", VEHICLE,
         ("FRad-B", "FRad-C", "PRad-A", "PRad-B", "PRad-C-I", "PRad-C-II", "PRad-D", "Nom-G"),
         "ratio", 3.0),
    Case("VolMin-B, vehicle-6, step / Kalman step", VEHICLE, ("VolMin-B",), "ratio", 4.0),
    Case("CZN-A, vehicle-6, (step + interval hull) / Kalman step", VEHICLE, ("CZN-A",),
         "ratio_hull", 20.0),
    # the moving-horizon estimator over a window of 5 steps (one unreduced constrained
    # zonotope; its gaps to the exact set are in reports/frontier.md: 1.14 and 1.03)
    Case("MHE (window 5), tank-6, (step + interval hull) / Kalman step", "tank6-linear",
         ("MHE",), "ratio_hull", 10.0, options=(("window", 5),)),
    Case("MHE (window 5), vehicle-6, (step + interval hull) / Kalman step", VEHICLE,
         ("MHE",), "ratio_hull", 10.0, options=(("window", 5),)),
    # the zonotopes of the tank systems reach their order (100 n generators) at step ~100
    Case("FRad-A, 100 tanks, ms per step", "tank100-linear", ("FRad-A",), "ms",
         50.0, repeat=1, steps=115, warmup=1),
    # the CZN observers reach their steady state at step ~60 (10240 generators, 160
    # constraints at 100 tanks; a hull there: 2n = 200 LPs over 10240 columns, ~40 s):
    # stepped there without hulls, then one step timed with its hull
    Case("CZN-A/B, 100 tanks, step + hull, ms", "tank100-linear",
         ("CZN-A", "CZN-B"), "ms_hull", 500.0, fast_forward=1),
    Case("zonotope observers, 200 tanks, ms per step", "tank200-linear",
         ("FRad-A",), "ms", 500.0, repeat=1, steps=110, warmup=1),
    # 200 tanks: 20489 generators, 326 constraints from step ~60; a hull ~45 s there
    Case("CZN-A/B, 200 tanks, step + hull, ms", "tank200-linear",
         ("CZN-A", "CZN-B"), "ms_hull", 2000.0, fast_forward=1),
    Case("VolMin-B, 60 tanks, ms per step", "tank60-linear", ("VolMin-B",), "ms", 500.0,
         repeat=1, steps=110, warmup=1),
    # order 100: 20000 generators from step ~100, 160 strips per step scored from leverages
    # (O(n r) each; the Gram scores' n^2 r took seconds per step from 100 tanks on)
    Case("VolMin-B, 200 tanks, ms per step", "tank200-linear", ("VolMin-B",), "ms", 500.0,
         repeat=1, steps=110, warmup=1),
    # a parallelotope (n x n) from the first step; its generator-axes search shortlisted by
    # the compiled exchange scores (observers/kernels/exchange.py)
    Case("ROPO, 200 tanks, ms per step", "tank200-linear", ("ROPO",), "ms", 500.0,
         repeat=1, steps=30, warmup=2),
)
#: rows of the issue's table this command does not measure, with the reason
NOT_MEASURED = (
    ("scaling study, largest n reached (CZN-A/B/MV/FO/DC/PR, ZB-A)", "200 for all",
     "measured by `make scaling`: reports/scaling.md, column *largest n* of its first table; "
     "its notes name the step that stops each observer and what that step cost, `step()` "
     "and interval hull apart"),
    ("`make bench-cold` (every row from an empty design and floor cache)", "<= 20 min",
     "not measured by this command: README.md and docs/guide/start.rst give its time on this "
     "machine, end to end, with its parts"),
)
_UNIT = {"ratio": "x", "ratio_hull": "x", "ms": " ms", "ms_hull": " ms"}


def metric_value(row: TimingRow, metric: str) -> float:
    """The value of ``metric`` (see :class:`Case`) in a timing row (NaN if not ok)."""
    if row.status != "ok":
        return math.nan
    if metric == "ratio":
        return row.ratio
    if metric == "ratio_hull":
        k = row.kalman_ms_median
        return row.step_hull_ms_median / k if k > 0 else math.nan
    if metric == "ms":
        return row.step_ms_median
    if metric == "ms_hull":
        return row.step_hull_ms_median
    raise ConfigError(f"unknown speed metric '{metric}'")


def measure(cases: tuple[Case, ...] = CASES, progress: bool = True) -> list[dict[str, Any]]:
    """Time every case; one dict per (case, observer) with the row and the metric value."""
    out = []
    for case in announced(cases, progress,
                          lambda c: f"timing {', '.join(c.observers)} on {c.scenario}"):
        plan = TimingPlan(case.repeat, case.warmup, case.steps or None, case.steady,
                          case.fast_forward, case.hulls)
        sc, warmup, rows = time_observers(list(case.observers), case.scenario, plan,
                                          own=dict(case.options))
        paper = paper_rows(sc.paper_table, sc.system.A.shape[0])
        for row in rows:
            p = paper.get(row.observer)
            paper_ms = p.t_ms if p is not None and p.t_ms else math.nan
            out.append({
                "case": case.label, "observer": row.observer, "metric": case.metric,
                "value": metric_value(row, case.metric), "target": case.target,
                "status": row.status, "message": row.message,
                "step_ms": row.step_ms_median, "hull_ms": row.hull_ms_median,
                "kalman_ms": row.kalman_ms_median, "paper_ms": paper_ms,
                "steps_timed": row.timed_steps, "first_timed": row.first_timed,
                "last_timed": (row.first_timed + row.timed_steps - 1 if case.fast_forward
                               else sc.N), "steady": row.steady,
            })
    return out


def timed_steps(r: dict[str, Any]) -> str:
    """The ``timed steps`` cell: the range of 1-based steps and whether it is steady."""
    if r["status"] != "ok" or not r.get("first_timed"):
        return MISSING
    span = f"{r['first_timed']}-{r['last_timed']}"
    steady = r.get("steady")
    return span if steady is None else f"{span} ({'steady' if steady else 'growing'})"


def load_previous(path: str | Path) -> tuple[dict[tuple[str, str], float], str]:
    """Metric values of the previous measurement by (case, observer), and its git commit
    (``({}, "")`` if there is no readable previous file)."""
    try:
        with open(path) as fh:
            data = json.load(fh)
        values = {(r["case"], r["observer"]): (math.nan if r["value"] is None else r["value"])
                  for r in data["results"]}
        return values, str(data.get("environment", {}).get("git", ""))
    except (OSError, ValueError, KeyError, TypeError):
        return {}, ""


def render(results: list[dict[str, Any]], previous: dict[tuple[str, str], float],
           previous_git: str, env: dict[str, str]) -> str:
    """The Markdown of ``reports/speed.md``."""
    lines = [
        "# Speed",
        "",
        "Written by `python -m benchmarks speed` (part of `make bench`) at commit "
        f"`{env.get('git', '')}`; Python {env.get('python', '')}, numpy "
        f"{env.get('numpy', '')}, {env.get('platform', '')}, single-threaded BLAS.",
        "Times are medians over the timed steps of repeated runs; *step / Kalman step* divides "
        "the observer's median step by the median step of a plain numpy Kalman filter "
        "(predict + update) timed right after it in the same process (see "
        "`benchmarks/timing/steps.py`). The machine is shared: read the milliseconds as "
        "indicative.",
        "",
        "*paper ms*: per-step time published with MATLAB + CORA (vehicle: Althoff & Rath, "
        "Automatica 2021, Table 3, i7-8565U; tanks: ARCH 2021 Tables 5/6, up to 30 tanks only); "
        "*ours / paper* = our median step (without hull) / paper ms. "
        f"*previous*: the value of `reports/speed.json` before this run (commit "
        f"`{previous_git or 'none'}`).",
        "",
        "*timed steps*: the steps of the record whose times enter the medians; *steady*: the "
        "set size (generators, constraints) is constant over them, the observer's cost in "
        "operation; *growing*: the set has not reached its order by the last step run, so the "
        "row times its start (cheaper).",
        "",
        "| case | observer | now | target | met | step ms | hull ms | paper ms | ours / paper "
        "| previous | now / previous | timed steps |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in results:
        unit = _UNIT[r["metric"]]
        v = r["value"]
        met = "n/a" if not math.isfinite(v) else ("yes" if v <= r["target"] else "no")
        now = fmt(v, 3, unit) if r["status"] == "ok" else r["status"]
        prev = previous.get((r["case"], r["observer"]), math.nan)
        ratio_paper = r["step_ms"] / r["paper_ms"] if math.isfinite(r["paper_ms"]) else math.nan
        ratio_prev = v / prev if math.isfinite(prev) and prev > 0 else math.nan
        lines.append(
            f"| {r['case']} | {r['observer']} | {now} | <= {fmt(r['target'], 3, unit)} | {met} | "
            f"{fmt(r['step_ms'], 3)} | {fmt(r['hull_ms'], 3)} | {fmt(r['paper_ms'], 3)} | "
            f"{fmt(ratio_paper, 3)} | {fmt(prev, 3, unit)} | {fmt(ratio_prev, 3)} | "
            f"{timed_steps(r)} |")
    for label, target, _why in NOT_MEASURED:
        lines.append(f"| {label} | | not measured | {target} | n/a | | | | | | | |")
    lines += ["", "Not measured by this command:", ""]
    lines += [f"- {label}: {why}." for label, _, why in NOT_MEASURED]
    failed = [r for r in results if r["status"] != "ok"]
    if failed:
        lines += ["", "Failures:", ""]
        lines += [f"- {r['observer']} ({r['case']}): {r['status']}: {r['message']}"
                  for r in failed]
    return "\n".join(lines) + "\n"


def write_speed_report(out: str | Path = DEFAULT_REPORT, json_path: str | Path = DEFAULT_JSON,
                       cases: tuple[Case, ...] = CASES, progress: bool = True,
                       exact_cases: tuple[ExactCase, ...] = EXACT_CASES,
                       hull_cases: tuple[HullCase, ...] = HULL_CASES,
                       step_cases: tuple[StepCase, ...] = STEP_CASES) -> Path:
    """Measure :data:`CASES` and the cold cost of the exact reference
    (:mod:`benchmarks.timing.exact_cost`), compare with ``json_path`` (the previous
    measurement), write the Markdown report ``out`` (ending with what to cite,
    :mod:`benchmarks.report.citation`, and stamped with the commit and machine it measured,
    :func:`benchmarks.report.freshness.measured`) and overwrite ``json_path`` with this
    measurement."""
    previous, previous_git = load_previous(json_path)
    results = measure(cases, progress)
    exact = measure_exact(exact_cases, progress)
    hulls = measure_hulls(hull_cases, progress)
    step_parts = measure_steps(step_cases, progress)
    env = environment()
    command = "python -m benchmarks speed"
    if Path(out) != DEFAULT_REPORT or Path(json_path) != DEFAULT_JSON:
        command += f" --out {out} --json {json_path}"
    text = render(results, previous, previous_git, env)
    if exact:
        text += "\n" + "\n".join(render_exact(exact)) + "\n"
    if step_parts:
        text += "\n" + "\n".join(render_steps(step_parts)) + "\n"
    if hulls:
        text += "\n" + "\n".join(render_hulls(hulls)) + "\n"
    text += "\n" + "\n".join(citation_lines("speed", PAPER_TABLES)) + "\n"
    text += "\n" + freshness.measured(command) + "\n"
    atomic_write_text(out, text)
    clean = [{k: (None if isinstance(v, float) and not math.isfinite(v) else v)
              for k, v in r.items()} for r in results]
    atomic_write_json(json_path, {"environment": env, "results": clean, "exact": exact,
                                  "hulls": hulls, "steps": step_parts})
    return Path(out)
