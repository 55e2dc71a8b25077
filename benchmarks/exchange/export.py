"""Export the problems of a configuration, one file per scenario instance
(``setobs-bench export``): the model, the sets and the record a tool in another language needs
to estimate the states, never the true states.

``json`` and ``mat`` write ``<label>.json`` / ``<label>.mat`` (MATLAB and Octave ``load`` read
the latter: numeric arrays, strings and nested structs); ``csv`` writes a folder ``<label>/``
with ``header.json`` (everything but the record) and the record as ``u.csv`` and ``y.csv``.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import scipy.io

from ..errors import ConfigError
from ..io import atomic_write_json, atomic_write_text, atomic_write_with, path_component
from .schema import FORMATS, PROBLEM_SCHEMA, PROBLEM_VERSION, STEP_CONVENTION, problem_label


def set_entry(S: Any) -> dict[str, Any]:
    """A zonotope as centre ``c`` and generator matrix ``G``, with ``lo``/``hi`` where it is a
    box (axis-aligned generators, at most one per coordinate).

    Parameters
    ----------
    S : Zonotope
        One of a system's sets (``X0``, ``W``, ``V``).

    Returns
    -------
    dict
        ``c`` (list), ``G`` (rows as lists), ``box`` (bool) and, for a box, ``lo`` and ``hi``.
    """
    c, G = np.asarray(S.c, float), np.asarray(S.G, float).reshape(len(S.c), -1)
    box = bool(np.all(np.count_nonzero(G, axis=0) <= 1)
               and np.all(np.count_nonzero(G, axis=1) <= 1))
    out: dict[str, Any] = {"c": c.tolist(), "G": G.tolist(), "box": box}
    if box:
        r = np.abs(G).sum(axis=1)
        out["lo"], out["hi"] = (c - r).tolist(), (c + r).tolist()
    return out


def _reference(f: Any) -> str:
    """``module:qualname`` of a Python function (its reference implementation)."""
    return f"{getattr(f, '__module__', '?')}:{getattr(f, '__qualname__', repr(f))}"


def _equations(system: Any) -> list[str]:
    """The dynamics of a nonlinear system as text, one line per state: the symbolic
    expressions of ``f`` where they can be derived, else the docstring of ``f``."""
    try:
        import sympy

        xs, us = system.derived.symbols  # 0-based names: x1..xn and u1..unu here
        names = {s: sympy.Symbol(f"{p}{i + 1}") for p, group in (("x", xs), ("u", us))
                 for i, s in enumerate(group)}
        exprs = [sympy.sympify(e).subs(names, simultaneous=True)
                 for e in system.derived.expressions]
        return [f"x{i + 1}[k+1] = {e} + w{i + 1}" for i, e in enumerate(exprs)]
    except Exception:  # a model that sympy cannot trace: its own words
        doc = (getattr(system._f, "__doc__", None) or "").strip()
        return [doc or f"see the reference implementation {_reference(system._f)}"]


def model_entry(system: Any) -> dict[str, Any]:
    """The model of a system: ``A``, ``B``, ``C`` of a linear one; the equations as text
    (states ``x1..xn``, inputs ``u1..unu``), the Python reference implementation
    (``module:qualname``) and ``C`` (a linear output) or the output's reference (a nonlinear
    one) of a nonlinear one."""
    if system.is_linear:
        return {"kind": "linear", "A": system.A.tolist(), "B": system.B.tolist(),
                "C": system.C.tolist()}
    out: dict[str, Any] = {"kind": "nonlinear", "equations": _equations(system),
                           "reference": _reference(system._f),
                           "output_linear": bool(system.output_is_linear)}
    if system.output_is_linear:
        out["C"] = system.C.tolist()
    else:
        out["output_reference"] = _reference(system._h)
    return out


def problem(inst: Any) -> dict[str, Any]:
    """The problem of one scenario instance of a configuration (JSON-ready).

    Parameters
    ----------
    inst : benchmarks.run.config.Instance
        The instance: its scenario, configuration entry and seed.

    Returns
    -------
    dict
        Schema and version, the scenario's name, label and seed, ``n``, ``nu``, ``ny``,
        ``N``, ``dt``, the step convention, the model, the sets ``X0``, ``W``, ``V``
        (:func:`set_entry`) and the record ``u`` (N x nu) and ``y`` (N x ny).  Never the true
        states.
    """
    sc, s = inst.scenario, inst.scenario.system
    name = str(inst.spec.get("name", sc.name))
    seed = "" if inst.seed is None else f", seed={inst.seed}"
    model = {**model_entry(s), "python": f"systems.scenario({name!r}{seed}).system"}
    u = np.zeros((sc.N, s.nu))
    u[:min(sc.N, sc.u.shape[0])] = sc.u[:sc.N]  # u[N-1] drives no stored state: 0 if absent
    return {
        "schema": PROBLEM_SCHEMA, "version": PROBLEM_VERSION,
        "scenario": {"name": name, "label":
                     problem_label(sc.name, inst.seed),
                     "seed": inst.seed, "description": sc.description, "source": sc.source},
        "n": int(s.n), "nu": int(s.nu), "ny": int(s.ny), "N": int(sc.N), "dt": float(s.dt),
        "state_names": list(sc.state_names) or [f"x{i + 1}" for i in range(s.n)],
        "convention": STEP_CONVENTION,
        "model": model,
        "sets": {k: set_entry(getattr(s, k)) for k in ("X0", "W", "V")},
        "u": u.tolist(), "y": np.asarray(sc.y, float).tolist(),
    }


def _matlab(value: Any) -> Any:
    """``value`` as ``scipy.io.savemat`` writes it for MATLAB: dicts as structs (``None``
    left out), lists of numbers as double arrays, of strings as cell arrays, booleans as 0/1."""
    if isinstance(value, dict):
        return {k: _matlab(v) for k, v in value.items() if v is not None}
    if isinstance(value, bool):
        return float(value)
    if isinstance(value, list):
        if value and all(isinstance(v, str) for v in value):
            return np.array(value, dtype=object)
        return np.array(value, dtype=float)
    return value


def _write_csv_folder(folder: Path, prob: dict[str, Any]) -> None:
    """A problem as a folder: ``header.json`` and the record as ``u.csv`` and ``y.csv``."""
    atomic_write_json(folder / "header.json",
                      {**{k: v for k, v in prob.items() if k not in ("u", "y")},
                       "record": {"u": "u.csv", "y": "y.csv"}})
    for key, width in (("u", prob["nu"]), ("y", prob["ny"])):
        head = ",".join(f"{key}{i + 1}" for i in range(width))
        rows = [",".join(repr(float(v)) for v in row) for row in prob[key]]
        atomic_write_text(folder / f"{key}.csv", "\n".join([head, *rows]) + "\n")


def export_config(cfg: Any, out: str | Path, fmt: str = "json") -> list[Path]:
    """Write the problem of every scenario instance of ``cfg`` into folder ``out``.

    Parameters
    ----------
    cfg : benchmarks.run.config.BenchConfig
        The configuration.
    out : str or Path
        Output folder (created).
    fmt : {"json", "mat", "csv"}
        File format (:data:`~.schema.FORMATS`).

    Returns
    -------
    list of Path
        The files (``csv``: folders) written, one per instance.
    """
    if fmt not in FORMATS:
        raise ConfigError(f"export: unknown format '{fmt}' (known: {', '.join(FORMATS)})")
    problems = [problem(inst) for inst in cfg.instances]  # every one built before any write
    out = Path(out)
    written = []
    for prob in problems:
        path = out / (path_component(prob["scenario"]["label"]) + FORMATS[fmt])
        if fmt == "json":
            atomic_write_json(path, prob)
        elif fmt == "mat":
            atomic_write_with(path, lambda tmp, p=prob: scipy.io.savemat(
                tmp, _matlab(p), long_field_names=True, do_compression=True))
        else:
            _write_csv_folder(path, prob)
        written.append(path)
    return written
