"""Inline system and scenario definitions in benchmark configs.

A config scenario is either a registered name (``vehicle6d-cora``), a mapping with a name and
keyword arguments (``{name: tank6-linear, seed: 3}``), or an inline definition.  A named
scenario may also replace the observer options it suggests (``options: {}`` runs every
observer with its own defaults) and take another name in the results (``label``), so that
one scenario can appear twice in a config::

    - {name: tank6-linear, seed: 0, options: {}, label: tank6-linear-defaults}

An inline definition::

    - name: my-plant
      system:
        A: [[1.0, 0.1], [0.0, 1.0]]
        B: [[0.0], [0.1]]
        C: [[1.0, 0.0]]
        W: {box: [0.01, 0.01]}                       # or {center: .., generators: ..}
        V: {box: [0.1]}                              # or {lo: .., hi: ..}
        X0: {center: [0, 0], generators: [[1, 0], [0, 1]]}
        dt: 0.1
      u: {file: u.csv}                               # N x nu rows (or a nested list)
      y: [[0.1], [0.2], ...]                         # N x ny, or `simulate:` instead
      # or: record: rec.csv  -- one CSV with a header row naming its columns y1, y2, u1, x1, ..
      # ({file: rec.csv, columns: [...]} or a header row also work for u, y, x_true alone;
      # see benchmarks/run/records.py)
      simulate: {steps: 200, seed: 0, noise: uniform}
      options: {order: 50, reduction: girard}
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path
from typing import Any

import numpy as np

from observers.sets import Interval, SetError, Zonotope
from systems import (
    NOISE_MODELS,
    LinearSystem,
    ModelError,
    Scenario,
    check_steps,
    scenario,
    simulate,
)

from ..errors import ConfigError
from .records import read_signal, signals_in

NAMED_KWARGS = {"seed", "noise", "steps"}
NAMED_KEYS = NAMED_KWARGS | {"options", "label"}
INLINE_KEYS = {"name", "system", "u", "y", "x_true", "record", "simulate", "options",
               "tolerance", "description", "large_tolerance"}
SYSTEM_KEYS = {"A", "B", "C", "W", "V", "X0", "dt"}


def _integer(value: Any, what: str, minimum: int) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < minimum:
        raise ConfigError(f"{what} must be an integer >= {minimum}, got {value!r}")
    return int(value)


def _number(value: Any, what: str, *, positive: bool) -> float:
    try:
        x = float(value)
    except (TypeError, ValueError):
        x = float("nan")
    if isinstance(value, bool) or not np.isfinite(x) or x < 0 or (positive and x == 0):
        kind = "a positive" if positive else "a non-negative"
        raise ConfigError(f"{what} must be {kind} number, got {value!r}")
    return x


def simulation_kwargs(spec: dict, where: str) -> dict[str, Any]:
    """Validated ``steps`` (>= 1), ``seed`` (>= 0) and ``noise`` (a known model) of ``spec``."""
    out: dict[str, Any] = {}
    if "steps" in spec:
        out["steps"] = _integer(spec["steps"], f"{where}: steps", 1)
    if "seed" in spec:
        out["seed"] = _integer(spec["seed"], f"{where}: seed", 0)
    if "noise" in spec:
        if spec["noise"] not in NOISE_MODELS:
            raise ConfigError(f"{where}: unknown noise model '{spec['noise']}' (known: "
                              f"{', '.join(NOISE_MODELS)})")
        out["noise"] = spec["noise"]
    return out


def _array(value: Any, what: str, base: Path | None, ndim: int = 2, signal: str | None = None,
           width: int | None = None, notes: list[str] | None = None) -> np.ndarray:
    """An array from a nested list or ``{file: path}`` (:mod:`.records`: header rows and named
    columns of ``signal`` accepted; which columns were read is appended to ``notes``)."""
    if isinstance(value, dict):
        a, note = read_signal(value, signal or "values", what, base, width)
        if notes is not None and signal is not None:
            notes.append(note)
    else:
        try:
            a = np.array(value, dtype=float)
        except (TypeError, ValueError):
            raise ConfigError(f"{what} must be a numeric array") from None
    if a.ndim == 1 and ndim == 2:
        a = a.reshape(-1, 1)
    if a.ndim != ndim:
        raise ConfigError(f"{what} must be a {ndim}-D array, got shape {a.shape}")
    return a


def parse_set(spec: Any, what: str, dim: int) -> Zonotope:
    """A set from ``{box: r, center: c}``, ``{center, generators}`` or ``{lo, hi}``."""
    if not isinstance(spec, dict):
        raise ConfigError(f"{what} must be a mapping like {{box: [...]}}, got {spec!r}")
    keys = set(spec)
    try:
        if "box" in keys and keys <= {"box", "center"}:
            r = np.atleast_1d(np.array(spec["box"], dtype=float))
            if r.size == 0:
                raise ConfigError(f"{what}: the box is empty (no radii given)")
            if np.any(r < 0):
                raise ConfigError(f"{what}: box radii must be non-negative")
            if r.size != dim:
                raise ConfigError(f"{what}: box has {r.size} radii, expected {dim}")
            return Zonotope.box(r, spec.get("center"))
        if keys == {"center", "generators"} or keys == {"generators"}:
            c = np.zeros(dim) if "center" not in spec else spec["center"]
            G = np.array(spec["generators"], dtype=float)
            if G.size == 0:
                raise ConfigError(f"{what}: the generator matrix is empty")
            Z = Zonotope(c, G.reshape(dim, -1) if G.ndim == 1 else G)
            if Z.dim != dim:
                raise ConfigError(f"{what}: dimension {Z.dim}, expected {dim}")
            return Z
        if keys == {"lo", "hi"}:
            Z = Zonotope.from_interval(Interval(spec["lo"], spec["hi"]))
            if Z.dim != dim:
                raise ConfigError(f"{what}: dimension {Z.dim}, expected {dim}")
            return Z
    except (SetError, TypeError, ValueError) as exc:
        if isinstance(exc, ConfigError):
            raise
        raise ConfigError(f"{what}: {exc}") from None
    raise ConfigError(f"{what}: expected keys box[/center], center/generators or lo/hi, got "
                      f"{sorted(keys)}")


def parse_system(spec: Any, where: str) -> LinearSystem:
    """A :class:`~systems.LinearSystem` from an inline mapping."""
    if not isinstance(spec, dict):
        raise ConfigError(f"{where}: 'system' must be a mapping")
    unknown = set(spec) - SYSTEM_KEYS
    missing = {"A", "C", "W", "V", "X0"} - set(spec)
    if unknown:
        raise ConfigError(f"{where}: unknown system key(s) {sorted(unknown)}")
    if missing:
        raise ConfigError(f"{where}: system is missing {sorted(missing)}")
    A = _array(spec["A"], f"{where}: A", None)
    if A.shape[0] != A.shape[1]:
        raise ConfigError(f"{where}: A must be square, got shape {A.shape}")
    n = A.shape[0]
    C = _array(spec["C"], f"{where}: C", None)
    if C.shape[1] != n:  # never transposed silently: a column may be a typo of a row
        raise ConfigError(f"{where}: C has shape {C.shape}; C must have one row per output "
                          f"and {n} columns (one per state)"
                          + (f"; for one output write C: [[{', '.join(['c'] * n)}]]"
                             if C.shape == (n, 1) else ""))
    B = _array(spec["B"], f"{where}: B", None) if "B" in spec else np.zeros((n, 0))
    try:
        system = LinearSystem(
            A, B, C,
            W=parse_set(spec["W"], f"{where}: W", n),
            V=parse_set(spec["V"], f"{where}: V", C.shape[0] if C.ndim == 2 else 1),
            X0=parse_set(spec["X0"], f"{where}: X0", n),
            dt=_number(spec.get("dt", 1.0), "dt", positive=True),
            name=where,
        )
        # an unstable mode no output sees makes every estimate grow without bound: not a
        # benchmark (unobservable but detectable systems, like the 6-tank one, are fine)
        system.require_detectable(where)
    except ModelError as exc:
        raise ConfigError(f"{where}: {exc}") from None
    return system


#: the largest containment tolerance accepted without ``large_tolerance: true`` (the
#: rounding of true states shipped with 3 decimals): a larger one switches the check off
MAX_TOLERANCE = 1e-3


def _tolerance(spec: dict, where: str) -> float:
    """The containment tolerance of an inline scenario, at most :data:`MAX_TOLERANCE` unless
    the entry says ``large_tolerance: true``."""
    tol = _number(spec.get("tolerance", 1e-9), f"{where}: tolerance", positive=False)
    override = spec.get("large_tolerance", False)
    if not isinstance(override, bool):
        raise ConfigError(f"{where}: 'large_tolerance' must be true or false")
    if tol > MAX_TOLERANCE and not override:
        raise ConfigError(f"{where}: tolerance {tol:g} exceeds {MAX_TOLERANCE:g}, which would "
                          "let the containment check pass sets that miss the true state; set "
                          "'large_tolerance: true' beside it if that is really meant")
    return tol


def _check_record(a: np.ndarray, what: str, cols: int, rows: int | None = None) -> np.ndarray:
    if a.shape[1] != cols and a.shape[0] == cols:
        a = a.T
    if a.shape[1] != cols:
        raise ConfigError(f"{what} has shape {a.shape}, expected (N, {cols})")
    if rows is not None and a.shape[0] not in (rows, rows - 1):
        raise ConfigError(f"{what} has {a.shape[0]} rows, expected {rows}")
    bad = np.argwhere(~np.isfinite(a))
    if bad.size:
        k, j = bad[0]
        raise ConfigError(f"{what}[{k}, {j}] is not finite ({a[k, j]})")
    return a


def _expand_record(spec: dict, where: str, base: Path | None) -> dict:
    """``record: FILE`` (or ``{file: FILE}``) as ``y``, ``u`` and ``x_true`` entries for the
    signals the file has named columns for (:func:`.records.signals_in`)."""
    if "record" not in spec:
        return spec
    rec = spec["record"]
    rec = {"file": rec} if isinstance(rec, str) else rec
    if not isinstance(rec, dict) or set(rec) != {"file"}:
        raise ConfigError(f"{where}: 'record' must be a file name or {{file: path}}")
    spec = {k: v for k, v in spec.items() if k != "record"}
    path = Path(rec["file"])
    path = path if path.is_absolute() or base is None else base / path
    found = signals_in(path, f"{where}: record")
    both = [s for s in found if s in spec]
    if both:
        raise ConfigError(f"{where}: {both} given both in 'record' and on their own")
    if "y" not in found:
        raise ConfigError(f"{where}: record file {path} has no columns named y1, y2, ...")
    return {**spec, **{s: dict(rec) for s in found}}


def build_inline(spec: dict, base: Path | None) -> Scenario:
    """A scenario from an inline definition (see the module docstring)."""
    name = str(spec["name"])
    where = f"scenario '{name}'"
    unknown = set(spec) - INLINE_KEYS
    if unknown:
        raise ConfigError(f"{where}: unknown key(s) {sorted(unknown)} (allowed: "
                          f"{', '.join(sorted(INLINE_KEYS))})")
    system = parse_system(spec["system"], where)
    spec = _expand_record(spec, where, base)
    notes: list[str] = []
    sim = spec.get("simulate")
    if ("y" in spec) == (sim is not None):
        raise ConfigError(f"{where}: give exactly one of 'y' (measurements, or a 'record' "
                          "file) or 'simulate'")
    if sim is not None:
        if not isinstance(sim, dict) or not set(sim) <= {"steps", "seed", "noise"}:
            raise ConfigError(f"{where}: 'simulate' takes steps, seed and noise")
        sim = {"steps": 100, "seed": 0, "noise": "uniform",
               **simulation_kwargs(sim, f"{where}: simulate")}
        steps = sim["steps"]
        try:
            check_steps(name, steps)
        except ModelError as exc:
            raise ConfigError(str(exc)) from None
        u = (np.zeros((steps, system.nu)) if "u" not in spec
             else _check_record(_array(spec["u"], f"{where}: u", base, signal="u",
                                       width=system.nu, notes=notes),
                                f"{where}: u", system.nu))
        try:
            run = simulate(system, u, steps=steps, seed=sim.get("seed", 0),
                           noise=sim.get("noise", "uniform"))
        except ModelError as exc:
            raise ConfigError(f"{where}: {exc}") from None
        u, y, x_true = run.u, run.y, run.x_true
    else:
        y = _check_record(_array(spec["y"], f"{where}: y", base, signal="y", width=system.ny,
                                 notes=notes), f"{where}: y", system.ny)
        N = y.shape[0]
        if N == 0:
            raise ConfigError(f"{where}: y is empty (0 steps)")
        u = (np.zeros((N, system.nu)) if "u" not in spec
             else _check_record(_array(spec["u"], f"{where}: u", base, signal="u",
                                       width=system.nu, notes=notes), f"{where}: u",
                                system.nu, N))
        x_true = None
        if "x_true" in spec:
            x_true = _check_record(_array(spec["x_true"], f"{where}: x_true", base,
                                          signal="x_true", width=system.n, notes=notes),
                                   f"{where}: x_true", system.n)
            if x_true.shape[0] != N:
                raise ConfigError(f"{where}: x_true has {x_true.shape[0]} rows, y has {N}")
    options = spec.get("options", {})
    if not isinstance(options, dict):
        raise ConfigError(f"{where}: 'options' must be a mapping")
    return Scenario(
        name=name, system=system, u=u, y=y, x_true=x_true, options=dict(options),
        description=str(spec.get("description", "inline scenario")),
        source="config" + ("; read " + "; ".join(notes) if notes else ""),
        tolerance=_tolerance(spec, where),
        state_names=tuple(f"x{i + 1}" for i in range(system.n)),
    )


def build_scenario(spec: Any, base: Path | None) -> Scenario:
    """Build a config scenario entry (name, name with kwargs, or inline definition)."""
    if isinstance(spec, str):
        spec = {"name": spec}
    if not isinstance(spec, dict) or "name" not in spec:
        raise ConfigError(f"a scenario must be a name or a mapping with 'name', got {spec!r}")
    if "system" in spec:
        return build_inline(spec, base)
    where = f"scenario '{spec['name']}'"
    kwargs = {k: v for k, v in spec.items() if k not in ("name", "options", "label")}
    unknown = set(spec) - NAMED_KEYS - {"name"}
    if unknown:
        raise ConfigError(f"{where}: unknown key(s) {sorted(unknown)} "
                          f"(a named scenario takes {', '.join(sorted(NAMED_KEYS))})")
    kwargs = simulation_kwargs(kwargs, where)
    try:
        sc = scenario(str(spec["name"]), **kwargs)
    except ModelError as exc:
        raise ConfigError(str(exc)) from None
    changes: dict[str, Any] = {}
    if "options" in spec:
        if not isinstance(spec["options"], dict):
            raise ConfigError(f"{where}: 'options' must be a mapping ({{}}: observer defaults)")
        changes["options"] = dict(spec["options"])
    if "label" in spec:
        if not isinstance(spec["label"], str) or not spec["label"].strip():
            raise ConfigError(f"{where}: 'label' must be a non-empty name")
        changes["name"] = spec["label"].strip()
    return dataclasses.replace(sc, **changes) if changes else sc


# -- scenario instances, built once per process ---------------------------------------------
_SCENARIOS: dict[str, Scenario] = {}


def instance_key(spec: dict, base: str | None) -> str:
    """The scenario instance of a configuration entry ``spec`` (seed included) read relative
    to the folder ``base``."""
    return json.dumps([spec, base], sort_keys=True, default=str)


def scenario_key(entry: Any) -> str:
    """The scenario instance of ``entry`` (a job or a floor task: its ``spec`` and ``base``)."""
    return instance_key(entry.spec, entry.base)


def remember_scenario(spec: dict, base: str | None, sc: Scenario) -> None:
    """Keep the built scenario ``sc`` of entry ``spec`` (this process needs not rebuild it)."""
    _SCENARIOS[instance_key(spec, base)] = sc


def scenario_of(entry: Any) -> Scenario:
    """The scenario of ``entry`` (a job or a floor task, with ``spec``, ``base`` and an
    optional built ``scenario``), built once per process."""
    key = scenario_key(entry)
    if getattr(entry, "scenario", None) is not None:
        _SCENARIOS.setdefault(key, entry.scenario)
    if key not in _SCENARIOS:
        _SCENARIOS[key] = build_scenario(entry.spec, Path(entry.base) if entry.base else None)
    return _SCENARIOS[key]
