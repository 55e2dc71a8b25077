"""Run a benchmark configuration: every observer on every scenario, with containment checks
and timings, written as ``runs.csv``, ``summary.csv`` and ``meta.json`` (one generation).

The work is a list of independent :class:`Job` values run by an executor
(:mod:`benchmarks.run.executors`: serial, local processes or Dask)."""

from __future__ import annotations

import dataclasses
import importlib
import pickle
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

from ..errors import ConfigError
from ..io import check_output_dir, environment, write_error, write_results
from ..metrics import PHASE_COLUMNS, add_relative_rms, median_ms, memory_columns, rms_radius
from ..verdicts import HULL_AND_EXACT, NA, BenchResult, contained_column, containment_verdict
from .config import BenchConfig, merge_options
from .describe import set_bounds
from .executors import JobFailure, SerialExecutor
from .floor import RecordFloor, compute_floors, floor_columns, observer_floor
from .membership import MembershipTester
from .progress import progress_bar
from .specs import remember_scenario, scenario_key, scenario_of

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
    return isinstance(S, (Interval, Zonotope, ConZonotope)) or hasattr(S, "distance") or (
        hasattr(S, "contains"))


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
            run.exact_verdict = containment_verdict(res.status, sc.N, exact_in, exact_decided)
    if not keep_sets:
        res.sets.clear()  # free memory; bounds are kept
    return run


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
    need = BYTES_PER_ROW * sum(len(cfg.variants_of(o)) for o in cfg.observers) * sum(
        sc.N * sc.system.n for sc in cfg.scenarios)
    have = available_memory()
    if have is not None and need > have:
        raise ConfigError(f"config '{cfg.name}': its results need about {need / 2**30:.3g} GiB "
                          f"of memory, {have / 2**30:.3g} GiB are available; use fewer steps, "
                          "scenarios or observers")


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
        (:func:`.config.merge_options`, merged here once)."""
        sc = scenario_of(self)
        return sc, merge_options(self.observer, sc, self.options, self.observer_options)


def _picklable(sc: Scenario) -> bool:
    """Whether ``sc`` can travel to a worker as it is (a nonlinear model's functions may be
    local: such a scenario is rebuilt there from its configuration entry instead)."""
    key = id(sc)
    if key not in _PICKLABLE:
        try:
            pickle.dumps(sc)
            _PICKLABLE[key] = True
        except (pickle.PicklingError, AttributeError, TypeError):
            _PICKLABLE[key] = False
    return _PICKLABLE[key]


_PICKLABLE: dict[int, bool] = {}


def is_project_module(module: str) -> bool:
    """Whether ``module`` belongs to the project's ``observers`` package (not a plugin)."""
    return module == "observers" or module.startswith("observers.")


def isolatable(cls: type) -> bool:
    """Whether observer class ``cls`` is a third-party plugin that a worker process can
    import by its module and name (a class defined in ``__main__`` or inside a function, as in
    a notebook or a test, cannot be: it runs in this process)."""
    module, qualname = getattr(cls, "__module__", ""), getattr(cls, "__qualname__", "")
    if is_project_module(module) or module == "__main__" or "<locals>" in qualname:
        return False
    try:
        obj = importlib.import_module(module)
        for part in qualname.split("."):
            obj = getattr(obj, part)
    except Exception:
        return False
    return obj is cls


def make_jobs(cfg: BenchConfig) -> list[Job]:
    """The jobs of ``cfg``: every scenario instance x observer x option variant."""
    base = str(cfg.base) if cfg.base is not None else None
    jobs = []
    for inst in cfg.instances:
        remember_scenario(inst.spec, base, inst.scenario)
        for name in cfg.observers:
            obs = cfg.observer_of(name)  # a labelled variant runs its observer
            per = cfg.labelled[name][1] if name in cfg.labelled else cfg.observer_options.get(
                name, {})
            cls = observers.get(obs).cls
            for label, opts in cfg.variants_of(obs):
                isolate = isolatable(cls)
                jobs.append(Job(spec=inst.spec, base=base, observer=obs, module=cls.__module__,
                                options=cfg.options, observer_options={**per, **opts},
                                containment=cfg.containment, seed=inst.seed, variant=label,
                                label=name if name != obs else "",
                                guaranteed=cfg.guaranteed(name), isolate=isolate,
                                info=observers.get(obs) if isolate else None))
    return jobs


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


def failed_job(job: Job, failure: JobFailure):
    """The rows of a job that produced no result (its worker died, it raised, timed out)."""
    sc = scenario_of(job)
    info = observers.get(job.observer)
    if job.label:
        info = dataclasses.replace(info, name=job.label, guaranteed=job.guaranteed)
    run = ObserverRun(sc, info, None, failure.status, failure.message)
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


def add_floor(cfg: BenchConfig, job: Job, floor: RecordFloor, runs: pd.DataFrame | None,
              summary: pd.DataFrame) -> None:
    """The floor columns of one job's rows (in place): ``floor_lo``/``floor_hi`` in its runs
    rows, the gap and the covering verdict in its summary rows (:func:`.floor.floor_columns`)."""
    if floor.kind == "empty":
        mark_inconsistent(summary, floor.message, job.containment)
    sc = scenario_of(job)
    N, n = sc.N, sc.system.n
    which = observer_floor(job.label or job.observer, cfg.floors)
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


def _write(out, runs_df: pd.DataFrame, summary: pd.DataFrame, meta: dict) -> None:
    """:func:`benchmarks.io.write_results`; a write error (a full disk) is one line."""
    try:
        write_results(out, {"runs.csv": runs_df, "summary.csv": summary}, meta)
    except OSError as exc:
        raise write_error(exc, f"the results to {out} (the previous results there, if any, "
                               "are intact)") from None


def largest_first(jobs: list[Job]) -> list[int]:
    """Job indices ordered by the size of their scenario's record (steps x states), largest
    first; jobs of equal size keep their order, so that the jobs of one scenario stay
    together.  Measured on ARCH Table 5 (12-30 tanks, in that order in the configuration):
    handed out in the configuration's order, the 30-tank jobs came last and one worker ran
    the last of them alone."""
    def size(job: Job) -> int:
        try:
            sc = scenario_of(job)
            return int(sc.N) * int(sc.system.n)
        except Exception:  # a scenario that cannot be built fails in its job, not here
            return 0

    sizes = [size(j) for j in jobs]
    return sorted(range(len(jobs)), key=lambda i: -sizes[i])


def _run_jobs(cfg: BenchConfig, executor, jobs: list[Job], payloads: list[Job], frames: list,
              progress: bool | None) -> None:
    """Run ``payloads`` (the jobs, or the jobs with their scenario) on ``executor`` and put
    each one's rows (or failure rows) into ``frames``.

    The jobs are handed out by :func:`largest_first` (the rows keep the configuration's
    order), so that the last jobs to finish are short ones and no worker waits long for
    another at the end."""
    order = largest_first(jobs)
    with progress_bar(len(jobs), cfg.name, progress) as bar:
        # the jobs of one scenario instance go to a worker together (built once there)
        for pos, outcome in executor.map(execute_job, [payloads[i] for i in order],
                                         keys=[scenario_key(jobs[i]) for i in order],
                                         isolate=[jobs[i].isolate for i in order]):
            i = order[pos]
            if isinstance(outcome, JobFailure):
                outcome = failed_job(jobs[i], outcome)
            frames[i] = outcome
            bar.set_postfix_str(f"{jobs[i].spec['name']}: {jobs[i].observer} "
                                f"{outcome[1]['status'].iloc[0]}", refresh=False)
            bar.update()


def run_config(cfg: BenchConfig, out: str | Path | None = None, progress: bool | None = None,
               executor=None):
    """Run every job of ``cfg`` (scenario x observer x option variant).

    Returns a :class:`~benchmarks.verdicts.BenchResult`: the pair ``(runs, summary)`` of data
    frames (``runs, summary = run_config(...)``) that also carries the verdict of the run
    (``.exit_code``, ``.meaning``, ``.problems``, ``.ok``: what ``setobs-bench run`` exits
    with and prints); with ``out`` the frames are also written there
    (``runs.csv``, ``summary.csv``, ``meta.json``) as one generation
    (:func:`benchmarks.io.write_results`), only once every job has finished. The output folder
    and the memory needed are checked before any job runs (:class:`ConfigError`).
    ``executor`` (:mod:`benchmarks.run.executors`, default serial) runs the
    jobs; a job it could not run (worker died, timeout) is a row with that status.  Timing
    columns of jobs run concurrently are marked ``timed = parallel`` (indicative only).
    """
    if out is not None:
        check_output_dir(out)
    check_memory(cfg)
    own = executor is None
    executor = executor or SerialExecutor()
    executor.set_limits(cfg.timeout, cfg.job_memory_limit(executor.workers))
    jobs = make_jobs(cfg)
    # the serial executor sends an isolated job with its scenario (built here already)
    payloads = [dataclasses.replace(j, scenario=scenario_of(j)) if j.isolate and
                executor.name == "serial" and _picklable(scenario_of(j)) else j for j in jobs]
    frames: list = [None] * len(jobs)
    try:
        floors = compute_floors(executor, jobs, cfg.exact)
        _run_jobs(cfg, executor, jobs, payloads, frames, progress)
    finally:
        if own:
            executor.close()
    for job, (runs, summ) in zip(jobs, frames, strict=True):
        add_floor(cfg, job, floors[scenario_key(job)], runs, summ)
    runs = [r for r, _ in frames if r is not None]
    runs_df = pd.concat(runs, ignore_index=True) if runs else pd.DataFrame(columns=RUN_COLUMNS)
    summary = add_relative_rms(pd.concat([s for _, s in frames], ignore_index=True))
    summary["timed"] = "serial" if executor.workers == 1 else "parallel"
    summary = summary[summary_columns(cfg.containment)]
    if out is not None:
        _write(out, runs_df, summary, {
            "config": {"name": cfg.name, "title": cfg.title, "raw": cfg.raw,
                       "containment": cfg.containment},
            "scenarios": {sc.name: {
                "N": sc.N, "n": sc.system.n, "dt": sc.system.dt, "paper_table": sc.paper_table,
                "description": sc.description, "source": sc.source,
                "state_names": list(sc.state_names), "tolerance": sc.tolerance,
                "sets": set_bounds(sc.system),
            } for sc in cfg.scenarios},
            "executor": {"name": executor.name, "workers": executor.workers,
                         "jobs": len(jobs)},
            "created": datetime.now(timezone.utc).isoformat(timespec="seconds"),
            "versions": environment(),
        })
    return BenchResult(runs_df, summary)
