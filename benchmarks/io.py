"""Atomic file output (write to a temporary file in the target folder, then rename) and the
environment recorded with every result.

A failed or interrupted run therefore never leaves half-written results behind, and the
previous results stay untouched until the new ones are complete.
"""

from __future__ import annotations

import json
import os
import platform
import subprocess
import sys
import tempfile
from importlib import metadata
from pathlib import Path

import pandas as pd

from .errors import ConfigError


def atomic_write_text(path: str | Path, text: str) -> None:
    """Write ``text`` to ``path`` atomically."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            fh.write(text)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def atomic_write_csv(path: str | Path, df: pd.DataFrame) -> None:
    """Write a data frame as CSV atomically (full float precision)."""
    atomic_write_text(path, df.to_csv(index=False, float_format="%.17g"))


def atomic_write_json(path: str | Path, obj) -> None:
    """Write ``obj`` as indented JSON atomically."""
    atomic_write_text(path, json.dumps(obj, indent=2, sort_keys=True, default=str) + "\n")


def atomic_savefig(fig, path: str | Path, **kwargs) -> None:
    """Save a matplotlib figure atomically."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.stem}.", suffix=path.suffix)
    os.close(fd)
    try:
        fig.savefig(tmp, **kwargs)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def load_results(folder: str | Path) -> tuple[pd.DataFrame, dict]:
    """Read ``summary.csv`` and ``meta.json`` (``{}`` if absent) of a results folder.

    Raises
    ------
    ConfigError
        If the folder has no ``summary.csv``.
    """
    folder = Path(folder)
    if not (folder / "summary.csv").is_file():
        raise ConfigError(f"no summary.csv in {folder} (run `python -m benchmarks run` first)")
    meta_path = folder / "meta.json"
    meta = json.loads(meta_path.read_text(encoding="utf-8")) if meta_path.is_file() else {}
    return pd.read_csv(folder / "summary.csv"), meta


#: packages whose versions :func:`environment` records
ENVIRONMENT_PACKAGES = ("numpy", "scipy", "cvxpy", "clarabel", "highspy", "pandas")


def environment() -> dict[str, str]:
    """Versions and platform of this process, as recorded in ``meta.json`` (``versions``).

    Returns
    -------
    dict of str to str
        ``python`` (version), ``platform``, ``blas_coretype`` (the OpenBLAS kernel family,
        ``OPENBLAS_CORETYPE``, pinned in :mod:`benchmarks`; ``"auto"`` if unset), the version
        of each of :data:`ENVIRONMENT_PACKAGES` (``"missing"`` if not installed) and ``git``
        (the short commit of this checkout, ``""`` outside a git checkout).
    """
    out = {"python": sys.version.split()[0], "platform": platform.platform(),
           "blas_coretype": os.environ.get("OPENBLAS_CORETYPE", "auto")}
    for pkg in ENVIRONMENT_PACKAGES:
        try:
            out[pkg] = metadata.version(pkg)
        except metadata.PackageNotFoundError:
            out[pkg] = "missing"
    try:
        out["git"] = subprocess.run(
            ["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True,
            cwd=Path(__file__).resolve().parent, timeout=5,
        ).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        out["git"] = ""
    return out
