"""The paper tables (and the textbook plants) under every OpenBLAS kernel of this CPU: how far
each accuracy cell moves.

``python -m benchmarks.studies.kernels`` (``make kernels``) re-runs each published table's
configuration and the textbook plants' (:data:`CONFIGS`) in a subprocess per OpenBLAS core
type of :data:`benchmarks.gate.blas.SPREAD_CORETYPES` that this CPU runs other than its own
(``OPENBLAS_CORETYPE=K`` is read when OpenBLAS loads, so each kernel is its own process), each
with an empty offline-design cache (a design cached under one kernel would hide the kernel
dependence of the design), and compares every accuracy cell (``rms_radius`` per observer,
scenario and state) with the committed result store ``results/CONFIG/summary.csv``, produced
by ``make bench`` under this CPU's own kernel.  It writes:

* ``results/kernels/kernel_spread.csv``: per configuration, scenario, observer (or labelled
  variant) and state, the largest relative difference over the kernels (``spread``) and any
  status that differs;
* ``reports/kernels.md``: per table, the cells compared, the largest spread, and every cell
  above :data:`benchmarks.report.spread.SHOWN_ABOVE` (1e-4), which the table reports print
  beside the value (:func:`benchmarks.report.spread.spread_note`).

This is the measurement behind issue 37's second acceptance: every accuracy cell of a
committed paper table agrees within 1e-4 relative under two kernels, or carries its measured
spread.  The regression subset has its own, faster measurement in ``baseline --update``
(``results/baseline/SENSITIVITY.md``).
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd

from ..errors import ConfigError
from ..gate.blas import available_coretypes
from ..io import atomic_write_text, blas_corename, environment, read_table
from ..report.citation import citation_lines
from ..report.numbers import fmt, markdown_table
from ..report.spread import KERNEL_CONFIGS, KERNEL_TABLE, SHOWN_ABOVE
from .cli import log, refuse, require_positive, study_parser, table_of, wrote

#: the configurations measured: the published tables and the textbook plants
CONFIGS = KERNEL_CONFIGS
#: the columns of ``kernel_spread.csv``
COLUMNS = ["config", "scenario", "observer", "state", "value", "spread", "kernels",
           "status_here", "status_other", "fingerprint"]
#: the table of the study (committed; ``setobs-bench stale`` checks its fingerprints)
TABLE = KERNEL_TABLE
#: a radius compared is at least this (absolute) in the denominator: a state whose radius is
#: zero in exact arithmetic (a state measured exactly) is compared absolutely
ATOL = 1e-12


def run_under(config: str, kernel: str, out: Path, jobs: int,
              observers: list[str] | None = None) -> pd.DataFrame:
    """``setobs-bench run CONFIG`` (only ``observers``, with their labelled variants, if
    given) under the OpenBLAS core type ``kernel`` into ``out``, with an empty design cache;
    its ``summary.csv``."""
    env = {**os.environ, "OPENBLAS_CORETYPE": kernel,
           "SETOBS_CACHE_DIR": str(out / "cache")}
    cmd = [sys.executable, "-m", "benchmarks", "run", config, "--out", str(out / "run"),
           "--no-progress"] + (["--jobs", str(jobs)] if jobs > 1 else [])
    for name in observers or []:
        cmd += ["--observer", name]
    proc = subprocess.run(cmd, env=env, capture_output=True, text=True)
    summary = out / "run" / "summary.csv"
    if proc.returncode != 0 or not summary.is_file():
        last = (proc.stderr.strip().splitlines() or ["no output"])[-1]
        raise RuntimeError(f"{config} under OPENBLAS_CORETYPE={kernel} failed: {last}")
    return read_table(summary)


def compare(here: pd.DataFrame, others: dict[str, pd.DataFrame], config: str) -> pd.DataFrame:
    """Per cell of ``here`` (this kernel's committed summary), the largest relative difference
    of ``rms_radius`` under the ``others`` kernels and any status that differs."""
    key = ["scenario", "observer", "state"]
    base = here[key + ["rms_radius", "status"]].copy()
    # the stored row's fingerprint (a result store's; a plain run has none)
    base["fingerprint"] = here["fingerprint"] if "fingerprint" in here.columns else ""
    spread = np.zeros(len(base))
    other_status = [""] * len(base)
    for kernel, df in others.items():
        m = base.merge(df[key + ["rms_radius", "status"]], on=key, how="left",
                       suffixes=("", "_k"))
        a = m["rms_radius"].to_numpy(float)
        b = m["rms_radius_k"].to_numpy(float)
        both = (m["status"] == "ok") & (m["status_k"] == "ok")
        rel = np.where(both, np.abs(a - b) / np.maximum(np.abs(a), ATOL), 0.0)
        spread = np.maximum(spread, np.nan_to_num(rel, nan=np.inf))
        for i, (s, k) in enumerate(zip(m["status"], m["status_k"], strict=True)):
            if s != k:
                other_status[i] = f"{kernel}: {k}"
    return pd.DataFrame({
        "config": config, "scenario": base["scenario"], "observer": base["observer"],
        "state": base["state"], "value": base["rms_radius"], "spread": spread,
        "kernels": "+".join(others), "status_here": base["status"],
        "status_other": other_status, "fingerprint": base["fingerprint"]})[COLUMNS]


def changed_rows(table: pd.DataFrame, results: Path, configs=CONFIGS
                 ) -> dict[str, set[tuple[str, str]]]:
    """Per configuration, the ``(scenario, observer)`` rows of its committed store whose
    fingerprint differs from the one the study's ``table`` measured (every row of a
    configuration the table does not hold)."""
    out = {}
    for config in configs:
        here = read_table(results / config / "summary.csv")
        then = table[table["config"] == config]
        measured = dict(zip(zip(then["scenario"], then["observer"], strict=True),
                            then["fingerprint"], strict=True))
        rows = {k for k, fp in zip(zip(here["scenario"], here["observer"], strict=True),
                                   here["fingerprint"], strict=True) if measured.get(k) != fp}
        if rows:
            out[config] = rows
    return out


def run_changed(table: pd.DataFrame, configs=CONFIGS, kernels: list[str] | None = None,
                jobs: int = 2, results: Path = Path("results"), log=lambda m: None
                ) -> pd.DataFrame:
    """``table`` with the rows whose stored fingerprint moved since it was measured measured
    again (their observers re-run under every other kernel, only on their configurations):
    the study's incremental run (``make kernels``)."""
    changed = changed_rows(table, results, configs)
    log(f"kernels: {sum(map(len, changed.values()))} row(s) changed in "
        f"{', '.join(changed) or 'no configuration'}")
    if not changed:
        return table
    names = {c: sorted({o.split("[")[0] for _, o in rows}) for c, rows in changed.items()}
    fresh = run_study(tuple(changed), kernels, jobs, results, log, observers=names)
    rows = {(c, *r) for c, rows in changed.items() for r in rows}
    fresh = fresh[[k in rows for k in zip(fresh["config"], fresh["scenario"],
                                           fresh["observer"], strict=True)]]
    old_keys = set(zip(fresh["config"], fresh["scenario"], fresh["observer"], strict=True))
    kept = table[[k not in old_keys for k in zip(table["config"], table["scenario"],
                                                 table["observer"], strict=True)]]
    merged = pd.concat([kept, fresh], ignore_index=True)
    order = {c: i for i, c in enumerate(configs)}
    merged = merged.assign(_c=merged["config"].map(order)).sort_values(
        ["_c"], kind="stable").drop(columns="_c").reset_index(drop=True)
    merged.attrs["here"] = fresh.attrs.get("here", table.attrs.get("here"))
    return merged[COLUMNS]


def run_study(configs=CONFIGS, kernels: list[str] | None = None, jobs: int = 2,
              results: Path = Path("results"), log=lambda m: None,
              observers: dict[str, list[str]] | None = None) -> pd.DataFrame:
    """Every configuration (only ``observers[config]`` where given) under every other
    kernel, compared with its committed store."""
    here = blas_corename()
    kernels = [k for k in (available_coretypes() if kernels is None else kernels)
               if k.lower() != here.lower()]
    if not kernels:
        raise RuntimeError(f"no OpenBLAS kernel other than {here} runs on this CPU")
    frames = []
    with tempfile.TemporaryDirectory(prefix="setobs-kernels-") as tmp:
        for config in configs:
            committed = results / config / "summary.csv"
            if not committed.is_file():
                raise RuntimeError(f"no committed store {committed} (run make bench first)")
            others = {}
            for k in kernels:
                t0 = time.perf_counter()
                others[k] = run_under(config, k, Path(tmp) / config / k, jobs,
                                      (observers or {}).get(config))
                log(f"{config} under {k}: {time.perf_counter() - t0:.0f} s")
            frames.append(compare(read_table(committed), others, config))
    df = pd.concat(frames, ignore_index=True)
    df.attrs["here"] = here
    return df


def report(df: pd.DataFrame, here: str, elapsed: float) -> str:
    """``reports/kernels.md`` from the table of :func:`run_study`."""
    env = environment()
    kernels = sorted({k for ks in df["kernels"] for k in str(ks).split("+")})
    compared = df[(df["status_here"] == "ok") & (df["status_other"] == "")]
    above = compared[compared["spread"] > SHOWN_ABOVE]
    parts = [
        "# The paper tables and the textbook plants under every OpenBLAS kernel of this CPU",
        "",
        "Each published table's configuration, and the textbook plants', re-run under the "
        f"OpenBLAS kernels {', '.join(kernels)} (one process each, an empty offline-design "
        "cache) and compared with the committed result store, produced by `make bench` "
        f"under {here}. A cell is "
        "an observer's RMS radius of one state on one scenario; **spread** is its largest "
        "relative difference over the kernels. Cells above "
        f"{SHOWN_ABOVE:g} are listed here and carry their spread beside the value in the "
        "table reports. Produced by `python -m benchmarks.studies.kernels`"
        + (f" in {elapsed / 60:.1f} min" if np.isfinite(elapsed) else "")
        + f" (git {env.get('git', '?')}).", "",
        f"**{len(compared)} accuracy cells compared, {len(above)} above {SHOWN_ABOVE:g}; "
        f"largest spread {fmt(compared['spread'].max(), 3) if len(compared) else 'n/a'}.**",
        "",
    ]
    head = ["table", "cells compared", "largest spread", f"cells above {SHOWN_ABOVE:g}",
            "status differs"]
    rows = []
    for config, g in df.groupby("config", sort=False):
        c = g[(g["status_here"] == "ok") & (g["status_other"] == "")]
        differs = g[g["status_other"] != ""]
        rows.append([config, str(len(c)), fmt(c["spread"].max(), 3) if len(c) else "n/a",
                     str(int((c["spread"] > SHOWN_ABOVE).sum())),
                     ", ".join(sorted({f"{r.observer} on {r.scenario} ({r.status_here} here, "
                                       f"{r.status_other})" for r in differs.itertuples()}))
                     or "none"])
    parts += markdown_table(head, rows).splitlines() + [""]
    if len(above):
        parts += [f"## Cells above {SHOWN_ABOVE:g}", ""]
        worst = (above.groupby(["config", "scenario", "observer"], sort=False)["spread"]
                 .agg(["max", "size"]).reset_index().sort_values("max", ascending=False))
        rows = [[r.config, r.scenario, r.observer, str(r.size), fmt(r.max, 3)]
                for r in worst.itertuples()]
        parts += markdown_table(["table", "scenario", "observer", "states", "largest spread"],
                                rows).splitlines() + [""]
    parts += ["---", ", ".join(f"{k} {v}" for k, v in env.items()), "",
              *citation_lines("kernels"), ""]
    return "\n".join(parts)


def _committed(table: Path) -> pd.DataFrame:
    df = read_table(table, dtype={"status_other": str})
    df["status_other"] = df["status_other"].fillna("")
    df.attrs["here"] = blas_corename()
    return df


def main(argv: list[str] | None = None) -> int:
    """Command line of the study."""
    p = study_parser("benchmarks.studies.kernels", __doc__, out="reports/kernels.md",
                     results="results", results_help="folder of the result stores",
                     render_help="no run: the report from results/kernels/kernel_spread.csv",
                     jobs_help="worker processes per run (default 2)")
    p.add_argument("--config", action="append", default=None,
                   help="a configuration to compare (repeatable; default the paper tables "
                        "and the textbook plants)")
    p.add_argument("--kernel", action="append", default=None,
                   help="an OpenBLAS core type to compare with (repeatable; default every "
                        "other one this CPU runs)")
    p.add_argument("--changed", action="store_true",
                   help="measure again only the rows whose stored fingerprint moved since "
                        "the committed table measured them (everything where there is none)")
    args = p.parse_args(argv)
    out, table = Path(args.out), Path(args.results) / TABLE.relative_to("results")
    configs = tuple(args.config or CONFIGS)
    try:
        require_positive(jobs=args.jobs)
        if args.changed and table.is_file() and not args.render:
            old = _committed(table)
            df, elapsed = table_of(table, False, lambda: run_changed(
                old, configs, args.kernel, args.jobs, Path(args.results), log=log))
        else:
            df, elapsed = table_of(table, args.render, lambda: run_study(
                configs, args.kernel, args.jobs, Path(args.results), log=log),
                read=_committed)
    except (ConfigError, RuntimeError) as exc:
        return refuse(exc)
    atomic_write_text(out, report(df, df.attrs["here"], elapsed))
    return wrote(out, table)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
