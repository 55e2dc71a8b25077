"""The full soundness audit as a result store: ``results/soundness/``, re-run where stale.

A row is one observer on one audit scenario (a line per realisation kind, the columns of
:data:`.audit.RESULT_COLUMNS`); its fingerprint (:mod:`benchmarks.store.fingerprint`) covers the
closure of the observer's plugin module, of the audit (realisations, membership tests, the
floor) and of the exact reference, the shipped data, and the audit's settings (realisations,
kinds, floor realisations).  ``setobs-bench audit`` with the default scenarios and observers
(``make audit``) runs only the stale or missing pairs, merges them into the store and renders
``reports/soundness.md`` from it (:func:`.audit_report.render_store`); ``--cold`` runs them all.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import observers

from ..errors import ConfigError
from ..io import atomic_write_text
from ..report.dated_block import keep_block
from ..store.fingerprint import Fingerprint, Fingerprinter, row_key
from ..store.graph import ROOT
from ..store.stale import Line
from ..store.store import (
    Layout,
    RunRows,
    Store,
    StoreLock,
    compare,
    load_store,
    merge,
    new_run,
    write_store,
)
from . import audit
from .audit_report import render_store

#: the store's folder and the report's file, relative to the project root
STORE = Path("results") / "soundness"
REPORT = Path("reports") / "soundness.md"
#: a row: an observer on a scenario, one line per realisation kind in the audit's order
LAYOUT = Layout(("scenario", "observer"), None, None)


@dataclass
class AuditPlan:
    """The audit's pairs, their fingerprints and the stale ones."""

    store: Store | None
    count: int
    prints: dict[str, Fingerprint]
    order: list[str]
    pairs: dict[str, tuple[str, str]]
    stale: dict[str, str] = field(default_factory=dict)
    dropped: list[str] = field(default_factory=list)


def audited_observers() -> list[str]:
    """The observers of the full audit: every built-in one but the exact reference (the floor
    the others are held to); installed plugins are audited on demand (``--observers``)."""
    return [i.name for i in observers.available()
            if i.family != "reference" and i.cls.__module__.startswith("observers.")]


def pair_fingerprint(fp: Fingerprinter, scenario: str, observer: str, count: int) -> Fingerprint:
    """The fingerprint of the audit of ``observer`` on ``scenario`` with ``count``
    realisations."""
    roots = [observers.get(observer).cls.__module__, audit.__name__,
             observers.get("Exact").cls.__module__]
    entry = {"audit": {"scenario": scenario, "observer": observer, "realisations": count,
                       "kinds": list(audit.KINDS), "floors": audit.FLOOR_REALISATIONS,
                       "rel_tol": audit.REL_TOL}}
    return fp.make(roots, entry)


def plan_audit(count: int, results: Path, cold: bool = False,
               fingerprinter: Fingerprinter | None = None) -> AuditPlan:
    """Compare the audit's pairs with its store in ``results``."""
    fp = fingerprinter or Fingerprinter()
    store = load_store(results / STORE.name, LAYOUT)
    pairs = {row_key(sc, obs): (sc, obs) for sc in audit.AUDIT_SCENARIOS
             for obs in audited_observers()}
    prints = {k: pair_fingerprint(fp, sc, obs, count) for k, (sc, obs) in pairs.items()}
    stale, dropped = compare(store, prints, fp.graph, cold)
    return AuditPlan(store, count, prints, list(pairs), pairs, stale, dropped)


def run_meta(count: int) -> dict:
    return {"config": {"name": STORE.name, "title": "Soundness audit"},
            "audit": {"realisations": count, "kinds": list(audit.KINDS),
                      "scenarios": list(audit.AUDIT_SCENARIOS),
                      "floor_realisations": audit.FLOOR_REALISATIONS}}


def bench_audit(count: int, jobs: int, results: Path = ROOT / "results",
                reports: Path = ROOT / "reports", cold: bool = False,
                progress: bool | None = None, notify=print):
    """Run the stale pairs of the audit, store them and render ``reports/soundness.md``.

    Returns
    -------
    (Store, DataFrame or None, int)
        The store, the rows just run (None if none), and how many pairs ran.
    """
    with StoreLock(results):
        p = plan_audit(count, results, cold)
        notify(f"audit: {len(p.stale)} of {len(p.order)} observer x scenario pairs to run")
        store, df = p.store, None
        if p.stale:
            only = {p.pairs[k] for k in p.stale}
            df = audit.run_audit(audit.AUDIT_SCENARIOS, sorted({o for _, o in only}),
                                 audit.Realisations(count), jobs, progress=progress, only=only)
            again = Fingerprinter()  # the tree must not have changed under the run
            moved = [k for k in p.stale if pair_fingerprint(again, *p.pairs[k], count).digest
                     != p.prints[k].digest]
            if moved:
                raise ConfigError(f"audit: the code changed while {moved[0]} ran; nothing "
                                  "stored, run `make audit` again")
            run_id, run = new_run(ROOT, {"name": "processes" if jobs > 1 else "serial",
                                         "workers": jobs})
            new = RunRows(df, {k: p.prints[k] for k in p.stale}, run_id, run, run_meta(count))
            store = merge(p.store, new, p.order, LAYOUT)
        elif p.dropped and store is not None:
            store = merge(store, RunRows.nothing(run_meta(count)), p.order, LAYOUT)
        if store is None:
            return None, df, 0
        if p.stale or p.dropped:
            write_store(results / STORE.name, store)
            store = load_store(results / STORE.name, LAYOUT)
        if rerender(results, reports):
            notify(f"wrote {reports / REPORT.name}")
        return store, df, len(p.stale)


def render(store: Store) -> str:
    """``reports/soundness.md`` of the audit's store."""
    summary, meta = store.view()
    return render_store(summary, meta)


def stale_lines(root: Path = ROOT, fingerprinter: Fingerprinter | None = None,
                reports: Path | None = None) -> list[Line]:
    """The audit's stale rows and whether its report (``reports/soundness.md``; ``reports``:
    another folder of reports) differs from its store rendered now (``setobs-bench stale``)."""
    try:
        stored = load_store(root / STORE, LAYOUT)
    except ConfigError as exc:
        return [Line("store", STORE.name, str(exc))]
    if stored is None:
        return [Line("store", STORE.name, f"no result store in {STORE} (run `make audit`)")]
    count = stored.meta.get("audit", {}).get("realisations")
    p = plan_audit(count, root / "results", fingerprinter=fingerprinter)
    out = [Line("row", STORE.name, f"{k.split('|')[1]} on {k.split('|')[0]}: {why} "
                                   "(`make audit`)") for k, why in p.stale.items()]
    out += [Line("row", STORE.name, f"{k.split('|')[1]} on {k.split('|')[0]}: no longer "
                                    "audited") for k in p.dropped]
    report = (reports if reports is not None else root / REPORT.parent) / REPORT.name
    if not report.is_file() or (text := report.read_text(encoding="utf-8")) != keep_block(
            text, render(stored)):
        out.append(Line("report", STORE.name, f"{REPORT} differs from its store rendered now "
                                              "(`make reports` renders it)"))
    return out


def rerender(results: Path, reports: Path) -> bool:
    """Render ``reports/soundness.md`` from the audit's store in ``results``; whether the file
    changed (False, and nothing written, without a store)."""
    store = load_store(results / STORE.name, LAYOUT)
    if store is None:
        return False
    out = reports / REPORT.name
    text = render(store)
    if out.is_file():
        old = out.read_text(encoding="utf-8")
        text = keep_block(old, text)  # its dated block: benchmarks.gate.dated
        if old == text:
            return False
    atomic_write_text(out, text)
    return True
