"""The incremental bench: run only the rows of a configuration that are stale or missing in its
store, merge them in, and render the committed report from the store.

``setobs-bench bench [CONFIG ...]`` (``make bench``) does, for each configuration:

1. read and check its store ``results/<name>/`` (:func:`.store.load_store`);
2. fingerprint every job of the configuration (:mod:`.fingerprint`) and compare with the
   stored rows: a row is run again if it is missing or its fingerprint differs (``--cold``:
   every row);
3. run those jobs (the observers with a stale row on the scenarios with a stale row; the run's
   own folder is ``results/<name>/run/``, local), merge their rows into the store and write it
   atomically under :class:`.store.StoreLock`;
4. render ``reports/<name>.md`` from the store (:func:`render`).

``setobs-bench run CONFIG --add NAME`` (:func:`add_observer`) is the same with the rows of one
more observer (a plugin): it runs only that observer's rows, takes the others from the store
shipped with the package where their fingerprints are current, and renders the whole table.
"""

from __future__ import annotations

import dataclasses
import json
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

from ..errors import ConfigError
from ..io import atomic_write_text
from ..report.markdown import render_report
from ..run.config import BenchConfig, load_config
from ..run.floors import FloorTask, floor_task
from ..run.runner import is_project_module, make_jobs, run_config
from ..run.specs import scenario_key
from .fingerprint import Fingerprint, Fingerprinter, changes, job_key
from .graph import ROOT
from .store import (
    FORMAT,
    RunRows,
    Store,
    StoreLock,
    compare,
    load_store,
    merge,
    new_run,
    write_store,
)

__all__ = ["Fingerprinter", "StoreLock", "add_observer", "bench_all", "bench_config",
           "is_store", "load_store", "plan", "published", "render_all", "shipped_results"]

#: where the stores live (relative to the project root)
RESULTS = Path("results")
#: where the committed reports live
REPORTS = Path("reports")


@dataclass
class Plan:
    """What a configuration's store needs: its jobs, their fingerprints and which are stale."""

    cfg: BenchConfig
    store: Store | None
    jobs: list
    prints: dict[str, Fingerprint]
    #: the row keys of the configuration, in its order
    order: list[str]
    #: row key -> why it must run (missing, or what changed)
    stale: dict[str, str] = field(default_factory=dict)
    #: stored rows no longer in the configuration
    dropped: list[str] = field(default_factory=list)


def plan(cfg: BenchConfig, store: Store | None, fingerprinter: Fingerprinter,
         cold: bool = False, add: str | None = None) -> Plan:
    """Compare the jobs of ``cfg`` with ``store``.

    A configuration's ``observers: all`` means the built-in observers here: an installed
    third-party plugin enters a store only when named (in the configuration, or as ``add``)."""
    named = cfg.raw.get("observers") if isinstance(cfg.raw.get("observers"), list) else []
    jobs = [j for j in make_jobs(cfg) if is_project_module(j.module)
            or j.observer in named or j.observer == add]
    prints = {job_key(j): fingerprinter.job(j, cfg) for j in jobs}
    if len(prints) != len(jobs):  # two jobs one row: the store could not tell them apart
        keys = [job_key(j) for j in jobs]
        twice = next(k for k in keys if keys.count(k) > 1)
        raise ConfigError(f"{cfg.name}: two jobs share the row key {twice} (scenario, seed, "
                          "observer, variant); give one scenario entry a 'label'")
    stale, dropped = compare(store, prints, fingerprinter.graph, cold)
    return Plan(cfg, store, jobs, prints, list(prints), stale, dropped)


def subset(cfg: BenchConfig, jobs: list, keys: set[str]) -> BenchConfig:
    """``cfg`` restricted to the observers and scenario instances of the jobs ``keys``."""
    chosen = [j for j in jobs if job_key(j) in keys]
    labels = {j.label or j.observer for j in chosen}
    specs = [j.spec for j in chosen]
    instances = [i for i in cfg.instances if i.spec in specs]
    return dataclasses.replace(
        cfg, observers=[o for o in cfg.observers if o in labels], instances=instances,
        scenarios=list({id(i.scenario): i.scenario for i in instances}.values()))


@dataclass
class Outcome:
    """What :func:`bench_config` did."""

    name: str
    ran: int
    total: int
    exit_code: int
    problems: list[str]
    report: Path | None


def run_stale(p: Plan, executor, out: Path, progress: bool | None = None):
    """Run the stale rows of plan ``p`` (their rectangle of observers x scenarios) into the run
    folder ``out``; returns ``(merged store, run result)``, or ``(None, None)`` if nothing is
    stale."""
    if not p.stale:
        return None, None
    sub = subset(p.cfg, p.jobs, set(p.stale))
    result = run_config(sub, out, progress=progress, executor=executor)
    fingerprinter = Fingerprinter()  # the tree as it is now, to compare with the plan
    ran = {job_key(j) for j in make_jobs(sub)}
    moved = {k: changes({"code": p.prints[k].code, "inputs": p.prints[k].inputs,
                         "data": p.prints[k].data}, fp, fingerprinter.graph)
             for k, fp in ((k, fingerprinter.job(j, p.cfg)) for k, j in
                           ((job_key(j), j) for j in p.jobs) if k in ran)
             if fp.digest != p.prints[k].digest}
    if moved:  # the tree changed under the run: its rows are of no single code
        key, why = next(iter(moved.items()))
        raise ConfigError(f"{p.cfg.name}: the code changed while its rows ran ({key}: {why}); "
                          "nothing stored, run `make bench` again")
    run_id, run = new_run(ROOT, {"name": executor.name, "workers": executor.workers})
    described = {k: result.meta[k] for k in ("config", "scenarios")}
    new = RunRows(result.summary, {k: p.prints[k] for k in ran}, run_id, run, described)
    merged = merge(p.store, new, p.order)
    return merged, result


def render(store: Store, out: Path) -> str:
    """The committed Markdown report of a store (written to ``out`` by the caller)."""
    summary, meta = store.view()
    return render_report(summary, meta, out)


def bench_config(p: Plan, results: Path, reports: Path, executor,
                 progress: bool | None = None, notify=print) -> Outcome:
    """Run the stale rows of plan ``p``, store them and render the report (see the module
    docstring).  The caller holds the :class:`.store.StoreLock` of ``results``."""
    folder = results / p.cfg.name
    store = p.store
    notify(f"{p.cfg.name}: {len(p.stale)} of {len(p.order)} rows to run"
           + (f", {len(p.dropped)} no longer in the configuration" if p.dropped else ""))
    code, problems = 0, []
    if p.stale:
        t0 = time.perf_counter()
        merged, result = run_stale(p, executor, folder / "run", progress)
        code, problems = result.exit_code, list(result.problems)
        store = merged
        notify(f"{p.cfg.name}: {len(p.stale)} rows run in {time.perf_counter() - t0:.0f} s")
    elif p.dropped and store is not None:
        kept = {k: store.meta.get(k, {}) for k in ("config", "scenarios")}
        store = merge(store, RunRows.nothing(kept), p.order)
    if store is None:
        return Outcome(p.cfg.name, 0, len(p.order), code, problems, None)
    if p.stale or p.dropped:
        write_store(folder, store)
        store = load_store(folder)  # render what was written (and check it reads back)
    out = reports / f"{p.cfg.name}.md"
    text = render(store, out)
    if not out.is_file() or out.read_text(encoding="utf-8") != text:
        atomic_write_text(out, text)
        notify(f"wrote {out}")
    return Outcome(p.cfg.name, len(p.stale), len(p.order), code, problems, out)


def prewarm_floors(plans: list[Plan], executor, notify=print) -> int:
    """Compute the exact floors of every record with a stale row, across configurations, in
    one parallel map, largest records first; they land in the exact reference's cache, where
    each configuration's run reads them.  Returns the number of records computed.

    Run configuration by configuration, a configuration with one long record keeps one worker
    busy and the others idle; across configurations every worker has a record to work on."""
    tasks, keys, sizes = [], [], []
    budget: float | None = 0.0
    for p in plans:
        if not p.stale or not p.cfg.exact:
            continue
        base = str(p.cfg.base) if p.cfg.base is not None else None
        stale_specs = [j.spec for j in p.jobs if job_key(j) in p.stale]
        for inst in p.cfg.instances:
            key = scenario_key(FloorTask(inst.spec, base))
            if inst.spec not in stale_specs or key in keys:
                continue
            if not getattr(inst.scenario.system, "is_linear", False):
                continue  # the falsifier's inner box has no cache to fill
            tasks.append(FloorTask(inst.spec, base, True))
            keys.append(key)
            sizes.append(inst.scenario.N * inst.scenario.system.n)
            budget = None if budget is None or p.cfg.timeout is None else max(
                budget, p.cfg.timeout)
    if len(tasks) < 2:
        return 0  # nothing to share out: the configuration's own run computes it
    order = sorted(range(len(tasks)), key=lambda i: (-sizes[i], keys[i]))
    tasks, keys = [tasks[i] for i in order], [keys[i] for i in order]
    executor.set_limits(budget or None, None)
    t0 = time.perf_counter()
    for _ in executor.map(floor_task, tasks, keys=keys):
        pass
    notify(f"floors: {len(tasks)} records in {time.perf_counter() - t0:.0f} s with "
           f"{executor.workers} worker(s)")
    return len(tasks)


def bench_all(names: list[str], results: Path, reports: Path, executor, cold: bool = False,
              progress: bool | None = None, notify=print) -> list[Outcome]:
    """``setobs-bench bench``: plan every configuration ``names``, compute the floors their
    stale rows need, then run, store and render them one by one (under the store lock)."""
    with StoreLock(results):
        fingerprinter = Fingerprinter()
        cfgs = [load_config(n) for n in names]
        plans = [plan(c, load_store(results / c.name), fingerprinter, cold) for c in cfgs]
        prewarm_floors(plans, executor, notify)
        return [bench_config(p, results, reports, executor, progress, notify) for p in plans]


def add_observer(cfg: BenchConfig, name: str, results: Path, executor, out: Path,
                 progress: bool | None = None, notify=print) -> tuple[Outcome, Path]:
    """Rank observer ``name`` (a plugin) in configuration ``cfg`` beside its stored rows.

    Runs only ``name``'s rows; every other row comes from the store ``results/<cfg>/`` where its
    fingerprint is current here, and is run too where it is not (so that the table never mixes
    rows of other code).  Writes the merged store and ``report.md`` to ``out`` (never to the
    shipped store).
    """
    import observers

    observers.get(name)  # UnknownObserver: a one-line error naming the known ones
    with_it = cfg if name in cfg.observers else dataclasses.replace(
        cfg, observers=[*cfg.observers, name])
    store = load_store(results / cfg.name)
    if store is None:
        raise ConfigError(f"run --add: no result store of '{cfg.name}' in {results} (its "
                          f"stored rows are what {name} is ranked beside)")
    p = plan(with_it, store, Fingerprinter(), add=name)
    if name in store.summary["observer"].unique():
        raise ConfigError(f"run --add: {name} is already in the stored table of "
                          f"'{cfg.name}'; use --observer {name} to run it alone")
    mine = {k for k in p.stale if k.split("|")[2] == name}
    others = {k: why for k, why in p.stale.items() if k not in mine}
    for key, why in others.items():
        notify(f"note: stored row {key} is not current here ({why}): it runs too")
    with tempfile.TemporaryDirectory(prefix="setobs-add-") as tmp:
        merged, result = run_stale(p, executor, Path(tmp) / "run", progress)
    assert merged is not None  # the new observer's rows are never stored
    write_store(out, merged)
    report = out / "report.md"
    atomic_write_text(report, render(merged, report))
    outcome = Outcome(cfg.name, len(p.stale), len(p.order), result.exit_code,
                      list(result.problems), report)
    return outcome, report



def is_store(folder: Path) -> bool:
    """Whether ``folder`` holds a result store (read from its ``meta.json``'s format line,
    without checking the rows)."""
    try:
        meta = json.loads((folder / "meta.json").read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return False
    return isinstance(meta, dict) and meta.get("format") == FORMAT


def published(root: Path = ROOT) -> list[str]:
    """The shipped configurations with a committed report (``reports/<name>.md``) or store."""
    from ..run.shipped import shipped_configs

    return [n for n in shipped_configs() if (root / REPORTS / f"{n}.md").is_file()
            or (root / RESULTS / n / "meta.json").is_file()]


def shipped_results() -> Path:
    """The folder of the stores shipped with the package: ``benchmarks/stores``, in a checkout
    a link to ``results/``, in an installed package a copy of its stores (package data)."""
    return Path(__file__).resolve().parent.parent / "stores"


def render_all(results: Path, reports: Path) -> list[Path]:
    """Render every store under ``results`` to ``reports/<name>.md``; the reports rewritten
    (none when nothing changed)."""
    changed = []
    for meta in sorted(results.glob("*/meta.json")):
        store = load_store(meta.parent)
        if store is None:
            continue
        out = reports / f"{meta.parent.name}.md"
        text = render(store, out)
        if not out.is_file() or out.read_text(encoding="utf-8") != text:
            atomic_write_text(out, text)
            changed.append(out)
    return changed
