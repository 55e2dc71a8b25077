"""Dated measurements: the second tier of freshness.

The published tables (the result stores of the shipped configurations, their reports and the
golden files of the gate) are the first tier: they are kept current at every landing
(``make bench``, :mod:`.stale`).  The studies and timing reports are the second tier: each is
a measurement made by one version of the code at one commit, and says so.  Each report of
:data:`DATED` carries, right under its title, a block rendered from its fingerprints
(:func:`block`)::

    <!-- dated -->
    *Measured by setobs-bench 0.15.0 at commit 06a6dea on 2026-12-06.* Rows the code has
    changed since: ESO-C, ESO-D (observers/numerics/ellipsoidal.py); `make robustness`
    measures them again.
    <!-- /dated -->

so that a reader sees which of its rows are older than the code, without blocking a landing.
``make reports`` re-renders the block (seconds, no run); ``make release`` measures again every
report with a changed row.

A *row* of a dated report is what the report measures per observer: its fingerprint is the
digest of the closure of the study's module, of the observer's plugin module (and of the exact
reference where the study holds its rows against the exact floor) and of the shipped data
(:func:`row_prints`).  Per report, ``results/reports.json`` records the version, commit and
date of the measurement and the digest of every row then (:func:`record`).  The kernel study
and the soundness audit are stores of fingerprinted rows of their own
(:mod:`benchmarks.studies.kernels`, :mod:`benchmarks.gate.audit_store`); their changed rows come
from there (:func:`changed_rows`).
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path

import observers

from ..errors import ConfigError
from ..io import atomic_write_text, json_text, read_json_object
from ..report.citation import project_version
from ..report.dated_block import BEGIN, END, with_block
from ..report.freshness import commit
from ..store import stale
from ..store.fingerprint import Fingerprinter, canonical, short
from ..store.graph import ROOT, ModuleGraph
from . import audit_store

#: the observers the studies over every guaranteed observer run
GUARANTEED = ("VolMin-B", "FRad-A", "FRad-B", "PRad-A", "PRad-B", "PRad-C-I", "PRad-C-II",
              "PRad-D", "CZN-A", "CZN-B", "CZN-MV", "ESO-A", "ESO-B", "FRad-C", "PRad-E",
              "Nom-G", "ESO-C", "ESO-D", "Hinf-G", "CZN-DC", "CZN-FO", "CZN-PR", "DD-CZ-A1",
              "DD-CZ-A2", "DD-Z-A1", "DD-Z-A2", "ESMF", "INT-CP", "MHE", "ROPO", "ZB-A",
              "VolMin-A", "MHE-PR")
#: the observers of the data-driven study
DATA_DRIVEN = ("DD-Z-A1", "DD-Z-A2", "DD-CZ-A1", "DD-CZ-A2", "KF-N4SID")


@dataclass(frozen=True)
class Dated:
    """A dated report: the module that measures it, the observers it runs (by name, through
    the registry: not among its imports), whether its rows are held against the exact floor,
    and the make target that measures it again."""

    module: str
    observers: tuple[str, ...]
    floor: bool
    target: str


#: the dated reports with rows of their own (``reports/<name>.md``)
DATED = {
    "datadriven": Dated("benchmarks.studies.alanwar2022", DATA_DRIVEN, False, "datadriven"),
    "noise_grid": Dated("benchmarks.studies.noise_grid", GUARANTEED, True, "noise-grid"),
    "robustness": Dated("benchmarks.studies.robustness", GUARANTEED, True, "robustness"),
    "speed": Dated("benchmarks.timing.speed", GUARANTEED, False, "speed"),
    "scaling": Dated("benchmarks.studies.scaling", GUARANTEED, False, "scaling"),
    "frontier": Dated("benchmarks.studies.frontier", GUARANTEED, True, "frontier"),
}
#: the dated reports whose rows are fingerprinted in a store of their own
STORED = {"kernels": "kernels", "soundness": "audit"}
#: where the records of the dated reports are kept
RECORD = Path("results") / "reports.json"


def row_prints(name: str, fingerprinter: Fingerprinter) -> tuple[dict[str, str], dict[str, str]]:
    """``({row: digest}, {module: digest})`` of the dated report ``name`` now: one row per
    observer it runs (see the module docstring), and the code of every module of their
    closures."""
    graph = fingerprinter.graph
    spec = DATED[name]
    data = short(hashlib.sha256(canonical(fingerprinter.data_digests()).encode()).hexdigest())
    base = set(graph.closure(spec.module))
    if spec.floor:
        base |= graph.closure(observers.get("Exact").cls.__module__)
    rows, code = {}, {}
    for obs in spec.observers:
        modules = base | graph.closure(observers.get(obs).cls.__module__)
        mine = {m: short(graph.modules[m].digest) for m in sorted(modules)}
        code.update(mine)
        rows[obs] = short(hashlib.sha256(canonical([mine, data]).encode()).hexdigest())
    return rows, code


def read_records(root: Path = ROOT) -> dict:
    """The records of the dated reports (``results/reports.json``), ``{}`` if none."""
    path = root / RECORD
    return read_json_object(path, fix="restore it with git") if path.is_file() else {}


def record(report: str | Path, root: Path = ROOT, measured_at: str | None = None,
           measured_by: str | None = None) -> dict:
    """Record that the dated report ``report`` was just measured from the current tree (its
    version, commit, date and the fingerprint of every row); returns the record.

    ``measured_at``/``measured_by``: the commit and version of a measurement made before
    (to record a report measured by an earlier commit whose rows are the same code)."""
    name = Path(report).stem
    if name not in DATED and name not in STORED:
        known = ", ".join(f"reports/{s}.md" for s in (*DATED, *STORED))
        raise ConfigError(f"stale --record: {report} is not a dated report (known: {known})")
    rec = read_records(root)
    rec[name] = {"version": measured_by or project_version(), "commit": measured_at or commit(root),
                 "date": datetime.now(timezone.utc).date().isoformat()}
    if name in DATED:  # the others' rows are fingerprinted in their stores
        rows, code = row_prints(name, Fingerprinter(ModuleGraph(root)))
        rec[name].update(rows=rows, code=code)
    path = root / RECORD
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_write_text(path, json_text(dict(sorted(rec.items()))))
    return rec[name]


def changed_rows(name: str, fingerprinter: Fingerprinter | None = None, root: Path = ROOT
                 ) -> dict[str, list[str]] | None:
    """``{row: [changed module paths]}`` of the rows of dated report ``name`` whose code changed
    since it was measured (an empty list: its data changed); None if it has no record."""
    fingerprinter = fingerprinter or Fingerprinter(ModuleGraph(root))
    if name in STORED:
        return _stored_changes(name, fingerprinter, root)
    old = read_records(root).get(name)
    if old is None:
        return None
    rows, code = row_prints(name, fingerprinter)
    graph = fingerprinter.graph
    out = {}
    for obs, digest in rows.items():
        if old.get("rows", {}).get(obs) == digest:
            continue
        modules = graph.closure(DATED[name].module) | graph.closure(
            observers.get(obs).cls.__module__)
        moved = sorted(m for m in modules if old.get("code", {}).get(m) != code.get(m))
        out[obs] = [graph.source_path(m) if m in graph.modules else m for m in moved]
    return out


def _stored_changes(name: str, fingerprinter: Fingerprinter, root: Path
                    ) -> dict[str, list[str]]:
    """The changed rows of the kernel study and of the soundness audit (their stores)."""
    if name == "kernels":
        return {row: [] for row in stale.kernel_changes(root)}
    stored = audit_store.load_store(root / audit_store.STORE, audit_store.LAYOUT)
    if stored is None:
        return {}
    count = stored.meta.get("audit", {}).get("realisations")
    p = audit_store.plan_audit(count, root / "results", fingerprinter=fingerprinter)
    return {f"{k.split('|')[1]} on {k.split('|')[0]}": [] for k in p.stale}


def _measured(name: str, root: Path) -> tuple[str, str, str]:
    """``(version, commit, date)`` of the measurement of dated report ``name``."""
    rec = read_records(root).get(name, {})
    return rec.get("version", "?"), rec.get("commit", "?"), rec.get("date", "?")


def block(name: str, fingerprinter: Fingerprinter, root: Path = ROOT) -> str:
    """The dated block of report ``name`` now (with its markers and a blank line after)."""
    ver, at, date = _measured(name, root)
    changed = changed_rows(name, fingerprinter, root)
    head = f"*Measured by setobs-bench {ver} at commit {at} on {date}.*"
    target = DATED[name].target if name in DATED else STORED[name]
    if changed is None:
        tail = f"No record of its rows (`make {target}` measures it and records them)."
    elif not changed:
        tail = "No row of it has changed in the code since."
    else:
        shown = []
        for row, paths in list(changed.items())[:12]:
            where = f" ({', '.join(paths[:2])}{' ...' if len(paths) > 2 else ''})" if paths else ""
            shown.append(row + where)
        more = f" and {len(changed) - 12} more" if len(changed) > 12 else ""
        tail = (f"Rows the code has changed since ({len(changed)}): {'; '.join(shown)}{more}; "
                f"`make {target}` measures them again.")
    return f"{BEGIN}\n{head} {tail}\n{END}\n\n"


def dated_reports(reports: Path) -> list[str]:
    """The dated reports present in ``reports``."""
    return [n for n in (*DATED, *STORED) if (reports / f"{n}.md").is_file()]


def refresh(reports: Path, root: Path = ROOT, fingerprinter: Fingerprinter | None = None
            ) -> list[Path]:
    """Re-render the dated block of every dated report in ``reports``; the files changed."""
    fingerprinter = fingerprinter or Fingerprinter(ModuleGraph(root))
    out = []
    for name in dated_reports(reports):
        path = reports / f"{name}.md"
        text = path.read_text(encoding="utf-8")
        new = with_block(text, block(name, fingerprinter, root))
        if new != text:
            atomic_write_text(path, new)
            out.append(path)
    return out


def outdated_blocks(reports: Path, root: Path = ROOT,
                    fingerprinter: Fingerprinter | None = None) -> list[str]:
    """The dated reports in ``reports`` whose block differs from its rendering now."""
    fingerprinter = fingerprinter or Fingerprinter(ModuleGraph(root))
    out = []
    for name in dated_reports(reports):
        text = (reports / f"{name}.md").read_text(encoding="utf-8")
        if with_block(text, block(name, fingerprinter, root)) != text:
            out.append(name)
    return out


__all__ = ["BEGIN", "DATED", "END", "RECORD", "STORED", "block", "changed_rows",
           "dated_reports", "outdated_blocks", "read_records", "record", "refresh",
           "with_block"]
