"""Provenance of a report: the stamp line that says what produced it, and where.

Committed reports are kept fresh by the result stores (:mod:`benchmarks.store`): a
configuration's report is a view of rows whose fingerprints ``setobs-bench stale`` checks, so
no report needs a hash of the code.  What remains here:

- :func:`stamp`: the last line of a report written by a run or a study,
  ``<!-- freshness: sha256=<hash> config=<path or -> command=<how to regenerate it> -->``, with
  :func:`content_hash` over the code (every ``*.py`` under ``observers/``, ``systems/``,
  ``benchmarks/``), the shipped data and the configuration: two local reports with the same
  stamp were made by the same tree;
- :func:`measured`: the last line of a timing report (``reports/speed.md``, ``scaling.md``,
  ``frontier.md``), ``<!-- measured: commit=<commit> machine=<cpu; cores; BLAS kernel>
  command=<command> -->``: a measurement of a machine, never stale for the code;
- :func:`machine` and :func:`commit`, which the result stores record for every run.
"""

from __future__ import annotations

import hashlib
import os
import platform
import subprocess
from pathlib import Path

#: the project root (the folder holding observers/, systems/, benchmarks/)
ROOT = Path(__file__).resolve().parent.parent.parent
#: code folders whose ``*.py`` files enter the hash
CODE_DIRS = ("observers", "systems", "benchmarks")
#: data folders whose files (all of them) enter the hash
DATA_DIRS = ("systems/data",)


def _inputs(config: str | None, root: Path) -> list[Path]:
    files = [p for d in CODE_DIRS for p in (root / d).rglob("*.py")
             if "__pycache__" not in p.parts and "configs" not in p.relative_to(root).parts]
    files += [p for d in DATA_DIRS for p in (root / d).rglob("*")
              if p.is_file() and "__pycache__" not in p.parts]
    if config:
        files.append(root / config)
    return sorted(set(files), key=lambda p: p.relative_to(root).as_posix())


def content_hash(config: str | None = None, root: Path = ROOT) -> str:
    """SHA-256 (hex) of the code, the shipped data and ``config`` (a path relative to ``root``).

    Parameters
    ----------
    config : str or None
        The configuration file a report was produced from (relative to ``root``), or None.
    root : Path
        Project root.

    Returns
    -------
    str
        The hex digest.
    """
    h = hashlib.sha256()
    for p in _inputs(config, root):
        rel = p.relative_to(root).as_posix()
        data = p.read_bytes() if p.is_file() else b"<missing>"
        h.update(f"{rel}\0{len(data)}\0".encode())
        h.update(data)
    return h.hexdigest()


def config_of(name: str | None, root: Path = ROOT) -> str | None:
    """``benchmarks/configs/<name>.yaml`` if that file exists, else None."""
    if not name:
        return None
    rel = f"benchmarks/configs/{name}.yaml"
    return rel if (root / rel).is_file() else None


def stamp(command: str, config: str | None = None, root: Path = ROOT) -> str:
    """The stamp line to append to a report produced by ``command`` from ``config``."""
    return (f"<!-- freshness: sha256={content_hash(config, root)} config={config or '-'} "
            f"command={command} -->")


def report_command(config: str | None, out: str | Path) -> str:
    """The command that regenerates the report ``out`` of a benchmark configuration."""
    if not config:
        return f"python -m benchmarks report <results dir> --no-figures --out {out}"
    name = Path(config).stem
    return (f"python -m benchmarks run {config} --out results/{name} && python -m benchmarks "
            f"report results/{name} --no-figures --out {out}")


def machine() -> dict[str, str]:
    """The machine of this process: processor model, cores, system, OpenBLAS kernel."""
    from ..io import blas_corename

    cpu = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return {"cpu": cpu, "cores": str(os.cpu_count() or 1), "system": platform.system(),
            "blas_coretype": blas_corename()}


def checkout_state(root: Path = ROOT, paths: tuple[str, ...] = (),
                   top_only: bool = False) -> tuple[str, bool]:
    """``(short commit, modified)`` of the git checkout at ``root``: ``modified`` if tracked
    files (under ``paths``, default all) differ from the commit; ``("", False)`` outside a
    checkout, where git is missing, or (``top_only``) where ``root`` is not the checkout's
    top level (a copy installed inside another repository)."""
    def git(*argv: str) -> str:
        return subprocess.run(["git", *argv], capture_output=True, text=True, cwd=root,
                              timeout=10).stdout.strip()

    try:
        if top_only:
            top = git("rev-parse", "--show-toplevel")
            if not top or Path(top).resolve() != Path(root).resolve():
                return "", False
        head = git("rev-parse", "--short", "HEAD")
        dirty = git("status", "--porcelain", "--untracked-files=no", "--", *paths)
    except (OSError, subprocess.SubprocessError):
        return "", False
    return head, bool(head and dirty)


def commit(root: Path = ROOT) -> str:
    """The commit of the checkout at ``root`` (``+dirty`` where tracked code differs), or
    ``""`` outside a git checkout."""
    head, dirty = checkout_state(root, ("observers", "systems", "benchmarks"))
    return head + ("+dirty" if dirty else "")


def measured(command: str) -> str:
    """The stamp line of a timing report: the commit and machine it measured."""
    m = machine()
    return (f"<!-- measured: commit={commit() or '?'} machine={m['cpu']}; {m['cores']} cores; "
            f"OpenBLAS {m['blas_coretype']} command={command} -->")
