"""CI regression gate: golden summaries of a fast benchmark subset, and their comparison.

``python -m benchmarks baseline --update`` runs the subset (``configs/regression.yaml``: every
registered observer on four small records) and writes one golden file per scenario,
``results/baseline/<scenario>.csv`` (observer x state: ``status``, ``rms_radius``,
``rel_rms``, ``violations``, ``rtol``), plus ``meta.json`` (with the version of setobs-bench
that wrote them, :data:`VERSION_KEY`: a change of a golden number is at least a minor version,
``CHANGELOG.md``).  ``python -m benchmarks check``
re-runs the subset and compares:

* the set of (scenario, observer) pairs: a pair missing now or new since the baseline fails
  (a new observer is gated only once it is in the baseline);
* ``status`` (ok, noGain, diverged) exactly; an ``error`` status (a crash) always fails;
* ``rms_radius`` within the observer's relative tolerance ``rtol``;
* ``rel_rms`` within ``rtol + rtol_best`` (a ratio: the tolerance of the best observer of
  that state adds), recomputed against the baseline's observers only, so that a new, better
  observer does not shift the ratios of the others;
* ``violations`` (interval-hull containment failures, where the true state is known) exactly;
* the soundness verdicts (:data:`benchmarks.verdicts.SOUNDNESS_COLUMNS`: ``contained``, exact
  membership of the true state in every set, computed by the gate beside the hull test): a
  guaranteed observer with ``no`` fails, and is never called tighter.  A tighter radius must
  also pass the short soundness audit before the last line calls it tighter
  (:mod:`.policy`).

Timings are never compared: a job only has to end within its time budget, derived from the
cost of each job recorded beside the golden files (``cost.json``, :mod:`.budget`).

Tolerances are data, not code paths: ``rtol`` is the larger of the class attribute
``REGRESSION_RTOL`` of the observer (``observers.Observer``: 1e-6, deterministic online
computations; ``OfflineGain``: 1e-4, gains from an SDP solver, accurate to the solver's
tolerance; a plugin sets its own) and a *measured* sensitivity to the BLAS kernel
(:mod:`~benchmarks.gate.blas`: an observer whose numbers depend on the kernel, e.g. an SDP
design on a flat optimum, gets a tolerance from the spread measured under the other OpenBLAS
kernel families; ``SENSITIVITY.md`` beside the golden files lists them).  An ``rtol`` of
:data:`CHAOTIC_RTOL` or more marks the observer as *chaotic* on that scenario: a 0.5 %
loosening may pass there; everywhere else it fails.  The comparison uses the larger of the
stored and the current class tolerance.

Installed third-party plugins (observers not defined in the ``observers`` package) are not
part of the project's baseline: ``baseline --update`` leaves them out and ``check`` lists them
as "not in the baseline" without failing, unless ``--strict``.

The last line of ``check`` says what changed: which observers got looser or tighter, which
changed containment (violations) or status, and which are new or missing.

Offline designs are recomputed by default (the design cache is switched off for the run,
``SETOBS_CACHE_DIR=off``), so that the gate tests the design code and never a stale cached
gain; ``--use-cache`` uses the cache instead.  Both the baseline and the check record which.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path

import pandas as pd

import observers

from ..errors import ConfigError
from ..io import (
    atomic_write_csv,
    atomic_write_json,
    environment,
    path_component,
    read_json_object,
)
from ..metrics import add_relative_rms
from ..report.citation import project_version
from ..report.numbers import fmt, text_table
from ..run.config import BenchConfig, load_config
from ..run.runner import is_project_module, run_config
from ..verdicts import HULL_AND_EXACT, NO, SOUNDNESS_COLUMNS
from .budget import GATE_TIMEOUT, GateExecutor, cpu_model

DEFAULT_CONFIG = Path(__file__).resolve().parent.parent / "configs" / "regression.yaml"
DEFAULT_BASELINE = Path("results") / "baseline"
BASELINE_COLUMNS = ["scenario", "observer", "state", "state_name", "status", "guaranteed",
                    "rms_radius", "rel_rms", "violations", "rtol", "kernel_spread", "gap",
                    "covers_exact"]
#: the precision of the exact floor (its agreement with an independent LP formulation),
#: added to an observer's tolerance where its gap is compared
GAP_RTOL = 1e-6
#: absolute tolerance of every comparison (values that are zero up to rounding)
ATOL = 1e-12
DEFAULT_RTOL = 1e-6
#: an observer with a tolerance from here on is chaotic on that scenario: the gate cannot see
#: a 0.5 % loosening of its radii (half of 0.5 %, since ``rel_rms`` adds the best one's)
CHAOTIC_RTOL = 0.0025


def is_project_observer(name: str) -> bool:
    """Whether ``name`` is one of the project's observers (not a third-party plugin)."""
    return is_project_module(getattr(observers.get(name).cls, "__module__", "") or "")


def regression_rtol(name: str) -> float:
    """The regression tolerance of observer ``name`` (its class's ``REGRESSION_RTOL``)."""
    rtol = getattr(observers.get(name).cls, "REGRESSION_RTOL", DEFAULT_RTOL)
    try:
        rtol = float(rtol)
    except (TypeError, ValueError):
        rtol = math.nan
    if not (math.isfinite(rtol) and 0 < rtol < 1):
        raise ConfigError(f"{name}: REGRESSION_RTOL must be a number in (0, 1), got {rtol!r}")
    return rtol


@contextmanager
def design_cache(use_cache: bool) -> Iterator[str]:
    """Switch the design cache off for the block unless ``use_cache``; yields a description."""
    if use_cache:
        yield f"cached designs ({os.environ.get('SETOBS_CACHE_DIR') or 'default cache folder'})"
        return
    old = os.environ.get("SETOBS_CACHE_DIR")
    os.environ["SETOBS_CACHE_DIR"] = "off"
    try:
        yield "designs recomputed (SETOBS_CACHE_DIR=off)"
    finally:
        if old is None:
            os.environ.pop("SETOBS_CACHE_DIR", None)
        else:
            os.environ["SETOBS_CACHE_DIR"] = old


def subset_config(path: str | Path = DEFAULT_CONFIG, plugins: bool = True) -> BenchConfig:
    """The regression subset; ``observers: all`` means every registered observer here,
    including the non-guaranteed baselines (their numbers are regression-tested too), and the
    installed third-party plugins unless ``plugins`` is False (the baseline leaves them out)."""
    cfg = load_config(path)
    if cfg.raw.get("observers", "all") == "all":
        excluded = set(map(str, cfg.raw.get("exclude", []) or []))
        cfg.observers = [i.name for i in observers.available() if i.name not in excluded
                         and (plugins or is_project_observer(i.name))]
    return cfg


def run_subset(cfg: BenchConfig, use_cache: bool = False, progress: bool | None = None,
               out: str | Path | None = None, executor: GateExecutor | None = None
               ) -> tuple[pd.DataFrame, str]:
    """Run the subset; returns the golden-file rows (with the soundness verdict columns,
    which the golden files do not store) and the design-cache description.

    Where the subset asks for the hull test, exact membership is checked beside it
    (``hull+exact``): the golden ``violations`` stay hull counts, and ``contained`` says
    whether the true state lies in every set.  The jobs run serially on ``executor``
    (:class:`~benchmarks.gate.budget.GateExecutor`: a budget per job from the recorded
    costs, and the wall time of each job; closed here), by default one with the budget of
    the configuration's ``timeout``, else :data:`~benchmarks.gate.budget.GATE_TIMEOUT`, for
    every job.  The compiled kernels are loaded first (:func:`benchmarks.run.warmup.warm`),
    outside every job's budget."""
    if cfg.containment == "hull":
        cfg.containment = HULL_AND_EXACT  # not in cfg.raw: the configuration is unchanged
    if "timeout" not in cfg.raw:  # a hanging plugin must not hold the gate for half an hour
        cfg.timeout = GATE_TIMEOUT
    # the compiled kernels loaded (compiled on a cold numba cache: minutes) before the first
    # timed job, so that no job's budget or recorded cost holds their compilation
    from ..run.warmup import warm

    warm(parallel=True)
    executor = executor or GateExecutor(cfg)
    try:
        with design_cache(use_cache) as cache_note:
            _, summary = run_config(cfg, out, progress=progress, executor=executor)
    finally:
        executor.close()
    frame = summary.copy()
    frame["rtol"] = [regression_rtol(o) for o in frame["observer"]]
    frame["kernel_spread"] = 0.0
    # the gap to the exact floor is gated; an upper bound (the falsifier's, on a nonlinear
    # record) is a search's result, not a number to hold the observers to
    frame.loc[frame["gap_kind"].astype(str) != "exact", "gap"] = float("nan")
    verdicts = [c for c in SOUNDNESS_COLUMNS if c in frame.columns and c not in
                BASELINE_COLUMNS]
    return frame[BASELINE_COLUMNS + verdicts], cache_note


#: the key of ``meta.json`` naming the version of setobs-bench that wrote the golden files
VERSION_KEY = "setobs_bench_version"


def record_version(folder: str | Path, version: str | None = None) -> Path:
    """Write the package version into the ``meta.json`` of the golden files in ``folder``,
    changing nothing else (no golden number is rewritten, nothing is run).

    Parameters
    ----------
    folder : str or Path
        A folder of golden files with a ``meta.json`` (e.g. ``results/baseline``).
    version : str, optional
        The version to record; default :func:`benchmarks.report.citation.project_version`.

    Returns
    -------
    Path
        The ``meta.json`` written.

    Raises
    ------
    ConfigError
        If ``folder`` has no ``meta.json`` or it is not a JSON object.
    """
    path = Path(folder) / "meta.json"
    if not path.is_file():
        raise ConfigError(f"no golden meta data {path} (make the baseline first)")
    meta = read_json_object(path, "baseline")
    atomic_write_json(path, _with_version(meta, version))
    return path


def _with_version(meta: dict, version: str | None = None) -> dict:
    """``meta`` with :data:`VERSION_KEY` set (the one code path of both writers)."""
    return {**meta, VERSION_KEY: project_version() if version is None else version}


def _meta(cfg: BenchConfig, cache_note: str, kernels_compared: list[str] | None = None
          ) -> dict:
    env = environment()
    return _with_version({
        "config": {"name": cfg.name, "raw": cfg.raw},
        "observers": cfg.observers,
        "design_cache": cache_note,
        "created": datetime.now(timezone.utc).isoformat(timespec="seconds"),
        "versions": env,
        # which machine and BLAS kernel produced the golden numbers, and the kernels whose
        # runs measured their spread (SENSITIVITY.md)
        "machine": {"cpu": cpu_model(), "blas_coretype": env.get("blas_coretype"),
                    "kernels_compared": list(kernels_compared or [])},
    })


def write_baseline(frame: pd.DataFrame, folder: str | Path, cfg: BenchConfig,
                   cache_note: str, kernels_compared: list[str] | None = None) -> list[Path]:
    """Write one golden CSV per scenario (atomically), remove stale ones, write meta.json
    (with the machine, its BLAS kernel and ``kernels_compared``)."""
    folder = Path(folder)
    written = []
    for sc, g in frame.groupby("scenario", sort=False):
        path = folder / f"{path_component(sc)}.csv"
        g = g[BASELINE_COLUMNS].reset_index(drop=True).assign(
            rtol=g["rtol"].map("{:g}".format).to_numpy(),
            kernel_spread=g["kernel_spread"].map("{:.3g}".format).to_numpy())
        atomic_write_csv(path, g)
        written.append(path)
    for stale in set(folder.glob("*.csv")) - set(written):
        stale.unlink()
    atomic_write_json(folder / "meta.json", _meta(cfg, cache_note, kernels_compared))
    return written


def unsound_pairs(frame: pd.DataFrame) -> list[tuple[str, str, str]]:
    """``(scenario, observer, column)`` of each guaranteed observer's run with ``no`` in a
    soundness verdict column (:data:`benchmarks.verdicts.SOUNDNESS_COLUMNS`)."""
    per = frame.drop_duplicates(["scenario", "observer"])
    guaranteed = per["guaranteed"].astype(str).str.lower().isin(["true", "1"])
    return [(s, o, col) for col in SOUNDNESS_COLUMNS if col in per.columns
            for s, o in zip(per.loc[guaranteed & (per[col].astype(str) == NO), "scenario"],
                            per.loc[guaranteed & (per[col].astype(str) == NO), "observer"],
                            strict=True)]


def baseline_problems(frame: pd.DataFrame) -> list[str]:
    """Why a run must not become the baseline: a crashed or stopped observer, or a guaranteed
    observer whose sets miss the true state (hull violations, or ``no`` in any soundness
    verdict column): a bug to fix, not a number to enshrine."""
    per = frame.drop_duplicates(["scenario", "observer"])
    crashed = per[per["status"].isin(["error", "timeout", "memory"])]
    unsound = per[(pd.to_numeric(per["violations"], errors="coerce").fillna(0) > 0)
                  & per["guaranteed"].astype(bool)]
    return ([f"{o} crashed on {s}" if st == "error" else f"{o} stopped on {s} ({st})"
             for s, o, st in zip(crashed["scenario"], crashed["observer"], crashed["status"],
                                 strict=True)]
            + [f"{o} violates containment on {s}"
               for s, o in zip(unsound["scenario"], unsound["observer"], strict=True)]
            + [f"{o} fails '{col}' on {s} (the true state is outside one of its sets)"
               for s, o, col in unsound_pairs(frame)])


def load_baseline(folder: str | Path) -> tuple[pd.DataFrame, dict]:
    """The golden rows of all scenarios and the baseline's meta data."""
    folder = Path(folder)
    files = sorted(folder.glob("*.csv"))
    if not files:
        raise ConfigError(f"no baseline in {folder} (write one with "
                          "`python -m benchmarks baseline --update`)")
    parts = []
    for path in files:
        try:
            df = pd.read_csv(path)
        except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError) as exc:
            raise ConfigError(f"baseline file {path} is not readable CSV: "
                              f"{str(exc).splitlines()[0]}") from None
        if "kernel_spread" not in df.columns:  # baselines written before it was measured
            df["kernel_spread"] = 0.0
        for col, missing_value in (("gap", math.nan), ("covers_exact", "n/a")):
            if col not in df.columns:  # baselines written before the exact floor existed
                df[col] = missing_value
        missing = [c for c in BASELINE_COLUMNS if c not in df.columns]
        if missing:
            raise ConfigError(f"baseline file {path} lacks column(s) {missing}")
        parts.append(df[BASELINE_COLUMNS])
    meta_path = folder / "meta.json"
    try:
        meta = json.loads(meta_path.read_text()) if meta_path.is_file() else {}
    except json.JSONDecodeError as exc:
        raise ConfigError(f"baseline {meta_path} is not valid JSON: {exc.msg}") from None
    return pd.concat(parts, ignore_index=True), meta


# -- comparison -----------------------------------------------------------------------------
def _close(a: float, b: float, tol: float) -> bool:
    if isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b):
        return True
    return bool(abs(a - b) <= tol * abs(b) + ATOL)


def _rel(a: float, b: float) -> float:
    if b == 0 or not (math.isfinite(a) and math.isfinite(b)):
        return math.nan if a == b or (math.isnan(a) and math.isnan(b)) else math.inf
    return abs(a - b) / abs(b)


@dataclass(frozen=True)
class _At:
    """Where a compared value is: scenario, observer and state (``-``: the observer's row)."""

    scenario: str
    observer: str
    state: str = "-"

    def row(self, metric, base, cur, tol, ok, note="") -> dict:
        """One row of :func:`compare` at this place."""
        rel = _rel(float(cur), float(base)) if isinstance(base, (int, float)) and isinstance(
            cur, (int, float)) else math.nan
        return {"scenario": self.scenario, "observer": self.observer, "state": self.state,
                "metric": metric, "baseline": base, "current": cur, "rel_diff": rel,
                "tol": tol, "ok": bool(ok), "note": note}


def _best_rtol(base: pd.DataFrame, rtols: dict[tuple[str, str], float]
               ) -> dict[tuple[str, int], float]:
    ok = base[(base["status"] == "ok") & base["guaranteed"].astype(bool)]
    out = {}
    for (sc, st), g in ok.groupby(["scenario", "state"]):
        best = g.loc[g["rms_radius"].idxmin(), "observer"]
        out[(sc, int(st))] = rtols.get((sc, best),
                                       float(g.loc[g["rms_radius"].idxmin(), "rtol"]))
    return out


def _normalise(df: pd.DataFrame) -> pd.DataFrame:
    df = df.copy()
    for col in ("rms_radius", "rel_rms", "violations", "rtol", "gap"):
        df[col] = pd.to_numeric(df[col], errors="coerce").astype(float)
    df["covers_exact"] = df["covers_exact"].astype(object).fillna("n/a").astype(str)
    df["state"] = df["state"].astype(int)
    df["status"] = df["status"].astype(str)
    df["guaranteed"] = df["guaranteed"].astype(str).str.lower().isin(["true", "1"])
    return df


def compare(base: pd.DataFrame, cur: pd.DataFrame, strict: bool = False) -> pd.DataFrame:
    """Every compared value as a row (``ok`` False for a regression); see the module doc.

    A third-party plugin that is not in the baseline is listed (``ok`` True, metric
    ``observer``, note "not in the baseline") unless ``strict``, where it fails."""
    base, cur = _normalise(base), _normalise(cur)
    rows: list[dict] = []
    bpairs = set(zip(base["scenario"], base["observer"], strict=True))
    cpairs = set(zip(cur["scenario"], cur["observer"], strict=True))
    for sc, obs in sorted(bpairs - cpairs):
        rows.append(_At(sc, obs).row("observer", "present", "missing", "", False,
                                     "in the baseline but not run now (removed or unregistered?)"))
    bad_verdicts: dict[tuple[str, str], list[str]] = {}
    for s_, o, c in unsound_pairs(cur):
        bad_verdicts.setdefault((s_, o), []).append(c)
    cur_status = dict(zip(zip(cur["scenario"], cur["observer"], strict=True), cur["status"],
                          strict=True))
    for sc, obs in sorted(cpairs - bpairs):
        plugin = not is_project_observer(obs)
        note = ("not in the baseline (third-party plugin, not gated; --strict fails on it)"
                if plugin and not strict else
                "not in the baseline: `python -m benchmarks baseline --update`")
        # a plugin's numbers are not gated, but a plugin that crashed, was stopped or is
        # unsound fails the gate (named on the last line)
        culprit = _culprit(cur_status[(sc, obs)], bad_verdicts.get((sc, obs)))
        rows.append(_At(sc, obs).row("observer", "absent", "present", "",
                                     plugin and not strict and not culprit,
                                     note + (f"; {FAILING}{culprit}" if culprit else "")))
    for (sc, obs), cols in sorted(bad_verdicts.items()):
        if (sc, obs) in bpairs:
            rows += [_At(sc, obs).row(col, "-", NO, "", False,
                                      VERDICT_NOTES.get(col, "a soundness verdict says no"))
                     for col in cols]
    keep = [p in bpairs for p in zip(cur["scenario"], cur["observer"], strict=True)]
    common = add_relative_rms(cur[keep].drop(columns="rel_rms"))
    # the larger of the stored (class or measured) and the current class tolerance
    stored = {(s, o): float(r) for s, o, r in zip(base["scenario"], base["observer"],
                                                  base["rtol"], strict=True)}
    rtols = {(s, o): max(float(r), stored.get((s, o), 0.0))
             for s, o, r in zip(common["scenario"], common["observer"], common["rtol"],
                                strict=True)}
    best = _best_rtol(base, rtols)
    merged = base.merge(common, on=["scenario", "observer", "state"], how="outer",
                        suffixes=("_b", "_c"), indicator="origin")
    merged = merged[merged["origin"] != "left_only"].copy()  # missing pairs reported above
    status_done: set[tuple[str, str]] = set()
    for r in merged.itertuples(index=False):
        sc, obs, st = r.scenario, r.observer, int(r.state)
        name = r.state_name_b if isinstance(r.state_name_b, str) else r.state_name_c
        label = f"{name}" if isinstance(name, str) else f"x{st + 1}"
        pair, cell = _At(sc, obs), _At(sc, obs, label)
        if r.origin == "right_only":
            rows.append(cell.row("state", "absent", "present", "", False,
                                 "state not in the baseline"))
            continue
        rtol = rtols[(sc, obs)]
        first = (sc, obs) not in status_done  # status and violations: once per observer
        status_done.add((sc, obs))
        if r.status_c == "error" or r.status_b != r.status_c:
            if first:
                note = "the observer crashed (see the warning above)" if (
                    r.status_c == "error") else ""
                rows.append(pair.row("status", r.status_b, r.status_c, "", False, note))
            continue
        if first:
            rows.append(pair.row("status", r.status_b, r.status_c, "", True))
            vb, vc = float(r.violations_b), float(r.violations_c)
            same = (math.isnan(vb) and math.isnan(vc)) or vb == vc
            rows.append(pair.row("violations", vb, vc, 0.0, same,
                                 "" if same else "containment changed"))
            cb, cc = r.covers_exact_b, r.covers_exact_c
            if cb != "n/a" or cc != "n/a":  # gated once the baseline has the exact floor
                rows.append(pair.row("covers_exact", cb, cc, 0.0, cb == cc,
                                     "" if cb == cc else "covering of the exact floor changed"))
        if r.status_c == "ok":
            rows.append(cell.row("rms_radius", float(r.rms_radius_b),
                                 float(r.rms_radius_c), rtol,
                                 _close(float(r.rms_radius_c), float(r.rms_radius_b), rtol)))
            tol_rel = rtol + best.get((sc, st), rtol)
            rows.append(cell.row("rel_rms", float(r.rel_rms_b), float(r.rel_rms_c), tol_rel,
                                 _close(float(r.rel_rms_c), float(r.rel_rms_b), tol_rel)))
            gb, gc = float(r.gap_b), float(r.gap_c)
            if not math.isnan(gb):  # an upper bound (nonlinear record) moves with its search
                tol_gap = rtol + GAP_RTOL
                rows.append(cell.row("gap", gb, gc, tol_gap, _close(gc, gb, tol_gap)))
    return pd.DataFrame(rows, columns=["scenario", "observer", "state", "metric", "baseline",
                                       "current", "rel_diff", "tol", "ok", "note"])


#: what a ``no`` in each soundness verdict column means, in the diff
VERDICT_NOTES = {
    "contained": "the true state is outside one of its sets (exact membership)",
    "covers_exact": "a state consistent with the data lies outside one of its interval hulls "
                    "(exact floor, or the falsifier on a nonlinear record)",
}

#: marks what went wrong with a plugin in its diff note
FAILING = "failing: "


def _culprit(status: str, bad_verdicts: list[str] | None) -> str:
    """What is wrong with a run (``""`` if nothing): its status, or its unsound verdicts."""
    if status not in ("ok", "noGain", "unsupported"):
        return f"status {status}"
    return (f"unsound ({', '.join(f'{c}: no' for c in bad_verdicts)})" if bad_verdicts
            else "")


def culprits(diff: pd.DataFrame) -> str:
    """The third-party plugins not in the baseline that crashed, were stopped or are
    unsound, with their scenarios and what went wrong (``""`` if none)."""
    rows = diff[(diff["metric"] == "observer") & (diff["current"] == "present")
                & diff["note"].astype(str).str.contains("third-party plugin")
                & diff["note"].astype(str).str.contains(FAILING, regex=False)]
    return "; ".join(f"{r.observer} on {r.scenario}: {str(r.note).split(FAILING, 1)[1]}"
                     for r in rows.itertuples(index=False))


def proof_rows(violations: dict[str, str]) -> pd.DataFrame:
    """Failing ``audit`` rows of the diff for observers that got tighter but whose sets
    missed the true state in the short soundness audit (``observer -> where``)."""
    note = ("tighter, but the short soundness audit found the true state outside its sets: "
            "not an improvement")
    return pd.DataFrame([_At("audit --short", o).row("audit", "0 violations", where, "", False,
                                                     note)
                         for o, where in violations.items()],
                        columns=["scenario", "observer", "state", "metric", "baseline",
                                 "current", "rel_diff", "tol", "ok", "note"])


def tighter_observers(diff: pd.DataFrame) -> list[str]:
    """Observers with an ``rms_radius`` that failed by getting smaller (to be proven sound
    before they are called tighter)."""
    own = diff[~diff["ok"] & (diff["metric"] == "rms_radius")]
    cur = pd.to_numeric(own["current"], errors="coerce")
    base = pd.to_numeric(own["baseline"], errors="coerce")
    return list(dict.fromkeys(own.loc[cur < base, "observer"]))


def _diff_table(rows: pd.DataFrame) -> str:
    """Fixed-width table of compared values (baseline and current to 10 digits)."""
    head = ["scenario", "observer", "state", "metric", "baseline", "current", "rel.diff", "tol",
            "verdict"]
    body = []
    for r in rows.itertuples(index=False):
        tol = r.tol if isinstance(r.tol, str) else ("exact" if r.tol == 0 else f"{r.tol:.0e}")
        verdict = "ok" if r.ok else "REGRESSION" + (f": {r.note}" if r.note else "")
        body.append([str(r.scenario), str(r.observer), str(r.state), r.metric,
                     _value_cell(r.baseline), _value_cell(r.current), fmt(r.rel_diff, 3),
                     tol or "-", verdict])
    return text_table(head, body)


def _value_cell(x) -> str:
    """A compared value: a word as it is, a number to 10 significant digits."""
    return x if isinstance(x, str) else fmt(x, 10)


def _consequential(diff: pd.DataFrame) -> pd.Series:
    """Failing ``rel_rms`` rows whose own ``rms_radius`` passed: the ratio moved because the
    best observer of that state changed, not this observer."""
    rms_ok = {(r.scenario, r.observer, r.state) for r in diff.itertuples(index=False)
              if r.metric == "rms_radius" and r.ok}
    return pd.Series([(not r.ok) and r.metric == "rel_rms"
                      and (r.scenario, r.observer, r.state) in rms_ok
                      for r in diff.itertuples(index=False)], index=diff.index, dtype=bool)


def _where(rows: pd.DataFrame) -> str:
    if rows.empty:
        return "none"
    per = rows.groupby("observer", sort=False)["scenario"].agg(lambda s: ", ".join(
        dict.fromkeys(map(str, s))))
    return "; ".join(f"{o} ({s})" for o, s in per.items())


def change_summary(diff: pd.DataFrame) -> str:
    """One line saying what changed: ``looser: ... | tighter: ... | containment: ...``
    (observers with their scenarios, "none" if nothing), then status changes, new and
    missing observers, and third-party plugins not in the baseline, where there are any."""
    own = diff[~diff["ok"] & ~_consequential(diff)]
    radius = own[own["metric"] == "rms_radius"]
    cur = pd.to_numeric(radius["current"], errors="coerce")
    base = pd.to_numeric(radius["baseline"], errors="coerce")
    # a smaller radius is "tighter" only if nothing says its sets miss the true state
    containment = own[own["metric"].isin(("violations", "audit", *SOUNDNESS_COLUMNS))]
    unproven = radius["observer"].isin(set(containment["observer"]))
    parts = [f"looser: {_where(radius[cur > base])}",
             f"tighter: {_where(radius[(cur < base) & ~unproven])}",
             f"containment: {_where(containment)}"]
    extra = {"status": own[own["metric"] == "status"],
             "new": own[(own["metric"] == "observer") & (own["current"] == "present")
                        & ~own["note"].astype(str).str.contains("third-party plugin")],
             "missing": own[(own["metric"] == "observer") & (own["current"] == "missing")],
             "not in the baseline (plugins)": diff[diff["ok"] & (diff["metric"] == "observer")]}
    bad_plugins = culprits(diff)
    parts += [f"{k}: {_where(v)}" for k, v in extra.items() if not v.empty]
    if bad_plugins:
        parts.append(f"plugins failing: {bad_plugins}")
    return " | ".join(parts)


def format_diff(diff: pd.DataFrame, only_failures: bool = True) -> str:
    """Fixed-width tables of the compared values (by default only the failing ones): first the
    observers' own changes, then the ratios that moved only because the best observer of a
    state changed."""
    if not only_failures:
        return _diff_table(diff)
    follow = _consequential(diff)
    own = diff[~diff["ok"] & ~follow]
    parts = [_diff_table(own)]
    if follow.any():
        parts += ["", "relative RMS that moved only because the best observer of the state "
                  "changed:", _diff_table(diff[follow])]
    return "\n".join(parts)


def config_changed(cfg: BenchConfig, meta: dict) -> bool:
    """Whether the subset's configuration differs from the one the baseline was made with."""
    raw = meta.get("config", {}).get("raw")
    if raw is None:
        return False
    return json.dumps(raw, sort_keys=True, default=str) != json.dumps(cfg.raw, sort_keys=True,
                                                                      default=str)


#: entries of the baseline's ``versions`` that change numerical results
NUMERIC_ENVIRONMENT = ("blas_coretype", "numpy", "scipy", "cvxpy", "clarabel", "highspy")


def environment_differences(meta: dict, current: dict | None = None) -> list[str]:
    """``"key: baseline -> current"`` for each numerically relevant version that differs
    between the baseline's environment and this one (hints for a failing check)."""
    current = environment() if current is None else current
    stored = meta.get("versions", {})
    return [f"{key}: {stored.get(key, '?')} -> {current.get(key, '?')}"
            for key in NUMERIC_ENVIRONMENT if stored.get(key, "?") != current.get(key, "?")]


def baseline_overview(frame: pd.DataFrame, meta: dict) -> str:
    """Plain-text overview of a stored baseline (``python -m benchmarks baseline``)."""
    lines = [f"baseline of {meta.get('created', '?')} ({meta.get('design_cache', '?')}; "
             f"setobs-bench {meta.get(VERSION_KEY, '?')}; "
             f"git {meta.get('versions', {}).get('git', '?')})"]
    per = frame.drop_duplicates(["scenario", "observer"])
    for obs, g in per.groupby("observer", sort=False):
        statuses = ", ".join(f"{s}: {st}" for s, st in zip(g["scenario"], g["status"],
                                                             strict=True))
        lines.append(f"  {obs:<12} rtol {float(g['rtol'].iloc[0]):.0e}  {statuses}")
    n_sc = frame["scenario"].nunique()
    lines.append(f"{per['observer'].nunique()} observers x {n_sc} scenarios, "
                 f"{len(frame)} rows")
    return "\n".join(lines)
