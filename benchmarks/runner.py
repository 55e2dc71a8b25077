"""Run a benchmark configuration: every observer on every scenario, with containment checks
and timings, written as ``runs.csv``, ``summary.csv`` and ``meta.json`` (one generation)."""

from __future__ import annotations

import sys
import traceback
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path

import numpy as np
import pandas as pd

import observers
from observers import DesignFailed, OptionError, RunResult, Unsupported
from observers.sets import ConZonotope, Interval, Zonotope
from systems import ModelError, Scenario, available_memory

from .config import BenchConfig
from .errors import ConfigError
from .io import check_output_dir, environment, write_results
from .membership import MembershipTester
from .metrics import add_relative_rms, median_ms, rms_radius
from .progress import progress_bar
from .verdicts import contained_column, containment_verdict

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
    in_set: np.ndarray | None = None  # per set: exact membership (hull with `hull`)
    decided: bool = True  # every set tested as the configuration asks (exact or hull)

    @property
    def violations(self) -> int:
        """Steps at which the true state is outside the estimated set."""
        return 0 if self.in_set is None else int(np.sum(~self.in_set))


def _testable(S) -> bool:
    """Whether :class:`MembershipTester` can test membership in ``S`` exactly."""
    return isinstance(S, (Interval, Zonotope, ConZonotope)) or hasattr(S, "distance") or (
        hasattr(S, "contains"))


def check_containment(res: RunResult, x_true: np.ndarray, tol: float, exact: bool):
    """Hull containment per step and state, set membership per step, and whether every
    set was tested as asked.

    The exact test (:mod:`benchmarks.membership`: a membership certificate, else an LP) runs
    only where the hull test passes, since a point outside the interval hull is outside the set.
    A set that offers no exact test (a plugin's set with only ``interval()``) leaves the run
    undecided (``decided`` False) unless the hull already shows a violation.

    Returns
    -------
    hull : ndarray of bool, shape (K, n)
        Hull containment per produced set and state (with tolerance ``tol``).
    in_set : ndarray of bool, shape (K,)
        Membership per produced set (exact if ``exact``, else the hull test).
    decided : bool
        Whether every set passed through the test that was asked for.
    """
    N = len(res.sets)
    x = x_true[:N]
    hull = (x >= res.lo[:N] - tol) & (x <= res.hi[:N] + tol)
    in_set = hull.all(axis=1)
    decided = True
    if exact:
        tester = MembershipTester()
        for k in np.flatnonzero(in_set):
            S = res.sets[k]
            if _testable(S):
                in_set[k] = tester.contains(S, x[k], tol, hull=(res.lo[k], res.hi[k]))
            else:
                decided = False
    return hull, in_set, decided


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
    res = observers.run(obs, sc.u, sc.y, keep_sets=sc.x_true is not None, on_error="status")
    if res.error is not None:  # a plugin bug: reported, and the benchmark goes on
        print(f"warning: {name} failed on {sc.name}: {res.message}", file=sys.stderr)
        traceback.print_exception(res.error, limit=3, file=sys.stderr)
    same_dim = res.lo.shape[1] == sc.system.n
    if not same_dim and res.status == "ok":
        res.status, res.failed_step = "error", 0
        res.message = f"its sets have dimension {res.lo.shape[1]}, the system {sc.system.n}"
    run = ObserverRun(sc, info, res, res.status, res.message)
    if same_dim and sc.x_true is not None and len(res.sets):  # also the sets before a crash
        run.contained, run.in_set, run.decided = check_containment(
            res, sc.x_true, sc.tolerance, exact=(containment == "exact"))
    if not keep_sets:
        res.sets.clear()  # free memory; bounds are kept
    return run


def _bounds(res: RunResult, N: int, n: int) -> tuple[np.ndarray, np.ndarray]:
    """The run's bounds as N x n arrays (NaN where a failed run produced none)."""
    if res.lo.shape == (N, n):
        return res.lo, res.hi
    return np.full((N, n), np.nan), np.full((N, n), np.nan)


def _rows_runs(run: ObserverRun) -> pd.DataFrame:
    sc, res = run.scenario, run.result
    N, n = sc.N, sc.system.n
    step = np.repeat(np.arange(N), n)
    state = np.tile(np.arange(n), N)
    lo, hi = (b.reshape(-1) for b in _bounds(res, N, n))
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


def _rows_summary(run: ObserverRun, containment: str) -> pd.DataFrame:
    sc, res, info = run.scenario, run.result, run.info
    n = sc.system.n
    verdict = containment_verdict(run.status, sc.N, run.in_set, run.decided)
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
        contained_column(containment): verdict,
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


#: bytes a run needs per scenario step, state and observer (the row of runs.csv as a data
#: frame and as CSV text, the bounds and the kept sets; measured about 150, rounded up)
BYTES_PER_ROW = 256


def check_memory(cfg: BenchConfig) -> None:
    """Refuse, before any work, a configuration whose results would not fit in memory.

    Raises
    ------
    ConfigError
        If the estimated size of the results (:data:`BYTES_PER_ROW` per step, state and
        observer) exceeds the memory available.
    """
    need = BYTES_PER_ROW * len(cfg.observers) * sum(sc.N * sc.system.n for sc in cfg.scenarios)
    have = available_memory()
    if have is not None and need > have:
        raise ConfigError(f"config '{cfg.name}': its results need about {need / 2**30:.3g} GiB "
                          f"of memory, {have / 2**30:.3g} GiB are available; use fewer steps, "
                          "scenarios or observers")


def run_config(cfg: BenchConfig, out: str | Path | None = None, progress: bool | None = None):
    """Run every (scenario, observer) pair of ``cfg``.

    Returns ``(runs, summary)`` data frames; with ``out`` they are also written there
    (``runs.csv``, ``summary.csv``, ``meta.json``) as one generation
    (:func:`benchmarks.io.write_results`). The output folder and the memory needed are
    checked before any observer runs (:class:`ConfigError`).
    """
    if out is not None:
        check_output_dir(out)
    check_memory(cfg)
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
            summaries.append(_rows_summary(run, cfg.containment))
            bar.set_postfix_str(f"{sc.name}: {name} {run.status}", refresh=False)
            bar.update()
    runs_df = pd.concat(runs, ignore_index=True) if runs else pd.DataFrame(columns=RUN_COLUMNS)
    summary = add_relative_rms(pd.concat(summaries, ignore_index=True))
    cols = ["scenario", "observer", "state", "state_name", "rms_radius", "rel_rms", "step_ms",
            "hull_ms", "design_s", contained_column(cfg.containment), "violations",
            "first_violation_step", "status", "failed_step", "message", "family", "set_type",
            "timing", "guaranteed"]
    summary = summary[cols]
    if out is not None:
        write_results(out, {"runs.csv": runs_df, "summary.csv": summary}, {
            "config": {"name": cfg.name, "title": cfg.title, "raw": cfg.raw,
                       "containment": cfg.containment},
            "scenarios": {sc.name: {
                "N": sc.N, "n": sc.system.n, "dt": sc.system.dt, "paper_table": sc.paper_table,
                "description": sc.description, "source": sc.source,
                "state_names": list(sc.state_names), "tolerance": sc.tolerance,
            } for sc in cfg.scenarios},
            "created": datetime.now(timezone.utc).isoformat(timespec="seconds"),
            "versions": environment(),
        })
    return runs_df, summary
