"""Accuracy and timing metrics of the papers.

Eq. (9) of Althoff & Rath (2021): ``r~_{i,l} = sqrt(1/N sum_k r_{i,k,l}^2)`` over all N stored
sets (including the first), and ``v_{i,l} = r~_{i,l} / min_l r~_{i,l}``.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from .verdicts import reference_rows

#: the phases of a step that ``summary.csv`` reports (mean milliseconds per step): an
#: observer's ``phase_times`` key -> its column (``hull``: the LPs inside a step, e.g. the
#: generator rescaling of a constrained-zonotope step; the interval hull of the returned set
#: is ``hull_ms``)
PHASE_COLUMNS = {"prediction": "prediction_ms", "update": "update_ms",
                 "reduction": "reduction_ms", "hull": "step_lp_ms"}
#: the columns of ``summary.csv`` that are measured times (or say how they were timed): they
#: differ between two runs of the same configuration, every other column must not
TIMING_COLUMNS = ("step_ms", "hull_ms", "design_s", *PHASE_COLUMNS.values(), "timed")


#: the steady part of a record starts after this fraction of its steps: the first steps are
#: dominated by the initial set, alike for every observer and for the floor, and dilute a
#: whole-record ratio (``gap``) towards 1; ``gap_steady`` and ``memory`` use the rest
STEADY_FRACTION = 0.2


def steady_start(N: int) -> int:
    """The first step of the steady part of an ``N``-step record: ``ceil(0.2 N)``
    (:data:`STEADY_FRACTION`), at most the last step (so that a short record keeps one)."""
    return min(int(math.ceil(STEADY_FRACTION * N)), max(N - 1, 0))


def memory_columns(doubles: np.ndarray | None) -> dict[str, float]:
    """``memory``: the median number of floating-point values of the estimated set over the
    steady steps (:func:`steady_start`); ``memory_peak``: the largest over the record
    (:func:`observers.sets.doubles` per step; NaN where nothing was counted)."""
    d = np.asarray([] if doubles is None else doubles, float)
    steady = d[steady_start(d.size):]
    steady = steady[np.isfinite(steady)]
    finite = d[np.isfinite(d)]
    return {"memory": float(np.median(steady)) if steady.size else float("nan"),
            "memory_peak": float(finite.max()) if finite.size else float("nan")}


def rms_radius(radius: np.ndarray) -> np.ndarray:
    """RMS over time of the interval radius, per state (``radius`` is N x n)."""
    return np.sqrt(np.mean(np.asarray(radius, float) ** 2, axis=0))


def warmup_steps(N: int) -> int:
    """Steps excluded from timing statistics (cache and allocator warm-up)."""
    return min(5, N // 10)


def median_ms(times: np.ndarray) -> float:
    """Median of per-step times in milliseconds, after the warm-up steps (NaN if none)."""
    t = np.asarray(times, float)
    t = t[warmup_steps(t.size):]
    t = t[np.isfinite(t)]
    return float(np.median(t) * 1e3) if t.size else float("nan")


def add_relative_rms(summary: pd.DataFrame) -> pd.DataFrame:
    """Add ``rel_rms`` (eq. 9): each state's RMS radius divided by the smallest one among the
    successful guaranteed observers (and option variants) of the same scenario and seed that do
    not violate containment (:func:`benchmarks.verdicts.reference_rows`)."""
    keys = ["scenario", "state"] + (["seed"] if "seed" in summary.columns else [])
    tmp = summary.assign(**{k: summary[k].astype(object).where(summary[k].notna(), "")
                            for k in keys})
    ok = reference_rows(summary)
    best = tmp[ok].groupby(keys)["rms_radius"].min().rename("_best")
    best = tmp.join(best, on=keys)["_best"].to_numpy(float)
    out = summary.copy()
    out["rel_rms"] = np.where(out["status"] == "ok", out["rms_radius"] / best, np.nan)
    return out


def timed_in_parallel(summary: pd.DataFrame) -> bool:
    """Whether the times of ``summary`` were measured while other jobs ran concurrently
    (``run --jobs``/``--executor dask``: column ``timed`` is ``parallel``)."""
    return "timed" in summary.columns and bool((summary["timed"] == "parallel").any())
