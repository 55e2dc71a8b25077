"""Run a benchmark configuration: every observer on every scenario, with containment checks
and timings, written as ``runs.csv``, ``summary.csv`` and ``meta.json`` (one generation).

The work is a list of independent :class:`~.rows.Job` values run by an executor
(:mod:`benchmarks.run.executors`: serial, local processes or Dask); what one job computes, its
rows, is :mod:`.rows` (the root of the rows' fingerprints).  This module only orchestrates:
it makes the jobs, has the floors and the jobs computed, and assembles and writes the
tables."""

from __future__ import annotations

import dataclasses
import importlib
import pickle
from datetime import datetime, timezone
from pathlib import Path

import pandas as pd

import observers
from systems import Scenario, available_memory

from ..errors import ConfigError
from ..io import check_output_dir, environment, write_error, write_results
from ..metrics import add_relative_rms
from ..verdicts import BenchResult
from .config import BenchConfig
from .describe import set_bounds
from .executors import JobFailure, SerialExecutor
from .floors import compute_floors
from .progress import progress_bar
from .rows import RUN_COLUMNS, Job, add_floor, execute_job, failed_job, summary_columns
from .specs import remember_scenario, scenario_key, scenario_of

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
                outcome = failed_job(jobs[i], outcome.status, outcome.message)
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
    with and prints) and its description (``.meta``: the configuration, the scenarios, the
    executor, the versions; what ``meta.json`` holds); with ``out`` the frames are also
    written there
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
        add_floor(job, floors[scenario_key(job)], runs, summ, cfg.floors)
    runs = [r for r, _ in frames if r is not None]
    runs_df = pd.concat(runs, ignore_index=True) if runs else pd.DataFrame(columns=RUN_COLUMNS)
    summary = add_relative_rms(pd.concat([s for _, s in frames], ignore_index=True))
    summary["timed"] = "serial" if executor.workers == 1 else "parallel"
    summary = summary[summary_columns(cfg.containment)]
    meta = {
        "config": {"name": cfg.name, "title": cfg.title, "raw": cfg.raw,
                   "containment": cfg.containment},
        "scenarios": {sc.name: {
            "N": sc.N, "n": sc.system.n, "dt": sc.system.dt, "paper_table": sc.paper_table,
            "description": sc.description, "source": sc.source,
            "state_names": list(sc.state_names), "tolerance": sc.tolerance,
            "sets": set_bounds(sc.system),
        } for sc in cfg.scenarios},
        "executor": {"name": executor.name, "workers": executor.workers, "jobs": len(jobs)},
        "created": datetime.now(timezone.utc).isoformat(timespec="seconds"),
        "versions": environment(),
    }
    if out is not None:
        _write(out, runs_df, summary, meta)
    return BenchResult(runs_df, summary, meta)
