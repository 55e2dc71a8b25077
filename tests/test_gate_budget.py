"""The regression gate's time budget per job (:mod:`benchmarks.gate.budget`): derived from the
job costs recorded beside the golden files (``cost.json``), a documented fallback without
them, one-line errors for a corrupted file, and a plugin that hangs in ``step()`` stopped by
its budget and named by ``check``."""

from __future__ import annotations

import importlib
import json
import shutil
from pathlib import Path

import pandas as pd
import pytest
import yaml

import observers
from benchmarks.cli import main
from benchmarks.errors import ConfigError
from benchmarks.gate import budget, policy, regression
from observers import registry

ROOT = Path(__file__).resolve().parents[1]
COMMITTED = ROOT / "results" / "baseline"


def _write_costs(folder: Path, seconds) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / budget.COST_FILE
    path.write_text(json.dumps({"created": "2026-12-03T00:00:00+00:00", "seconds": seconds}))
    return path


# -- the arithmetic ---------------------------------------------------------------------------
def test_budgets_from_a_cost_file_hand_derived(tmp_path):
    _write_costs(tmp_path, {"a": {"X": 0.2, "Y": 0.65, "Z": 3.0},
                            "b": {"X": 0.1},
                            "d": {"X": 2.0}})
    b = budget.load_costs(tmp_path)
    # recorded: 20 x the cost, rounded up to a whole second, at least 10 s
    assert b.of("a", "X").seconds == 10  # 20 x 0.2 = 4 -> the minimum
    assert b.of("a", "Y").seconds == 13  # 20 x 0.65 = 13 (not 14: no rounding noise)
    assert b.of("a", "Z").seconds == 60  # 20 x 3.0
    assert b.of("d", "X").seconds == 40  # 20 x 2.0
    assert b.of("a", "Z").basis == "20x its recorded 3 s"
    assert b.of("a", "X").basis.startswith("the minimum")
    # not recorded: 20 x the median job of its scenario, within 10-15 s
    assert b.of("a", "Plugin").seconds == 13  # median of a: 0.65 -> 13
    assert b.of("b", "Plugin").seconds == 10  # median of b: 0.1 -> 2 -> the minimum
    assert b.of("d", "Plugin").seconds == 15  # median of d: 2.0 -> 40 -> the cap
    assert "median recorded job of a (0.65 s)" in b.of("a", "Plugin").basis
    # a new scenario: the median of every recorded job (0.1, 0.2, 0.65, 2, 3) -> 13
    assert b.of("c", "X").seconds == 13
    assert "every scenario" in b.of("c", "X").basis
    _write_costs(tmp_path, {"a": {"X": 0.2, "Y": 0.3}, "b": {"X": 0.1, "Y": 0.5}})
    # every recorded job: 0.1, 0.2, 0.3, 0.5 -> median 0.25 -> 5 -> the minimum
    assert budget.load_costs(tmp_path).of("new", "P").seconds == 10
    assert budget.load_costs(tmp_path).of("a", "P").seconds == 10  # (0.2 + 0.3) / 2 -> 5
    assert budget.load_costs(tmp_path).of("b", "P").seconds == 10  # 0.3 -> 6
    _write_costs(tmp_path, {"a": {"X": 0.7, "Y": 0.74, "Z": 0.6}})
    assert budget.load_costs(tmp_path).of("new", "P").seconds == 14  # 20 x 0.7


def test_a_hanging_plugin_adds_at_most_two_minutes_to_the_committed_gate():
    """Each of the subset's scenarios gives a plugin without a recorded cost at most
    NEW_JOB_MAX_BUDGET_S, and the committed cost file covers every golden job."""
    costs = budget.load_costs(COMMITTED)
    assert costs is not None, "results/baseline/cost.json: `baseline --record-cost`"
    raw = yaml.safe_load(regression.DEFAULT_CONFIG.read_text())
    names = [s if isinstance(s, str) else s.get("label", s["name"]) for s in raw["scenarios"]]
    assert sum(costs.of(sc, "Some-Plugin").seconds for sc in names) <= 120
    golden, _ = regression.load_baseline(COMMITTED)
    pairs = set(zip(golden["scenario"], golden["observer"], strict=True))
    recorded = {(sc, o) for sc, per in costs.seconds.items() for o in per}
    assert pairs == recorded


# -- a missing or corrupted cost file ---------------------------------------------------------
@pytest.fixture
def mini_cfg(tmp_path):
    path = tmp_path / "mini.yaml"
    path.write_text(yaml.safe_dump({"name": "mini", "observers": ["FRad-A"],
                                    "containment": "hull",
                                    "scenarios": [{"name": "alamo2d-sim", "steps": 10}]}))
    return path


def test_without_a_cost_file_every_job_gets_the_fixed_budget_and_a_note(tmp_path, mini_cfg):
    assert budget.load_costs(tmp_path) is None
    res = policy.Outcome()
    ex = policy._gate_executor(res, regression.subset_config(mini_cfg), tmp_path)
    assert ex.budgets is None and ex.fixed.startswith("no cost.json")
    [(to_err, note)] = res.messages
    assert to_err and note.startswith("note: no job costs in ") and "300 s" in note
    assert "--record-cost" in note


def test_a_timeout_in_the_configuration_wins_over_the_costs(tmp_path, mini_cfg):
    _write_costs(tmp_path, {"alamo2d-sim": {"FRad-A": 0.01}})
    cfg = regression.subset_config(mini_cfg)
    assert policy._gate_executor(policy.Outcome(), cfg, tmp_path).budgets is not None
    cfg.raw["timeout"] = 42
    res = policy.Outcome()
    ex = policy._gate_executor(res, cfg, tmp_path)
    assert ex.budgets is None and "configuration" in ex.fixed and not res.messages


@pytest.mark.parametrize(("text", "why"), [
    ("{not json", "not JSON"),
    ('{"seconds": []}', "no 'seconds' mapping"),
    ('["a"]', "no 'seconds' mapping"),
    ('{"seconds": {}}', "no job recorded"),
    ('{"seconds": {"a": {"X": -1}}}', "X on a: -1 is not a number of seconds"),
    ('{"seconds": {"a": {"X": "fast"}}}', "X on a: 'fast' is not"),
    ('{"seconds": {"a": {"X": NaN}}}', "X on a: nan is not"),
])
def test_a_corrupted_cost_file_is_a_one_line_error(tmp_path, text, why):
    (tmp_path / budget.COST_FILE).write_text(text)
    with pytest.raises(ConfigError) as err:
        budget.load_costs(tmp_path)
    msg = str(err.value)
    assert len(msg.splitlines()) == 1 and why in msg and str(tmp_path / "cost.json") in msg
    assert msg.endswith("rewrite them with `python -m benchmarks baseline --record-cost`")


def test_check_with_a_corrupted_cost_file_exits_2_before_running(tmp_path, capsys):
    folder = tmp_path / "baseline"
    shutil.copytree(COMMITTED, folder)
    (folder / budget.COST_FILE).write_text("{}")
    code = main(["check", "--baseline", str(folder), "--out", str(tmp_path / "o"),
                 "--no-progress"])
    err = capsys.readouterr().err
    assert code == 2 and err.startswith("error: job costs ") and len(err.splitlines()) == 1
    assert not (tmp_path / "o").exists()  # nothing ran


# -- end to end: a plugin that hangs in step() ----------------------------------------------
@pytest.fixture
def sleeper():
    """Register Test-Sleep (its ``step`` sleeps for ever) for the test's duration."""
    import tests.plugins.sleeper as mod

    importlib.reload(mod)
    yield "Test-Sleep"
    registry.unregister("Test-Sleep", missing_ok=True)


def test_a_plugin_hanging_in_step_is_stopped_by_its_budget_and_named(tmp_path, sleeper,
                                                                     capsys):
    keep = {"FRad-A", sleeper}
    cfg = {"name": "mini", "observers": "all", "containment": "hull",
           "exclude": [i.name for i in observers.available() if i.name not in keep],
           "scenarios": [{"name": "alamo2d-sim", "seed": 1, "steps": 20},
                         {"name": "alamo2d-sim", "seed": 2, "steps": 20, "label": "other"}]}
    path = tmp_path / "mini.yaml"
    path.write_text(yaml.safe_dump(cfg))
    base, out = tmp_path / "baseline", tmp_path / "check"
    common = ["--config", str(path), "--baseline", str(base), "--no-progress"]
    assert main(["baseline", *common, "--update", "--kernels", "none"]) == 0
    assert "cost.json" in capsys.readouterr().out
    costs = json.loads((base / budget.COST_FILE).read_text())
    assert set(costs["seconds"]) == {"alamo2d-sim", "other"}  # plugins left out
    assert all(set(per) == {"FRad-A"} for per in costs["seconds"].values())
    assert costs["executor"] == "serial" and costs["commit"] is not None
    budgets = budget.load_costs(base)

    assert main(["check", *common, "--out", str(out)]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    summary = pd.read_csv(out / "summary.csv").drop_duplicates(["scenario", "observer"])
    stopped = summary[summary["observer"] == sleeper].set_index("scenario")
    for sc in ("alamo2d-sim", "other"):
        b = budgets.of(sc, sleeper)
        assert b.seconds < budget.GATE_TIMEOUT  # not the old 300 s per job
        assert stopped.loc[sc, "status"] == "timeout"
        assert stopped.loc[sc, "message"] == f"stopped after the budget of {b.seconds:g} s"
        line = (f"TIMEOUT: plugin {sleeper} on {sc}: stopped after its budget of "
                f"{b.seconds:g} s (no recorded cost: 20x the median recorded job of {sc} ")
        assert sum(e.startswith(line) for e in err) == 1, err
    ok = summary[summary["observer"] == "FRad-A"]
    assert (ok["status"] == "ok").all()  # its own budget (recorded) let it finish
    assert err[-1].startswith("check FAILED") and "plugins failing: " in err[-1]
    assert f"{sleeper} on alamo2d-sim: status timeout" in err[-1]
