"""Read and check a tool's result file (``setobs-result``, JSON or ``.mat``): one estimated
set per step of one scenario, in one of the representations of
:data:`~.schema.SET_FIELDS`, mapped onto the harness's sets
(:class:`~observers.sets.Interval`, :class:`~observers.sets.Zonotope`,
:class:`~observers.sets.ConZonotope`, :class:`~observers.sets.Ellipsoid`).

Every problem is one :class:`~benchmarks.errors.ConfigError` line naming the file, the
scenario, the step and the field.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import scipy.io

from observers.errors import EmptySet
from observers.sets import ConZonotope, Ellipsoid, Interval, SetError, Zonotope

from ..errors import ConfigError
from ..io import read_json_object
from .schema import RESULT_SCHEMA, RESULT_VERSION, SET_FIELDS

#: the metadata fields of a result's ``tool`` entry
TOOL_FIELDS = ("name", "version", "language", "machine")


@dataclass
class ExternalResult:
    """A checked result file: a tool's sets for every step of one scenario."""

    path: Path
    scenario: str
    tool: dict[str, str]
    set_type: str
    sets: list = field(repr=False)
    #: seconds per step as the tool measured them (None: not given)
    times: np.ndarray | None = field(default=None, repr=False)
    guaranteed: bool = True

    @property
    def observer(self) -> str:
        """The observer name of its rows: ``ext:<tool>``."""
        return f"ext:{self.tool['name']}"


class _Where:
    """The place of a problem in a result file, for one-line messages."""

    def __init__(self, path: Path, scenario: str = "?"):
        self.path, self.scenario = path, scenario

    def error(self, step: int | str, fld: str, problem: str) -> ConfigError:
        return ConfigError(f"{self.path}: scenario {self.scenario}: step {step}: field "
                           f"{fld}: {problem}")


def _load(path: Path) -> dict[str, Any]:
    """The raw content of a result file (JSON, or a MATLAB ``.mat`` with nested structs)."""
    if not path.is_file():
        raise ConfigError(f"{path}: no such result file")
    if path.suffix.lower() == ".mat":
        try:
            data = scipy.io.loadmat(path, simplify_cells=True)
        except Exception as exc:  # scipy's reader raises several kinds for a bad file
            raise ConfigError(f"{path}: not a readable .mat file ({exc})") from None
        return {k: v for k, v in data.items() if not k.startswith("__")}
    return read_json_object(path, "result file")


def _text(value: Any) -> str:
    """A string field (a MATLAB char array arrives as ``str``)."""
    return value if isinstance(value, str) else str(value)


def _numbers(value: Any, where: _Where, step: int, fld: str) -> np.ndarray:
    """A field as a float array with every entry finite."""
    try:
        a = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise where.error(step, fld, "not numeric") from None
    bad = np.argwhere(~np.isfinite(a))
    if bad.size:
        idx = tuple(int(i) for i in bad[0])
        raise where.error(step, fld, f"entry {list(idx)} is {a[idx]} (every value must be "
                                     "finite: an unbounded set is refused)")
    return a


def _vector(value: Any, n: int, where: _Where, step: int, fld: str) -> np.ndarray:
    a = _numbers(value, where, step, fld).reshape(-1)
    if a.size != n:
        raise where.error(step, fld, f"has {a.size} entries, expected {n}")
    return a


def _matrix(value: Any, rows: int, where: _Where, step: int, fld: str,
            cols: int | None = None) -> np.ndarray:
    """A matrix with ``rows`` rows (a vector of ``rows`` entries is one column: a ``.mat``
    file squeezes a single column, and a 1-row matrix into a vector)."""
    a = _numbers(value, where, step, fld)
    if a.ndim <= 1 and rows == 1:
        a = a.reshape(1, -1)
    elif a.ndim <= 1 and cols == 1:
        a = a.reshape(-1, 1)
    elif a.ndim <= 1 and a.size == rows:
        a = a.reshape(rows, 1)
    elif a.ndim == 1 and a.size == 0:
        a = a.reshape(rows, 0)
    if a.ndim != 2 or a.shape[0] != rows or (cols is not None and a.shape[1] != cols):
        want = f"({rows}, {'m' if cols is None else cols})"
        raise where.error(step, fld, f"has shape {a.shape}, expected {want}")
    return a


def make_set(kind: str, entry: Any, n: int, where: _Where, step: int):
    """One step's set of representation ``kind`` from its fields, checked (dimension ``n``,
    finite, not empty)."""
    if not isinstance(entry, dict):
        raise where.error(step, "steps", f"a step must be a mapping with {SET_FIELDS[kind]}")
    missing = [f for f in SET_FIELDS[kind] if f not in entry]
    if missing:
        raise where.error(step, missing[0], f"missing (a {kind} has {', '.join(SET_FIELDS[kind])})")
    try:
        if kind == "interval":
            lo = _vector(entry["lo"], n, where, step, "lo")
            hi = _vector(entry["hi"], n, where, step, "hi")
            if np.any(lo > hi):
                i = int(np.argmax(lo > hi))
                raise where.error(step, "lo", f"lo > hi in state {i + 1} (an empty set)")
            return Interval(lo, hi)
        if kind == "ellipsoid":
            return Ellipsoid(_vector(entry["q"], n, where, step, "q"),
                             _matrix(entry["Q"], n, where, step, "Q", cols=n))
        c = _vector(entry["c"], n, where, step, "c")
        G = _matrix(entry["G"], n, where, step, "G")
        if kind == "zonotope":
            return Zonotope(c, G)
        A = _matrix(entry["A"], np.size(entry["b"]), where, step, "A", cols=G.shape[1])
        b = _vector(entry["b"], A.shape[0], where, step, "b")
        S = ConZonotope(c, G, A, b)
        S.interval()  # an empty constrained zonotope has no hull
        return S
    except EmptySet:
        raise where.error(step, "A", "the constrained zonotope is empty") from None
    except SetError as exc:
        raise where.error(step, SET_FIELDS[kind][-1], str(exc)) from None


def _steps(data: dict[str, Any], kind: str, where: _Where) -> list:
    """The per-step entries: a list ``steps``, or (``.mat``) arrays stacked over the steps
    (``lo``, ``hi`` N x n of an interval; ``c`` N x n and ``G`` n x m x N of a zonotope)."""
    steps = data.get("steps")
    if steps is None and kind in ("interval", "zonotope"):
        first, *rest = SET_FIELDS[kind]
        if first in data:
            stacked = np.asarray(data[first], dtype=float)
            count = stacked.shape[0] if stacked.ndim else 1
            others = {f: np.asarray(data.get(f), dtype=float) for f in rest}
            return [{first: np.atleast_2d(stacked)[k],
                     **{f: (v[..., k] if f == "G" else np.atleast_2d(v)[k])
                        for f, v in others.items()}} for k in range(count)]
    if isinstance(steps, dict):  # a .mat struct array of one step
        steps = [steps]
    if isinstance(steps, np.ndarray):
        steps = list(steps)
    if not isinstance(steps, list):
        raise where.error("-", "steps", "missing (a list with one set per step)")
    return steps


def read_result(path: str | Path, n: int | None = None, N: int | None = None,
                shapes: dict[str, tuple[int, int]] | None = None, config: str = ""
                ) -> ExternalResult:
    """Read and check a result file.

    Parameters
    ----------
    path : str or Path
        A ``setobs-result`` file (``.json`` or ``.mat``).
    n, N : int, optional
        The state dimension and number of steps of the scenario it answers: every set must
        have dimension ``n``, and there must be exactly ``N`` of them.
    shapes : dict, optional
        ``label -> (n, N)`` of the scenarios of configuration ``config``: the scenario the
        result answers must be one of them (its ``n`` and ``N`` then checked as above).
    config : str
        The configuration's name (for the message).

    Returns
    -------
    ExternalResult

    Raises
    ------
    ConfigError
        One line naming the file, scenario, step and field of the first problem.
    """
    path = Path(path)
    data = _load(path)
    where = _Where(path, _text(data.get("scenario", "?")))
    if data.get("schema") != RESULT_SCHEMA:
        raise where.error("-", "schema", f"is {data.get('schema')!r}, expected "
                                         f"{RESULT_SCHEMA!r}")
    version = data.get("version")
    if not isinstance(version, (int, float)) or float(version) != RESULT_VERSION:
        raise where.error("-", "version", f"is {version!r}, this harness reads version "
                                          f"{RESULT_VERSION}")
    if "scenario" not in data:
        raise where.error("-", "scenario", "missing (the label of the problem it answers)")
    if shapes is not None:
        if where.scenario not in shapes:
            raise where.error("-", "scenario", f"not a scenario of config '{config}' (its "
                                               f"scenarios: {', '.join(shapes)})")
        n, N = shapes[where.scenario]
    tool = data.get("tool")
    if not isinstance(tool, dict) or not str(tool.get("name", "")).strip():
        raise where.error("-", "tool", "missing, or without a name")
    tool = {k: _text(tool.get(k, "")).strip() for k in TOOL_FIELDS}
    kind = _text(data.get("set", ""))
    if kind not in SET_FIELDS:
        raise where.error("-", "set", f"is {kind!r}, expected one of {', '.join(SET_FIELDS)}")
    steps = _steps(data, kind, where)
    if N is not None and len(steps) != N:
        missing = len(steps) < N
        raise where.error(len(steps) if missing else N, "steps",
                          f"{'missing' if missing else 'one too many'}: the result has "
                          f"{len(steps)} sets, the scenario {N} steps")
    if n is None:
        first = steps[0] if steps and isinstance(steps[0], dict) else {}
        n = int(np.size(first.get(SET_FIELDS[kind][0] if kind != "ellipsoid" else "q", [])))
    sets = [make_set(kind, entry, n, where, k) for k, entry in enumerate(steps)]
    times = None
    if data.get("times") is not None:
        times = _numbers(data["times"], where, "-", "times").reshape(-1)
        if times.size != len(sets) or np.any(times < 0):
            raise where.error("-", "times", f"must be {len(sets)} non-negative seconds, one "
                                            "per step")
    guaranteed = data.get("guaranteed", True)
    if isinstance(guaranteed, (int, float)) and not isinstance(guaranteed, bool):
        guaranteed = bool(guaranteed) if not math.isnan(guaranteed) else True
    return ExternalResult(path, where.scenario, tool, kind, sets, times, bool(guaranteed))


def result_file(res_sets: list, scenario: str, tool: dict[str, str], kind: str = "zonotope",
                times: list[float] | None = None) -> dict[str, Any]:
    """The content of a result file (JSON-ready) of harness sets, e.g. an observer's run.

    Parameters
    ----------
    res_sets : list
        One set per step (:class:`Interval`, :class:`Zonotope`, :class:`ConZonotope` or
        :class:`Ellipsoid`, all of representation ``kind``).
    scenario : str
        The label of the problem answered.
    tool : dict
        ``name`` and optionally ``version``, ``language``, ``machine``.
    kind : str
        The representation (:data:`~.schema.SET_FIELDS`).
    times : list of float, optional
        Seconds per step.
    """
    def entry(S) -> dict[str, Any]:
        return {f: np.asarray(getattr(S, f), float).tolist() for f in SET_FIELDS[kind]}

    out = {"schema": RESULT_SCHEMA, "version": RESULT_VERSION, "scenario": scenario,
           "tool": dict(tool), "set": kind, "steps": [entry(S) for S in res_sets]}
    if times is not None:
        out["times"] = list(times)
    return out
