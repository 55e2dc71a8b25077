"""The regression gate's time budget per job, from the recorded cost of each job.

``results/baseline/cost.json`` (:data:`COST_FILE`, beside the golden files, never mixed with
their numbers) holds the cost of each job of the subset: seconds of wall time of one observer
on one scenario, its offline design and its run included, measured on the subset run serially
as ``check`` runs it (the project's observers in the gate's process, designs recomputed unless
``--use-cache``).  ``baseline --update`` writes it from its run on this machine's own BLAS
kernel; ``baseline --record-cost`` runs the subset once only to rewrite it (the golden files
untouched).

``check`` gives each job (:meth:`JobBudgets.of`):

* a job with a recorded cost: :data:`BUDGET_FACTOR` x its cost, at least :data:`MIN_BUDGET_S`;
* a job without one (a third-party plugin, a new observer, a new scenario):
  :data:`BUDGET_FACTOR` x the median recorded job of its scenario (of every scenario, for a
  new scenario), at least :data:`MIN_BUDGET_S` and at most :data:`NEW_JOB_MAX_BUDGET_S`;

rounded up to a whole second.  The cap keeps a plugin that hangs in ``step()`` from holding
the gate: each of its jobs of the subset's 7 scenarios is stopped after at most 15 s, under
2 minutes in all.  A job over its budget is stopped and reported as ``timeout``
(:class:`GateExecutor`), with one line naming it, its scenario and its budget
(:func:`timeout_lines`).  A ``timeout:`` in the subset's configuration replaces every per-job
budget (``check`` has no ``--timeout`` option); the floors (the exact reference of each
scenario, computed before the jobs) keep :data:`GATE_TIMEOUT`.

Without a cost file (a baseline written before costs were recorded) every job gets
:data:`GATE_TIMEOUT`, as before, and ``check`` says so on one line; a cost file that cannot be
read is an error (exit 2) naming the file and the command that rewrites it.
"""

from __future__ import annotations

import json
import math
import os
import platform
import statistics
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

from ..errors import ConfigError
from ..io import atomic_write_json, environment
from ..run.config import BenchConfig
from ..run.executors import JobFailure, ProcessExecutor, SerialExecutor
from ..run.rows import Job
from ..run.runner import is_project_module

#: the job costs, in the baseline folder
COST_FILE = "cost.json"
#: the budget of a job is this many times its recorded cost ...
BUDGET_FACTOR = 20.0
#: ... and never less than this (seconds): a job of a few milliseconds on a loaded machine
MIN_BUDGET_S = 10.0
#: the most a job without a recorded cost gets (seconds): a plugin that hangs adds at most
#: this per scenario of the subset to the gate
NEW_JOB_MAX_BUDGET_S = 15.0
#: the time budget of every job without a cost file (and of the floors), unless the subset's
#: configuration sets one
GATE_TIMEOUT = 300.0
#: how the costs are measured (``check`` runs the subset the same way)
COST_EXECUTOR = "serial"
_RECORD = "python -m benchmarks baseline --record-cost"


@dataclass(frozen=True)
class Budget:
    """The time budget of one job and how it was derived (for the message of a timeout)."""

    seconds: float
    basis: str


def _ceil_s(x: float) -> float:
    """``x`` seconds rounded up to a whole second (``20 x 0.65`` is 13, not 14)."""
    return float(math.ceil(round(x, 6)))


def recorded_budget(cost: float) -> Budget:
    """The budget of a job that took ``cost`` seconds when the costs were recorded."""
    scaled = _ceil_s(BUDGET_FACTOR * cost)
    if scaled < MIN_BUDGET_S:
        return Budget(MIN_BUDGET_S, f"the minimum; {BUDGET_FACTOR:g}x its recorded "
                                    f"{cost:.3g} s is less")
    return Budget(scaled, f"{BUDGET_FACTOR:g}x its recorded {cost:.3g} s")


def unrecorded_budget(median: float, where: str) -> Budget:
    """The budget of a job without a recorded cost, from the ``median`` recorded job of
    ``where`` (its scenario, or every scenario)."""
    seconds = min(NEW_JOB_MAX_BUDGET_S, max(MIN_BUDGET_S, _ceil_s(BUDGET_FACTOR * median)))
    return Budget(seconds, f"no recorded cost: {BUDGET_FACTOR:g}x the median recorded job of "
                           f"{where} ({median:.3g} s), within {MIN_BUDGET_S:g}-"
                           f"{NEW_JOB_MAX_BUDGET_S:g} s")


class JobBudgets:
    """The budget of each job of the subset from the recorded costs
    (``{scenario: {observer: seconds}}``; see the module docstring)."""

    def __init__(self, seconds: dict[str, dict[str, float]], source: str = COST_FILE):
        if not any(seconds.values()):
            raise ConfigError(f"{source} records no job")
        self.seconds, self.source = seconds, source

    def of(self, scenario: str, observer: str) -> Budget:
        """The budget of ``observer`` on ``scenario``."""
        per = self.seconds.get(scenario, {})
        if observer in per:
            return recorded_budget(per[observer])
        if per:
            return unrecorded_budget(statistics.median(per.values()), scenario)
        every = [s for jobs in self.seconds.values() for s in jobs.values()]
        return unrecorded_budget(statistics.median(every), "every scenario")


def _bad(path: Path, why: str) -> ConfigError:
    return ConfigError(f"job costs {path} unreadable ({why}); rewrite them with `{_RECORD}`")


def load_costs(folder: str | Path) -> JobBudgets | None:
    """The budgets from the cost file of baseline ``folder``; None if there is none.

    Raises
    ------
    ConfigError
        One line naming the file, if it is not a cost file (not JSON, no ``seconds``
        mapping of scenarios to mappings of observers to seconds >= 0).
    """
    path = Path(folder) / COST_FILE
    if not path.is_file():
        return None
    try:
        data = json.loads(path.read_text())
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise _bad(path, f"not JSON: {getattr(exc, 'msg', exc)}") from None
    except OSError as exc:
        raise _bad(path, exc.strerror or type(exc).__name__) from None
    seconds = data.get("seconds") if isinstance(data, dict) else None
    if not isinstance(seconds, dict) or not all(isinstance(v, dict) for v in seconds.values()):
        raise _bad(path, "no 'seconds' mapping of scenarios to {observer: seconds}")
    out: dict[str, dict[str, float]] = {}
    for sc, jobs in seconds.items():
        for obs, s in jobs.items():
            ok = isinstance(s, (int, float)) and not isinstance(s, bool)
            if not (ok and math.isfinite(s) and s >= 0):
                raise _bad(path, f"{obs} on {sc}: {s!r} is not a number of seconds")
            out.setdefault(str(sc), {})[str(obs)] = float(s)
    if not out:
        raise _bad(path, "no job recorded")
    return JobBudgets(out, str(path))


def cpu_model() -> str:
    """The CPU's model name (``/proc/cpuinfo``), else what ``platform`` knows."""
    try:
        with open("/proc/cpuinfo") as fh:
            for line in fh:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def write_costs(folder: str | Path, seconds: dict[tuple[str, str], float], command: str,
                design_cache: str, load: tuple[float, float] | None = None) -> Path:
    """Write the job costs ``{(scenario, observer): seconds}`` to the cost file of baseline
    ``folder`` (atomically), with the machine, the commit and when; returns its path."""
    per: dict[str, dict[str, float]] = {}
    for (sc, obs), s in seconds.items():
        per.setdefault(sc, {})[obs] = round(s, 3)
    env = environment()
    path = Path(folder) / COST_FILE
    atomic_write_json(path, {
        "about": "wall seconds of each job of the regression subset (one observer on one "
                 "scenario, design and run), run serially as `check` runs them; `check` gives "
                 f"each job {BUDGET_FACTOR:g}x its cost, at least {MIN_BUDGET_S:g} s "
                 "(benchmarks/gate/budget.py)",
        "created": datetime.now(timezone.utc).isoformat(timespec="seconds"),
        "commit": env.get("git", ""),
        "command": command,
        "executor": COST_EXECUTOR,
        "design_cache": design_cache,
        "machine": {"cpu": cpu_model(), "cores": os.cpu_count(), "platform": env.get("platform"),
                    "python": env.get("python"), "blas_coretype": env.get("blas_coretype"),
                    "load_average_1min": list(load) if load else None},
        "total_seconds": round(sum(seconds.values()), 1),
        "seconds": per,
    })
    return path


def load_average() -> float:
    """The 1-minute load average of the machine (NaN where unknown)."""
    try:
        return round(os.getloadavg()[0], 2)
    except (OSError, AttributeError):
        return math.nan


# -- the executor of the gate -----------------------------------------------------------------
@dataclass(frozen=True)
class Stopped:
    """A job of the gate stopped by its time budget."""

    scenario: str
    observer: str
    budget: Budget
    plugin: bool


class GateExecutor:
    """The serial executor of the regression subset, with a time budget per job.

    Runs every job as :class:`~benchmarks.run.executors.SerialExecutor` does (the project's
    observers in this process, third-party plugins in one worker process), but gives each
    observer's job its own budget from ``budgets`` (:class:`JobBudgets`; without it, the
    budget set by the runner, the configuration's ``timeout`` or :data:`GATE_TIMEOUT`), and
    records the wall time of each job (:attr:`seconds`, ``(scenario, observer) -> s``) and
    the jobs its budget stopped (:attr:`stopped`).  Other tasks (the floors) keep the budget
    set by the runner.  ``fixed`` says where the runner's budget comes from (in the message
    of a job it stopped).
    """

    name = "serial"
    workers = 1

    def __init__(self, cfg: BenchConfig, budgets: JobBudgets | None = None,
                 fixed: str = "the gate's fixed budget per job"):
        self.budgets, self.fixed = budgets, fixed
        self.timeout: float | None = None
        self.memory_limit: int | None = None
        self._names = {_spec_key(i.spec): i.scenario.name for i in cfg.instances}
        self._here = SerialExecutor()
        self._pool: ProcessExecutor | None = None
        self.seconds: dict[tuple[str, str], float] = {}
        self.stopped: list[Stopped] = []

    def set_limits(self, timeout: float | None, memory_limit: int | None) -> None:
        """The job timeout of the jobs without a budget of their own (as every executor's)."""
        self._here.set_limits(timeout, memory_limit)  # checks them
        self.timeout, self.memory_limit = timeout, memory_limit

    def _where(self, job: Any) -> tuple[str, str] | None:
        if not isinstance(job, Job):
            return None
        spec = job.spec if isinstance(job.spec, dict) else {"name": job.spec}
        scenario = self._names.get(_spec_key(job.spec)) or str(spec.get("label",
                                                                         spec.get("name")))
        return scenario, job.label or job.observer

    def budget_of(self, job: Any) -> Budget | None:
        """The budget of ``job`` (None: the runner's, :attr:`timeout`)."""
        where = self._where(job)
        return self.budgets.of(*where) if self.budgets is not None and where else None

    def map(self, fn: Callable[[Any], Any], jobs: Sequence[Any],
            keys: Sequence[Any] | None = None,
            isolate: Sequence[bool] | None = None) -> Iterator[tuple[int, Any]]:
        """Yield ``(index, fn(job) or JobFailure)`` in job order, each job with its budget."""
        for i, job in enumerate(jobs):
            budget = self.budget_of(job)
            runner = self._isolated() if isolate is not None and isolate[i] else self._here
            runner.set_limits(budget.seconds if budget else self.timeout, self.memory_limit)
            t0 = time.perf_counter()
            out = [o for _, o in runner.map(fn, [job])][-1]
            where = self._where(job)
            if where is not None:
                self.seconds[where] = max(self.seconds.get(where, 0.0),
                                          time.perf_counter() - t0)
                if isinstance(out, JobFailure) and out.status == "timeout":
                    self.stopped.append(Stopped(
                        *where, budget or Budget(self.timeout or math.inf, self.fixed),
                        not is_project_module(job.module)))
            yield i, out

    def _isolated(self) -> ProcessExecutor:
        if self._pool is None:
            self._pool = ProcessExecutor(1, self.timeout, self.memory_limit)
        return self._pool

    def close(self) -> None:
        """End the worker process of the isolated jobs, if one was started."""
        self._here.close()
        if self._pool is not None:
            self._pool.close()
            self._pool = None


def _spec_key(spec: Any) -> str:
    return json.dumps(spec, sort_keys=True, default=str)


def timeout_lines(stopped: Sequence[Stopped]) -> list[str]:
    """One line per job stopped by its budget: the observer (a plugin or not), the scenario
    and the budget it exceeded."""
    return [f"TIMEOUT: {'plugin ' if s.plugin else ''}{s.observer} on {s.scenario}: stopped "
            f"after its budget of {s.budget.seconds:g} s ({s.budget.basis})" for s in stopped]
