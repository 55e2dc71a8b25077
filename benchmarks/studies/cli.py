"""The command line the table-producing studies share (:mod:`.robustness`, :mod:`.noise_grid`,
:mod:`benchmarks.studies.kernels`): run the study and write its table, or with ``--render``
render the committed table again without running anything; bad input is one line and exit
code 2.
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Callable
from pathlib import Path

import pandas as pd

from ..errors import ConfigError
from ..io import atomic_write_csv, read_table


def study_parser(module: str, doc: str, *, out: str, results: str, results_help: str,
                 render_help: str, jobs_help: str = "worker processes (default 2)"
                 ) -> argparse.ArgumentParser:
    """The parser of a study's ``python -m`` command with the options every study has:
    ``--jobs``, ``--out`` (the Markdown report), ``--results`` and ``--render``.

    Parameters
    ----------
    module : str
        The study's module (``benchmarks.studies.X``), for the usage line.
    doc : str
        The module docstring; its first line describes the command.
    out, results : str
        Defaults of ``--out`` and ``--results``.
    results_help, render_help, jobs_help : str
        Help texts of ``--results``, ``--render`` and ``--jobs``.
    """
    p = argparse.ArgumentParser(prog=f"python -m {module}", description=doc.splitlines()[0])
    p.add_argument("--jobs", type=int, default=2, help=jobs_help)
    p.add_argument("--out", default=out, help="Markdown report")
    p.add_argument("--results", default=results, help=results_help)
    p.add_argument("--render", action="store_true", help=render_help)
    return p


def require_positive(**counts: int) -> None:
    """Refuse a count below one (``--jobs 0``) in one line naming the option."""
    bad = [f"--{name}" for name, value in counts.items() if value < 1]
    if bad:
        raise ConfigError(f"{' and '.join(bad)} must be >= 1")


def table_of(table: Path, render_only: bool, run: Callable[[], pd.DataFrame],
             read: Callable[[Path], pd.DataFrame] = read_table) -> tuple[pd.DataFrame, float]:
    """The study's table and the seconds its run took: with ``render_only`` the committed
    ``table`` (``read``; NaN seconds), else a fresh ``run()`` written to ``table``."""
    if render_only:
        if not table.is_file():
            raise ConfigError(f"no table {table} to render (run the study first)")
        return read(table), float("nan")
    t0 = time.perf_counter()
    df = run()
    atomic_write_csv(table, df)
    return df, time.perf_counter() - t0


def refuse(exc: Exception) -> int:
    """Print a study's one-line error and return its exit code (2)."""
    print(f"error: {exc}", file=sys.stderr)
    return 2


def wrote(out: Path, table: Path) -> int:
    """Say which files the study wrote; exit code 0."""
    print(f"wrote {out} and {table}", file=sys.stderr)
    return 0


def log(message: str) -> None:
    """A study's progress line (standard error)."""
    print(message, file=sys.stderr)
