"""Run a benchmark configuration: every observer on every scenario, with containment checks
and timings, written as ``runs.csv``, ``summary.csv`` and ``meta.json`` (atomically)."""

from __future__ import annotations

import sys
import traceback
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path

import numpy as np
import pandas as pd

import observers
from observers import DesignFailed, Diverged, OptionError, RunResult, Unsupported
from systems import ModelError, Scenario

from .config import BenchConfig
from .errors import ConfigError
from .io import atomic_write_csv, atomic_write_json, environment
from .membership import MembershipTester
from .metrics import add_relative_rms, median_ms, rms_radius
from .progress import progress_bar

RUN_COLUMNS = ["scenario", "observer", "step", "t", "state", "lo", "hi", "radius", "x_true",
               "contained", "in_set"]


@dataclass
class ObserverRun:
    """Result of one observer on one scenario, including containment."""

    scenario: Scenario
    info: observers.ObserverInfo
    result: RunResult | None
    status: str
    message: str = ""
    contained: np.ndarray | None = None  # N x n, hull containment (with tolerance)
    in_set: np.ndarray | None = None  # N, exact set membership (or hull if not checked)

    @property
    def violations(self) -> int:
        """Steps at which the true state is outside the estimated set."""
        return 0 if self.in_set is None else int(np.sum(~self.in_set))


def check_containment(res: RunResult, x_true: np.ndarray, tol: float, exact: bool):
    """Hull containment per step and state, and exact set membership per step.

    The exact test (:mod:`benchmarks.membership`: a membership certificate, else an LP) runs
    only where the hull test passes, since a point outside the interval hull is outside the set.
    """
    N = len(res.sets)
    x = x_true[:N]
    hull = (x >= res.lo[:N] - tol) & (x <= res.hi[:N] + tol)
    in_set = hull.all(axis=1)
    if exact:
        tester = MembershipTester()
        for k in np.flatnonzero(in_set):
            S = res.sets[k]
            if hasattr(S, "contains"):
                in_set[k] = tester.contains(S, x[k], tol, hull=(res.lo[k], res.hi[k]))
    return hull, in_set


def design_observer(name: str, sc: Scenario, options: dict
                    ) -> tuple[observers.Observer | None, str, str]:
    """Create observer ``name`` for ``sc.system`` (its offline design); a failed design
    becomes a status, not an exception.

    Parameters
    ----------
    name : str
        Registered observer name.
    sc : Scenario
        The scenario whose system the observer is designed for.
    options : dict
        Observer options (e.g. :meth:`BenchConfig.options_for`).

    Returns
    -------
    obs : Observer or None
        The designed observer, ``None`` if the design failed.
    status : str
        ``"ok"``, or the table status of the failure: ``"noGain"`` (design infeasible),
        ``"unsupported"`` (the observer does not apply to this system) or ``"error"`` (a bug in
        the plugin, reported with a short traceback on stderr).
    message : str
        Why the design failed (``""`` if it did not).

    Raises
    ------
    ConfigError
        If an option is invalid for this observer.
    """
    try:
        return observers.create(name, sc.system, **options), "ok", ""
    except OptionError as exc:
        raise ConfigError(str(exc)) from None
    except (DesignFailed, ModelError) as exc:
        return None, "noGain", str(exc)
    except Unsupported as exc:
        return None, "unsupported", str(exc)
    except Exception as exc:  # a plugin bug must not end the whole benchmark
        print(f"warning: {name} failed in its design on {sc.name}: {exc}", file=sys.stderr)
        traceback.print_exc(limit=3, file=sys.stderr)
        return None, "error", f"{type(exc).__name__}: {exc}"


def run_observer(name: str, sc: Scenario, options: dict, containment: str,
                 keep_sets: bool = False) -> ObserverRun:
    """Design and run one observer; failures become statuses, not exceptions.

    ``keep_sets``: keep the estimated sets in ``run.result.sets`` (for the soundness audit).
    """
    info = observers.get(name)
    obs, status, message = design_observer(name, sc, options)
    if obs is None:
        return ObserverRun(sc, info, None, status, message)
    try:
        res = observers.run(obs, sc.u, sc.y, keep_sets=sc.x_true is not None)
    except Diverged as exc:  # pragma: no cover - run() already converts these
        return ObserverRun(sc, info, None, "diverged", str(exc))
    except Exception as exc:
        print(f"warning: {name} failed on {sc.name}: {exc}", file=sys.stderr)
        traceback.print_exc(limit=3, file=sys.stderr)
        return ObserverRun(sc, info, None, "error", f"{type(exc).__name__}: {exc}")
    run = ObserverRun(sc, info, res, res.status, res.message)
    if sc.x_true is not None and len(res.sets):
        run.contained, run.in_set = check_containment(
            res, sc.x_true, sc.tolerance, exact=(containment == "exact"))
    if not keep_sets:
        res.sets.clear()  # free memory; bounds are kept
    return run


def _rows_runs(run: ObserverRun) -> pd.DataFrame:
    sc, res = run.scenario, run.result
    N, n = sc.N, sc.system.n
    step = np.repeat(np.arange(N), n)
    state = np.tile(np.arange(n), N)
    lo = res.lo.reshape(-1)
    hi = res.hi.reshape(-1)
    xt = sc.x_true.reshape(-1) if sc.x_true is not None else np.full(N * n, np.nan)
    contained = np.full((N, n), np.nan)
    in_set = np.full(N, np.nan)
    if run.contained is not None:
        k = run.contained.shape[0]
        contained[:k] = run.contained
        in_set[:k] = run.in_set
    return pd.DataFrame({
        "scenario": sc.name, "observer": run.info.name, "step": step,
        "t": step * sc.system.dt, "state": state, "lo": lo, "hi": hi, "radius": 0.5 * (hi - lo),
        "x_true": xt, "contained": contained.reshape(-1), "in_set": np.repeat(in_set, n),
    })


def _rows_summary(run: ObserverRun) -> pd.DataFrame:
    sc, res, info = run.scenario, run.result, run.info
    n = sc.system.n
    names = sc.state_names or tuple(f"x{i + 1}" for i in range(n))
    ok = run.status == "ok"
    first_violation = (int(np.argmax(~run.in_set)) if run.in_set is not None
                       and run.violations else -1)
    return pd.DataFrame({
        "scenario": sc.name,
        "observer": info.name,
        "state": np.arange(n),
        "state_name": list(names),
        "rms_radius": rms_radius(res.radius) if ok else np.full(n, np.nan),
        "step_ms": median_ms(res.step_times) if res is not None else np.nan,
        "hull_ms": median_ms(res.hull_times) if res is not None else np.nan,
        "design_s": res.design_time if res is not None else np.nan,
        "contained_all": (bool(run.contained.all()) if run.contained is not None else None),
        "violations": run.violations if run.in_set is not None else None,
        "first_violation_step": first_violation if run.in_set is not None else None,
        "status": run.status,
        "failed_step": res.failed_step if res is not None else None,
        "message": run.message,
        "family": info.family,
        "set_type": info.set_type,
        "timing": info.timing,
        "guaranteed": info.guaranteed,
    })


def run_config(cfg: BenchConfig, out: str | Path | None = None, progress: bool | None = None):
    """Run every (scenario, observer) pair of ``cfg``.

    Returns ``(runs, summary)`` data frames; with ``out`` they are also written there
    (``runs.csv``, ``summary.csv``, ``meta.json``), each file atomically.
    """
    pairs = [(sc, name) for sc in cfg.scenarios for name in cfg.observers]
    runs, summaries = [], []
    with progress_bar(len(pairs), cfg.name, progress) as bar:
        for sc, name in pairs:
            run = run_observer(name, sc, cfg.options_for(name, sc), cfg.containment)
            if run.result is not None:
                runs.append(_rows_runs(run))
            else:
                res = RunResult(name, np.full((sc.N, sc.system.n), np.nan),
                                np.full((sc.N, sc.system.n), np.nan), [], np.full(sc.N, np.nan),
                                np.full(sc.N, np.nan), np.nan, run.status, run.message)
                run.result = res
            summaries.append(_rows_summary(run))
            bar.set_postfix_str(f"{sc.name}: {name} {run.status}", refresh=False)
            bar.update()
    runs_df = pd.concat(runs, ignore_index=True) if runs else pd.DataFrame(columns=RUN_COLUMNS)
    summary = add_relative_rms(pd.concat(summaries, ignore_index=True))
    cols = ["scenario", "observer", "state", "state_name", "rms_radius", "rel_rms", "step_ms",
            "hull_ms", "design_s", "contained_all", "violations", "first_violation_step",
            "status", "failed_step", "message", "family", "set_type", "timing", "guaranteed"]
    summary = summary[cols]
    if out is not None:
        out = Path(out)
        out.mkdir(parents=True, exist_ok=True)
        atomic_write_csv(out / "runs.csv", runs_df)
        atomic_write_csv(out / "summary.csv", summary)
        atomic_write_json(out / "meta.json", {
            "config": {"name": cfg.name, "title": cfg.title, "raw": cfg.raw},
            "scenarios": {sc.name: {
                "N": sc.N, "n": sc.system.n, "dt": sc.system.dt, "paper_table": sc.paper_table,
                "description": sc.description, "source": sc.source,
                "state_names": list(sc.state_names), "tolerance": sc.tolerance,
            } for sc in cfg.scenarios},
            "created": datetime.now(timezone.utc).isoformat(timespec="seconds"),
            "versions": environment(),
        })
    return runs_df, summary
