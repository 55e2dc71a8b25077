"""Freshness of the committed reports: a content hash of what each report was produced from.

Every report written by the harness (``python -m benchmarks report``, ``audit``, the studies)
ends with a stamp line::

    <!-- freshness: sha256=<hash> config=<path or -> command=<how to regenerate it> -->

``<hash>`` is :func:`content_hash`: a SHA-256 over a well-defined set of files, the code
(every ``*.py`` under ``observers/``, ``systems/`` and ``benchmarks/`` except the
configurations), the shipped data (every file under ``systems/data/``) and, for a report of a
benchmark configuration, that configuration file.  Paths enter relative to the project root
with ``/`` separators and files in sorted order, so the hash depends only on the contents.

:func:`stale_reports` compares the stamps of ``reports/*.md`` with the hashes of the current
tree (cheap: no benchmark is re-run) and names every report whose stamp is missing or differs,
with the command that regenerates it; ``python -m benchmarks check --reports reports`` (what
``make check`` runs) fails on any.  Since every report depends on the code, any change to it
makes every report stale: regenerate them all with ``make reports`` once the code is final.
"""

from __future__ import annotations

import hashlib
import re
from dataclasses import dataclass
from pathlib import Path

#: the project root (the folder holding observers/, systems/, benchmarks/)
ROOT = Path(__file__).resolve().parent.parent.parent
#: code folders whose ``*.py`` files enter the hash
CODE_DIRS = ("observers", "systems", "benchmarks")
#: data folders whose files (all of them) enter the hash
DATA_DIRS = ("systems/data",)
_STAMP = re.compile(r"<!-- freshness: sha256=([0-9a-f]+) config=(\S+) command=(.*?) -->")


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


def default_command(path: Path, root: Path = ROOT) -> str:
    """The command that regenerates a report that carries no stamp, from its file name."""
    if path.stem == "soundness":
        return f"python -m benchmarks audit --report {path}"
    if path.stem == "datadriven":
        return f"python -m benchmarks.studies.alanwar2022 --out {path}"
    if path.stem == "speed":
        return "python -m benchmarks speed"
    if path.stem == "scaling":
        return f"python -m benchmarks.studies.scaling --out {path} --results results/scaling"
    if path.stem == "frontier":
        return f"python -m benchmarks.studies.frontier --out {path} --results results/frontier"
    return report_command(config_of(path.stem, root), path)


@dataclass(frozen=True)
class Stale:
    """A report whose stamp is missing or does not match the current tree."""

    report: Path
    reason: str
    command: str


def read_stamp(path: Path) -> tuple[str, str | None, str] | None:
    """The last stamp of a report: ``(digest, config or None, command)``; None without one."""
    found = _STAMP.findall(path.read_text(encoding="utf-8", errors="replace"))
    if not found:
        return None
    digest, config, command = found[-1]
    return digest, None if config == "-" else config, command


def check_report(path: Path, root: Path = ROOT) -> Stale | None:
    """None if the report's stamp matches the current tree, else why not."""
    text = path.read_text(errors="replace")
    found = _STAMP.findall(text)
    if not found:
        return Stale(path, "no freshness stamp", default_command(path, root))
    digest, config, command = found[-1]
    config = None if config == "-" else config
    if config and not (root / config).is_file():
        return Stale(path, f"its configuration {config} no longer exists", command)
    if digest != content_hash(config, root):
        return Stale(path, "code, data or configuration changed since it was written", command)
    return None


def stale_reports(folder: str | Path = "reports", root: Path = ROOT) -> list[Stale]:
    """Every ``*.md`` in ``folder`` (except its README.md index) that is not fresh."""
    folder = Path(folder)
    out = []
    for path in sorted(folder.glob("*.md")):
        if path.name == "README.md":
            continue
        bad = check_report(path, root)
        if bad is not None:
            out.append(bad)
    return out


def format_stale(stale: list[Stale]) -> str:
    """One line per stale report: its path, why, and the command that regenerates it."""
    return "\n".join(f"STALE REPORT {s.report}: {s.reason}; regenerate with `{s.command}`"
                     for s in stale)
