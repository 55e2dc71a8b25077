"""The CI regression gate: `baseline --update` then `check`, against baselines in tmp dirs.

Acceptance: scaling an observer's gain by 1.01 makes the check fail with a diff naming the
observer and the states; restoring it passes.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml

import observers
from benchmarks.cli import main
from benchmarks.gate import regression
from observers import registry
from observers.builtin import frad
from observers.errors import DesignFailed
from observers.families import ConstantGainPropagationObserver
from observers.offline import OfflineGain

ROOT = Path(__file__).resolve().parents[1]


def subset(tmp_path, observers_=("FRad-A", "FRad-B", "FRad-C"), scenarios=None,
           file: str = "mini.yaml") -> Path:
    cfg = {"name": "mini", "title": "mini regression subset",
           "scenarios": scenarios or ["alamo2d", "vehicle2d-cora"],
           "observers": list(observers_), "containment": "hull"}
    path = tmp_path / file
    path.write_text(yaml.safe_dump(cfg))
    return path


def gate(tmp_path, command: str, cfg: Path, *extra: str) -> int:
    argv = [command, "--config", str(cfg), "--baseline", str(tmp_path / "baseline"),
            "--no-progress", *extra]
    if command == "check":
        argv += ["--out", str(tmp_path / "check")]
    elif "--update" in extra:
        argv += ["--kernels", "none"]  # the kernel sensitivity: tests/test_gate_everywhere.py
    return main(argv)


def perturb_frad_a(monkeypatch) -> None:
    """Make FRad-A's strip intersection 1 % wider (its generators times 1.01), as a changed
    algorithm would, at every step: FRad-A leaves its compiled kernel, which makes every set
    (the first too, since 0.12.0), for the numpy path, whose formula is widened (bug: with
    the first set compiled too the widened numpy formula ran nowhere and the check passed)."""
    monkeypatch.setattr(frad.FRadA, "KERNEL", None)
    original = frad.alamo_frad_strips

    def wider(*args):
        c, G = original(*args)
        return c, 1.01 * G

    monkeypatch.setattr(frad, "alamo_frad_strips", wider)


def test_perturbed_gain_fails_the_check_and_restoring_it_passes(tmp_path, capsys, monkeypatch):
    cfg = subset(tmp_path)
    assert gate(tmp_path, "baseline", cfg, "--update") == 0
    assert sorted(p.name for p in (tmp_path / "baseline").iterdir()) == [
        "SENSITIVITY.md", "alamo2d.csv", "cost.json", "meta.json", "vehicle2d-cora.csv"]
    assert gate(tmp_path, "check", cfg) == 0
    assert "check passed" in capsys.readouterr().out

    original = frad.alamo_frad_strips
    perturb_frad_a(monkeypatch)
    assert gate(tmp_path, "check", cfg) == 1
    captured = capsys.readouterr()
    table = captured.out
    own, _, follow = table.partition("moved only because the best observer")
    # the diff names the observer and every state whose radius changed ...
    for scenario, state in [("alamo2d", "x1"), ("alamo2d", "x2"), ("vehicle2d-cora", "beta"),
                            ("vehicle2d-cora", "yaw_rate")]:
        assert any(line.split()[:4] == [scenario, "FRad-A", state, "rms_radius"]
                   and "REGRESSION" in line for line in own.splitlines()), own
    assert "FRad-B" not in own and "FRad-C" not in own  # their own radii did not change
    assert "looser: FRad-A (" in captured.err.splitlines()[-1]
    diff = pd.read_csv(tmp_path / "check" / "diff.csv")
    assert set(diff.loc[~diff["ok"] & (diff["metric"] == "rms_radius"), "observer"]) == {
        "FRad-A"}

    monkeypatch.setattr(frad, "alamo_frad_strips", original)
    assert gate(tmp_path, "check", cfg) == 0


@pytest.fixture
def offline_observer():
    """A constant-gain observer with an 'offline design' (OfflineGain: REGRESSION_RTOL 1e-4)."""
    gain = {"L": np.array([[0.02], [0.01]])}

    @observers.register("Test-OfflineGate", family="propagation", set_type="zonotope",
                        ready_for_control=True)
    class OfflineGate(OfflineGain, ConstantGainPropagationObserver):
        """Constant gain from a stand-in 'solver' (test only)."""

        def design_gain(self):
            if gain["L"] is None:
                raise DesignFailed(f"{self.name}: the LMI is infeasible (test)")
            return gain["L"]

    yield gain
    registry.unregister("Test-OfflineGate")


def test_solver_dependent_designs_get_their_looser_documented_tolerance(tmp_path, capsys,
                                                                       offline_observer):
    assert regression.regression_rtol("FRad-A") == 1e-6
    assert regression.regression_rtol("Test-OfflineGate") == OfflineGain.REGRESSION_RTOL == 1e-4
    cfg = subset(tmp_path, ["FRad-A", "Test-OfflineGate"], ["vehicle2d-cora"])
    assert gate(tmp_path, "baseline", cfg, "--update") == 0
    stored = pd.read_csv(tmp_path / "baseline" / "vehicle2d-cora.csv")
    assert set(stored.groupby("observer")["rtol"].first().items()) == {
        ("FRad-A", 1e-6), ("Test-OfflineGate", 1e-4)}
    offline_observer["L"] = np.array([[0.02], [0.01]]) * (1 + 1e-6)  # solver-level noise
    assert gate(tmp_path, "check", cfg) == 0
    offline_observer["L"] = np.array([[0.02], [0.01]]) * 1.01  # a real change
    assert gate(tmp_path, "check", cfg) == 1
    assert "Test-OfflineGate" in capsys.readouterr().out
    offline_observer["L"] = None  # the design became infeasible: ok -> noGain
    assert gate(tmp_path, "check", cfg) == 1
    out = capsys.readouterr().out
    assert any(line.split()[:6] == ["vehicle2d-cora", "Test-OfflineGate", "-", "status", "ok",
                                    "noGain"] for line in out.splitlines()), out


def test_the_check_recomputes_designs_unless_asked_to_use_the_cache(tmp_path, monkeypatch,
                                                                   offline_observer):
    cache = tmp_path / "cache"
    monkeypatch.setenv("SETOBS_CACHE_DIR", str(cache))
    cfg = subset(tmp_path, ["Test-OfflineGate"], ["alamo2d"])
    assert gate(tmp_path, "baseline", cfg, "--update") == 0
    assert not cache.exists()  # recomputed, not cached
    meta = json.loads((tmp_path / "baseline" / "meta.json").read_text())
    assert meta["design_cache"] == "designs recomputed (SETOBS_CACHE_DIR=off)"
    assert gate(tmp_path, "check", cfg, "--use-cache") == 0
    assert list(cache.glob("Test-OfflineGate-*.npz"))
    import os

    assert os.environ["SETOBS_CACHE_DIR"] == str(cache)  # restored after the run


def test_new_missing_and_reconfigured_observers_fail_the_check(tmp_path, capsys):
    cfg = subset(tmp_path, ["FRad-A", "FRad-B"], ["alamo2d"])
    assert gate(tmp_path, "baseline", cfg, "--update") == 0
    more = subset(tmp_path, ["FRad-A", "FRad-B", "FRad-C"], ["alamo2d"], "more.yaml")
    assert gate(tmp_path, "check", more) == 1  # config changed since the baseline
    assert "changed since the baseline" in capsys.readouterr().err
    # same config text, but one baseline observer is no longer run / a new one appears
    base = tmp_path / "baseline" / "alamo2d.csv"
    df = pd.read_csv(base)
    df.loc[df["observer"] == "FRad-B", "observer"] = "FRad-Old"
    df.to_csv(base, index=False)
    assert gate(tmp_path, "check", cfg) == 1
    out = capsys.readouterr().out
    assert "FRad-Old" in out and "in the baseline but not run now" in out
    assert "FRad-B" in out and "not in the baseline" in out


def test_baseline_refuses_an_unsound_or_crashing_observer(tmp_path, capsys):
    @observers.register("Test-Unsound", family="strip", set_type="zonotope",
                        ready_for_control=False)
    class Unsound(frad.FRadA):
        """Reports only the centre of FRad-A's set (test only)."""

        def step(self, u_prev, y):
            from observers.sets import Zonotope

            return Zonotope(super().step(u_prev, y).c)

    try:
        cfg = subset(tmp_path, ["FRad-A", "Test-Unsound"], [{"name": "alamo2d-sim", "seed": 1}])
        assert gate(tmp_path, "baseline", cfg, "--update") == 1
        assert "Test-Unsound violates containment on alamo2d-sim" in capsys.readouterr().err
        assert not (tmp_path / "baseline").exists()
        assert gate(tmp_path, "baseline", cfg, "--update", "--force") == 1  # never enshrined
    finally:
        registry.unregister("Test-Unsound")


def test_malformed_baseline_is_a_one_line_error(tmp_path, capsys):
    cfg = subset(tmp_path, ["FRad-A"], ["alamo2d"])
    (tmp_path / "baseline").mkdir()
    (tmp_path / "baseline" / "alamo2d.csv").write_text("scenario,observer\nalamo2d,FRad-A\n")
    assert gate(tmp_path, "check", cfg) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("error: baseline file") and "lacks column(s)" in err
    assert len(err.splitlines()) == 1


def test_committed_baseline_matches_the_regression_subset():
    """results/baseline/ holds one golden file per scenario of configs/regression.yaml."""
    frame, meta = regression.load_baseline(ROOT / "results" / "baseline")
    cfg = regression.subset_config()
    assert set(frame["scenario"]) == {sc.name for sc in cfg.scenarios}
    assert not regression.config_changed(cfg, meta)
    assert {"FRad-A", "FRad-B", "FRad-C"} <= set(frame["observer"])
    ok = frame[(frame["status"] == "ok") & frame["guaranteed"].astype(bool)]  # eq. (9) minima
    assert ok["rms_radius"].gt(0).all() and ok.groupby(["scenario", "state"])[
        "rel_rms"].min().round(12).eq(1.0).all()


def test_a_containment_failure_fails_the_check(tmp_path, capsys, monkeypatch):
    cfg = subset(tmp_path, ["FRad-A"], [{"name": "alamo2d-sim", "seed": 2, "noise": "vertex"}])
    assert gate(tmp_path, "baseline", cfg, "--update") == 0
    step = frad.FRadA.step

    def shrunk(self, u_prev, y):
        from observers.sets import Zonotope

        S = step(self, u_prev, y)
        return Zonotope(S.c, 0.3 * S.G)

    monkeypatch.setattr(frad.FRadA, "step", shrunk)
    assert gate(tmp_path, "check", cfg) == 1
    rows = [line.split() for line in capsys.readouterr().out.splitlines()]
    assert any(r[:6] == ["alamo2d-sim", "FRad-A", "-", "violations", "0"] + r[5:6]
               and r[5] != "0" and "containment" in r for r in rows), rows


def test_a_failing_check_names_environment_differences_from_the_baseline(tmp_path, capsys,
                                                                         monkeypatch):
    cfg = subset(tmp_path, observers_=("FRad-A",), scenarios=["alamo2d"])
    assert gate(tmp_path, "baseline", cfg, "--update") == 0
    meta_path = tmp_path / "baseline" / "meta.json"
    meta = json.loads(meta_path.read_text())
    assert meta["versions"]["blas_coretype"]  # recorded with the baseline
    meta["versions"]["blas_coretype"] = "Prescott"
    meta_path.write_text(json.dumps(meta))
    assert gate(tmp_path, "check", cfg) == 0  # equal results: no note needed
    capsys.readouterr()
    perturb_frad_a(monkeypatch)
    assert gate(tmp_path, "check", cfg) == 1
    err = capsys.readouterr().err
    assert "environment differs from the baseline's (blas_coretype: Prescott -> " in err
    assert regression.environment_differences(meta, meta["versions"]) == []
