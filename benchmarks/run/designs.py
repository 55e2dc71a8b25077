"""Offline designs of several configs in parallel, into the design cache
(``python -m benchmarks designs CONFIG... [--jobs N]``; the first step of ``make bench``).

The offline designs (SDPs of the PRad, Nom-G and Hinf-G gains) dominate a cold ``make bench``
and are independent of each other.  This command computes every cached design
(:class:`observers.offline.OfflineGain`) that the configs need, once per (scenario, observer,
options), in ``jobs`` worker processes, largest systems first.  The designs land in the
design cache (:func:`observers.offline.cache_dir`), from which the sequential runs of
``python -m benchmarks run`` then load them; the runs themselves stay sequential, so their
step times are not disturbed by a parallel job.  Loading a cached design gives the same
arrays as computing it, so no result changes.
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import observers
from observers.offline import OfflineGain, cache_dir

from ..errors import ConfigError
from .config import load_config
from .executors import run_tasks
from .progress import progress_bar
from .rows import design_observer

#: one design: (config path, scenario index in the config, observer name)
Task = tuple[str, int, str]


def design_tasks(paths: list[str | Path]) -> list[Task]:
    """The cached designs of the configs ``paths``, each (scenario, observer, options) once,
    largest state dimension first."""
    seen: set[tuple[str, str, str]] = set()
    tasks: list[tuple[int, Task]] = []
    for path in paths:
        cfg = load_config(path)
        for i, sc in enumerate(cfg.scenarios):
            for name in cfg.observers:  # registered names and labelled variants
                if not issubclass(observers.get(cfg.observer_of(name)).cls, OfflineGain):
                    continue
                options = cfg.options_for(name, sc)
                key = (sc.name, cfg.observer_of(name),
                       json.dumps(options, sort_keys=True, default=repr))
                if key not in seen:
                    seen.add(key)
                    tasks.append((sc.system.n, (str(path), i, name)))
    tasks.sort(key=lambda t: -t[0])  # stable: config order among equal sizes
    return [t for _, t in tasks]


def design_task(task: Task) -> tuple[str, str, str, float]:
    """Compute (or load) one design; returns ``(scenario, observer, status, seconds)``."""
    path, i, name = task
    cfg = load_config(path)
    sc = cfg.scenarios[i]
    t0 = time.perf_counter()
    _, status, _ = design_observer(cfg.observer_of(name), sc, cfg.options_for(name, sc))
    return sc.name, name, status, time.perf_counter() - t0


def prewarm(paths: list[str | Path], jobs: int = 2, progress: bool | None = None
            ) -> list[tuple[str, str, str, float]]:
    """Fill the design cache for the configs ``paths`` with ``jobs`` worker processes.

    Returns
    -------
    list of (scenario, observer, status, seconds)
        One entry per design (``[]`` if the design cache is disabled).

    Raises
    ------
    ConfigError
        If ``jobs`` is below 1 or a config is invalid.
    """
    if jobs < 1:
        raise ConfigError(f"--jobs must be at least 1, got {jobs}")
    tasks = design_tasks(paths)
    if cache_dir() is None or not tasks:
        return []
    with progress_bar(len(tasks), "designs", progress) as bar:
        def done(_, res) -> None:
            bar.set_postfix_str(f"{res[0]}: {res[1]} {res[2]}", refresh=False)
            bar.update()

        return run_tasks(design_task, tasks, jobs, done)
