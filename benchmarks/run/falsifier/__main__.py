"""``python -m benchmarks.run.falsifier SCENARIO``: the falsifier's measurement tool (see
:func:`main`)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from .inner_box import FLOORS, SearchOptions, falsify, spread_steps


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m benchmarks.run.falsifier SCENARIO``: run observers on a scenario, falsify
    their hulls at steps spread over the record, print the inner box's RMS radii, the
    violations, the gap upper bounds and the cost (a measurement tool; the harness calls
    :func:`falsify`)."""
    import argparse

    import observers
    import systems

    ap = argparse.ArgumentParser(prog="python -m benchmarks.run.falsifier",
                                 description=main.__doc__.split(":", 1)[1].strip())
    ap.add_argument("scenario")
    ap.add_argument("--observers", default="all",
                    help="comma-separated names, or 'all' (the guaranteed observers that "
                         "accept the system)")
    ap.add_argument("--steps", type=int, default=10, help="steps searched (default 10)")
    ap.add_argument("--first", type=float, default=0.2,
                    help="first searched step as a fraction of the record (default 0.2)")
    ap.add_argument("--floor", choices=FLOORS, default="filtered")
    ap.add_argument("--window", default="auto", help="an integer, 'auto' or 'none'")
    ap.add_argument("--starts", type=int, default=1)
    args = ap.parse_args(argv)
    window = None if args.window == "none" else (
        "auto" if args.window == "auto" else int(args.window))
    sc = systems.scenario(args.scenario)
    names = ([i.name for i in observers.available() if i.guaranteed]
             if args.observers == "all" else args.observers.split(","))
    hulls = {}
    for name in names:
        info = observers.get(name)
        allowed = info.option_defaults() if info.scenario_options is None else (
            info.scenario_options)
        try:
            obs = observers.create(name, sc.system,
                                   **{k: v for k, v in sc.options.items() if k in allowed})
        except (observers.Unsupported, observers.DesignFailed, observers.OptionError):
            continue
        hulls[name] = observers.run(obs, sc.u, sc.y, keep_sets=False, on_error="status")
    steps = spread_steps(sc.N, args.steps, int(args.first * sc.N))
    res = falsify(sc.system, sc, steps=steps, hulls=hulls,
                  options=SearchOptions(starts=args.starts, floor=args.floor, window=window))
    st = res.stats
    print(f"{sc.name}: steps {steps.tolist()}, floor {res.floor}, window {args.window}, "
          f"starts {args.starts}: {st['seconds']:.2f} s, {st['lps']} LPs, {st['loads']} "
          f"models, {st['corrections']} corrections, {st['runs']} runs")
    rms = np.sqrt(np.mean(res.inner_radius ** 2, axis=0))
    print("inner box RMS radii: " + " ".join(f"{r:.4g}" for r in rms))
    for name, gap in res.gap_upper.items():
        bad = sum(v.observer == name for v in res.violations)
        print(f"{name:>12}: gap <= {np.mean(gap):.3g} (states: "
              + " ".join(f"{g:.3g}" for g in gap) + f"); violations: {bad}")
    for v in res.violations[:20]:
        print(f"  {v.observer} step {v.step} x{v.state + 1} {v.side}: consistent {v.value:.9g} "
              f"outside {v.bound:.9g} by {v.excess:.3g}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
