"""The frontier study: the Pareto front on hand-made points, and a tiny run of the study
(two observers on the simulated 20-step Alamo example) with its report and figure."""

from __future__ import annotations

import numpy as np
import pandas as pd

from benchmarks.studies import frontier


def test_pareto_front_of_hand_made_points():
    g = pd.DataFrame({
        "status": ["ok", "ok", "ok", "ok", "ok", "error"],
        "covers_exact": ["yes", "yes", "yes", "no", "yes", "n/a"],
        "violations": [0, 0, 0, 0, 0, np.nan],
        # a: cheap and wide, b: dear and tight, c: beaten by a (dearer, wider), d: unsound,
        # e: ties a on cost and is tighter (beats a), f: did not run
        "cost_ratio": [1.0, 10.0, 2.0, 0.5, 1.0, np.nan],
        "gap": [3.0, 1.1, 4.0, 1.0, 2.0, np.nan],
    })
    assert frontier.pareto(g).tolist() == [False, True, False, False, True, False]


def test_tiny_study_runs_and_reports(tmp_path):
    settings = {"alamo2d-sim": [("MHE", "window", (1, 3)), ("FRad-A", "order", (5,)),
                            ("MHE[lp]", "window", (2,))]}
    df = frontier.run_study({"alamo2d-sim": None}, budget=120, settings=settings)
    assert list(df["observer"]) == ["MHE", "MHE", "FRad-A", "MHE[lp]"]
    assert (df["status"] == "ok").all(), df["message"].tolist()
    assert (df["covers_exact"] == "yes").all() and (df["violations"] == 0).all()
    assert (df["gap"] >= 1 - 1e-6).all() and (df["cost_ratio"] > 0).all()
    mhe = df[df["observer"] == "MHE"]["gap"].to_numpy()
    assert mhe[1] <= mhe[0] + 1e-12  # a longer window is not wider on this record
    assert df["pareto"].any()
    out = tmp_path / "frontier.md"
    fig = frontier.figures.frontier(df, tmp_path / "frontier")[0]
    fig_memory = frontier.figures.frontier(df, tmp_path / "frontier_memory", x="memory")[0]
    text = frontier.report(df, fig, out, budget=120, elapsed=1.0, fig_memory=fig_memory)
    assert "Pareto front, cheapest first:" in text and "| MHE | window=1 |" in text
    assert fig.is_file() and fig_memory.is_file() and "gap against memory" in text
    # MHE returns the interval hull of its window (2 n values of the 2-D state); FRad-A a
    # zonotope of order at most 5: at most 2 + 2 * 10 values
    assert (df[df["observer"] == "MHE"]["memory"] == 4).all()
    assert 0 < df[df["observer"] == "FRad-A"]["memory"].iloc[0] <= 22
    assert (df["gap_steady"] >= 1 - 1e-6).all()


def test_budget_spent_marks_the_rest_not_run():
    settings = {"alamo2d-sim": [("MHE", "window", (1,))]}
    df = frontier.run_study({"alamo2d-sim": None}, budget=1e-9, settings=settings)
    assert df["status"].tolist() == ["not run"] and df["message"].tolist() == ["budget"]


def test_a_nonlinear_record_gets_upper_bounds_of_the_gap(tmp_path):
    """On a nonlinear record the floor is the falsifier's inner box: the gaps are upper
    bounds, printed with ``<=``, and the cost is against the extended Kalman filter."""
    settings = {"vanderpol-sim": [("MHE-PR", "window", (1, 3))]}
    df = frontier.run_study({"vanderpol-sim": 40}, budget=300, settings=settings)
    assert (df["status"] == "ok").all(), df["message"].tolist()
    assert (df["gap_kind"] == "upper bound").all()
    assert (df["gap"] >= 1 - 1e-6).all() and (df["cost_ratio"] > 0).all()
    assert (df["violations"] == 0).all() and (df["covers_exact"] != "no").all()
    fig = frontier.figures.frontier(df, tmp_path / "frontier")[0]
    text = frontier.report(df, fig, tmp_path / "frontier.md", budget=300, elapsed=1.0)
    assert "| MHE-PR | window=3 | <= " in text and "(gap <= " in text
