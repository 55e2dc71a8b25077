"""Score tools' result files against a configuration (``setobs-bench score``): every result is
replayed as observer ``ext:<tool>`` (:mod:`.replay`) through the harness's own runner on the
configuration restricted to the scenario it answers, so that every column is computed as for
a native observer; the step times are then the tool's own (median ms after the warm-up, NaN
where the file gives none; column ``timed`` = ``tool``).

The rows are written with the configuration's stored rows (its result store, where there is
one) as one results folder (``summary.csv``, ``runs.csv``, ``meta.json``) that ``setobs-bench
report`` renders, ``rel_rms`` recomputed over the union.  Every result file is read and checked
before anything runs; a bad one is a one-line :class:`~benchmarks.errors.ConfigError` and
nothing is written.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from ..errors import ConfigError
from ..io import check_output_dir, environment, path_component, write_results
from ..metrics import PHASE_COLUMNS, add_relative_rms, median_ms
from ..run.config import BenchConfig
from ..run.floor import misses_floor
from ..run.runner import run_config
from ..store import bench as store_bench
from ..verdicts import NA, contained_column, exit_code
from .replay import remember, replay_observer
from .results import ExternalResult, read_result
from .schema import instance_labels

#: the value of column ``timed`` of a row whose step times the tool measured itself
TOOL_TIMED = "tool"
#: steps a verdict line names at most
SHOWN_STEPS = 10


@dataclass
class ScoreOutcome:
    """What :func:`score` wrote and found."""

    out: Path
    summary: pd.DataFrame
    verdicts: list[str]
    code: int
    problems: list[str]


def read_results(paths: list[str | Path], cfg: BenchConfig) -> list[ExternalResult]:
    """Read and check every result file against ``cfg`` (scenario known, ``N`` sets of
    dimension ``n``; one result per tool and scenario)."""
    labels = instance_labels(cfg)
    shapes = {k: (int(i.scenario.system.n), int(i.scenario.N)) for k, i in labels.items()}
    results, seen = [], {}
    for path in paths:
        res = read_result(path, shapes=shapes, config=cfg.name)
        key = (res.observer, res.scenario)
        if key in seen:
            raise ConfigError(f"{path}: scenario {res.scenario}: step -: field tool: "
                              f"{res.tool['name']} answers it already in {seen[key]}")
        seen[key] = path
        results.append(res)
    if not results:
        raise ConfigError("score: give at least one result file")
    return results


def _tool_times(summary: pd.DataFrame, res: ExternalResult) -> pd.DataFrame:
    """The rows with the tool's own step times (our replay's are meaningless)."""
    out = summary.copy()
    out["step_ms"] = median_ms(res.times) if res.times is not None else np.nan
    for col in ("hull_ms", "design_s", *PHASE_COLUMNS.values()):
        out[col] = np.nan
    out["timed"] = TOOL_TIMED
    return out


def _steps(mask: np.ndarray) -> str:
    """``"3, 4, 9"`` (at most :data:`SHOWN_STEPS`, then ``...``)."""
    steps = [str(int(k)) for k in np.flatnonzero(mask)]
    return ", ".join(steps[:SHOWN_STEPS]) + (", ..." if len(steps) > SHOWN_STEPS else "")


def verdict(res: ExternalResult, runs: pd.DataFrame, summary: pd.DataFrame, N: int, n: int,
            tol: float, containment: str) -> str:
    """One line: contained yes/no (the violating steps), covers exact yes/no (the steps)."""
    row = summary.iloc[0]
    head = f"{res.observer} on {res.scenario} ({res.path}):"
    if row["status"] != "ok":
        return f"{head} status {row['status']}: {row['message']}"
    contained = str(row[contained_column(containment)])
    text = f"contained {contained}"
    if len(runs) == N * n and contained == "no":
        in_set = runs["in_set"].to_numpy(float).reshape(N, n)[:, 0]
        text += f" (first violating step {int(row['first_violation_step'])}; steps " \
                f"{_steps(in_set == 0)})"
    covers = str(row["covers_exact"])
    text += f"; covers exact {covers}"
    if covers == "no" and len(runs) == N * n:
        lo, hi, flo, fhi = (runs[c].to_numpy(float).reshape(N, n)
                            for c in ("lo", "hi", "floor_lo", "floor_hi"))
        text += f" (steps {_steps(misses_floor(flo, fhi, lo, hi, tol))})"
    elif covers == NA:
        text += " (no exact floor for this record)"
    return f"{head} {text}"


def _stored(cfg: BenchConfig) -> tuple[pd.DataFrame | None, dict]:
    """The stored rows of ``cfg`` and their ``meta.json`` (its result store), or ``(None,
    {})`` where it has none."""
    store = store_bench.load_store(store_bench.shipped_results() / path_component(cfg.name))
    if store is None:
        return None, {}
    return store.view()


def score(paths: list[str | Path], cfg: BenchConfig, out: str | Path | None = None
          ) -> ScoreOutcome:
    """Score result files against configuration ``cfg`` and write the rows to ``out``.

    Parameters
    ----------
    paths : list of str or Path
        Result files (``setobs-result``, JSON or ``.mat``).
    cfg : BenchConfig
        The configuration whose scenarios they answer.
    out : str or Path, optional
        Output folder (default ``scored/<config>``).

    Returns
    -------
    ScoreOutcome
        The folder, the external rows, a verdict line per result, the exit code (that of
        ``run``: 1 if a guaranteed result misses the true state or the exact floor) and the
        lines explaining it.
    """
    out = Path(out) if out is not None else Path("scored") / path_component(cfg.name)
    check_output_dir(out)
    results = read_results(paths, cfg)
    labels = instance_labels(cfg)
    runs_frames, frames, lines, scenarios = [], [], [], {}
    for res in results:
        remember(res)
        name = replay_observer(res)
        inst = labels[res.scenario]
        sub = dataclasses.replace(
            cfg, scenarios=[inst.scenario], instances=[inst], observers=[name], options={},
            observer_options={name: {"result": str(res.path), "scenario": res.scenario}},
            variants={}, labelled={}, floors={})
        outcome = run_config(sub, None, progress=False)
        summary = _tool_times(outcome.summary, res)
        sc = inst.scenario
        lines.append(verdict(res, outcome.runs, summary, sc.N, sc.system.n, sc.tolerance,
                             cfg.containment))
        runs_frames.append(outcome.runs)
        frames.append(summary)
        scenarios.update(outcome.meta["scenarios"])
    external = pd.concat(frames, ignore_index=True)
    stored, stored_meta = _stored(cfg)
    union = external if stored is None else pd.concat([stored, external], ignore_index=True)
    union = add_relative_rms(union)
    meta = _meta(cfg, results, stored_meta, scenarios)
    write_results(out, {"runs.csv": pd.concat(runs_frames, ignore_index=True),
                        "summary.csv": union}, meta)
    code, problems = exit_code(external)
    return ScoreOutcome(out, union[union["family"] == "external"], lines, code, problems)


def _meta(cfg: BenchConfig, results: list[ExternalResult], stored_meta: dict,
          scenarios: dict[str, Any]) -> dict[str, Any]:
    """``meta.json`` of a scored folder: the configuration, its scenarios, the result files
    and their tools, and whether stored rows were merged."""
    return {
        "config": {"name": cfg.name, "title": cfg.title, "raw": cfg.raw,
                   "containment": cfg.containment},
        "scenarios": {**stored_meta.get("scenarios", {}), **scenarios},
        "external": [{"file": str(r.path), "scenario": r.scenario, "observer": r.observer,
                      "set": r.set_type, "tool": r.tool,
                      "times": "tool" if r.times is not None else "none"} for r in results],
        "stored_rows": bool(stored_meta),
        "executor": {"name": "serial", "workers": 1, "jobs": len(results)},
        "created": datetime.now(timezone.utc).isoformat(timespec="seconds"),
        "versions": environment(),
    }
