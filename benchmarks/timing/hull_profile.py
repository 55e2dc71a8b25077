"""Where the interval hull of a constrained zonotope spends its time (a section of
``reports/speed.md``, written by ``python -m benchmarks speed``).

The hull of a constrained zonotope ``{c + G xi : A xi = b, |xi| <= 1}`` is 2n LPs with one
feasible set (:class:`observers.sets.HullLP`).  For each case of :data:`HULL_CASES` the
observer is stepped to its steady state without hulls (:func:`.steps.to_steady_state`), and
the hull of that set is solved ``repeat`` times by each solver strategy of the case (the
batched dual simplex, warm HiGHS, sifting with the compiled restricted LPs and with HiGHS's);
the fastest repetition is reported with its work counters (LPs, simplex iterations per LP,
HiGHS fallbacks) and the share of its time in each phase
(:attr:`observers.sets.HullLPStats.seconds`: one compiled call, set-up of the batch, pivots,
refactorisations, certification; the start vertex, restricted LPs and pricing of sifting;
the weak-duality bounds, HiGHS).  Every solver's bounds are sound; the table gives how much
looser and how much tighter each strategy's bounds are than warm HiGHS's at most, relative
to the set's radius (HiGHS's dual points are accurate to its tolerances, ~1e-7).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from time import perf_counter
from typing import Any

import numpy as np

import systems
from observers.sets import HullLP

from ..report.numbers import fmt
from ..run.progress import announced
from ..run.rows import design_observer, merge_options
from .steps import to_steady_state

#: the solver strategies compared (:attr:`observers.sets.HullLP.SOLVERS`); HiGHS is the
#: reference of the *looser* / *tighter* columns
SOLVERS = ("batched", "highs", "sifting", "sifting-highs")


@dataclass(frozen=True)
class HullCase:
    """One profiled hull: ``observer`` at its steady state on ``scenario``; ``repeat`` timed
    solves per solver strategy of ``solvers`` (the fastest is reported; ``"highs"`` always
    runs, as the reference)."""

    scenario: str
    observer: str
    repeat: int = 5
    solvers: tuple[str, ...] = SOLVERS


#: the profiled hulls: the 30-tank set of ARCH 2021 Table 5 (the cold bench's costliest hulls)
#: and the 100- and 200-tank sets of the speed table (at 200 tanks without the batched dual
#: simplex, whose dense pivots over 326 rows would take minutes)
HULL_CASES: tuple[HullCase, ...] = (
    HullCase("tank30-linear", "CZN-A"),
    HullCase("tank100-linear", "CZN-A", repeat=1),
    HullCase("tank200-linear", "CZN-A", repeat=1, solvers=("highs", "sifting", "sifting-highs")),
)
#: the phases of :attr:`observers.sets.HullLPStats.seconds`, in the order of the table
#: (``"solve"``: one compiled call of the batched dual simplex, its phases not split)
PHASE_LABELS = {"solve": "compiled call", "setup": "setup", "pivots": "pivots",
                "refactor": "refactor", "certify": "certify", "start": "start",
                "models": "models", "restricted": "restricted", "pricing": "pricing",
                "bounds": "bounds", "highs": "HiGHS"}
PHASES = tuple(PHASE_LABELS)


def steady_hull_problem(case: HullCase) -> tuple[dict[str, Any], tuple[np.ndarray, ...]]:
    """``(facts, (G, A, b))`` of the steady-state set of ``case`` (facts: step, n, p, r, or
    ``status``/``message`` if the observer failed on the way)."""
    sc = systems.scenario(case.scenario)
    obs, status, message = design_observer(case.observer, sc, merge_options(case.observer, sc))
    if obs is None:
        return {"status": status, "message": message}, ()
    obs.reset()
    k, last = 0, None
    try:
        for S in to_steady_state(obs, sc):
            k, last = k + 1, S
    except Exception as exc:  # a failure is the row's status, never the report's end
        return {"status": "error", "message": f"step {k + 1}: {type(exc).__name__}: {exc}"}, ()
    if last is None or not hasattr(last, "arrays"):
        return {"status": "error", "message": "no constrained zonotope to profile"}, ()
    _, G, A, b = last.arrays()
    return {"status": "ok", "step": k, "n": G.shape[0], "p": A.shape[0], "r": G.shape[1]}, (
        G, A, b)


def profile_hull(case: HullCase) -> list[dict[str, Any]]:
    """One row per solver strategy of :data:`SOLVERS` for ``case`` (see the module
    docstring)."""
    facts, problem = steady_hull_problem(case)
    base = {"scenario": case.scenario, "observer": case.observer, **facts}
    solvers = tuple(dict.fromkeys(("highs", *case.solvers)))
    solvers = tuple(s for s in SOLVERS if s in solvers)
    if facts["status"] != "ok":
        return [dict(base, solver=s) for s in solvers]
    G, A, b = problem
    Gd = np.vstack([G, -G])
    radius = np.abs(G).sum(axis=1)
    rows, bounds = [], {}
    for solver in solvers:
        best = None
        for _ in range(case.repeat):
            lp = HullLP(solver)
            t0 = perf_counter()
            ub = lp.maximize_many(Gd, A, b)
            seconds = perf_counter() - t0
            if best is None or seconds < best[0]:
                best = (seconds, lp.stats, ub)
        seconds, stats, bounds[solver] = best
        rows.append(dict(base, solver=solver, ms=1e3 * seconds, lps=stats.solves,
                         iterations=stats.iterations_per_solve, fallbacks=stats.fallbacks,
                         shares={ph: stats.seconds.get(ph, 0.0) / seconds for ph in PHASES}))
    n = G.shape[0]
    for row in rows:
        # positive where the strategy's bound is the looser one (all are sound upper bounds)
        diff = (bounds[row["solver"]] - bounds["highs"]) / np.concatenate([radius, radius])
        row["looser"] = float(diff.max()) if n else math.nan
        row["tighter"] = float(-diff.min()) if n else math.nan
    return rows


def measure_hulls(cases: tuple[HullCase, ...] = HULL_CASES, progress: bool = True
                  ) -> list[dict[str, Any]]:
    """:func:`profile_hull` of every case."""
    return [row for case in announced(
        cases, progress, lambda c: f"profiling the hull of {c.observer} on {c.scenario}")
        for row in profile_hull(case)]


def render_hulls(rows: list[dict[str, Any]]) -> list[str]:
    """The Markdown section of the profile."""
    lines = [
        "## Where a constrained zonotope's interval hull spends its time",
        "",
        "The observer stepped to its steady state without hulls, then the hull of that set "
        "(2n LPs over its r generators and p constraints) solved by each strategy of "
        "`HullLP`: *batched*, the batched dual simplex (compiled; every problem pivots in "
        "lock step, the pivot rows of all of them one matrix product); *highs*, one warm "
        "HiGHS run per direction; *sifting*, working sets of columns, all columns priced by "
        "one matrix product per round and chunk of directions, the restricted LPs by the "
        "compiled dual simplex from the start vertex's basis (`observers/lp/sifting_jit.py`); "
        "*sifting-highs*, the same with the restricted LPs by HiGHS "
        "(`observers/lp/sifting.py`). "
        "Fastest of the repetitions; *phases*: share of its time in one compiled call of the "
        "batched dual simplex (not split into its phases), the set-up of the numpy batch "
        "(crash basis, reduced costs), the pivots, the refactorisations, the certification "
        "of the optimum; sifting's start vertex (one cold HiGHS solve), the first working "
        "sets (their HiGHS models), the restricted LPs (with the columns added to them), the "
        "pricing; the weak-duality bounds and HiGHS (LPs a strategy did not finish, or every "
        "LP with *highs*); *iterations per LP* are HiGHS's or the batch's simplex iterations "
        "(sifting: those of its restricted LPs and start). *looser / tighter than HiGHS*: the "
        "largest amount by which the strategy's bounds exceed / undercut warm HiGHS's, over "
        "the set's radius (all are sound bounds of dual points; HiGHS's are accurate to its "
        "tolerances).",
        "",
        "| set | step | n | p | r | solver | ms per hull | ms per LP | iterations per LP "
        "| HiGHS fallbacks | " + " | ".join(PHASE_LABELS.values())
        + " | looser than HiGHS | tighter than HiGHS |",
        "|" + "---|" * (12 + len(PHASES)),
    ]
    for r in rows:
        head = f"| {r['observer']}, {r['scenario']} "
        if r["status"] != "ok":
            lines.append(head + f"| {r['status']}: {r['message']} |" + " |" * (10 + len(PHASES)))
            continue
        shares = " | ".join(f"{100 * r['shares'][ph]:.0f} %" for ph in PHASES)
        lines.append(
            head + f"| {r['step']} | {r['n']} | {r['p']} | {r['r']} | {r['solver']} | "
            f"{fmt(r['ms'], 3)} | {fmt(r['ms'] / max(r['lps'], 1), 3)} | "
            f"{fmt(r['iterations'], 3)} | {r['fallbacks']} | {shares} | "
            f"{fmt(r['looser'], 2)} | {fmt(r['tighter'], 2)} |")
    return lines
