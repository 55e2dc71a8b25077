"""A result store: ``results/<config>/summary.csv`` and ``results/<config>/meta.json``, committed.

``summary.csv`` holds the summary rows of a configuration (one line per observer x scenario
instance x variant x state; the columns of ``setobs-bench run``'s ``summary.csv``) with two
more: ``fingerprint`` (:mod:`.fingerprint`: what produced the row) and ``run_id`` (the run that
produced it).  ``meta.json`` holds

- ``format``: :data:`FORMAT`;
- ``config``, ``scenarios``: the configuration and its scenarios' facts (as in a run's
  ``meta.json``: what the reports need);
- ``runs``: per run id, when, on which commit and machine, with which BLAS kernel and versions
  and executor;
- ``rows``: per row key (:func:`.fingerprint.row_key`), its fingerprint, its run and the digest
  of its content (every field of its lines, as text: :func:`content_digests`);
- ``fingerprints``, ``code``, ``data``: what each fingerprint was made of (module digests and
  data files, shared between rows), so that ``stale`` can say which module changed;
- ``files``: size and SHA-256 of ``summary.csv``.

Reading (:func:`load_store`) checks all of it: a half-written, truncated, corrupted or
hand-edited ``summary.csv``, a row whose content or fingerprint does not match ``meta.json``,
is refused with a one-line message.  Writing (:func:`write_store`) builds both files in a
temporary folder beside the store and swaps the folders atomically (the other files of the
folder, local run outputs, move along), so that a kill leaves the old store or the new one,
never a mixture; :class:`StoreLock` keeps two writers off one ``results/`` folder.
"""

from __future__ import annotations

import csv
import fcntl
import hashlib
import io
import json
import os
import shutil
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import pandas as pd

from ..errors import ConfigError
from ..io import csv_text, json_text, new_run_id, read_table, remove_stale_generations, swap_in
from ..metrics import add_relative_rms
from ..report.freshness import commit, machine
from .fingerprint import Fingerprint, canonical, changes, row_key, short

FORMAT = "setobs-bench store 1"
#: columns the store adds to a run's summary
STORE_COLUMNS = ("fingerprint", "run_id")
SUMMARY = "summary.csv"
META = "meta.json"


@dataclass(frozen=True)
class Layout:
    """What a store's rows are: the columns that key a row (a row is one or more lines), the
    column that orders the lines of a row, and the columns derived across rows, recomputed
    after every merge."""

    keys: tuple[str, ...]
    #: the column ordering the lines of a row (None: the order they came in)
    within: str | None
    derive: Callable[[pd.DataFrame], pd.DataFrame] | None = None


#: a configuration's summary: one row per observer x scenario instance x variant, a line per
#: state; ``rel_rms`` is relative to the best observer of each scenario
CONFIG = Layout(("scenario", "seed", "observer", "variant"), "state", add_relative_rms)


def _sha(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def keys_of(summary: pd.DataFrame, layout: Layout = CONFIG) -> pd.Series:
    """The row key of every line of a summary."""
    return pd.Series([row_key(*t) for t in summary[list(layout.keys)].itertuples(index=False)],
                     index=summary.index, dtype=object)


def content_digests(data: bytes, layout: Layout = CONFIG) -> dict[str, str]:
    """Row key -> digest of that row's lines as text in ``summary.csv`` (every field but
    ``run_id``, read as written: no number is parsed, so the digest is the same whoever
    reads it)."""
    reader = csv.reader(io.StringIO(data.decode("utf-8"), newline=""))
    header = next(reader, [])
    try:
        at = [header.index(c) for c in layout.keys]
    except ValueError:
        return {}  # no key column: no row (the caller names the mismatch)
    keep = [i for i, c in enumerate(header) if c != "run_id"]
    columns = [header[i] for i in keep]
    groups: dict[str, list[list[str]]] = {}
    for fields in reader:
        groups.setdefault(row_key(*(fields[i] for i in at)), []).append(
            [fields[i] for i in keep])
    return {key: short(_sha(canonical([columns, lines]).encode()))
            for key, lines in groups.items()}


class Store:
    """The rows of one configuration and their metadata (a value: :func:`merge` returns a new
    one)."""

    def __init__(self, summary: pd.DataFrame, meta: dict, layout: Layout = CONFIG):
        self.summary = summary
        self.meta = meta
        self.layout = layout

    @property
    def rows(self) -> dict[str, dict]:
        return self.meta.get("rows", {})

    def fingerprint_record(self, key: str) -> dict:
        """``{"code": {...}, "inputs": ..., "data": {...}}`` of a stored row."""
        fp = self.rows[key]["fingerprint"]
        rec = self.meta["fingerprints"][fp]
        return {"code": self.meta["code"].get(rec["code"], {}), "inputs": rec["inputs"],
                "data": self.meta["data"].get(rec["data"], {})}

    def view(self) -> tuple[pd.DataFrame, dict]:
        """``(summary, meta)`` as the report writers take them (the store's columns dropped)."""
        return self.summary.drop(columns=list(STORE_COLUMNS)), self.meta


def load_store(folder: str | Path, layout: Layout = CONFIG) -> Store | None:
    """Read and check the store of ``folder``; None if there is none (or it holds rows of
    another layout).

    Raises
    ------
    ConfigError
        One line naming what is wrong: half-written, truncated, corrupted or hand-edited.
    """
    folder = Path(folder)
    meta_path, path = folder / META, folder / SUMMARY
    if not meta_path.is_file() and not path.is_file():
        return None
    fix = (f"restore it (`git checkout -- {folder}`) or re-run it (`setobs-bench bench "
           f"{folder.name} --cold`)")
    try:
        meta = json.loads(meta_path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise ConfigError(f"store {folder}: {META} is missing; {fix}") from None
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise ConfigError(f"store {folder}: {META} is not valid JSON "
                          f"({getattr(exc, 'msg', exc)}); {fix}") from None
    if not isinstance(meta, dict) or meta.get("format") != FORMAT:
        return None  # a run's output folder, not a store
    if meta.get("layout", list(CONFIG.keys)) != list(layout.keys):
        return None  # a store of other rows (the audit's, read with its own layout)
    if not path.is_file():
        raise ConfigError(f"store {folder}: {SUMMARY} is missing; {fix}")
    data = path.read_bytes()
    want = meta.get("files", {}).get(SUMMARY, {})
    if len(data) != want.get("bytes") or _sha(data) != want.get("sha256"):
        cut = len(data) < want.get("bytes", 0) and not data.endswith(b"\n")
        how = "truncated (half-written?)" if cut else \
            "changed since it was written (hand-edited or corrupted?)"
        raise ConfigError(f"store {folder}: {SUMMARY} is {how}: it does not match {META}; {fix}")
    try:
        # only an empty cell is missing: a verdict's "n/a" stays text, so that the rows a merge
        # keeps are written back as they were read
        summary = read_table(io.BytesIO(data), keep_default_na=False, na_values=[""])
    except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError) as exc:
        raise ConfigError(f"store {folder}: {SUMMARY} is not readable CSV: "
                          f"{str(exc).splitlines()[0]}; {fix}") from None
    rows = meta.get("rows", {})
    keys = keys_of(summary, layout)
    digests = content_digests(data, layout)
    if set(keys) != set(rows):
        extra = sorted(set(keys) ^ set(rows))[:2]
        raise ConfigError(f"store {folder}: the rows of {SUMMARY} and {META} differ "
                          f"({', '.join(extra)}); {fix}")
    for key, lines in summary.groupby(keys, sort=False):
        rec = rows[key]
        if set(lines["fingerprint"]) != {rec.get("fingerprint")}:
            raise ConfigError(f"store {folder}: row {key} has fingerprint "
                              f"{lines['fingerprint'].iloc[0]}, {META} says "
                              f"{rec.get('fingerprint')}; {fix}")
        if set(lines["run_id"]) != {rec.get("run")} or rec.get("run") not in meta.get("runs", {}):
            raise ConfigError(f"store {folder}: row {key} names a run that {META} does not "
                              f"record; {fix}")
        if digests.get(key) != rec.get("content"):
            raise ConfigError(f"store {folder}: the content of row {key} does not match its "
                              f"fingerprint's record (edited by hand?); {fix}")
        if rec["fingerprint"] not in meta.get("fingerprints", {}):
            raise ConfigError(f"store {folder}: row {key}'s fingerprint is not described in "
                              f"{META}; {fix}")
    return Store(summary, meta, layout)


def compare(store: Store | None, prints: dict[str, Fingerprint], graph, cold: bool = False
            ) -> tuple[dict[str, str], list[str]]:
    """Which rows must run, and why (missing, or what changed: :func:`.fingerprint.changes`;
    ``cold``: all), and which stored rows are no longer wanted, for the rows ``prints`` (row
    key -> fingerprint now) against ``store``."""
    stored = store.rows if store is not None else {}
    stale = {}
    for key, fp in prints.items():
        if cold:
            stale[key] = "cold run"
        elif key not in stored:
            stale[key] = "no stored row"
        elif stored[key]["fingerprint"] != fp.digest:
            stale[key] = changes(store.fingerprint_record(key), fp, graph)
    return stale, [k for k in stored if k not in prints]


def new_run(root: Path, executor: dict) -> tuple[str, dict]:
    """A run id and its record (when, commit, machine, versions, executor)."""
    from datetime import datetime, timezone

    from ..io import environment

    versions = environment()
    versions.pop("git", None)
    return new_run_id(), {
        "created": datetime.now(timezone.utc).isoformat(timespec="seconds"),
        "commit": commit(root), "machine": machine(), "versions": versions,
        "executor": executor}


@dataclass(frozen=True)
class RunRows:
    """What a run brings to a store (:func:`merge`).

    Attributes
    ----------
    rows : DataFrame or None
        ``summary.csv`` rows of the run (without the store's columns); None: no run, only
        the rows no longer in the configuration go (:meth:`nothing`).
    prints : dict
        Row key -> fingerprint, for every key of ``rows``.
    run_id, run : str, dict
        The run's id and record (:func:`new_run`).
    meta : dict
        ``config`` and ``scenarios`` of the run (as in a run's ``meta.json``), and any other
        key to record (the audit's settings).
    """

    rows: pd.DataFrame | None
    prints: dict[str, Fingerprint]
    run_id: str | None
    run: dict | None
    meta: dict

    @classmethod
    def nothing(cls, meta: dict) -> RunRows:
        """No run: only the rows no longer in the configuration go (``meta`` as above)."""
        return cls(None, {}, None, None, meta)


def merge(old: Store | None, new: RunRows, order: list[str], layout: Layout = CONFIG
          ) -> Store:
    """The store with the rows of the run ``new`` (keyed as in its ``prints``) in place of
    their old versions; rows whose key is not in ``order`` (no longer in the configuration)
    are dropped, and the rest are ordered as ``order``.  The layout's derived columns are
    recomputed over the merged rows (a configuration's ``rel_rms``: its reference is the best
    observer of each scenario, whichever run made it).

    Parameters
    ----------
    old : Store or None
        The store so far.
    new : RunRows
        The run's rows, fingerprints, id, record and meta data.
    order : list of str
        The row keys of the configuration, in its order.
    layout : Layout
        What the rows are (:data:`CONFIG`), if there is no ``old`` store to say it.
    """
    new_rows, prints, run_id, run, run_meta = new.rows, new.prints, new.run_id, new.run, new.meta
    layout = old.layout if old is not None else layout
    if new_rows is None:  # only drop the rows no longer in the configuration
        new_rows = old.summary.iloc[0:0].drop(columns=list(STORE_COLUMNS))
    new_rows = new_rows.copy()
    keys = keys_of(new_rows, layout)
    new_rows["fingerprint"] = [prints[k].digest for k in keys]
    new_rows["run_id"] = run_id
    frames = [new_rows]
    meta = {"format": FORMAT, "config": run_meta.get("config", {}), "scenarios": {},
            "runs": {}, "rows": {}, "fingerprints": {}, "code": {}, "data": {}}
    if old is not None:
        old_keys = keys_of(old.summary, layout)
        keep = ~old_keys.isin(set(keys)) & old_keys.isin(set(order))
        frames.insert(0, old.summary[keep])
        meta["scenarios"].update(old.meta.get("scenarios", {}))
        for key in set(keys_of(old.summary[keep], layout)):
            meta["rows"][key] = dict(old.rows[key])
            fp = old.rows[key]["fingerprint"]
            rec = old.meta["fingerprints"][fp]
            meta["fingerprints"][fp] = rec
            meta["code"][rec["code"]] = old.meta["code"][rec["code"]]
            meta["data"][rec["data"]] = old.meta["data"][rec["data"]]
    meta["scenarios"].update(run_meta.get("scenarios", {}))
    for key in set(keys):
        p = prints[key]
        code_id = short(_sha(canonical(p.code).encode()))
        data_id = short(_sha(canonical(p.data).encode()))
        meta["code"][code_id] = p.code
        meta["data"][data_id] = p.data
        meta["fingerprints"][p.digest] = {"code": code_id, "inputs": p.inputs, "data": data_id}
        meta["rows"][key] = {"fingerprint": p.digest, "run": run_id}
    summary = pd.concat([f for f in frames if len(f)], ignore_index=True)
    rank = {k: i for i, k in enumerate(order)}
    all_keys = keys_of(summary, layout)
    by = ["_rank"] + (["_within"] if layout.within else [])
    summary = summary.assign(_rank=all_keys.map(rank),
                             _within=summary[layout.within] if layout.within else 0
                             ).sort_values(by, kind="stable").drop(columns=["_rank", "_within"])
    summary = summary.reset_index(drop=True)
    columns = [c for c in summary.columns if c not in STORE_COLUMNS] + list(STORE_COLUMNS)
    if layout.derive is not None:
        summary = layout.derive(summary)
    summary = summary[columns]
    runs = {**(old.meta.get("runs", {}) if old else {}), **({run_id: run} if run_id else {})}
    used = set(summary["run_id"])
    meta["runs"] = {r: v for r, v in runs.items() if r in used}
    # the executor of the reports' caption on parallel times: the most workers among the runs
    meta["executor"] = max((v.get("executor", {}) for v in meta["runs"].values()),
                           key=lambda e: (e.get("workers", 1), e.get("name", "")), default={})
    used_sc = set(summary["scenario"]) if "scenario" in summary.columns else set()
    meta["scenarios"] = {k: v for k, v in meta["scenarios"].items() if k in used_sc}
    meta["rows"] = {k: meta["rows"][k] for k in dict.fromkeys(keys_of(summary, layout))}
    meta["fingerprints"] = dict(sorted(meta["fingerprints"].items()))
    meta["code"] = dict(sorted(meta["code"].items()))
    meta["data"] = dict(sorted(meta["data"].items()))
    meta["layout"] = list(layout.keys)
    meta.update({k: v for k, v in run_meta.items() if k not in ("config", "scenarios")})
    return Store(summary, meta, layout)


def store_bytes(store: Store) -> tuple[bytes, bytes]:
    """The two files of a store as written (``summary.csv``, ``meta.json``)."""
    data = csv_text(store.summary).encode("utf-8")
    digests = content_digests(data, store.layout)
    rows = {key: {**rec, "content": digests[key]} for key, rec in store.meta["rows"].items()}
    meta = {**store.meta, "rows": rows,
            "files": {SUMMARY: {"bytes": len(data), "sha256": _sha(data)}}}
    return data, json_text(meta).encode("utf-8")


def write_store(folder: str | Path, store: Store) -> None:
    """Write ``store`` to ``folder`` atomically (see the module docstring)."""
    folder = Path(folder)
    folder.parent.mkdir(parents=True, exist_ok=True)
    remove_stale_generations(folder)
    data, meta = store_bytes(store)
    tmp = folder.parent / f".{folder.name}.new-{os.getpid()}-{new_run_id()}"
    tmp.mkdir()
    try:
        for name, payload in ((SUMMARY, data), (META, meta)):
            with open(tmp / name, "wb") as fh:
                fh.write(payload)
                fh.flush()
                os.fsync(fh.fileno())
        if not folder.exists():
            os.rename(tmp, folder)
            return
        # local run outputs and HTML pages stay with the store
        tmp = swap_in(tmp, folder, (SUMMARY, META), new_run_id())
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


class StoreLock:
    """An exclusive lock on the stores under one ``results/`` folder (``.store.lock``); a second
    writer fails at once with a one-line :class:`ConfigError` naming the holder."""

    def __init__(self, root: str | Path):
        self.path = Path(root) / ".store.lock"
        self._fh = None

    def __enter__(self) -> StoreLock:
        self.path.parent.mkdir(parents=True, exist_ok=True)
        fh = open(self.path, "a+")  # noqa: SIM115 - held until __exit__
        try:
            fcntl.flock(fh.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            fh.seek(0)
            holder = fh.read().strip() or "another process"
            fh.close()
            raise ConfigError(f"another `make bench` is writing the stores of {self.path.parent} "
                              f"(lock {self.path} held by {holder}); wait for it to end") from None
        fh.seek(0)
        fh.truncate()
        fh.write(f"pid {os.getpid()}")
        fh.flush()
        self._fh = fh
        return self

    def __exit__(self, *exc) -> None:
        if self._fh is not None:
            fcntl.flock(self._fh.fileno(), fcntl.LOCK_UN)
            self._fh.close()
            self._fh = None

