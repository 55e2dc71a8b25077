"""Where a constrained zonotope's step spends its time (a section of ``reports/speed.md``,
written by ``python -m benchmarks speed``).

For each case of :data:`STEP_CASES` the observer is stepped to its steady state
(:func:`.steps.to_steady_state`, no hulls), then ``steps`` further steps are timed plainly
(the median, in milliseconds) and once more under :mod:`cProfile`, whose inclusive times of
the functions of :data:`PARTS` give each part's share of the step (the parts do not call each
other; *rest* is the remainder: stacking and copying arrays, the observer's own Python).  The
shares come from the profiled steps, the milliseconds from the plain ones (the profiler's
overhead is small against functions of milliseconds, but not nothing).
"""

from __future__ import annotations

import cProfile
import pstats
from dataclasses import dataclass
from time import perf_counter
from typing import Any

import numpy as np

import systems

from ..report.numbers import fmt
from ..run.progress import announced
from ..run.rows import design_observer, merge_options
from .steps import to_steady_state


@dataclass(frozen=True)
class StepCase:
    """``observer`` on ``scenario``: ``steps`` steady steps timed, and profiled."""

    scenario: str
    observer: str
    steps: int = 20


#: the profiled steps: the 6-D vehicle of Althoff & Rath (2021) (the speed table's ratio to a
#: Kalman step) and the steady 100-tank set of the speed table
STEP_CASES: tuple[StepCase, ...] = (
    StepCase("vehicle6d-cora", "CZN-A", steps=100),
    StepCase("tank100-linear", "CZN-A", steps=3),
)

#: the parts of a step: (column, (module file suffix, function name)) -- functions that do
#: not call one another, so that their inclusive times add up
PARTS: tuple[tuple[str, tuple[str, str]], ...] = (
    ("prediction", ("observers/builtin/czn.py", "predict")),
    ("intersection", ("observers/sets/conzono_ops.py", "intersect")),
    ("propagation", ("observers/sets/conzono_ops.py", "implied_bounds")),
    ("regression", ("observers/sets/conzono_ops.py", "regress")),
    ("reduction", ("observers/sets/conzono_ops.py", "lifted_reduce")),
)


def _inclusive(stats: pstats.Stats, where: tuple[str, str]) -> float:
    """Inclusive seconds of the function ``where`` (file suffix, name) in ``stats``."""
    suffix, name = where
    total = 0.0
    for (file, _line, func), (_cc, _nc, _tt, ct, _callers) in stats.stats.items():
        if func == name and file.replace("\\", "/").endswith(suffix):
            total += ct
    return total


def profile_step(case: StepCase) -> dict[str, Any]:
    """The row of ``case``: set size, median ms per step and the share of each part."""
    row: dict[str, Any] = {"scenario": case.scenario, "observer": case.observer}
    sc = systems.scenario(case.scenario)
    obs, status, message = design_observer(case.observer, sc,
                                           merge_options(case.observer, sc))
    if obs is None:
        return dict(row, status=status, message=message)
    try:
        obs.reset()
        k = sum(1 for _ in to_steady_state(obs, sc))
        if k + 2 * case.steps > sc.N:
            return dict(row, status="n/a", message=f"the record ends {sc.N - k} steps after "
                        f"the steady state, {2 * case.steps} are needed")
        times = []
        for j in range(k, k + case.steps):
            t0 = perf_counter()
            S = obs.step(sc.u[j - 1], sc.y[j])
            times.append(perf_counter() - t0)
        prof = cProfile.Profile()
        t0 = perf_counter()
        prof.enable()
        for j in range(k + case.steps, k + 2 * case.steps):
            S = obs.step(sc.u[j - 1], sc.y[j])
        prof.disable()
        profiled = perf_counter() - t0
    except Exception as exc:  # a failure is the row's status, never the report's end
        return dict(row, status="error", message=f"{type(exc).__name__}: {exc}")
    stats = pstats.Stats(prof)
    parts = {label: _inclusive(stats, where) / profiled for label, where in PARTS}
    parts["rest"] = max(0.0, 1.0 - sum(parts.values()))
    _c, G, A, _b = S.arrays()
    return dict(row, status="ok", step=k + 2 * case.steps, n=G.shape[0], p=A.shape[0],
                r=G.shape[1], ms=1e3 * float(np.median(times)), shares=parts)


def measure_steps(cases: tuple[StepCase, ...] = STEP_CASES, progress: bool = True
                  ) -> list[dict[str, Any]]:
    """:func:`profile_step` of every case."""
    return [profile_step(case) for case in announced(
        cases, progress, lambda c: f"profiling the step of {c.observer} on {c.scenario}")]


def render_steps(rows: list[dict[str, Any]]) -> list[str]:
    """The Markdown section of the profile."""
    labels = [label for label, _ in PARTS] + ["rest"]
    lines = [
        "## Where a constrained zonotope's step spends its time",
        "",
        "The observer stepped to its steady state, then its steps (without hulls) timed "
        "(*ms per step*, median) and profiled (the same number of further steps under "
        "cProfile): the share of the step in the prediction, the intersection with the "
        "measurement's strips, the interval constraint propagation of the exact rescaling "
        "(`implied_bounds`, compiled), the least-squares gain of the constraint folding "
        "(`regress`), the order reduction of the lifted zonotope (`lifted_reduce`, its kernel "
        "compiled) and the rest (stacking and copying "
        "arrays, the observer's Python).",
        "",
        "| set | step | n | p | r | ms per step | " + " | ".join(labels) + " |",
        "|---|---|---|---|---|---|" + "---|" * len(labels),
    ]
    for r in rows:
        head = f"| {r['observer']}, {r['scenario']} "
        if r["status"] != "ok":
            lines.append(head + f"| {r['status']}: {r['message']} |" + " |" * (4 + len(labels)))
            continue
        shares = " | ".join(f"{100 * r['shares'][label]:.0f} %" for label in labels)
        lines.append(head + f"| {r['step']} | {r['n']} | {r['p']} | {r['r']} | "
                     f"{fmt(r['ms'], 3)} | {shares} |")
    return lines
