"""Scaling study: rows per variant, size and observer; budgets; missing scenarios listed."""

from __future__ import annotations

import numpy as np

from benchmarks.report import figures
from benchmarks.studies import scaling


def test_study_rows_exponent_timeout_and_missing_scenarios(tmp_path):
    df = scaling.run_study(sizes=(3, 4, 6), names=["FRad-A", "FRad-C"],
                           variants=("linear", "bogus"), steps=8, design_budget=60,
                           run_budget=60, log=lambda m: None)
    assert len(df) == 2 * 3 * 2
    lin = df[df["variant"] == "linear"]
    assert (lin["status"] == "ok").all() and (lin["total_ms"] > 0).all()
    # eq. (9) per size: the best observer of each size has 1 in at least one state, so its
    # mean over the states is >= 1, and every mean is >= 1
    assert (lin["rel_rms"] >= 1 - 1e-12).all()
    bogus = df[df["variant"] == "bogus"]
    assert (bogus["status"] == "not run").all()
    assert bogus["message"].str.startswith("scenario not available").all()
    exp = scaling.exponents(df)
    assert np.isfinite(exp.loc[exp["variant"] == "linear", "step_exponent"]).all()
    out = tmp_path / "scaling.md"
    fig, pdf = figures.scaling(df, ("linear", "bogus"), scaling.REALTIME_MS,
                               tmp_path / "scaling")
    text = scaling.report(df, fig, out, sizes=(3, 4, 6), steps=8, design_budget=60,
                          run_budget=60, elapsed=1.0)
    assert "real-time limit" in text.lower() and "scenario not available" in text
    assert fig.is_file() and pdf.is_file() and fig.name == "scaling.png"


def test_a_run_over_budget_is_timeout_and_larger_sizes_are_not_attempted():
    df = scaling.run_study(sizes=(3, 4), names=["FRad-A"], variants=("linear",), steps=400,
                           design_budget=60, run_budget=1e-3, log=lambda m: None)
    first, second = df.sort_values("n").itertuples(index=False)
    assert first.status == "timeout" and "budget" in first.message
    assert second.status == "not run" and second.message == "not attempted: timeout at n=3"
