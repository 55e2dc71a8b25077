"""Labelled variants in benchmark configurations: the same observer twice, under its own label."""

from __future__ import annotations

import pytest

from benchmarks import run_config, write_report
from benchmarks.errors import ConfigError
from benchmarks.run.config import parse_config


def cfg(variants):
    return parse_config({"name": "v", "scenarios": ["vehicle2d-cora"],
                         "observers": ["FRad-A", "FRad-B"], "containment": "hull",
                         "variants": variants}, "v")


def test_variant_runs_beside_its_observer_with_its_options_and_guarantee(tmp_path):
    c = cfg({"FRad-B[textbook]": {"observer": "FRad-B", "options": {"variant": "textbook"}},
             "FRad-A[ng]": {"observer": "FRad-A", "guaranteed": False}})
    assert c.observers == ["FRad-A", "FRad-B", "FRad-B[textbook]", "FRad-A[ng]"]
    assert c.options_for("FRad-B[textbook]", c.scenarios[0])["variant"] == "textbook"
    assert "variant" not in c.options_for("FRad-B", c.scenarios[0])
    _, summary = run_config(c, tmp_path)
    first = summary.groupby("observer").first()
    assert bool(first.loc["FRad-B"]["guaranteed"])
    assert not bool(first.loc["FRad-A[ng]"]["guaranteed"])
    # a different option gives different radii; the same observer unlabelled gives the same
    assert first.loc["FRad-B[textbook]"]["rms_radius"] != first.loc["FRad-B"]["rms_radius"]
    assert first.loc["FRad-A[ng]"]["rms_radius"] == first.loc["FRad-A"]["rms_radius"]
    text = write_report(tmp_path).read_text()
    assert "| FRad-A[ng] |" in text and "not guaranteed" in text
    # the row of a variant follows its observer's row
    assert text.index("| FRad-A |") < text.index("| FRad-A[ng] |") < text.index("| FRad-B |")


@pytest.mark.parametrize("variants, message", [
    ({"X[a]": {"observer": "Nope"}}, "variant X\\[a\\]: unknown observer"),
    ({"X[a]": {"options": {}}}, "must be a mapping with an 'observer' key"),
    ({"X[a]": {"observer": "FRad-B", "options": {"bogus": 1}}}, "no option"),
    ({"X[a]": {"observer": "FRad-B", "guaranteed": "no"}}, "'guaranteed' must be true"),
    ({"FRad-A": {"observer": "FRad-B"}}, "are observer names"),
    (["X"], "'variants' must be a mapping"),
])
def test_bad_variants_are_one_line_config_errors(variants, message):
    with pytest.raises(ConfigError, match=message):
        cfg(variants)
