"""The rows of one job: a pure function of the job (its scenario entry, observer and options)
and, for the floor columns, of its record's floor.

This module is what a stored row is computed by, and the root of every row's fingerprint
(:mod:`benchmarks.store.fingerprint`): the observer's design and run, the containment checks
(:mod:`.membership`), the metrics, the per-step and per-state frames, the floor columns
(:mod:`.floor`) and the merge of the options it runs with.  It imports nothing that
orchestrates a run (executors, progress bars, input/output, the store, the gate, the reports):
a change there changes no row (``tests/test_layering.py`` keeps it so).  The runner
(:mod:`.runner`) hands the jobs to an executor and writes their rows.
"""

from __future__ import annotations

import dataclasses
import importlib
import sys
import traceback
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd

import observers
from observers import DesignFailed, OptionError, RunResult, Unsupported
from observers.sets import Interval
from systems import ModelError, Scenario

from ..errors import ConfigError
from ..metrics import PHASE_COLUMNS, median_ms, memory_columns, rms_radius
from ..verdicts import HULL_AND_EXACT, NA, contained_column, containment_verdict
from .floor import RecordFloor, floor_columns, observer_floor
from .membership import MembershipTester
from .specs import scenario_of

RUN_COLUMNS = ["scenario", "seed", "observer", "variant", "step", "t", "state", "lo", "hi",
               "radius", "x_true", "contained", "in_set", "floor_lo", "floor_hi"]
#: the floor columns of ``summary.csv`` (:mod:`.floor`)
FLOOR_COLUMNS = ["floor", "gap", "gap_steady", "gap_kind", "covers_exact", "uncovered_steps",
                 "first_uncovered_step"]


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
    #: the exact-membership verdict beside a hull test (containment ``hull+exact``)
    exact_verdict: str = NA
    #: mean milliseconds per step of each phase the observer times (``phase_times``:
    #: prediction, update, reduction, hull of a nonlinear or constrained-zonotope step)
    phase_ms: dict = dataclasses.field(default_factory=dict)

    @property
    def violations(self) -> int:
        """Steps at which the true state is outside the estimated set."""
        return 0 if self.in_set is None else int(np.sum(~self.in_set))


def _testable(S) -> bool:
    """Whether :class:`MembershipTester` can test membership in ``S`` exactly."""
    return isinstance(S, Interval) or any(hasattr(S, a) for a in ("box_form", "distance",
                                                                    "contains"))


def check_containment(res: RunResult, x_true: np.ndarray, tol: float, exact: bool):
    """Hull containment per step and state, set membership per step, and whether every
    set was tested as asked.

    The exact test (:mod:`benchmarks.run.membership`: a membership certificate, else an LP) runs
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
                 keep_sets: bool = False, budget: float | None = None) -> ObserverRun:
    """Design and run one observer; failures become statuses, not exceptions.

    ``keep_sets``: keep the estimated sets in ``run.result.sets`` (for the soundness audit);
    ``budget``: seconds for the run, stopped early (status ``timeout``) once its projected
    time exceeds them (:func:`observers.run`).
    """
    info = observers.get(name)
    obs, status, message = design_observer(name, sc, options)
    if obs is None:
        return ObserverRun(sc, info, None, status, message)
    res = observers.run(obs, sc.u, sc.y, keep_sets=sc.x_true is not None, on_error="status",
                        budget=budget)
    if res.error is not None:  # a plugin bug: reported, and the benchmark goes on
        print(f"warning: {name} failed on {sc.name}: {res.message}", file=sys.stderr)
        traceback.print_exception(res.error, limit=3, file=sys.stderr)
    same_dim = res.lo.shape[1] == sc.system.n
    if not same_dim and res.status == "ok":
        res.status, res.failed_step = "error", 0
        res.message = f"its sets have dimension {res.lo.shape[1]}, the system {sc.system.n}"
    if isinstance(res.error, MemoryError):  # the job's memory limit (or the machine's)
        res.status = "memory"
    run = ObserverRun(sc, info, res, res.status, res.message,
                      phase_ms=_phase_ms(obs, len(res.step_times)))
    if same_dim and sc.x_true is not None and len(res.sets):  # also the sets before a crash
        run.contained, run.in_set, run.decided = check_containment(
            res, sc.x_true, sc.tolerance, exact=(containment == "exact"))
        if containment == HULL_AND_EXACT:  # the gate: exact membership beside the hull
            _, exact_in, exact_decided = check_containment(res, sc.x_true, sc.tolerance, True)
            run.exact_verdict = containment_verdict(res.status, sc.N, _with_empty(exact_in, res),
                                                    exact_decided)
    if same_dim and sc.x_true is not None:
        run.in_set = _with_empty(run.in_set, res)
    if not keep_sets:
        res.sets.clear()  # free memory; bounds are kept
    return run


def _with_empty(in_set: np.ndarray | None, res: RunResult) -> np.ndarray | None:
    """``in_set`` with the step at which the estimate became empty (status ``empty``) as a
    miss: the record comes from a true trajectory, which no empty set contains, so an empty
    estimate is a violation of the guarantee at that step, not a neutral outcome (a record
    that no state fits is told apart by its exact floor: :func:`mark_inconsistent`)."""
    k = res.failed_step
    if res.status != "empty" or k is None:
        return in_set
    seen = np.ones(0, dtype=bool) if in_set is None else in_set
    return np.append(seen, False) if seen.size == k else in_set


def _phase_ms(obs, steps: int) -> dict:
    """Mean milliseconds per step of each phase the observer timed (its ``phase_times``, the
    numpy path of the family loops: nothing for a step taken by a compiled kernel)."""
    times = getattr(obs, "phase_times", None)
    if not isinstance(times, dict) or not steps or not any(v > 0 for v in times.values()):
        return {}
    return {PHASE_COLUMNS[k]: 1e3 * float(v) / steps for k, v in times.items()
            if k in PHASE_COLUMNS and v > 0}




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
        contained[:run.contained.shape[0]] = run.contained
    if run.in_set is not None:  # one more than the sets where the estimate became empty
        in_set[:run.in_set.size] = run.in_set
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
    extra = {"contained": run.exact_verdict} if containment == HULL_AND_EXACT else {}
    return pd.DataFrame({
        **extra,
        "scenario": sc.name,
        "observer": info.name,
        "state": np.arange(n),
        "state_name": list(names),
        "rms_radius": rms_radius(res.radius) if ok else np.full(n, np.nan),
        "step_ms": median_ms(res.step_times) if res is not None else np.nan,
        "hull_ms": median_ms(res.hull_times) if res is not None else np.nan,
        "design_s": res.design_time if res is not None else np.nan,
        **{col: run.phase_ms.get(col, np.nan) for col in PHASE_COLUMNS.values()},
        **memory_columns(res.doubles if res is not None else None),
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


def merge_options(name: str, scenario: Scenario, options: dict[str, Any] | None = None,
                  own: dict[str, Any] | None = None) -> dict[str, Any]:
    """The options observer ``name`` runs with on ``scenario``.

    Scenario defaults < ``options`` (the config's, for every observer) < ``own`` (the
    observer's own options and sweep variant), restricted to the options the observer accepts
    for the scenario and global ones (all of ``own``: an unknown one is the observer's error to
    report); scenario defaults only for the options listed in the observer's
    ``SCENARIO_OPTIONS``; observers with a ``training`` option also get the scenario's offline
    experiment.
    """
    info = observers.get(name)
    accepted = info.option_defaults()
    from_scenario = accepted if info.scenario_options is None else info.scenario_options
    merged = {k: v for k, v in scenario.options.items() if k in from_scenario}
    merged.update({k: v for k, v in (options or {}).items() if k in accepted})
    merged.update(own or {})
    if "training" in accepted and "training" not in merged and scenario.training is not None:
        merged["training"] = scenario.training  # offline data for data-driven observers
    return merged


@dataclass(frozen=True)
class Job:
    """One independent unit of a run: an observer (one option variant) on one scenario.

    Picklable: the scenario travels as its config entry and is rebuilt (once per process) in
    a worker; ``module`` is imported there so that plugin observers are registered.
    """

    spec: dict
    base: str | None
    observer: str
    module: str
    options: dict
    observer_options: dict
    containment: str
    seed: int | None = None
    variant: str = ""
    #: a labelled variant of the config (``ESO-C[cora]``): its label and guarantee
    label: str = ""
    guaranteed: bool = True
    #: run in a worker process even by the serial executor (a third-party plugin: a crash,
    #: hang or leak of it must not end the run)
    isolate: bool = False
    #: the built scenario, sent with an isolated job of the serial executor (so that a
    #: scenario built in code, which no worker could rebuild from its entry, still runs)
    scenario: Scenario | None = dataclasses.field(default=None, compare=False, repr=False)
    #: the registry entry of an isolated job's observer, registered again in a worker where
    #: importing ``module`` does not (a plugin registered by a call, not at import)
    info: observers.ObserverInfo | None = dataclasses.field(default=None, compare=False,
                                                             repr=False)

    def inputs(self) -> tuple[Scenario, dict]:
        """The job's scenario (built once per process) and the options its observer runs with
        (:func:`merge_options`, merged here once)."""
        sc = scenario_of(self)
        return sc, merge_options(self.observer, sc, self.options, self.observer_options)


def _job_frames(job: Job, sc: Scenario, run: ObserverRun):
    """``(runs rows or None, summary rows)`` of a finished or failed job."""
    runs = None
    if run.result is not None:
        runs = _rows_runs(run)
    else:
        run.result = RunResult(job.observer, np.full((sc.N, sc.system.n), np.nan),
                               np.full((sc.N, sc.system.n), np.nan), [], np.full(sc.N, np.nan),
                               np.full(sc.N, np.nan), np.nan, run.status, run.message)
    summary = _rows_summary(run, job.containment)
    for df in (runs, summary):
        if df is not None:
            df.insert(1, "seed", job.seed)
            df.insert(3, "variant", job.variant)
    return runs, summary


def execute_job(job: Job, budget: float | None = None):
    """Run one job (in this process or a worker): ``(runs rows or None, summary rows)``;
    ``budget``: seconds for the observer's run, as in :func:`run_observer`."""
    if job.observer not in observers.names():  # registered here already: nothing to import
        importlib.import_module(job.module)
    if job.info is not None and job.observer not in observers.names():
        i = job.info
        observers.register(i.name, family=i.family, set_type=i.set_type,
                           ready_for_control=i.ready_for_control, guaranteed=i.guaranteed,
                           reference=i.reference)(i.cls)
    sc, options = job.inputs()
    run = run_observer(job.observer, sc, options, job.containment, budget=budget)
    if job.label:  # its rows carry the label and its own guarantee
        run.info = dataclasses.replace(run.info, name=job.label, guaranteed=job.guaranteed)
    return _job_frames(job, sc, run)


def failed_job(job: Job, status: str, message: str):
    """The rows of a job that produced no result (its worker died, it raised, timed out):
    ``status`` and ``message`` say which."""
    sc = scenario_of(job)
    info = observers.get(job.observer)
    if job.label:
        info = dataclasses.replace(info, name=job.label, guaranteed=job.guaranteed)
    run = ObserverRun(sc, info, None, status, message)
    return _job_frames(job, sc, run)


def summary_columns(containment: str) -> list[str]:
    """Columns of ``summary.csv`` (the containment column is named by the check made; the
    gate's ``hull+exact`` has both)."""
    both = ["contained"] if containment == HULL_AND_EXACT else []
    return ["scenario", "seed", "observer", "variant", "state", "state_name", "rms_radius",
            "rel_rms", "step_ms", "hull_ms", "design_s", *PHASE_COLUMNS.values(), "timed",
            "memory", "memory_peak", contained_column(containment),
            *both, "violations", "first_violation_step", *FLOOR_COLUMNS, "status",
            "failed_step", "message", "family", "set_type", "timing", "guaranteed"]


def mark_inconsistent(summary: pd.DataFrame, message: str, containment: str) -> None:
    """Every row of a record that no state fits (its exact floor is empty): status
    ``inconsistent``, the reason as its message, and no containment verdict (the data, not
    the observer, are at fault)."""
    summary["status"] = "inconsistent"
    summary["message"] = ("the record contradicts the model (no initial state in X0 and no "
                          f"noise in W and V reproduce y): {message}; not a fault of this "
                          "observer")
    for col in {contained_column(containment), "contained"} & set(summary.columns):
        summary[col] = NA
    summary[["violations", "first_violation_step"]] = None


def add_floor(job: Job, floor: RecordFloor, runs: pd.DataFrame | None, summary: pd.DataFrame,
              floors: dict[str, str] | None = None) -> None:
    """The floor columns of one job's rows (in place): ``floor_lo``/``floor_hi`` in its runs
    rows, the gap and the covering verdict in its summary rows (:func:`.floor.floor_columns`);
    ``floors``: the configuration's ``floors`` entry (which floor an observer is held to)."""
    if floor.kind == "empty":
        mark_inconsistent(summary, floor.message, job.containment)
    sc = scenario_of(job)
    N, n = sc.N, sc.system.n
    which = observer_floor(job.label or job.observer, floors)
    if runs is not None and len(runs) == N * n:
        lo, hi = (runs[c].to_numpy(float).reshape(N, n) for c in ("lo", "hi"))
    else:
        lo = hi = np.full((N, n), np.nan)
    cols = floor_columns(floor, which, lo, hi, summary["status"].iloc[0] == "ok",
                         sc.tolerance)
    for key, value in cols.items():
        summary[key] = value
    if summary["family"].iloc[0] == "reference" and floor.kind == "exact":
        # the reference's own run read the hulls the floor had just computed (or a previous
        # run had): its cost is the floor's, not a cache read
        ms = 1e3 * floor.step_seconds
        summary["step_ms"], summary["hull_ms"] = ms, 0.0 if np.isfinite(ms) else np.nan
        notes = [] if np.isfinite(ms) else [
            "exact hulls read from the cache (their cost: reports/speed.md)"]
        if floor.unchecked:
            steps = ", ".join(map(str, floor.unchecked))
            notes.append(f"an LP of step(s) {steps} was not solved to optimality by any "
                         "strategy: no observer is held to the floor there")
        if notes:
            summary["message"] = "; ".join(notes)
    if runs is not None:
        flo, fhi = floor.bounds(which, N, n)
        runs["floor_lo"], runs["floor_hi"] = flo.reshape(-1), fhi.reshape(-1)
