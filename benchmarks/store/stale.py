"""What is out of date, without running anything: ``setobs-bench stale``.

Freshness has two tiers.  The first, checked here, is what every landing keeps current:

- **Rows.**  For every shipped configuration, the fingerprint of each job
  (:mod:`.fingerprint`) against its stored row in ``results/<name>/``: a row is stale if its
  fingerprint differs (the line says which module, data file or configuration entry changed),
  missing if the store has none, and gone if the configuration no longer has it.
- **Reports of configurations.**  ``reports/<name>.md`` is rendered from the store again in
  memory and compared byte for byte: out of date if the renderer or the store changed since.

The second tier are the dated measurements (the studies, the soundness audit, the kernel study
and the timing reports, :mod:`benchmarks.gate.dated`): each says the version and commit that
measured it and which of its rows the code has changed since; they never block a landing.
:func:`kernel_changes` gives the rows of the kernel study (``reports/kernels.md``,
:mod:`benchmarks.studies.kernels`), which keeps the fingerprint of every stored row it
measured.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from ..errors import ConfigError
from ..io import read_table
from ..run.config import load_config
from ..run.shipped import shipped_configs
from .bench import REPORTS, RESULTS, plan, render
from .fingerprint import Fingerprinter
from .graph import ROOT, ModuleGraph
from .store import load_store


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


def kernel_changes(root: Path = ROOT) -> list[str]:
    """The rows of the kernel study (``OBSERVER on SCENARIO (CONFIG)``) whose stored
    fingerprint differs from the one it measured, and the tables it measures but never
    measured (``CONFIG (not measured)``)."""
    from ..report.spread import KERNEL_CONFIGS as CONFIGS
    from ..report.spread import KERNEL_TABLE as TABLE

    path = root / TABLE
    if not path.is_file():
        return [f"{c} (not measured)" for c in CONFIGS]
    measured = read_table(path)
    out = []
    for config in CONFIGS:
        summary = root / RESULTS / config / "summary.csv"
        if not summary.is_file():
            continue
        here = read_table(summary)
        m = measured[measured["config"] == config]
        if m.empty:
            out.append(f"{config} (not measured)")
            continue
        now = dict(zip(zip(here["scenario"], here["observer"], strict=True),
                       here["fingerprint"], strict=True))
        then = dict(zip(zip(m["scenario"], m["observer"], strict=True), m["fingerprint"],
                        strict=True))
        out += [f"{o} on {s} ({config})" for s, o in sorted(k for k in now
                                                             if then.get(k) != now[k])]
    return out


def find_stale(names: list[str] | None = None, root: Path = ROOT, reports: Path | None = None,
               fingerprinter: Fingerprinter | None = None) -> list[Line]:
    """Every stale row, store and report of the shipped configurations ``names`` (default
    all: the published ones); ``reports``: the folder of the committed reports (default
    ``ROOT/reports``)."""
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
    return out
