"""Per-step timing of observers (a benchmark, not a test).

    python -m benchmarks.step_timing ESO-C ESO-D --scenario vehicle6d-cora --repeat 20

Each observer is designed once (the design is not timed), then run ``--repeat`` times over the
scenario's record.  Every ``step()`` call is timed with ``perf_counter``; the first steps of
each repetition are dropped as warm-up (as in ``summary.csv``).  Printed per observer: the
median over repetitions of the per-repetition median step time, the spread (min-max) of these
medians, and the same for the interval hull.  Timings on a shared machine are indicative.
"""

from __future__ import annotations

import argparse
import sys
from time import perf_counter

import numpy as np

import observers
import systems
from observers.base import as_record

from .cli import USER_ERRORS
from .metrics import warmup_steps


def time_steps(obs, u: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Seconds of every ``step()`` and every interval hull over one run of the record."""
    N = y.shape[0]
    steps, hulls = np.empty(N), np.empty(N)
    obs.reset()
    for k in range(N):
        u_prev = u[k - 1] if k > 0 else None
        t0 = perf_counter()
        S = obs.step(u_prev, y[k])
        t1 = perf_counter()
        S.interval()
        steps[k], hulls[k] = t1 - t0, perf_counter() - t1
    return steps, hulls


def measure(name: str, sc, repeat: int) -> dict[str, float]:
    """Median per-step and per-hull times (microseconds) of ``name`` on scenario ``sc``."""
    accepted = observers.get(name).cls.option_defaults()
    obs = observers.create(name, sc.system, **{k: v for k, v in sc.options.items()
                                               if k in accepted})
    u, y = as_record(sc.u, sc.y, sc.system.nu, sc.system.ny)
    skip = warmup_steps(y.shape[0])
    med_step, med_hull = [], []
    for _ in range(repeat):
        steps, hulls = time_steps(obs, u, y)
        med_step.append(np.median(steps[skip:]) * 1e6)
        med_hull.append(np.median(hulls[skip:]) * 1e6)
    return {"step_us": float(np.median(med_step)), "step_min": float(np.min(med_step)),
            "step_max": float(np.max(med_step)), "hull_us": float(np.median(med_hull)),
            "design_s": obs.design_time, "steps": y.shape[0] - skip}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.step_timing",
                                     description=__doc__.splitlines()[0])
    parser.add_argument("observers", nargs="+", help="observer names")
    parser.add_argument("--scenario", default="vehicle6d-cora")
    parser.add_argument("--repeat", type=int, default=10, help="repetitions (default 10)")
    args = parser.parse_args(argv)
    try:
        if args.repeat < 1:
            raise ValueError("--repeat must be at least 1")
        sc = systems.scenario(args.scenario)
        print(f"{sc.name}: {args.repeat} repetitions, median over steps after warm-up")
        print(f"{'observer':<10} {'step [us]':>10} {'min-max of medians':>20} "
              f"{'hull [us]':>10} {'design [s]':>11}")
        for name in args.observers:
            r = measure(name, sc, args.repeat)
            print(f"{name:<10} {r['step_us']:>10.1f} {r['step_min']:>9.1f} - "
                  f"{r['step_max']:<8.1f} {r['hull_us']:>10.1f} {r['design_s']:>11.2f}")
    except (*USER_ERRORS, ValueError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
