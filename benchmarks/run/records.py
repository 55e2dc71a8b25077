"""Measured records from CSV files as people have them: with or without a header row, with
named columns (``t, y1, y2, u1, x1, ...``), comma, semicolon, tab or blank separated.

A config reads a signal from a file with ``y: {file: rec.csv}`` (likewise ``u`` and
``x_true``), or all of them from one file with ``record: rec.csv``.  With a header row the
columns of a signal are found by name: ``y1, y2, ...`` for the measurements, ``u1, ...`` for the
inputs, ``x1, ...`` (or ``x_true1, ...``) for the true states, also written ``y_1``, ``y[1]``
or ``y(1)``, in any order and among other columns (a time column ``t`` is simply not read);
``{file: rec.csv, columns: [a, b]}`` names them explicitly.  A header whose columns carry no
such names is accepted when the file has exactly as many columns as the signal needs.  A file
without a header row is read as before: every column, in order.  :func:`read_signal` says which
columns it read (the scenario's ``source`` and ``setobs-bench run`` repeat it).
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import ConfigError

#: the column-name prefix of each signal
PREFIXES = {"y": ("y",), "u": ("u",), "x_true": ("x_true", "x")}
#: columns that are never a signal (time stamps, step counters)
TIME_COLUMNS = {"t", "time", "k", "step", "t_s", "time_s"}


@dataclass(frozen=True)
class CsvTable:
    """A CSV file read as numbers: its header (``None`` without one) and its rows."""

    path: Path
    names: list[str] | None
    data: np.ndarray


def _is_number(token: str) -> bool:
    try:
        float(token)
    except ValueError:
        return False
    return True


def _split(line: str, sep: str | None) -> list[str]:
    return [t.strip().strip('"').strip("'") for t in (line.split(sep) if sep else line.split())]


def read_csv(path: Path, what: str) -> CsvTable:
    """Read ``path``: comment (``#``) and blank lines skipped, the separator taken from the
    first line (comma, semicolon, tab, else blanks), a first line with any non-numeric cell
    taken as the header.

    Raises
    ------
    ConfigError
        Unreadable file, rows of different lengths, or a cell that is not a number (with its
        line and column).
    """
    try:
        text = path.read_text(encoding="utf-8-sig")
    except OSError:
        raise ConfigError(f"{what}: cannot read file {path}") from None
    except UnicodeDecodeError:
        raise ConfigError(f"{what}: file {path} is not UTF-8 text") from None
    lines = [(i + 1, ln) for i, ln in enumerate(text.splitlines())
             if ln.strip() and not ln.lstrip().startswith("#")]
    if not lines:
        return CsvTable(path, None, np.zeros((0, 0)))
    first = lines[0][1]
    sep = next((s for s in (",", ";", "\t") if s in first), None)
    head = _split(first, sep)
    names = None
    if not all(_is_number(t) for t in head):
        names, lines = head, lines[1:]
    rows = []
    for lineno, ln in lines:
        cells = _split(ln, sep)
        if len(cells) != len(head):
            raise ConfigError(f"{what}: file {path} line {lineno} has {len(cells)} columns, "
                              f"the first line {len(head)}")
        try:
            rows.append([float(c) for c in cells])
        except ValueError:
            j = next(j for j, c in enumerate(cells) if not _is_number(c))
            col = f" ({names[j]})" if names else ""
            raise ConfigError(f"{what}: file {path} line {lineno} column {j + 1}{col}: "
                              f"{cells[j]!r} is not a number") from None
    data = np.array(rows, dtype=float).reshape(len(rows), len(head))
    return CsvTable(path, names, data)


def _index(name: str, prefixes: tuple[str, ...]) -> int | None:
    """The number ``i`` of a column named ``<prefix>i`` (``y1``, ``y_1``, ``y[1]``, ``y(1)``),
    None otherwise."""
    for prefix in prefixes:
        m = re.fullmatch(rf"{re.escape(prefix)}[ _]?[\[(]?(\d+)[\])]?", name.strip(), re.I)
        if m:
            return int(m.group(1))
    return None


def select(table: CsvTable, signal: str, what: str, width: int | None = None,
           columns: list[str] | None = None) -> tuple[np.ndarray, str]:
    """The columns of ``signal`` (``y``, ``u`` or ``x_true``) in ``table`` and a note saying
    which were read.

    Parameters
    ----------
    table : CsvTable
        The file.
    signal : str
        Which signal (its column-name prefixes: :data:`PREFIXES`).
    what : str
        The config location, for messages.
    width : int, optional
        The number of columns the signal needs (the system's ny, nu or n), to check the named
        columns and to accept a header without signal names.
    columns : list of str, optional
        Explicit column names.

    Returns
    -------
    values : ndarray
        N x k.
    note : str
        E.g. ``"y from rec.csv columns y1, y2 (header row)"``.
    """
    name = table.path.name
    if table.names is None:
        if columns:
            raise ConfigError(f"{what}: 'columns' given but file {table.path} has no header row")
        return table.data, f"{signal} from {name}: all {table.data.shape[1]} columns (no header)"
    names = table.names
    if columns:
        missing = [c for c in columns if c not in names]
        if missing:
            raise ConfigError(f"{what}: file {table.path} has no column(s) {missing} (its "
                              f"columns: {', '.join(names)})")
        picked = [names.index(c) for c in columns]
    else:
        found = {}
        for j, c in enumerate(names):
            i = _index(c, PREFIXES[signal])
            if i is not None:
                if i in found:
                    raise ConfigError(f"{what}: file {table.path} has two columns for "
                                      f"{signal} {i}: {names[found[i]]!r} and {c!r}")
                found[i] = j
        if found:
            order = sorted(found)
            if order != list(range(order[0], order[0] + len(order))):
                raise ConfigError(f"{what}: file {table.path}: the {signal} columns "
                                  f"{[names[found[i]] for i in order]} are not numbered "
                                  "consecutively")
            picked = [found[i] for i in order]
        else:
            rest = [j for j, c in enumerate(names) if c.strip().lower() not in TIME_COLUMNS]
            if width is not None and len(rest) == width and not any(
                    _index(names[j], p) is not None for p in _all_prefixes() for j in rest):
                picked = rest
            else:
                hint = "" if width is None else f" ({width} expected)"
                raise ConfigError(
                    f"{what}: file {table.path} has a header row ({', '.join(names)}) but no "
                    f"columns named {signal if signal != 'x_true' else 'x'}1, "
                    f"{signal if signal != 'x_true' else 'x'}2, ...{hint}; name them so or "
                    "list them with {file: ..., columns: [...]}")
    if width is not None and len(picked) != width:
        raise ConfigError(f"{what}: file {table.path} has {len(picked)} {signal} column(s) "
                          f"({', '.join(names[j] for j in picked)}), expected {width}")
    note = f"{signal} from {name} columns {', '.join(names[j] for j in picked)} (header row)"
    return table.data[:, picked], note


def _all_prefixes() -> tuple[str, ...]:
    return tuple(p for ps in PREFIXES.values() for p in ps)


def read_signal(spec: dict, signal: str, what: str, base: Path | None,
                width: int | None = None) -> tuple[np.ndarray, str]:
    """A signal given as ``{file: path[, columns: [...]]}`` (path relative to ``base``):
    its N x k values and the note of :func:`select`."""
    unknown = set(spec) - {"file", "columns"}
    if "file" not in spec or unknown:
        raise ConfigError(f"{what}: expected a list or {{file: path[, columns: [...]]}}, got "
                          f"keys {sorted(spec)}")
    columns = spec.get("columns")
    if columns is not None and (not isinstance(columns, list) or not columns):
        raise ConfigError(f"{what}: 'columns' must be a non-empty list of column names")
    path = Path(spec["file"])
    if not path.is_absolute() and base is not None:
        path = base / path
    table = read_csv(path, what)
    return select(table, signal, what, width, [str(c) for c in columns] if columns else None)


def signals_in(path: Path, what: str) -> list[str]:
    """The signals (``y``, ``u``, ``x_true``) a header-row file has named columns for."""
    table = read_csv(path, what)
    if table.names is None:
        raise ConfigError(f"{what}: file {path} has no header row: a 'record' file needs "
                          "named columns (y1, ..., u1, ..., x1, ...)")
    found = []
    for signal, prefixes in PREFIXES.items():
        if any(_index(c, prefixes) is not None for c in table.names):
            found.append(signal)
    return found
