"""Runner, metrics (eq. 9), report and the CLI's handling of bad configs."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml

import observers
from benchmarks import load_config, run_config, write_report
from benchmarks.cli import main
from benchmarks.metrics import add_relative_rms, median_ms, rms_radius

INLINE = {
    "name": "toy",
    "system": {"A": [[0.9, 0.1], [0.0, 0.8]], "B": [[0.0], [1.0]], "C": [[1.0, 0.0]],
               "W": {"box": [0.01, 0.01]}, "V": {"box": [0.1]},
               "X0": {"center": [0, 0], "generators": [[1, 0], [0, 1]]}},
    "simulate": {"steps": 30, "seed": 1},
    "options": {"order": 10, "reduction": "girard"},
}


def write_cfg(tmp_path, cfg, name="cfg.yaml"):
    path = tmp_path / name
    path.write_text(yaml.safe_dump(cfg))
    return path


def test_eq9_relative_rms_hand_example():
    r = np.array([[1.0, 2.0], [3.0, 2.0]])  # two steps, two states
    np.testing.assert_allclose(rms_radius(r), [np.sqrt(5.0), 2.0])
    s = pd.DataFrame({"scenario": "s", "observer": ["a", "a", "b", "b", "c", "c"],
                      "state": [0, 1] * 3, "rms_radius": [2.0, 4.0, 1.0, 8.0, 0.5, 0.1],
                      "status": ["ok"] * 4 + ["diverged"] * 2, "guaranteed": True})
    out = add_relative_rms(s)
    np.testing.assert_allclose(out["rel_rms"][:4], [2.0, 1.0, 1.0, 2.0])
    assert out["rel_rms"][4:].isna().all()  # failed observers are not in the minimum
    assert median_ms(np.array([1.0] * 5 + [0.002, 0.001, 0.003] * 20)) == pytest.approx(2.0)


def test_run_writes_runs_summary_and_report(tmp_path):
    cfg_path = write_cfg(tmp_path, {"scenarios": ["vehicle2d-cora", INLINE],
                                    "observers": ["FRad-A", "FRad-B", "FRad-C"],
                                    "observer_options": {"FRad-B": {"variant": "textbook"}}})
    out = tmp_path / "res"
    assert main(["run", str(cfg_path), "--out", str(out), "--no-progress"]) == 0
    runs = pd.read_csv(out / "runs.csv")
    summary = pd.read_csv(out / "summary.csv")
    for col in ("scenario", "observer", "state", "rms_radius", "rel_rms", "step_ms", "design_s",
                "contained", "status"):
        assert col in summary.columns
    assert len(runs) == 3 * (100 * 2 + 30 * 2)
    assert set(runs.columns) >= {"lo", "hi", "radius", "x_true", "contained", "step"}
    best = summary.groupby(["scenario", "state"])["rel_rms"].min()
    np.testing.assert_allclose(best, 1.0)
    toy = summary[summary["scenario"] == "toy"]
    assert (toy["contained"] == "yes").all() and (toy["violations"] == 0).all()
    cora = summary[summary["scenario"] == "vehicle2d-cora"]  # no true states in CORA's record
    assert cora["violations"].isna().all()
    literal = pd.read_csv(out / "summary.csv", keep_default_na=False)  # pandas reads n/a as NaN
    assert set(literal.loc[literal["scenario"] == "vehicle2d-cora", "contained"]) == {"n/a"}
    assert main(["report", str(out)]) == 0
    text = (out / "report.md").read_text()
    assert "| FRad-A |" in text and (out / "report_figures" / "toy" / "FRad-A.png").is_file()


def test_report_shows_published_values_beside_ours(tmp_path):
    cfg = load_config(write_cfg(tmp_path, {"scenarios": ["tank6-linear"],
                                           "observers": ["FRad-A"], "containment": "hull"}))
    run_config(cfg, tmp_path / "r", progress=False)
    text = write_report(tmp_path / "r", figures=False).read_text()
    assert "(1.06)" in text  # FRad-A v1 of ARCH 2021 Table 3
    assert "(0.3812)" in text  # its absolute radius: 1.060 x 0.3596


@pytest.mark.parametrize(
    ("cfg", "message"),
    [
        ({"scenarios": ["vehicle2d-cora"], "observers": ["FRad-Z"]},
         "unknown observer 'FRad-Z'"),
        ({"scenarios": ["vehicle2d-cora"], "observers": ["FRad-A"],
          "observer_options": {"FRad-A": {"gain": 1}}}, "FRad-A has no option"),
        ({"scenarios": ["nowhere"], "observers": ["FRad-A"]}, "unknown scenario 'nowhere'"),
        ({"scenarios": [dict(INLINE, system=dict(INLINE["system"], B=[[0.0], [1.0], [2.0]]))],
          "observers": ["FRad-A"]}, r"B has shape \(3, 1\), expected \(2, \*\)"),
        ({"scenarios": [{"name": "nan", "system": INLINE["system"],
                         "y": [[0.1], [float("nan")], [0.2]]}], "observers": ["FRad-A"]},
         r"scenario 'nan': y\[1, 0\] is not finite"),
        ({"scenarios": [dict(INLINE, system=dict(INLINE["system"], V={"box": []}))],
          "observers": ["FRad-A"]}, "V: the box is empty"),
        ({"scenarios": ["vehicle2d-cora"], "observers": ["FRad-A"], "colour": "red"},
         "unknown key"),
        ({"scenarios": ["vehicle2d-cora"], "observers": ["FRad-A"], "options": {"order": -1}},
         "order must be a finite number >= 1"),
    ],
)
def test_bad_configs_end_with_one_line_error(tmp_path, capsys, cfg, message):
    path = write_cfg(tmp_path, cfg)
    assert main(["run", str(path), "--out", str(tmp_path / "o"), "--no-progress"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("error: ") and len(err.splitlines()) == 1
    assert re.search(message, err), err


def test_malformed_yaml_and_missing_file(tmp_path, capsys):
    bad = tmp_path / "bad.yaml"
    bad.write_text("scenarios: [vehicle2d-cora\nobservers: all\n")
    assert main(["run", str(bad)]) == 2
    err = capsys.readouterr().err
    assert "malformed YAML (line" in err and len(err.strip().splitlines()) == 1
    assert main(["run", str(tmp_path / "missing.yaml")]) == 2
    assert "config file not found" in capsys.readouterr().err


def test_failed_run_leaves_previous_results_untouched(tmp_path):
    good = write_cfg(tmp_path, {"scenarios": ["vehicle2d-cora"], "observers": ["FRad-A"]})
    out = tmp_path / "res"
    assert main(["run", str(good), "--out", str(out), "--no-progress"]) == 0
    before = (out / "summary.csv").read_bytes()
    bad = write_cfg(tmp_path, {"scenarios": ["vehicle2d-cora"], "observers": ["Nope"]}, "b.yaml")
    assert main(["run", str(bad), "--out", str(out), "--no-progress"]) == 2
    assert (out / "summary.csv").read_bytes() == before
    assert not list(out.glob(".*tmp"))


def test_shipped_configs_are_valid():
    for path in sorted((Path(__file__).parents[1] / "benchmarks" / "configs").glob("*.yaml")):
        cfg = load_config(path)
        assert cfg.scenarios and cfg.observers, path


def test_scenario_defaults_apply_only_to_declared_options(monkeypatch):
    # the CORA scenarios set order 100 for the papers' zonotope observers; the data-driven
    # observers declare order and reduction as scenario options (issue 18: the paper's 5
    # boxes away the 6-tank); an observer that declares none keeps its own default
    cfg = load_config(Path(__file__).parents[1] / "benchmarks" / "configs" / "quick.yaml")
    sc = next(s for s in cfg.scenarios if s.name == "tank6-linear")
    assert cfg.options_for("FRad-A", sc)["order"] == 100
    assert cfg.options_for("DD-CZ-A1", sc)["order"] == 100
    assert cfg.options_for("DD-CZ-A2", sc)["reduction"] == "pca"
    monkeypatch.setattr(observers.get("DD-CZ-A1").cls, "SCENARIO_OPTIONS", ())
    assert "order" not in cfg.options_for("DD-CZ-A1", sc)
    cfg.observer_options["DD-CZ-A1"] = {"order": 7}
    assert cfg.options_for("DD-CZ-A1", sc)["order"] == 7


def test_linear_model_observers_are_unsupported_on_nonlinear_systems(tmp_path):
    cfg = load_config(write_cfg(tmp_path, {"scenarios": [{"name": "tank6-nonlinear",
                                                          "steps": 20}],
                                           "observers": ["PRad-B"], "containment": "hull"}))
    _, summary = run_config(cfg, progress=False)
    assert set(summary["status"]) == {"unsupported"}
    assert "missing: A, B" in summary["message"].iloc[0]


def test_nonlinear_capable_observers_run_on_nonlinear_systems(tmp_path):
    cfg = load_config(write_cfg(tmp_path, {"scenarios": [{"name": "tank6-nonlinear",
                                                          "steps": 20}],
                                           "observers": ["FRad-A", "FRad-C"],
                                           "containment": "hull"}))
    _, summary = run_config(cfg, progress=False)
    assert set(summary["status"]) == {"ok"}
    assert (summary["contained_hull"] == "yes").all() and (summary["violations"] == 0).all()


def test_paper_relative_uses_only_the_observers_the_paper_compares():
    from benchmarks.report.tables import paper_relative

    df = pd.DataFrame({"observer": ["A", "A", "B", "B", "X", "X"], "state": [0, 1] * 3,
                       "rms_radius": [2.0, 4.0, 1.0, 8.0, 0.5, 0.1], "status": "ok",
                       "guaranteed": True})
    np.testing.assert_allclose(paper_relative(df, {"A", "B"}), [2.0, 1.0, 1.0, 2.0, 0.5, 0.025])
