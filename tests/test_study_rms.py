"""The studies take the RMS radius from its one definition, benchmarks.metrics.rms_radius (no
study recomputes it by hand): exact_check's ratio of an observer to a reference of exactly
twice its radius is exactly 1/2 (powers of two scale the mean of squares and its root
exactly)."""

from __future__ import annotations

import ast
from pathlib import Path

import numpy as np

import observers
import systems
from benchmarks.studies import exact_check

STUDIES = Path(__file__).resolve().parents[1] / "benchmarks" / "studies"


def _hand_rms(tree: ast.AST) -> list[int]:
    """Lines of ``sqrt(mean(...))`` calls (an RMS written out) in a module."""
    out = []
    for node in ast.walk(tree):
        if (isinstance(node, ast.Call) and getattr(node.func, "attr", None) == "sqrt"
                and node.args and isinstance(node.args[0], ast.Call)
                and getattr(node.args[0].func, "attr", None) == "mean"):
            out.append(node.lineno)
    return out


def test_no_study_writes_the_rms_radius_out():
    found = {p.name: _hand_rms(ast.parse(p.read_text())) for p in sorted(STUDIES.glob("*.py"))}
    assert {name: lines for name, lines in found.items() if lines} == {}


def test_exact_check_ratio_of_twice_the_radius_is_one_half():
    sc = systems.scenario("tank6-linear", seed=0)
    info = observers.get("FRad-B")  # the options exact_check gives it
    opts = {k: v for k, v in sc.options.items() if k in info.option_defaults()
            and (info.scenario_options is None or k in info.scenario_options)}
    res = observers.run(observers.create("FRad-B", sc.system, **opts), sc.u, sc.y,
                        keep_sets=False)
    c = np.zeros_like(res.radius)
    hulls = {"filt_lo": c - 2.0 * res.radius, "filt_hi": c + 2.0 * res.radius}
    hulls.update(pred_lo=hulls["filt_lo"], pred_hi=hulls["filt_hi"])
    assert exact_check.ratios(sc, hulls, ["FRad-B"]) == {
        "FRad-B": "0.5 (states 0.5-0.5, filtered)"}
