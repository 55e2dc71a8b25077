"""The floors of a run's records: which floor each record gets, computed by the executor
before the observers' jobs.

A linear record gets the exact floor (:func:`.floor.exact_floor`), a nonlinear one the
falsifier's inner box (:func:`.floor_inner.inner_floor`); the fingerprint of a row names the
same module for the same record (:meth:`benchmarks.store.fingerprint.Fingerprinter.roots`).
Orchestration: no row depends on this module's code.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from systems import Scenario

from .executors import JobFailure
from .floor import RecordFloor, exact_floor
from .floor_inner import inner_floor
from .specs import scenario_key, scenario_of


def compute_floor(sc: Scenario, enabled: bool = True,
                  budget: int | None = None) -> RecordFloor:
    """The floor of ``sc``'s record (:mod:`.floor`); never raises for a record it cannot
    handle (``kind = "none"`` with the reason).  ``budget``: the falsifier's budget of simplex
    iterations on a nonlinear record (:func:`.floor_inner.inner_floor`)."""
    if not enabled:
        return RecordFloor("none", message="not computed (exact: false in the configuration)")
    if getattr(sc.system, "is_linear", False):
        return exact_floor(sc)
    return inner_floor(sc, budget)


@dataclass(frozen=True)
class FloorTask:
    """The accuracy floor of one scenario instance (:func:`compute_floor`), run by the
    executor before the observers' jobs (picklable like a job)."""

    spec: dict
    base: str | None
    enabled: bool = True
    scenario: Scenario | None = dataclasses.field(default=None, compare=False, repr=False)


def floor_task(task: FloorTask) -> RecordFloor:
    """Compute the floor of ``task``'s scenario (in this process or a worker)."""
    return compute_floor(scenario_of(task), task.enabled)


def compute_floors(executor: Any, jobs: Sequence[Any], enabled: bool = True
                   ) -> dict[str, RecordFloor]:
    """The floor of every scenario instance of ``jobs`` (each with ``spec``, ``base`` and an
    optional built ``scenario``), by the executor (the exact reference of a long record takes
    minutes: the instances run in parallel with ``--jobs``; its cache makes a second run
    free); keyed by :func:`.specs.scenario_key`; ``enabled``: the configuration's ``exact``."""
    keys = list(dict.fromkeys(scenario_key(j) for j in jobs))
    first = {scenario_key(j): j for j in reversed(jobs)}
    tasks = [FloorTask(first[k].spec, first[k].base, enabled,
                       first[k].scenario if executor.name == "serial" else None) for k in keys]
    floors: dict[str, RecordFloor] = {}
    for i, out in executor.map(floor_task, tasks, keys=keys):
        if isinstance(out, JobFailure):
            out = RecordFloor("none", message=f"no floor: {out.status}: {out.message}")
        floors[keys[i]] = out
    return floors
