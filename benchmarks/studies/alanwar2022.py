"""Report on the data-driven observers of Alanwar, Berndt, Johansson, Sandberg (ECC 2022).

``python -m benchmarks.studies.alanwar2022 --out reports/datadriven.md`` writes a Markdown report
and a figure (``datadriven.png`` beside it, like the paper's Figs. 2 and 3):

1. width of the set of models ``M_Sigma`` (paper construction vs the sound ones) and whether
   it contains the true ``[A B]``, over seeds;
2. containment of the true state by the four data-driven observers at every step over seeds,
   and the share of steps where the Kalman 3-sigma ellipsoid missed it;
3. set sizes (interval radii, area at the snapshot step) and per-step times against the
   paper's (indicative: medians over repetitions on a shared 2-core machine);

and ends with what to cite (:mod:`benchmarks.report.citation`).

It takes a few minutes; it is not part of the test suite.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from time import perf_counter

import numpy as np
import pandas as pd

import observers
import systems
from observers.numerics.datadriven import (
    check_training,
    paper_model_set,
    refined_model_set,
    sound_model_set,
)
from observers.sets import Zonotope
from observers.sets.planar import polygon, set_area
from systems.rotating import INPUT_SET, rotating_target
from systems.training import offline_experiment

from ..io import atomic_write_text
from ..metrics import median_ms, rms_radius
from ..report import figures, freshness
from ..report.citation import citation_lines
from ..report.numbers import MISSING, fmt
from ..report.paper import load_table
from .robustness import holds_sentence

DD = ("DD-Z-A1", "DD-Z-A2", "DD-CZ-A1", "DD-CZ-A2")
KF = "KF-N4SID"
MODEL_BASED = ("FRad-A", "FRad-B", "FRad-C")
SNAPSHOT = 34  # the paper's snapshot step (published code)
COLORS = {"DD-Z-A1": "tab:blue", "DD-Z-A2": "tab:orange", "DD-CZ-A1": "tab:green",
          "DD-CZ-A2": "tab:red", KF: "tab:purple", KF + " (paper tuning)": "tab:gray"}


def model_widths(seeds: int) -> list[str]:
    """Section 1: widths of M_Sigma and containment of [A_tr B_tr]."""
    s = rotating_target()
    AB = np.hstack([s.A, s.B])
    cases = {
        "published code: sensor 1, noise <0,1>, M=100, T=100": (
            [[1.0, 0.4]], Zonotope.box([1.0]), 100),
        "published code, T=500": ([[1.0, 0.4]], Zonotope.box([1.0]), 500),
        "paper Sec. IV: z = x + gamma, Z_gamma = <0, 0.02 I>, T=500 (our scenario)": (
            np.eye(2), Zonotope.box([0.02, 0.02]), 500),
        "three sensors stacked, noise <0, 0.02> each, T=500": (
            s.C, Zonotope.box(np.full(4, 0.02)), 500),
    }
    rows = ["| experiment | construction | max width | mean width | contains [A B] | fails |",
            "|---|---|---|---|---|---|"]
    for label, (C, Gam, T) in cases.items():
        res: dict[str, list] = {"paper (Lemma 1)": [], "sound (theorem)": [],
                                "sound + LP (default)": []}
        fails = dict.fromkeys(res, 0)
        for seed in range(seeds):
            tr = offline_experiment(s, T, 1000 + seed, INPUT_SET, C=C, Gamma=Gam)
            data = check_training(tr, 2, 1, "report")
            P = paper_model_set(data, s.W, 100.0)
            res["paper (Lemma 1)"].append((P.width(), P.contains(AB)))
            try:
                S = sound_model_set(data, s.W)
            except observers.DesignFailed:
                fails["sound (theorem)"] += 1
                fails["sound + LP (default)"] += 1
                continue
            res["sound (theorem)"].append((S.M.width(), S.M.contains(AB, 1e-12)))
            R = refined_model_set(data, s.W, S.M)
            res["sound + LP (default)"].append((R.width(), R.contains(AB)))
        for name, vals in res.items():
            if not vals:
                rows.append(f"| {label} | {name} | - | - | - | {fails[name]}/{seeds} "
                            "(experiment sensors not of full column rank) |")
                continue
            w = np.array([v[0] for v in vals])
            inside = sum(v[1] for v in vals)
            rows.append(f"| {label} | {name} | {fmt(np.median(w.max(axis=(1, 2))), 3)} | "
                        f"{fmt(np.median(w.mean(axis=(1, 2))), 3)} | {inside}/{len(vals)} | "
                        f"{fails[name]}/{seeds} |")
    return rows


def _create(name: str, sc, **extra):
    accepted = observers.get(name).cls.option_defaults()
    opts = {k: v for k, v in sc.options.items() if k in accepted}
    if "training" in accepted:
        opts["training"] = sc.training
    opts.update(extra)
    return observers.create(name, sc.system, **opts)


def containment(seeds: int) -> tuple[list[str], dict]:
    """Section 2: containment over seeds (every step), KF 3-sigma misses, sizes."""
    variants = [(n, "sound-lp") for n in DD] + [(n, "sound") for n in DD] + [
        (n, "paper") for n in DD] + [(KF, "uniform"), (KF, "paper")] + [
        (n, None) for n in MODEL_BASED]
    stats = {v: {"miss": 0, "steps": 0, "rad": [], "fail": 0} for v in variants}
    defaults = {(n, "sound-lp") for n in DD} | {(KF, "uniform")} | {(n, None)
                                                                     for n in MODEL_BASED}
    runs: list[dict] = []  # the configuration's observers (default options), per seed
    for seed in range(seeds):
        sc = systems.scenario("rotating-target", seed=seed)
        for name, model in variants:
            extra = {"model": model} if name in DD else {"tuning": model}
            if name in MODEL_BASED:
                extra = {"order": 5}
            st = stats[(name, model)]
            try:
                obs = _create(name, sc, **extra)
            except observers.DesignFailed:
                st["fail"] += 1
                continue
            res = observers.run(obs, sc.u, sc.y)
            miss = sum(not S.contains(x, 1e-9) for S, x in zip(res.sets, sc.x_true,
                                                                strict=False))
            st["steps"] += len(res.sets)
            st["miss"] += miss
            st["rad"].append(res.radius[5:].mean(axis=0))
            if (name, model) in defaults:
                runs.append({"scenario": "rotating-target", "realisation": seed,
                             "observer": name, "status": res.status, "violations": miss,
                             "rms": float(np.mean(rms_radius(res.radius)))})
    rows = ["| observer | model | steps checked | steps outside | mean radius x1, x2 "
            "(steps >= 5) |", "|---|---|---|---|---|"]
    for (name, model), st in stats.items():
        rad = np.mean(st["rad"], axis=0) if st["rad"] else [np.nan, np.nan]
        label = (f"N4SID, {model} tuning" if name == KF else model) or "true A, B"
        share = (f"{st['miss']} ({100 * st['miss'] / st['steps']:.1f} %)" if st["steps"]
                 else "-")
        rows.append(f"| {name} | {label} | {st['steps']} | {share} | {fmt(rad[0], 3)}, "
                    f"{fmt(rad[1], 3)} |")
    stats["runs"] = runs
    return rows, stats


def timings(reps: int) -> tuple[list[str], dict]:
    """Section 3: median per-step time over repetitions vs the paper."""
    paper = load_table("alanwar2022_datadriven").get("time_per_step_s", {})
    sc = systems.scenario("rotating-target", seed=0)
    rows = ["| observer | step ms (median) | hull ms | paper s/step | speed-up |",
            "|---|---|---|---|---|"]
    out = {}
    for name in (*DD, KF):
        obs = _create(name, sc)
        step, hull = [], []
        for _ in range(reps):
            res = observers.run(obs, sc.u, sc.y)
            step.append(median_ms(res.step_times))
            hull.append(median_ms(res.hull_times))
        ms, hms = float(np.median(step)), float(np.median(hull))
        out[name] = ms
        p = paper.get(name)
        rows.append(f"| {name} | {fmt(ms)} | {fmt(hms)} | {fmt(p) if p else MISSING} | "
                    f"{fmt(1e3 * p / ms, 3, 'x') if p else MISSING} |")
    return rows, out


def other_scenarios() -> list[str]:
    """Section 4: the data-driven observers on the vehicle-2D and tank-6 records."""
    rows = ["| scenario | observer | RMS radius per state | step ms | steps outside |",
            "|---|---|---|---|---|"]
    for name in ("vehicle2d-sim", "tank6-linear"):
        sc = systems.scenario(name, seed=0)
        for obs_name, extra in (("FRad-B", {}), *((n, {}) for n in DD), (KF, {}),
                                (KF, {"tuning": "paper"})):
            obs = _create(obs_name, sc, **extra)
            if "tuning" in extra:
                obs_name += " (paper tuning)"
            res = observers.run(obs, sc.u, sc.y)
            rms = rms_radius(res.radius)
            miss = sum(not S.contains(x, sc.tolerance) for S, x in zip(res.sets, sc.x_true,
                                                                      strict=False))
            rows.append(f"| {name} | {obs_name} | {', '.join(fmt(r, 3) for r in rms)} | "
                        f"{fmt(median_ms(res.step_times), 3)} | {miss}/{len(res.sets)} |")
    return rows


def figure(base: Path) -> list[str]:
    """Figure like the paper's Figs. 2-3 (``base.png``, ``base.pdf``): x1 bounds over time, sets
    at the snapshot step; returns the Markdown rows of the sets' areas."""
    sc = systems.scenario("rotating-target", seed=0)
    runs = {name: observers.run(_create(name, sc), sc.u, sc.y) for name in (*DD, KF)}
    kf_paper = KF + " (paper tuning)"
    runs[kf_paper] = observers.run(_create(KF, sc, tuning="paper"), sc.u, sc.y)
    rows = ["| set at step 34 | area |", "|---|---|"]
    rows += [f"| {name} | {set_area(r.sets[SNAPSHOT]):.3f} |" for name, r in runs.items()]
    drawn = figures.DataDrivenRuns(
        np.arange(sc.N), sc.x_true, {name: (r.lo, r.hi) for name, r in runs.items()},
        {name: polygon(r.sets[SNAPSHOT]) for name, r in runs.items()}, SNAPSHOT)
    figures.datadriven(drawn, ((("DD-Z-A1", "DD-Z-A2", KF, kf_paper), "zonotopes"),
                               (("DD-CZ-A1", "DD-CZ-A2", KF, kf_paper), "constrained zonotopes")),
                       COLORS, base)
    return rows


def build(out: Path, seeds: int, reps: int) -> Path:
    """Compute everything and write ``out`` (Markdown) and the figure beside it."""
    t0 = perf_counter()
    png = out.with_suffix(".png")
    fig_rows = figure(out.parent / out.stem)
    widths = model_widths(seeds)
    cont, cont_stats = containment(seeds)
    holds = holds_sentence("alanwar2022", ("rotating-target",),
                           pd.DataFrame(cont_stats["runs"]), freshness.ROOT / "results")
    times, _ = timings(reps)
    others = other_scenarios()
    text = f"""# Data-driven set-based estimation (Alanwar, Berndt, Johansson, Sandberg, ECC 2022)

Generated by `python -m benchmarks.studies.alanwar2022 --out {out}` ({seeds} seeds, {reps} timing
repetitions, {perf_counter() - t0:.0f} s).  Scenario `rotating-target` (paper Sec. IV): three
sensors stacked, |v| <= 1, |w| <= 0.02, X0 = <0, 15 I>, x(0) = [-10, 10], inputs uniform in
[-10, 10], 50 online steps; offline experiment T = 500 with z = x + gamma, |gamma| <= 0.02.
All four observers reduce to order 5 (Girard).

![bounds and sets]({png.name})

Reading guide (details in the sections below):

* The published code learns M_Sigma from sensor 1 alone (a scalar output with noise |v| <= 1
  and a null-space bound M = 100); its set is hundreds wide, so the time update carries no
  information and the estimate is the intersection of the measurement sets.  Our sound
  construction refuses such data (the state is not reconstructible from one scalar output).
* On the paper's offline experiment (z = x + gamma, |gamma| <= 0.02) the sound sets are
  narrower than Lemma 1's and provably contain every consistent [A B]; the LP refinement
  (default) is narrower still.
* The Kalman 3-sigma ellipsoid is "comparable in size" to the guaranteed sets only with the
  published code's tuning (Q = 0.1 I, R = I, both overstated; the code also drew semi-axes
  3 eig(P) instead of 3 sqrt(eig(P))).  With the covariances of the actual uniform noise it is
  five to seven times smaller but misses the true state on some steps, and on the 6-tank
  system (slow modes, tiny Q) its small identification error makes it miss most steps.

## 1. The set of models M_Sigma

Entry-wise widths of the interval hull of M_Sigma (median over {seeds} seeds) and how often it
contains the true [A_tr B_tr].  *paper (Lemma 1)*: the construction as published, with the
"adapted" Hansen-Bliek-Rohn formula for the interval pseudo-inverse, which is not an enclosure
(see `observers/datadriven/learning.py`; a test exhibits members whose pseudo-inverse lies
outside it).  *sound (theorem)*: our matrix zonotope from the exact identity
[A B] = (Xh+ + E+ - W - A E-) D^+ with an a-priori bound on the bilinear term.
*sound + LP*: its interval hull tightened by the per-sample linear constraints (dual-checked LP
bounds); the observers' default.

{chr(10).join(widths)}

## 2. Containment over {seeds} seeds (every step) and Kalman 3-sigma misses

FRad-A/B/C are model-based (true A and B, order 5), for reference.

{chr(10).join(cont)}

## 3. Per-step times (seed 0, median of {reps} runs; indicative, shared 2-core machine)

The paper: MATLAB + CORA on an i5-8365U.  Our step excludes the interval hull (`hull ms`,
linear programs for constrained zonotopes).

{chr(10).join(times)}

## 4. Area of the sets at step {SNAPSHOT} (seed 0; Fig. 3 of the paper)

{chr(10).join(fig_rows)}

## 5. Other scenarios (separate seeded offline experiments, full-state sensors)

FRad-B uses the true model; FRad-B and the data-driven observers use the scenario's order (100,
PCA; for the constrained-zonotope observers of the lifted zonotope), not the paper's 5.

{chr(10).join(others)}

## 6. Does the published single-record ranking hold over the seeds?

The observers of the configuration `alanwar2022` with their default options on the {seeds}
seeds of section 2 (each a new offline experiment and record), ranked by their mean RMS radius
(a run outside which the true state left is not ranked), against the committed result store's
single record (seed 0): {holds}
"""
    command = f"python -m benchmarks.studies.alanwar2022 --out {out}"
    cite = "\n".join(citation_lines("datadriven"))
    atomic_write_text(out, f"{text}\n{cite}\n\n{freshness.stamp(command)}\n")
    return out


def main(argv: list[str] | None = None) -> int:
    """Command line entry point."""
    p = argparse.ArgumentParser(prog="python -m benchmarks.studies.alanwar2022",
                                description=__doc__)
    p.add_argument("--out", default="reports/datadriven.md", help="Markdown file to write")
    p.add_argument("--seeds", type=int, default=20, help="seeds for sections 1 and 2")
    p.add_argument("--reps", type=int, default=5, help="timing repetitions")
    args = p.parse_args(argv)
    path = build(Path(args.out), args.seeds, args.reps)
    print(f"wrote {path}")
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
