"""Scaling study: rows per variant, size and observer; budgets; missing scenarios listed."""

from __future__ import annotations

import time

import numpy as np
import pytest

import observers
from benchmarks.report import figures
from benchmarks.studies import scaling
from observers.base import BUDGET_WINDOW
from observers.sets import Interval


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
    text = scaling.report(df, fig, out, scaling.StudyRun(sizes=(3, 4, 6), steps=8,
                                                         design_budget=60, run_budget=60,
                                                         elapsed=1.0))
    assert "real-time limit" in text.lower() and "scenario not available" in text
    assert fig.is_file() and pdf.is_file() and fig.name == "scaling.png"


def test_a_run_over_budget_is_timeout_and_larger_sizes_are_not_attempted():
    df = scaling.run_study(sizes=(3, 4), names=["FRad-A"], variants=("linear",), steps=400,
                           design_budget=60, run_budget=1e-3, log=lambda m: None)
    first, second = df.sort_values("n").itertuples(index=False)
    assert first.status == "timeout" and "budget" in first.message
    assert second.status == "not run" and second.message == "not attempted: timeout at n=3"


class _Sleepy:
    """An observer whose steps take at least ``seconds[k]`` (the last entry from then on)."""

    def __init__(self, seconds):
        self.seconds, self.k = list(seconds), 0

    def step(self, u_prev, y):
        time.sleep(self.seconds[min(self.k, len(self.seconds) - 1)])
        self.k += 1
        return Interval([-1.0], [1.0])


def test_a_budgeted_run_that_cannot_finish_stops_once_its_projection_is_over():
    # every step >= 20 ms: after the first window of steps the 40-step record projects to
    # >= 0.8 s, over a budget of 0.1 s, whatever the machine does
    res = observers.run(_Sleepy([0.02]), None, np.zeros((40, 1)), budget=0.1)
    assert res.status == "timeout" and res.failed_step == BUDGET_WINDOW
    assert np.isfinite(res.lo[:BUDGET_WINDOW]).all() and np.isnan(res.lo[BUDGET_WINDOW:]).all()
    assert f"stopped after step {BUDGET_WINDOW - 1} of 40" in res.message
    assert "over the budget of 0.1 s" in res.message


def test_one_slow_first_step_does_not_stop_a_budgeted_run():
    # 0.3 s once (a compiled kernel loading, say), then instant steps: the median of the
    # window projects ~0.3 s for the record, within 5 s
    res = observers.run(_Sleepy([0.3, 0.0]), None, np.zeros((40, 1)), budget=5.0)
    assert res.status == "ok" and np.isfinite(res.lo).all()


@pytest.mark.parametrize("budget", [0, -1.0, float("nan"), "5"])
def test_a_budget_that_is_not_a_positive_number_is_refused(budget):
    with pytest.raises(ValueError, match="budget must be a positive number"):
        observers.run(_Sleepy([0.0]), None, np.zeros((4, 1)), budget=budget)


def test_a_run_projected_over_budget_in_the_study_names_its_step():
    # CZN-A's steps on 12 tanks cost milliseconds (2.4 ms at full order): 20000 of them are
    # far over 20 s, and the projection stops the run in its worker after a few steps (a
    # first step that compiles the kernels included), long before the executor's hard stop
    df = scaling.run_study(sizes=(12,), names=["CZN-A"], variants=("linear",), steps=20000,
                           design_budget=60, run_budget=20.0, log=lambda m: None)
    (row,) = df.itertuples(index=False)
    assert row.status == "timeout" and "stopped after step" in row.message, row.message
    assert "over the budget of 20 s" in row.message


def test_a_run_stopped_by_its_budget_names_what_its_steps_cost():
    # a hand-made study: CZN-A ran at n = 6 (1 + 2 ms), was stopped by its budget at n = 12
    # after steps of 20 ms + 600 ms (the hull the larger part); a run stopped from outside
    # (no times) keeps the bare cell
    import pandas as pd
    df = pd.DataFrame([
        scaling._row("linear", 6, "CZN-A", "ok", step_ms=1.0, hull_ms=2.0, total_ms=3.0,
                     rel_rms=1.0),
        scaling._row("linear", 12, "CZN-A", "timeout", "stopped after step 4 of 40",
                     step_ms=20.0, hull_ms=600.0),
        scaling._row("linear", 6, "FRad-A", "timeout", "stopped after the budget of 30 s"),
        scaling._row("linear", 12, "FRad-A", "timeout", "stopped after step 2 of 40"),
    ])
    table = "\n".join(scaling._size_table(df, "linear", (6, 12), "time"))
    assert "| CZN-A | 1 + 2 | timeout (20 + 600) |" in table
    assert "| FRad-A | timeout | timeout |" in table
    notes = "\n".join(scaling.failures(df, steps=40))
    assert ("stopped after step 4 of 40; per step over the steps run: `step()` 20 ms + "
            "interval hull 600 ms (medians), most of it the interval hull") in notes
    assert notes.count("per step over the steps run") == 1
    # stopped at step 2 of 40: within the 4 warm-up steps (40 // 10) the medians leave out
    assert ("stopped after the budget of 30 s\n" in notes
            or notes.endswith("stopped after the budget of 30 s"))
    assert scaling.stop_cost(df.iloc[3], 40) == (
        "; `step()` and interval hull not timed apart: it stopped within the first 4 steps, "
        "which the medians leave out")
