"""One notation per table column (issue 28: ``0.4353`` beside ``4.970e-04`` in one column),
checked on hand-made columns and on the cells of a report table."""

from __future__ import annotations

import re

import pandas as pd
import pytest

from benchmarks.report.numbers import Num, column_notation, fmt, format_columns, markdown_table
from benchmarks.report.tables import scenario_table_data

NUMBER = re.compile(r"[-+]?\d*\.?\d+(e[-+]\d+)?")


def test_fmt_notations_by_hand():
    assert fmt(0.43527, notation="plain") == "0.4353"
    assert fmt(4.97e-4, notation="plain") == "0.000497"
    assert fmt(6.331, notation="sci") == "6.331e+00"
    assert fmt(123456.0, notation="plain") == "123456"
    assert fmt(1.0, notation="plain") == "1" and fmt(0.0, notation="sci") == "0"
    assert fmt(float("nan"), notation="plain") == "n/a"
    with pytest.raises(ValueError, match="notation"):
        fmt(1.0, notation="fixed")


def test_a_column_is_plain_or_scientific_throughout():
    assert column_notation([0.4353, 4.97e-4, 12.0, None, float("nan")]) == "plain"
    assert column_notation([0.4353, 2e-6]) == "sci"
    assert column_notation([0.5, 3e7]) == "sci"
    rows = format_columns([["a", Num(0.4353), Num(1.5, paper=1.06)],
                           ["b", Num(4.97e-4), Num(2e-6, note="n/a")],
                           ["c", Num(None), "text"]])
    assert rows == [["a", "0.4353", "1.500e+00 (1.060e+00)"],
                    ["b", "0.000497", "2.000e-06 (n/a)"],
                    ["c", "n/a", "text"]]
    assert markdown_table(["x", "y"], [[Num(0.5), Num(5e-7)]]).endswith(
        "| 0.5 | 5.000e-07 |")


def test_report_table_columns_have_one_notation():
    # a design-time column spanning 4e-5 .. 6.3 s and a hull column with 1.6e-4 (the issue's
    # example mixed 4.442e-04 with 0.01582 in one column)
    rows = []
    for k, (obs, design, hull) in enumerate([("FRad-A", 4.3e-5, 0.0156), ("PRad-E", 6.331, 1.6e-4),
                                             ("CZN-A", 0.0158, 0.23)]):
        for state in (0, 1):
            rows.append({"scenario": "s", "observer": obs, "state": state, "rms_radius": 1.0 + k,
                         "rel_rms": 1.0 + k, "step_ms": 0.01 * (k + 1), "hull_ms": hull,
                         "design_s": design, "status": "ok", "guaranteed": True,
                         "contained": "n/a", "violations": None, "failed_step": None,
                         "message": None, "timed": "serial", "seed": None, "variant": None})
    head, cells = scenario_table_data(pd.DataFrame(rows), {"scenarios": {"s": {"n": 2}}})
    for j, name in enumerate(head):
        if name in ("Observer", "contained"):
            continue
        column = [row[j] for row in cells]
        kinds = {"e" in c for c in column}
        assert len(kinds) == 1, (name, column)  # all scientific or all plain
    assert [row[head.index("design s")] for row in cells] == ["0.000043", "0.0158", "6.331"]
