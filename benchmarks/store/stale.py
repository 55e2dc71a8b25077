"""What is out of date, without running anything: ``setobs-bench stale``.

- **Rows.**  For every shipped configuration, the fingerprint of each job
  (:mod:`.fingerprint`) against its stored row in ``results/<name>/``: a row is stale if its
  fingerprint differs (the line says which module, data file or configuration entry changed),
  missing if the store has none, and gone if the configuration no longer has it.
- **Reports of configurations.**  ``reports/<name>.md`` is rendered from the store again in
  memory and compared byte for byte: out of date if the renderer or the store changed since.
- **The soundness audit** is a store of its own (:mod:`benchmarks.gate.audit_store`, checked
  by :func:`benchmarks.gate.policy.stale`, which adds its lines to these).
- **Studies** (``reports/datadriven.md``, ``noise_grid.md``, ``robustness.md``): one
  fingerprint per report, over the closure of the study's module and of the observers it runs,
  recorded in ``results/reports.json`` by ``setobs-bench stale --record REPORT`` right after
  the report is regenerated (``make datadriven``, ``make noise-grid``, ``make robustness`` do
  it).
- **The kernel study** (``reports/kernels.md``, :mod:`benchmarks.studies.kernels`) measures
  the committed rows of the paper tables themselves: each of its cells keeps the fingerprint
  of the stored row it measured, and the study is stale for every row whose stored fingerprint
  moved since (``make kernels`` measures again).
- **Measurements** (``reports/speed.md``, ``scaling.md``, ``frontier.md``) describe a machine,
  not the code: they carry their commit and machine and are never stale here; ``make speed``,
  ``make scaling`` and ``make frontier`` measure again.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass
from pathlib import Path

import observers

from ..errors import ConfigError
from ..io import json_text, read_json_object, read_table
from ..run.config import load_config
from ..run.shipped import shipped_configs
from .bench import REPORTS, RESULTS, plan, render
from .fingerprint import Fingerprinter, canonical, short
from .graph import ROOT, ModuleGraph
from .store import load_store

#: reports that measure a machine: never stale for the code
MEASUREMENTS = ("speed", "scaling", "frontier")
#: study reports: the module that writes each and the observers it runs (by name, through the
#: registry, so not among its imports); the soundness audit is a store of its own
#: (:mod:`benchmarks.gate.audit_store`)
#: the observers the studies over every guaranteed observer run (and the exact reference of
#: their floors)
_GUARANTEED = ("Exact", "VolMin-B", "FRad-A", "FRad-B", "PRad-A", "PRad-B", "PRad-C-I",
               "PRad-C-II", "PRad-D", "CZN-A", "CZN-B", "CZN-MV", "ESO-A", "ESO-B", "FRad-C",
               "PRad-E", "Nom-G", "ESO-C", "ESO-D", "Hinf-G", "CZN-DC", "CZN-FO", "CZN-PR",
               "DD-CZ-A1", "DD-CZ-A2", "DD-Z-A1", "DD-Z-A2", "ESMF", "INT-CP", "MHE", "ROPO",
               "ZB-A", "VolMin-A", "MHE-PR")
STUDIES = {"datadriven": ("benchmarks.studies.alanwar2022",
                          ("DD-Z-A1", "DD-Z-A2", "DD-CZ-A1", "DD-CZ-A2", "KF-N4SID")),
           "noise_grid": ("benchmarks.studies.noise_grid", _GUARANTEED),
           "robustness": ("benchmarks.studies.robustness", _GUARANTEED)}
#: the make target that regenerates (and records) each study report
STUDY_TARGETS = {"datadriven": "datadriven", "noise_grid": "noise-grid",
                 "robustness": "robustness"}
#: where the fingerprints of the study reports are recorded
STUDY_RECORD = Path("results") / "reports.json"


@dataclass(frozen=True)
class Line:
    """One stale thing: ``kind`` is ``row``, ``report`` or ``store``."""

    kind: str
    config: str
    text: str

    def __str__(self) -> str:
        return f"STALE {self.kind.upper()} {self.config}: {self.text}"


def _row_text(key: str, why: str) -> str:
    scenario, seed, obs, variant = key.split("|")
    where = scenario + (f" seed {seed}" if seed else "") + (f" variant {variant}"
                                                              if variant else "")
    return f"{obs} on {where}: {why}"


def stale_config(name: str, path: Path, fingerprinter: Fingerprinter, root: Path = ROOT,
                 reports: Path | None = None) -> list[Line]:
    """The stale rows of one configuration and whether its report is out of date."""
    folder = root / RESULTS / name
    report = (reports if reports is not None else root / REPORTS) / f"{name}.md"
    try:
        store = load_store(folder)
    except ConfigError as exc:
        return [Line("store", name, str(exc))]
    if store is None:
        return [Line("store", name, f"no result store in {folder.relative_to(root)} (run "
                                    f"`setobs-bench bench {name}`)")]
    cfg = load_config(path)
    p = plan(cfg, store, fingerprinter)
    out = [Line("row", name, _row_text(k, why)) for k, why in p.stale.items()]
    out += [Line("row", name, _row_text(k, "no longer in the configuration"))
            for k in p.dropped]
    shown = report.relative_to(root) if report.is_relative_to(root) else report
    if not report.is_file():
        out.append(Line("report", name, f"{shown} is missing (`make reports` renders it)"))
    elif report.read_text(encoding="utf-8") != render(store, report):
        out.append(Line("report", name, f"{shown} differs from its store rendered now "
                                        "(`make reports` renders it)"))
    return out


def study_fingerprint(name: str, fingerprinter: Fingerprinter) -> dict:
    """``{"digest": ..., "code": {...}, "data": ...}`` of a study report now."""
    graph = fingerprinter.graph
    module, names = STUDIES[name]
    roots = [module, *sorted({observers.get(n).cls.__module__ for n in names})]
    modules = set().union(*(graph.closure(r) for r in roots))
    code = {m: short(graph.modules[m].digest) for m in sorted(modules)}
    data = short(hashlib.sha256(canonical(fingerprinter.data_digests()).encode()).hexdigest())
    digest = short(hashlib.sha256(canonical([code, data]).encode()).hexdigest())
    return {"digest": digest, "code": code, "data": data}


def _read_record(root: Path) -> dict:
    path = root / STUDY_RECORD
    if not path.is_file():
        return {}
    return read_json_object(path, fix="restore it with git")


def record_study(report: str | Path, root: Path = ROOT) -> str:
    """Record that the study report ``report`` was just produced from the current tree."""
    name = Path(report).stem
    if name not in STUDIES:
        raise ConfigError(f"stale --record: {report} is not a study report (known: "
                          f"{', '.join(f'reports/{s}.md' for s in STUDIES)}; the audit's "
                          "report is rendered from its store)")
    rec = _read_record(root)
    rec[name] = study_fingerprint(name, Fingerprinter(ModuleGraph(root)))
    path = root / STUDY_RECORD
    path.parent.mkdir(parents=True, exist_ok=True)
    from ..io import atomic_write_text
    atomic_write_text(path, json_text(dict(sorted(rec.items()))))
    return rec[name]["digest"]


def stale_studies(fingerprinter: Fingerprinter, root: Path = ROOT,
                  reports: Path | None = None) -> list[Line]:
    """The study reports whose recorded fingerprint differs from the tree's."""
    rec = _read_record(root)
    reports = reports if reports is not None else root / REPORTS
    out = []
    for name in STUDIES:
        if not (reports / f"{name}.md").is_file():
            continue
        now = study_fingerprint(name, fingerprinter)
        old = rec.get(name)
        if old is None:
            out.append(Line("report", name, f"reports/{name}.md has no recorded fingerprint "
                                            f"in {STUDY_RECORD}"))
        elif old.get("digest") != now["digest"]:
            changed = sorted(m for m in set(old.get("code", {})) | set(now["code"])
                             if old.get("code", {}).get(m) != now["code"].get(m))
            what = ", ".join(fingerprinter.graph.source_path(m) if m in
                             fingerprinter.graph.modules else m for m in changed[:3])
            more = f" and {len(changed) - 3} more" if len(changed) > 3 else ""
            why = f"code changed: {what}{more}" if changed else "data changed"
            out.append(Line("report", name,
                            f"reports/{name}.md: {why} (`make {STUDY_TARGETS[name]}`)"))
    return out


def stale_kernels(root: Path = ROOT, reports: Path | None = None) -> list[Line]:
    """The rows whose stored fingerprint differs from the one the kernel study measured
    (:mod:`benchmarks.studies.kernels`), and the tables it measures but never measured."""

    from ..report.spread import KERNEL_CONFIGS as CONFIGS
    from ..report.spread import KERNEL_TABLE as TABLE

    reports = reports if reports is not None else root / REPORTS
    if not (reports / "kernels.md").is_file():
        return []
    path = root / TABLE
    if not path.is_file():
        return [Line("report", "kernels", f"reports/kernels.md has no table {TABLE} "
                                          "(`make kernels`)")]
    measured = read_table(path)
    out = []
    for config in CONFIGS:
        summary = root / RESULTS / config / "summary.csv"
        if not summary.is_file():
            continue
        here = read_table(summary)
        m = measured[measured["config"] == config]
        if m.empty:
            out.append(Line("report", "kernels", f"{config} not measured under the other "
                                                 "OpenBLAS kernels (`make kernels`)"))
            continue
        now = dict(zip(zip(here["scenario"], here["observer"], strict=True),
                       here["fingerprint"], strict=True))
        then = dict(zip(zip(m["scenario"], m["observer"], strict=True), m["fingerprint"],
                        strict=True))
        moved = sorted(k for k in now if then.get(k) != now[k])
        if moved:
            shown = ", ".join(f"{o} on {s}" for s, o in moved[:3])
            more = f" and {len(moved) - 3} more" if len(moved) > 3 else ""
            out.append(Line("report", "kernels", f"{config}: {shown}{more} changed since "
                                                 "measured (`make kernels`)"))
    return out


def find_stale(names: list[str] | None = None, root: Path = ROOT, reports: Path | None = None,
               fingerprinter: Fingerprinter | None = None) -> list[Line]:
    """Every stale row, store and report of the shipped configurations ``names`` (default
    all: the published ones) and of the study reports; ``reports``: the folder of the
    committed reports (default ``ROOT/reports``)."""
    shipped = shipped_configs()
    if names:
        unknown = [n for n in names if n not in shipped]
        if unknown:
            raise ConfigError(f"stale: unknown configuration(s) {', '.join(unknown)} (shipped: "
                              f"{', '.join(shipped)})")
    fingerprinter = fingerprinter or Fingerprinter(ModuleGraph(root))
    reports = Path(reports) if reports is not None else root / REPORTS
    out: list[Line] = []
    for name, path in shipped.items():
        if names and name not in names:
            continue
        if not names and not ((reports / f"{name}.md").is_file()
                              or (root / RESULTS / name / "meta.json").is_file()):
            continue  # not published (a sweep): no store, no report
        out += stale_config(name, path, fingerprinter, root, reports)
    if not names:
        out += stale_studies(fingerprinter, root, reports)
        out += stale_kernels(root, reports)
    return out
