"""Issue 27, "trust, round three": nothing a plugin does can hang, kill or fool a run or the
gate.  The misbehaving plugins are ``tests/plugins/misbehave.py`` (importable by workers, as
an installed plugin package would be), run through the real command line and executors."""

from __future__ import annotations

import importlib

import pandas as pd
import pytest
import yaml

from benchmarks.cli import main
from benchmarks.verdicts import EXIT_CRASH
from observers import registry


@pytest.fixture
def misbehaving():
    """Register Test-Hang, Test-Exit, Test-Leak and Test-Lie (and remove them after)."""
    import tests.plugins.misbehave as mod

    importlib.reload(mod)
    yield mod.NAMES
    for name in mod.NAMES:
        registry._REGISTRY.pop(name, None)


def _cfg(tmp_path, observers, name="bad", steps=12, **extra) -> str:
    cfg = {"name": name, "scenarios": [{"name": "alamo2d-sim", "steps": steps}],
           "observers": observers, "containment": "hull", **extra}
    path = tmp_path / f"{name}.yaml"
    path.write_text(yaml.safe_dump(cfg))
    return str(path)


def _pairs(out) -> pd.DataFrame:
    s = pd.read_csv(out / "summary.csv", keep_default_na=False)
    return s.drop_duplicates(["observer"]).set_index("observer")


# -- defects 1 and 2: a hanging, crashing or leaking plugin is its own row ------------------
@pytest.mark.parametrize("executor", [[], ["--jobs", "2"], ["--executor", "dask", "--jobs", "2"]],
                         ids=["serial", "jobs2", "dask"])
def test_hanging_exiting_and_leaking_plugins_become_rows_and_the_run_completes(
        tmp_path, misbehaving, executor, capsys):
    if "dask" in executor:
        pytest.importorskip("distributed")
    cfg = _cfg(tmp_path, ["FRad-A", "Test-Hang", "Test-Exit", "Test-Leak"])
    out = tmp_path / "out"
    code = main(["run", cfg, "--out", str(out), "--no-progress", "--timeout", "12",
                 "--memory-limit", "1500M", *executor])
    assert code == EXIT_CRASH
    pairs = _pairs(out)
    assert pairs.loc["FRad-A", "status"] == "ok"
    assert pairs.loc["Test-Hang", "status"] == "timeout"
    assert pairs.loc["Test-Exit", "status"] == "error"
    assert "exit code 9" in pairs.loc["Test-Exit", "message"]
    assert pairs.loc["Test-Leak", "status"] == "memory"
    err = capsys.readouterr().err
    assert "STOPPED: " in err and "Test-Hang on alamo2d-sim (timeout" in err
    assert "Test-Leak on alamo2d-sim (memory" in err
    assert "Test-Exit on alamo2d-sim" in err.split("CRASHED: ")[1]


def test_timeout_and_memory_limit_from_the_config_and_refused_when_malformed(
        tmp_path, misbehaving, capsys):
    cfg = _cfg(tmp_path, ["Test-Hang"], timeout=3, memory_limit="2G")
    out = tmp_path / "out"
    assert main(["run", cfg, "--out", str(out), "--no-progress"]) == EXIT_CRASH
    assert _pairs(out).loc["Test-Hang", "message"] == "stopped after the budget of 3 s"
    capsys.readouterr()
    for bad in ({"timeout": -1}, {"timeout": "soon"}, {"memory_limit": "lots"}):
        assert main(["run", _cfg(tmp_path, ["FRad-A"], name="b", **bad), "--out",
                     str(tmp_path / "b"), "--no-progress"]) == 2
        assert capsys.readouterr().err.startswith("error: config 'b': ")
    assert main(["run", cfg, "--out", str(out), "--timeout", "0", "--no-progress"]) == 2
    assert "--timeout" in capsys.readouterr().err
