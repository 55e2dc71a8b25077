"""Check and time the exact reference ``Exact`` on whole records (issue 24).

``python -m benchmarks.studies.exact_check tank6-linear vehicle6d-cora`` runs ``Exact``
(cold: no cache) on each scenario's whole record, times it (both floors: filtered and
predicted hulls at every step), solves the hulls again at every step (or every ``--every``
steps) by an independent formulation from scratch (:mod:`observers.numerics.exact_reference`:
``explicit``, states and noise factors as variables, the default; or ``dense``, states
eliminated, whose cost per step grows with the square of the record), and reports the
largest deviation relative to the radius (the acceptance bound is 1e-6).  ``--ratios``
adds the ratio observer / exact of the RMS radius over the steps from 20 % of the record on
(each observer against its registry floor), averaged over the states.  ``--no-check`` only
times ``Exact``.  The exit code is 1 if a deviation exceeds the bound.
"""

from __future__ import annotations

import argparse
import sys
import time

import numpy as np

import observers
import systems
from observers.numerics.exact_reference import dense_hulls, explicit_hulls

from ..metrics import rms_radius

#: acceptance bound of the deviation from the independent formulation, relative to the radius
RTOL = 1e-6
_KEYS = ("pred_lo", "pred_hi", "filt_lo", "filt_hi")


def time_exact(sc) -> tuple[dict[str, np.ndarray], float, float, dict]:
    """Exact's hulls of the whole record without the cache: (hulls, CPU s, wall s, stats)."""
    obs = observers.create("Exact", sc.system, cache=False)
    c0, w0 = time.process_time(), time.perf_counter()
    res = observers.run(obs, sc.u, sc.y, keep_sets=False)
    cpu, wall = time.process_time() - c0, time.perf_counter() - w0
    if res.status != "ok":
        raise SystemExit(f"{sc.name}: Exact stopped: {res.message}")
    return obs.hull_arrays(), cpu, wall, obs.lp_stats


def deviation(hulls: dict[str, np.ndarray], ref: dict[int, tuple]) -> dict[str, float]:
    """Largest ``|Exact - reference|`` over the reference radius, per floor, over the checked
    steps."""
    worst = {"predicted": 0.0, "filtered": 0.0}
    for k, r in ref.items():
        for floor, lo, hi, a, b in (("predicted", r[0], r[1], "pred_lo", "pred_hi"),
                                    ("filtered", r[2], r[3], "filt_lo", "filt_hi")):
            rad = 0.5 * (hi - lo)
            err = np.maximum(np.abs(hulls[a][k] - lo), np.abs(hulls[b][k] - hi))
            worst[floor] = max(worst[floor], float(np.max(err / rad)))
    return worst


def ratios(sc, hulls: dict[str, np.ndarray], names: list[str]) -> dict[str, str]:
    """Observer / exact RMS radius over the steps from 20 % of the record, mean over the
    states (and the range), each observer against its floor."""
    first = int(np.ceil(0.2 * sc.N))
    out = {}
    for name in names:
        info = observers.get(name)
        accepted = info.option_defaults()
        allowed = info.scenario_options
        opts = {k: v for k, v in sc.options.items()
                if k in accepted and (allowed is None or k in allowed)}
        res = observers.run(observers.create(name, sc.system, **opts), sc.u, sc.y,
                            keep_sets=False)
        if res.status != "ok":
            out[name] = res.status
            continue
        key = "pred" if info.floor == "predicted" else "filt"
        r_ex = 0.5 * (hulls[f"{key}_hi"] - hulls[f"{key}_lo"])[first:]
        r_ob = res.radius[first:]
        q = rms_radius(r_ob) / rms_radius(r_ex)
        out[name] = f"{q.mean():.3g} (states {q.min():.3g}-{q.max():.3g}, {info.floor})"
    return out


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m benchmarks.studies.exact_check",
                                description=__doc__.splitlines()[0])
    p.add_argument("scenarios", nargs="+", help="linear scenarios, e.g. tank6-linear")
    p.add_argument("--reference", choices=("explicit", "dense"), default="explicit",
                   help="independent formulation (default: explicit)")
    p.add_argument("--every", type=int, default=1, help="check every k-th step (default 1)")
    p.add_argument("--no-check", action="store_true", help="only time Exact")
    p.add_argument("--ratios", nargs="*", default=None, metavar="OBSERVER",
                   help="RMS-radius ratios observer/exact (default list: FRad-A CZN-B ROPO)")
    args = p.parse_args(argv)
    failed = False
    for name in args.scenarios:
        sc = systems.scenario(name)
        s = sc.system
        hulls, cpu, wall, stats = time_exact(sc)
        print(f"{name}: {sc.N} steps, n = {s.n}; Exact (filtered + predicted, no cache): "
              f"{cpu:.1f} s CPU, {wall:.1f} s wall; {stats['solves']} LPs, "
              f"{stats['iterations'] / max(stats['solves'], 1):.1f} simplex iterations per LP"
              + (f"; not optimal at steps {stats['inexact_steps']}"
                 if stats["inexact_steps"] else ""), flush=True)
        if not args.no_check:
            steps = sorted(set(range(0, sc.N, args.every)) | {sc.N - 1})
            solve = explicit_hulls if args.reference == "explicit" else dense_hulls
            sets = tuple((S.c, S.G) for S in (s.X0, s.W, s.V))
            c0 = time.process_time()
            ref = solve((s.A, s.B, s.C, *sets), sc.u, sc.y, steps=steps)
            worst = deviation(hulls, ref)
            ok = max(worst.values()) <= RTOL
            failed |= not ok
            print(f"  vs {args.reference} LP from scratch at {len(steps)} steps "
                  f"({time.process_time() - c0:.0f} s CPU): largest deviation / radius "
                  f"predicted {worst['predicted']:.2e}, filtered {worst['filtered']:.2e} "
                  f"-> {'ok' if ok else 'FAILED'} (bound {RTOL:g})", flush=True)
        if args.ratios is not None:
            names = args.ratios or ["FRad-A", "CZN-B", "ROPO"]
            for obs, text in ratios(sc, hulls, names).items():
                print(f"  RMS radius {obs} / Exact (steps >= 20 %): {text}", flush=True)
    return 1 if failed else 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
