"""Timing of the constrained-zonotope observers: ``step()`` and the interval hull (2n LPs).

Usage::

    .venv/bin/python -m benchmarks.czn_timing                       # CZN-A/B on vehicle6d-cora
    .venv/bin/python -m benchmarks.czn_timing --scenario vehicle2d-cora --max-constraints none

For every observer and repetition the whole record is run as the benchmark runner does
(``step()``, then ``S.interval()``); the per-step times after a warm-up are summarised by
their median, and the medians of the repetitions by their median.  Wall-clock times
(``perf_counter``) and CPU times of this process (``process_time``, less sensitive to other
jobs on a shared machine) are both reported, with the simplex iterations per LP and the
number of LPs the batched solver handed to HiGHS (``--hull-solver highs``: HiGHS only, for
comparison).
Indicative numbers only: this is not a test.
"""

from __future__ import annotations

import argparse
import json
import sys
from time import perf_counter, process_time

import numpy as np

import observers
import systems
from observers.sets import HullLP


def time_run(name: str, sc, options: dict, warmup: int = 5, hull_solver: str = "auto"
             ) -> dict:
    """One run of ``name`` over the scenario record; medians over steps after ``warmup``."""
    obs = observers.create(name, sc.system, hull_solver=hull_solver, **options)
    obs.reset()
    N = sc.y.shape[0]
    rows = np.full((N, 4), np.nan)
    iters = np.full(N, np.nan)
    fallbacks = 0
    for k in range(N):
        u_prev = sc.u[k - 1] if k > 0 else None
        w0, c0 = perf_counter(), process_time()
        S = obs.step(u_prev, sc.y[k])
        w1, c1 = perf_counter(), process_time()
        it0, lp0, fb0 = obs._lp.iterations, obs._lp.solves, obs._lp.fallbacks
        S.interval()
        w2, c2 = perf_counter(), process_time()
        rows[k] = (w1 - w0, c1 - c0, w2 - w1, c2 - c1)
        if obs._lp.solves > lp0:
            iters[k] = (obs._lp.iterations - it0) / (obs._lp.solves - lp0)
        fallbacks += obs._lp.fallbacks - fb0
    med = np.median(rows[warmup:], axis=0) * 1e3
    return {"step_ms": med[0], "step_cpu_ms": med[1], "hull_ms": med[2], "hull_cpu_ms": med[3],
            "total_ms": med[0] + med[2], "total_cpu_ms": med[1] + med[3],
            "iters_per_lp": float(np.nanmedian(iters[warmup:])),
            "constraints": S.num_constraints, "generators": S.num_generators,
            "highs_fallbacks": fallbacks}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenario", default="vehicle6d-cora")
    ap.add_argument("--observers", default="CZN-A,CZN-B")
    ap.add_argument("--repetitions", type=int, default=3)
    ap.add_argument("--max-constraints", default="auto",
                    help="'auto' (default), an integer, or 'none' (CORA: all constraints)")
    ap.add_argument("--hull-solver", default="auto", choices=HullLP.SOLVERS,
                    help="LP solver of the interval hulls (default: auto, the batched dual "
                         "simplex where it pays off)")
    ap.add_argument("--json", help="also write the results to this file")
    args = ap.parse_args(argv)
    sc = systems.scenario(args.scenario)
    mc = args.max_constraints
    mc = None if mc.lower() == "none" else (mc if mc == "auto" else int(mc))
    options = {**sc.options, "max_constraints": mc}
    out = {}
    for name in args.observers.split(","):
        reps = [time_run(name, sc, options, hull_solver=args.hull_solver)
                for _ in range(args.repetitions)]
        summary = {k: float(np.median([r[k] for r in reps])) for k in reps[0]}
        out[name] = summary
        print(f"{sc.name} {name} (max_constraints={mc}, {args.repetitions} reps, median of "
              f"per-step medians): step {summary['step_ms']:.3f} ms (cpu "
              f"{summary['step_cpu_ms']:.3f}), hull {summary['hull_ms']:.3f} ms (cpu "
              f"{summary['hull_cpu_ms']:.3f}), step+hull {summary['total_ms']:.3f} ms (cpu "
              f"{summary['total_cpu_ms']:.3f}); {summary['iters_per_lp']:.1f} simplex "
              f"iterations per LP ({args.hull_solver}), {int(summary['highs_fallbacks'])} LPs "
              f"handed to HiGHS; final set {int(summary['generators'])} generators, "
              f"{int(summary['constraints'])} constraints")
    if args.json:
        with open(args.json, "w") as fh:
            json.dump({"scenario": sc.name, "options": {k: str(v) for k, v in options.items()},
                       "results": out}, fh, indent=2)
    return 0


if __name__ == "__main__":
    sys.exit(main())
