"""Sweep configs: expansion into instances and variants, aggregation over seeds, report."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from benchmarks import parse_config, write_report
from benchmarks.io import write_results
from benchmarks.report.aggregate import aggregate_seeds, is_sweep
from benchmarks.run.runner import make_jobs


def test_sweep_expands_sizes_seeds_and_the_option_grid():
    cfg = parse_config({"scenarios": [{"name": "tank{n}-linear", "steps": 5}, "alamo2d-sim"],
                        "observers": ["FRad-A", "FRad-C"],
                        "sweep": {"seeds": {"count": 2}, "sizes": [3, 4],
                                  "grid": {"FRad-A": {"order": [5, 10],
                                                      "reduction": ["girard", "pca"]}}}},
                       "s")
    names = [(i.scenario.name, i.seed) for i in cfg.instances]
    assert names == [("tank3-linear", 0), ("tank3-linear", 1), ("tank4-linear", 0),
                     ("tank4-linear", 1), ("alamo2d-sim", 0), ("alamo2d-sim", 1)]
    assert [i.scenario.system.n for i in cfg.instances] == [3, 3, 4, 4, 2, 2]
    labels = [v for v, _ in cfg.variants_of("FRad-A")]
    assert labels == ['order=5,reduction="girard"', 'order=5,reduction="pca"',
                      'order=10,reduction="girard"', 'order=10,reduction="pca"']
    jobs = make_jobs(cfg)
    assert len(jobs) == 6 * (4 + 1)
    # different seeds give different records
    a, b = cfg.instances[0].scenario, cfg.instances[1].scenario
    assert not np.array_equal(a.y, b.y)


def _summary(rows):
    cols = ["scenario", "seed", "observer", "variant", "state", "rel_rms", "step_ms", "hull_ms",
            "design_s", "status", "violations", "guaranteed"]
    return pd.DataFrame(rows, columns=cols)


def test_aggregation_over_seeds_by_hand():
    # FRad-A: seed 0 states (1, 3) -> 2; seed 1 states (2, 4) -> 3; seed 2 diverged
    rows = [("s", 0, "FRad-A", "", 0, 1.0, 0.1, 0.01, 0.5, "ok", 0, True),
            ("s", 0, "FRad-A", "", 1, 3.0, 0.1, 0.01, 0.5, "ok", 0, True),
            ("s", 1, "FRad-A", "", 0, 2.0, 0.3, 0.03, 0.5, "ok", 0, True),
            ("s", 1, "FRad-A", "", 1, 4.0, 0.3, 0.03, 0.5, "ok", 0, True),
            ("s", 2, "FRad-A", "", 0, np.nan, np.nan, np.nan, 0.5, "diverged", None, True),
            ("s", 2, "FRad-A", "", 1, np.nan, np.nan, np.nan, 0.5, "diverged", None, True)]
    df = _summary(rows)
    assert is_sweep(df)
    agg = aggregate_seeds(df).iloc[0]
    assert (agg["runs"], agg["ok"]) == (3, 2)
    assert agg["rel_mean"] == pytest.approx(2.5)
    assert agg["rel_std"] == pytest.approx(np.sqrt(0.5))  # sample std of (2, 3)
    assert (agg["rel_min"], agg["rel_max"]) == (2.0, 3.0)
    assert agg["step_ms"] == pytest.approx(0.2)
    assert agg["failed"] == "diverged 1"
    assert not is_sweep(df[df["seed"] == 0])


def test_report_of_a_sweep_aggregates(tmp_path):
    rows = [("s", seed, "FRad-A", "order=5", st, 1.0 + seed, 0.1, 0.01, 0.0, "ok", 0, True)
            for seed in (0, 1) for st in (0, 1)]
    out = tmp_path / "res"
    write_results(out, {"runs.csv": pd.DataFrame(columns=["scenario"]),
                        "summary.csv": _summary(rows)}, {"config": {"title": "sweep"}})
    text = write_report(out, figures=False).read_text()
    assert "## s (2 seeds)" in text
    assert "| FRad-A | order=5 | 2 (2) | 1.5 | 0.7071 | 1 | 2 |" in text
