"""The fidelity claims (``benchmarks/gate/fidelity.yaml``): every published cell of the tables
this project reproduces, the row of ours that answers it, its tolerance and its status.

:data:`TABLES` names the published tables and where our rows are (configuration, scenario,
published table); :func:`published_cells` lists the cells each table publishes (read from
``systems/data/paper_tables/``, :mod:`benchmarks.report.paper`); :func:`load_claims` reads
and checks the claims file: one claim per published cell, none for anything else. A bad file
(unknown table, row or cell, a published cell not listed, an unknown status, a missing
tolerance or reason) is a :class:`~benchmarks.errors.ConfigError` of one line.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import yaml

from ..errors import ConfigError
from ..report.paper import load_table

#: the claims file shipped with the package
CLAIMS_FILE = Path(__file__).resolve().parent / "fidelity.yaml"
#: what a claim says of its cell
STATUSES = ("within", "explained", "open")
#: the kinds of cell, each with a default tolerance in the file
KINDS = ("avg", "state", "time")


@dataclass(frozen=True)
class TableSource:
    """Where a published table and our rows for it are.

    Attributes
    ----------
    title : str
        The table's citation in the report.
    paper : str
        Key of ``systems/data/paper_tables/<paper>.yaml``.
    config : str
        Our configuration (its store ``results/<config>/``).
    scenarios : dict
        Cell column -> scenario: ``{"": scenario}`` for a table of one record (cells ``v1 ..
        vn``, ``avg`` or ``t_ms``), ``{"n12": "tank12-linear", ...}`` for a scaling table (one
        average per size).
    variant : str
        The part of a scaling table's file (``linear`` or ``nonlinear``).
    """

    title: str
    paper: str
    config: str
    scenarios: dict[str, str]
    variant: str = "linear"


def _sizes(kind: str, sizes: tuple[int, ...]) -> dict[str, str]:
    return {f"n{n}": f"tank{n}-{kind}" for n in sizes}


#: the published tables, in the order of the report
TABLES: dict[str, TableSource] = {
    "ARCH T3": TableSource("Althoff, ARCH 2021, Table 3 (linearised 6 tanks)",
                           "arch2021_table3_tank6_linear", "arch2021_table3",
                           {"": "tank6-linear"}),
    "ARCH T4": TableSource("Althoff, ARCH 2021, Table 4 (nonlinear 6 tanks)",
                           "arch2021_table4_tank6_nonlinear", "arch2021_table4",
                           {"": "tank6-nonlinear"}),
    "ARCH T5": TableSource("Althoff, ARCH 2021, Table 5 (linearised 12-30 tanks)",
                           "arch2021_table5_6_tank_scaling", "arch2021_table5",
                           _sizes("linear", (12, 18, 24, 30))),
    "ARCH T6": TableSource("Althoff, ARCH 2021, Table 6 (nonlinear 18-30 tanks)",
                           "arch2021_table5_6_tank_scaling", "arch2021_table6",
                           _sizes("nonlinear", (18, 24, 30)), "nonlinear"),
    "ARCH T6 (12 tanks)": TableSource("Althoff, ARCH 2021, Table 6 (nonlinear 12 tanks)",
                                      "arch2021_table5_6_tank_scaling",
                                      "arch2021_table6_12tanks",
                                      _sizes("nonlinear", (12,)), "nonlinear"),
    "Automatica T3": TableSource("Althoff & Rath, Automatica 2021, Table 3 (6-state vehicle, "
                                 "CORA's record)", "automatica2021_table3_vehicle6",
                                 "automatica2021_table3", {"": "vehicle6d-cora"}),
    "Alanwar 2022": TableSource("Alanwar et al., ECC 2022, Sec. IV (rotating target; times "
                                "only)", "alanwar2022_datadriven", "alanwar2022",
                                {"": "rotating-target"}),
}


@dataclass(frozen=True)
class Claim:
    """One published cell and what we claim of it.

    Attributes
    ----------
    table, row, cell : str
        The table (a key of :data:`TABLES`), the published row and the cell (``v1``.., ``avg``,
        ``n12``.., ``t_ms``).
    published : float or str
        The published value (``noGain``, ``inf``, ``nan`` where it is not a number).
    ours : str
        Our row (observer or labelled variant) that answers it.
    kind : str
        ``avg``, ``state`` or ``time`` (:data:`KINDS`).
    tol : float
        Relative tolerance.
    status : str
        One of :data:`STATUSES`.
    reason : str
        Why an ``explained`` or ``open`` cell is not reproduced (``""`` for ``within``).
    """

    table: str
    row: str
    cell: str
    published: float | str
    ours: str
    kind: str
    tol: float
    status: str
    reason: str = field(default="")


def _published_value(x) -> float | str | None:
    """A published entry: a number, ``noGain``/``inf``/``nan``, or ``None`` (not computed)."""
    if x is None:
        return None
    if isinstance(x, str):
        return x
    v = float(x)
    if math.isnan(v):
        return "nan"
    return "inf" if math.isinf(v) else v


def published_cells(table: str) -> dict[str, dict[str, float | str]]:
    """Published row -> cell -> value of ``table`` (a key of :data:`TABLES`), in the paper's
    order; a cell the paper left empty ("-", not computed) is absent."""
    src = TABLES[table]
    tab = load_table(src.paper)
    out: dict[str, dict[str, float | str]] = {}
    if "tanks" in tab:
        index = {f"n{n}": j for j, n in enumerate(tab["tanks"])}
        for row, values in (tab.get(src.variant) or {}).items():
            cells = {c: _published_value(values["avg"][index[c]]) for c in src.scenarios}
            out[row] = {c: v for c, v in cells.items() if v is not None}
        return {r: c for r, c in out.items() if c}
    for row, values in (tab.get("rows") or {}).items():
        v = [float(x) for x in values["v"]]
        cells: dict[str, float | str] = {f"v{i + 1}": x for i, x in enumerate(v)}
        cells["avg"] = float(values["avg"]) if "avg" in values else sum(v) / len(v)
        out[row] = cells
    for row, seconds in (tab.get("time_per_step_s") or {}).items():
        out.setdefault(row, {})["t_ms"] = 1e3 * float(seconds)
    return out


def cell_kind(cell: str) -> str:
    """The kind of a cell name (:data:`KINDS`): ``t_ms`` a time, ``v<i>`` a state, else an
    average (``avg``, ``n<size>``)."""
    if cell == "t_ms":
        return "time"
    return "state" if cell.startswith("v") else "avg"


def _defaults(raw: dict, where: str) -> dict[str, float]:
    tol = raw.get("tolerance")
    if not isinstance(tol, dict):
        raise ConfigError(f"{where}: no 'tolerance:' block (the default relative tolerance of "
                          f"each kind of cell: {', '.join(KINDS)})")
    return {k: _tolerance(tol.get(k), f"{where}: tolerance.{k}") for k in KINDS}


def _tolerance(value, where: str) -> float:
    if value is None:
        raise ConfigError(f"{where}: missing tolerance (a relative number, e.g. 0.10)")
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not value > 0:
        raise ConfigError(f"{where}: tolerance {value!r} is not a positive number")
    return float(value)


def _row_claims(table: str, row: str, entry, published: dict[str, float | str],
                defaults: dict[str, float], where: str) -> list[Claim]:
    """The claims of one row of the file (every cell it publishes, none other)."""
    if not isinstance(entry, dict):
        raise ConfigError(f"{where}: {table}, {row}: expected a mapping of cells to statuses")
    entry = dict(entry)
    ours = entry.pop("ours", row)
    reason = entry.pop("reason", "")
    if not isinstance(ours, str) or not ours:
        raise ConfigError(f"{where}: {table}, {row}: 'ours' must name a row of ours")
    _same_keys(entry, published, f"{where}: {table}, {row}", "cell",
               f"(the paper publishes: {', '.join(published)})",
               "(every published cell needs a status)")
    out = []
    for cell, value in entry.items():
        at = f"{where}: {table}, {row}, {cell}"
        spec = value if isinstance(value, dict) else {"status": value}
        extra = set(spec) - {"status", "tol", "reason"}
        if extra:
            raise ConfigError(f"{at}: unknown key {sorted(extra)[0]!r} (status, tol, reason)")
        status = spec.get("status")
        if status not in STATUSES:
            raise ConfigError(f"{at}: status {status!r} is not one of {', '.join(STATUSES)}")
        kind = cell_kind(cell)
        tol = _tolerance(spec["tol"], at) if "tol" in spec else defaults[kind]
        why = str(spec.get("reason", reason) or "").strip()
        if status != "within" and not why:
            raise ConfigError(f"{at}: an {status} cell needs a reason")
        out.append(Claim(table, row, cell, published[cell], ours, kind, tol, status,
                         why if status != "within" else ""))
    return out


def load_claims(path: str | Path = CLAIMS_FILE) -> list[Claim]:
    """Read and check the claims file: one :class:`Claim` per published cell of every table of
    :data:`TABLES`, in the file's order.

    Raises
    ------
    ConfigError
        One line naming the problem: unreadable file, unknown table, row or cell, a published
        cell or table not listed, an unknown status, a missing tolerance or reason.
    """
    where = Path(path).name
    try:
        raw = yaml.safe_load(Path(path).read_text(encoding="utf-8"))
    except (OSError, yaml.YAMLError) as exc:
        raise ConfigError(f"{where}: cannot read the fidelity claims ({str(exc).splitlines()[0]})"
                          ) from None
    if not isinstance(raw, dict) or not isinstance(raw.get("tables"), dict):
        raise ConfigError(f"{where}: expected a mapping with 'tolerance:' and 'tables:'")
    defaults = _defaults(raw, where)
    tables = raw["tables"]
    unknown = [t for t in tables if t not in TABLES]
    if unknown:
        raise ConfigError(f"{where}: unknown table {unknown[0]!r} (known: {', '.join(TABLES)})")
    absent = [t for t in TABLES if t not in tables]
    if absent:
        raise ConfigError(f"{where}: table {absent[0]!r} is not listed (every published cell "
                          "needs a status)")
    claims: list[Claim] = []
    for table, spec in tables.items():
        rows = spec.get("rows") if isinstance(spec, dict) else None
        if not isinstance(rows, dict):
            raise ConfigError(f"{where}: {table}: expected 'rows:' (published row -> cells)")
        published = published_cells(table)
        _same_keys(rows, published, f"{where}: {table}", "row",
                   f"(published rows: {', '.join(published)})", "")
        for row, entry in rows.items():
            claims += _row_claims(table, row, entry, published[row], defaults, where)
    return claims


def _same_keys(given, published, where: str, what: str, known: str, why: str) -> None:
    """One-line errors for a key of ``given`` the paper does not publish, and for a published
    key ``given`` does not list (the first of each)."""
    unknown = [k for k in given if k not in published]
    if unknown:
        raise ConfigError(f"{where}: unknown {what} {unknown[0]!r} {known}")
    missing = [k for k in published if k not in given]
    if missing:
        raise ConfigError(f"{where}: published {what} {missing[0]!r} is not listed {why}".rstrip())
