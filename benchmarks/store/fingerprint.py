"""What a stored row is made of, as one digest: its fingerprint.

A row of ``results/<config>/summary.csv`` (one observer, or labelled variant, on one scenario
instance; one line per state) is produced by

- the code of its computation: the closure (:class:`.graph.ModuleGraph`) of the observer's
  plugin module, of the observers an option names (``MHE``'s inner observer), of the module
  that makes one job's rows (``benchmarks.run.rows``: the design and run, containment checks,
  metrics, the floor columns, the scenario built from its entry, the models of ``systems``),
  and, when the configuration computes floors, of the floor of its record: the exact reference
  (``Exact``'s plugin) for a linear record, the falsifier's inner box
  (``benchmarks.run.floor_inner``) for a nonlinear one.  What orchestrates a run (the runner,
  the executors, Dask, progress bars, input/output, the store, the gate, the reports) is in no
  row's closure: an edit there changes no row (``tests/test_layering.py``);
- the data shipped with the models (every file under ``systems/data/``) and the user's records
  named by the scenario entry;
- its entry in the configuration: the scenario entry (seed included), the options, the
  observer's options and variant, the containment check, the floors and the job's time budget.

Versions of numpy, the BLAS kernel and the machine are not part of the fingerprint: they are
recorded beside the rows (the store's ``runs``), so that a store says which machine produced
which row.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import observers

from ..run.floor import observer_floor
from ..run.specs import scenario_of
from .graph import ROOT, ModuleGraph

#: the harness modules every row is computed by (their closures are derived from the code)
HARNESS = ("benchmarks.run.rows",)
#: the module of the floor of a nonlinear record (in the closure of those rows only)
INNER_FLOOR = "benchmarks.run.floor_inner"
#: folders whose every file is data of the models
DATA_DIRS = ("systems/data",)
#: length of a stored digest (hex digits)
SHORT = 16


def short(digest: str) -> str:
    return digest[:SHORT]


def _sha(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def canonical(obj: Any) -> str:
    """JSON with sorted keys and no spaces: the same text for equal values."""
    return json.dumps(obj, sort_keys=True, separators=(",", ":"), default=str)


@dataclass(frozen=True)
class Fingerprint:
    """The fingerprint of a row and its parts (to say what changed).

    Attributes
    ----------
    digest : str
        The row's fingerprint (hex, :data:`SHORT` digits).
    code : dict
        ``{module: digest}`` of every module of its computation.
    inputs : str
        Digest of its configuration entry.
    data : dict
        ``{file: digest}`` of the data files and records it reads.
    """

    digest: str
    code: dict[str, str]
    inputs: str
    data: dict[str, str]


def scenario_name(spec: dict) -> str:
    """The name of the scenario a configuration entry builds, as its rows carry it: its
    ``label`` where it has one (the same record once more under another name), else its
    ``name``."""
    label = spec.get("label")
    return label.strip() if isinstance(label, str) and label.strip() else spec["name"]


def job_key(job) -> str:
    """The key of a job's rows in a store: ``scenario|seed|observer|variant`` (the scenario
    as :func:`scenario_name`, the observer the labelled variant's label where there is one, as
    in ``summary.csv``)."""
    return row_key(scenario_name(job.spec), job.seed, job.label or job.observer, job.variant)


def row_key(*values: Any) -> str:
    """The key of a stored row from its key columns (``scenario, seed, observer, variant`` of a
    configuration's summary): the values joined by ``|``, a missing one empty, an integral
    number without its decimals, so that a key read back from CSV is the key written."""
    parts = []
    for v in values:
        if v is None or (isinstance(v, float) and v != v) or v == "":
            parts.append("")
        elif isinstance(v, (int, float)) and float(v).is_integer():
            parts.append(str(int(v)))
        elif isinstance(v, str) and v.replace(".", "", 1).lstrip("-").isdigit():
            parts.append(str(int(float(v))) if float(v).is_integer() else v)
        else:
            parts.append(str(v))
    return "|".join(parts)


class Fingerprinter:
    """Fingerprints of the jobs of configurations against one reading of the source tree.

    Parameters
    ----------
    graph : ModuleGraph, optional
        The module graph (read from the project root by default).
    """

    def __init__(self, graph: ModuleGraph | None = None):
        self.graph = graph or ModuleGraph()
        self._data: dict[str, str] | None = None
        self._files: dict[Path, str] = {}

    def data_digests(self) -> dict[str, str]:
        """``{path: digest}`` of every file of :data:`DATA_DIRS`."""
        if self._data is None:
            root = self.graph.root
            self._data = {p.relative_to(root).as_posix(): short(_sha(p.read_bytes()))
                          for d in DATA_DIRS for p in sorted((root / d).rglob("*"))
                          if p.is_file() and "__pycache__" not in p.parts}
        return self._data

    def _file(self, path: Path) -> str:
        if path not in self._files:
            self._files[path] = short(_sha(path.read_bytes()))
        return self._files[path]

    def _records(self, spec: Any, base: str | None) -> dict[str, str]:
        """The files a scenario entry names (its CSV records), by content."""
        out: dict[str, str] = {}

        def visit(value):
            if isinstance(value, dict):
                for v in value.values():
                    visit(v)
            elif isinstance(value, (list, tuple)):
                for v in value:
                    visit(v)
            elif isinstance(value, str) and ("/" in value or value.endswith((".csv", ".txt"))):
                path = Path(value)
                if not path.is_absolute() and base:
                    path = Path(base) / path
                if path.is_file():
                    out[value] = self._file(path.resolve())
        visit(spec)
        return out

    def roots(self, job, exact: bool) -> list[str]:
        """The modules whose closures make the job's code (the floor's by the linearity of
        the job's system, as :func:`benchmarks.run.floors.compute_floor` chooses it)."""
        names = [job.module, *HARNESS]
        if exact:
            linear = getattr(scenario_of(job).system, "is_linear", False)
            names.append(observers.get("Exact").cls.__module__ if linear else INNER_FLOOR)
        known = set(observers.names())
        for value in {**job.options, **job.observer_options}.values():
            if isinstance(value, str) and value in known:  # an observer named by an option
                names.append(observers.get(value).cls.__module__)
        return names

    def code_of(self, roots: list[str]) -> dict[str, str]:
        """``{module: digest}`` of the closures of ``roots`` (an outside package is read where
        its source can be found; else its name stands for it)."""
        modules: set[str] = set()
        for name in roots:
            top = name.split(".")[0]
            if name not in self.graph.modules and not self.graph.add_package(top):
                modules.add(name)
                continue
            modules |= self.graph.closure(name)
        return {m: short(self.graph.modules[m].digest) if m in self.graph.modules else "?"
                for m in sorted(modules)}

    def make(self, roots: list[str], entry: dict, records: dict[str, str] | None = None
             ) -> Fingerprint:
        """The fingerprint of a row computed by the closures of ``roots`` from its entry
        ``entry`` (any JSON value) and the shipped data, plus ``records`` (file digests)."""
        code = self.code_of(roots)
        data = {**self.data_digests(), **(records or {})}
        inputs = short(_sha(canonical(entry).encode()))
        digest = short(_sha(canonical({"code": code, "inputs": inputs, "data": data}).encode()))
        return Fingerprint(digest, code, inputs, data)

    def job(self, job, cfg) -> Fingerprint:
        """The fingerprint of ``job`` of configuration ``cfg``."""
        entry = {
            "scenario": job.spec, "options": job.options,
            "observer_options": job.observer_options, "containment": job.containment,
            "seed": job.seed, "variant": job.variant, "label": job.label,
            "guaranteed": job.guaranteed, "exact": cfg.exact,
            "floor": observer_floor(job.label or job.observer, cfg.floors) if cfg.exact else "",
            "timeout": cfg.timeout, "observer": job.observer,
        }
        return self.make(self.roots(job, cfg.exact), entry, self._records(job.spec, job.base))


def changes(stored: dict, now: Fingerprint, graph: ModuleGraph) -> str:
    """What differs between a stored fingerprint record and the current one, in words."""
    parts = []
    old_code = stored.get("code", {})
    changed = sorted(m for m in set(old_code) | set(now.code)
                     if old_code.get(m) != now.code.get(m))
    if changed:
        paths = [graph.source_path(m) if m in graph.modules else m for m in changed]
        more = f" and {len(paths) - 3} more" if len(paths) > 3 else ""
        parts.append("code changed: " + ", ".join(paths[:3]) + more)
    if stored.get("inputs") != now.inputs:
        parts.append("its configuration entry changed")
    old_data = stored.get("data", {})
    files = sorted(f for f in set(old_data) | set(now.data) if old_data.get(f) != now.data.get(f))
    if files:
        more = f" and {len(files) - 3} more" if len(files) > 3 else ""
        parts.append("data changed: " + ", ".join(files[:3]) + more)
    return "; ".join(parts) or "fingerprint differs"


__all__ = ["ROOT", "Fingerprint", "Fingerprinter", "canonical", "changes", "job_key",
           "row_key"]
