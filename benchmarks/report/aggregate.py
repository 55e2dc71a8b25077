"""Aggregation of a sweep over its seeds: per scenario, observer and option variant, the mean
and spread of the relative RMS radius and the times, and how many seeds ran.

The unit of a sweep is one run (scenario, seed, observer, variant); its accuracy is the mean
over the states of ``rel_rms`` (eq. 9, against the best observer of the same seed).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from observers.registry import table_order

from ..metrics import timed_in_parallel
from .numbers import Num, markdown_table

KEYS = ["scenario", "observer", "variant"]


def is_sweep(summary: pd.DataFrame) -> bool:
    """True if ``summary`` has several seeds of a scenario or option variants."""
    if "seed" not in summary.columns:
        return False
    seeds = summary.groupby("scenario")["seed"].nunique(dropna=False)
    return bool((seeds > 1).any() or (_variants(summary) != "").any())


def _variants(summary: pd.DataFrame) -> pd.Series:
    """The ``variant`` column as strings (empty when absent or not set; a CSV reads an
    all-empty column as NaN floats)."""
    if "variant" not in summary.columns:
        return pd.Series("", index=summary.index)
    v = summary["variant"].astype(object)
    return v.where(v.notna(), "").astype(str)


def per_run(summary: pd.DataFrame) -> pd.DataFrame:
    """One row per run: mean ``rel_rms`` over the states, times, status, violations."""
    df = summary.assign(variant=_variants(summary))
    g = df.groupby(KEYS + ["seed"], sort=False, dropna=False)
    return g.agg(rel_rms=("rel_rms", "mean"), step_ms=("step_ms", "first"),
                 hull_ms=("hull_ms", "first"), design_s=("design_s", "first"),
                 status=("status", "first"), violations=("violations", "first"),
                 guaranteed=("guaranteed", "first")).reset_index()


def aggregate_seeds(summary: pd.DataFrame) -> pd.DataFrame:
    """Per scenario, observer and variant over the seeds: ``runs``, ``ok``, mean, standard
    deviation, min and max of the per-run relative RMS (successful runs only), median step,
    hull and design times, total violations and the other statuses with their counts."""
    runs = per_run(summary)
    rows = []
    for key, g in runs.groupby(KEYS, sort=False):
        ok = g[g["status"] == "ok"]
        rel = ok["rel_rms"].to_numpy(float)
        others = g.loc[g["status"] != "ok", "status"].value_counts()
        rows.append({
            **dict(zip(KEYS, key, strict=True)), "runs": len(g), "ok": len(ok),
            "rel_mean": float(np.mean(rel)) if rel.size else np.nan,
            "rel_std": float(np.std(rel, ddof=1)) if rel.size > 1 else np.nan,
            "rel_min": float(np.min(rel)) if rel.size else np.nan,
            "rel_max": float(np.max(rel)) if rel.size else np.nan,
            "step_ms": float(np.nanmedian(ok["step_ms"])) if len(ok) else np.nan,
            "hull_ms": float(np.nanmedian(ok["hull_ms"])) if len(ok) else np.nan,
            "design_s": float(np.nanmedian(ok["design_s"])) if len(ok) else np.nan,
            "violations": int(g["violations"].fillna(0).sum()),
            "failed": ", ".join(f"{s} {n}" for s, n in others.items()),
        })
    return pd.DataFrame(rows)


def sweep_tables(summary: pd.DataFrame) -> list[str]:
    """Markdown lines: one table per scenario of :func:`aggregate_seeds`."""
    agg = aggregate_seeds(summary)
    par = " (parallel)" if timed_in_parallel(summary) else ""
    head = ["Observer", "variant", "runs (ok)", "rel. RMS mean", "std", "min", "max",
            f"step ms{par}", f"hull ms{par}", f"design s{par}", "violations", "failed runs"]
    out = []
    for sc, g in agg.groupby("scenario", sort=False):
        seeds = summary.loc[summary["scenario"] == sc, "seed"].nunique()
        order = {n: i for i, n in enumerate(table_order(g["observer"].unique()))}
        g = g.assign(_o=g["observer"].map(order)).sort_values(["_o", "variant"], kind="stable")
        rows = [[r.observer, r.variant or "-", f"{r.runs} ({r.ok})", Num(r.rel_mean),
                 Num(r.rel_std), Num(r.rel_min), Num(r.rel_max), Num(r.step_ms),
                 Num(r.hull_ms), Num(r.design_s), f"**{r.violations}**" if r.violations else "0",
                 r.failed or "-"] for r in g.itertuples(index=False)]
        out += [f"## {sc} ({seeds} seed{'s' if seeds != 1 else ''})", "",
                markdown_table(head, rows), ""]
    return out
