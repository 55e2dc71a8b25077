"""The cost of the exact reference (issue 24): the ``Exact`` section of ``reports/speed.md``.

The accuracy floor of every linear table is the exact consistent set of the record, computed
once per record by the reference estimator ``Exact`` (:mod:`observers.builtin.exact`) and
cached, so that a warm ``make bench`` pays nothing for it.  This module measures what a cold
computation costs: for each record of :data:`EXACT_CASES` it runs ``Exact`` with its cache off
over every step (both floors, filtered and predicted) and reports the wall time, the CPU time
of the process, the HiGHS solves and simplex iterations, and the steps whose LPs were not
solved to optimality (their bounds are still sound, from the dual point, but may be loose),
against the budget the issue sets.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Any

import observers
import systems

from ..report.numbers import fmt
from ..run.progress import announced


@dataclass(frozen=True)
class ExactCase:
    """A record whose exact reference is timed and its budget (seconds, wall)."""

    scenario: str
    budget_s: float


#: the records and budgets of the exact-set issue: the 6-tank table's record, CORA's 6-D
#: vehicle record and the 30-tank record of ARCH Table 5, every step
EXACT_CASES: tuple[ExactCase, ...] = (
    ExactCase("tank6-linear", 60.0),
    ExactCase("vehicle6d-cora", 120.0),
    ExactCase("tank30-linear", 900.0),
)


def time_exact(case: ExactCase) -> dict[str, Any]:
    """Run ``Exact`` (no cache) over ``case``'s whole record; wall and CPU seconds, LP work."""
    sc = systems.scenario(case.scenario)
    obs = observers.create("Exact", sc.system, cache=False)
    wall0, cpu0 = time.perf_counter(), time.process_time()
    res = observers.run(obs, sc.u, sc.y, keep_sets=False)
    wall, cpu = time.perf_counter() - wall0, time.process_time() - cpu0
    stats = obs.lp_stats
    return {"scenario": case.scenario, "states": sc.system.n, "steps": sc.N,
            "status": res.status, "message": res.message, "wall_s": wall, "cpu_s": cpu,
            "budget_s": case.budget_s, "solves": stats["solves"],
            "iterations": stats["iterations"], "inexact_steps": stats["inexact_steps"]}


def measure_exact(cases: tuple[ExactCase, ...] = EXACT_CASES,
                  progress: bool = True) -> list[dict[str, Any]]:
    """Time every case of ``cases`` (one dict each, see :func:`time_exact`)."""
    return [time_exact(case) for case in announced(
        cases, progress, lambda c: f"timing the exact reference of {c.scenario}")]


def render_exact(results: list[dict[str, Any]]) -> list[str]:
    """The Markdown lines of the exact-reference section."""
    lines = [
        "## The exact reference (the accuracy floor)",
        "",
        "`Exact` over the whole record, cache off, both floors (filtered and predicted: 4n LPs "
        "per step, warm started from the previous step's basis); *inexact steps*: steps with "
        "an LP HiGHS did not solve to optimality (bounds still sound, possibly loose). A warm "
        "`make bench` reads these hulls from the cache.",
        "",
        "| record | states | steps | wall s | CPU s | budget s | met | ms per step | LP solves "
        "| simplex iterations | inexact steps |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in results:
        ok = r["status"] == "ok"
        met = ("yes" if r["wall_s"] <= r["budget_s"] else "no") if ok else r["status"]
        per = 1e3 * r["wall_s"] / r["steps"] if ok and r["steps"] else math.nan
        inexact = ", ".join(map(str, r["inexact_steps"])) or "none"
        lines.append(
            f"| {r['scenario']} | {r['states']} | {r['steps']} | {fmt(r['wall_s'], 3)} | "
            f"{fmt(r['cpu_s'], 3)} | {fmt(r['budget_s'], 3)} | {met} | {fmt(per, 3)} | "
            f"{r['solves']} | {r['iterations']} | {inexact} |")
    failed = [r for r in results if r["status"] != "ok"]
    if failed:
        lines += [""] + [f"- {r['scenario']}: {r['status']}: {r['message']}" for r in failed]
    return lines
