"""Per-step timing of observers over repeated runs (a benchmark script, not a test).

::

    python -m benchmarks.steptime VolMin-B --scenario vehicle6d-cora --repeat 5

prints, per observer, the median and the 90th percentile of the ``step()`` time in ms over all
steps after the warm-up of every repetition (the offline design is done once, outside the
timing).  The machine is shared and timings are noisy: read them as indicative.
"""

from __future__ import annotations

import argparse

import numpy as np

import observers
import systems

from .metrics import warmup_steps


def step_times(name: str, scenario: str, repeat: int = 5, **options) -> np.ndarray:
    """``step()`` times in seconds of ``repeat`` runs of ``name`` on ``scenario`` (warm-up
    steps of each run dropped)."""
    sc = systems.scenario(scenario)
    obs = observers.create(name, sc.system, **{**sc.options, **options})
    out = []
    for _ in range(repeat):
        res = observers.run(obs, sc.u, sc.y, keep_sets=False)
        if res.status != "ok":
            raise observers.ObserverError(f"{name} on {scenario}: {res.status} ({res.message})")
        t = res.step_times[warmup_steps(sc.N):]
        out.append(t[np.isfinite(t)])
    return np.concatenate(out)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m benchmarks.steptime", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("observers", nargs="+", help="observer names")
    p.add_argument("--scenario", default="vehicle6d-cora")
    p.add_argument("--repeat", type=int, default=5)
    args = p.parse_args(argv)
    print(f"{'observer':12s} {'scenario':18s} {'median ms':>10s} {'p90 ms':>8s} {'steps':>6s}")
    for name in args.observers:
        t = step_times(name, args.scenario, args.repeat) * 1e3
        print(f"{name:12s} {args.scenario:18s} {np.median(t):10.3f} {np.percentile(t, 90):8.3f} "
              f"{t.size:6d}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
