"""Shipped configurations by name (``setobs-bench run arch2021_table3``, ``list configs``),
also from a non-editable install outside the repository, and ``run_config``'s verdict in
Python (issue 28)."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest

from benchmarks import ConfigError, load_config, run_config
from benchmarks.cli import main
from benchmarks.run.shipped import resolve_config, shipped_configs
from benchmarks.verdicts import EXIT_CODES_HELP, EXIT_MEANINGS, BenchResult

ROOT = Path(__file__).resolve().parents[1]


def test_every_shipped_config_has_a_name():
    names = shipped_configs()
    on_disk = {p.relative_to(ROOT / "benchmarks" / "configs").with_suffix("").as_posix()
               for p in (ROOT / "benchmarks" / "configs").rglob("*.yaml")}
    assert set(names) == on_disk and "sweeps/seeds_3x22x20" in names
    assert resolve_config("arch2021_table3") == names["arch2021_table3"]
    assert resolve_config("arch2021_table3.yaml") == names["arch2021_table3"]
    assert resolve_config("benchmarks/configs/quick.yaml").name == "quick.yaml"


def test_a_local_file_wins_over_a_shipped_name(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    Path("quick").write_text("name: mine\nscenarios: [alamo2d]\nobservers: [FRad-A]\n")
    assert load_config("quick").name == "mine"
    with pytest.raises(ConfigError, match=r"no shipped config of that name; shipped: .*quick"):
        load_config("no_such_table")


def test_list_configs(capsys):
    assert main(["list", "configs"]) == 0
    out = capsys.readouterr().out
    assert "arch2021_table3" in out and "Linearised 6-tank system (ARCH 2021, Table 3)" in out


def test_run_a_shipped_config_by_name_with_some_of_its_observers(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # no benchmarks/configs/ here
    assert main(["run", "arch2021_table3", "--observer", "FRad-A", "--observer", "ESO-B",
                 "--out", "t3", "--no-progress"]) == 0
    summary = pd.read_csv(tmp_path / "t3" / "summary.csv")
    assert set(summary["observer"]) == {"FRad-A", "ESO-B", "ESO-B[cora]"}  # with its variant
    assert main(["run", "arch2021_table3", "--observer", "VolMin-A", "--out", "x"]) == 2


def test_run_config_returns_the_verdict():
    cfg = load_config(ROOT / "benchmarks" / "configs" / "quick.yaml")
    cfg.observers = ["FRad-A"]
    cfg.scenarios = cfg.scenarios[1:2]  # alamo2d
    cfg.instances = cfg.instances[1:2]
    result = run_config(cfg, progress=False)
    runs, summary = result  # still the pair
    assert isinstance(result, BenchResult) and result.summary is summary
    assert result.exit_code == 0 and result.ok and result.problems == []
    assert result.meaning == EXIT_MEANINGS[0] and result.meaning in EXIT_CODES_HELP
    bad = summary.assign(status="ok", contained_hull="no", violations=3)
    verdict = BenchResult(runs, bad)
    assert verdict.exit_code == 1 and not verdict.ok
    assert verdict.problems == ["CONTAINMENT VIOLATIONS: FRad-A on alamo2d"]


def _copy_sources(dst: Path) -> None:
    """The files a wheel is built from (no caches, no results)."""
    for name in ("pyproject.toml", "README.md", "LICENSE"):
        shutil.copy2(ROOT / name, dst / name)
    for pkg in ("observers", "systems", "benchmarks"):
        shutil.copytree(ROOT / pkg, dst / pkg, ignore=shutil.ignore_patterns(
            "__pycache__", "*.nbi", "*.nbc", "*.pyc"))


@pytest.mark.heavy
@pytest.mark.slow
def test_run_by_name_from_a_non_editable_install_outside_the_repository(tmp_path):
    src, target, work = tmp_path / "src", tmp_path / "site", tmp_path / "work"
    for d in (src, work):
        d.mkdir()
    _copy_sources(src)
    pip = [sys.executable, "-m", "pip", "install", "--quiet", "--no-deps",
           "--no-build-isolation", "--no-index", "--target", str(target), str(src)]
    done = subprocess.run(pip, capture_output=True, text=True, timeout=600)
    if done.returncode != 0 and "setuptools" in done.stderr:
        pytest.skip("no setuptools >= 77 to build the wheel (pip install -e '.[test]')")
    assert done.returncode == 0, done.stderr
    assert (target / "benchmarks" / "configs" / "arch2021_table3.yaml").is_file()
    assert (target / "benchmarks" / "configs" / "sweeps" / "seeds_3x22x20.yaml").is_file()
    # SETOBS_NUMBA=0: the fresh copy has no compiled kernels cached, and compiling them (a
    # minute or more) is not what this test is about
    env = {**os.environ, "PYTHONPATH": str(target), "SETOBS_NUMBA": "0"}
    script = target / "bin" / "setobs-bench"
    cmd = [sys.executable, str(script)] if script.is_file() else [
        sys.executable, "-c", "import sys; from benchmarks.cli import main; sys.exit(main())"]
    where = subprocess.run(cmd[:1] + ["-c", "import benchmarks; print(benchmarks.__file__)"],
                           capture_output=True, text=True, cwd=work, env=env, timeout=120)
    assert where.stdout.strip().startswith(str(target))  # the installed copy, not the repo's
    listed = subprocess.run(cmd + ["list", "configs"], capture_output=True, text=True,
                            cwd=work, env=env, timeout=300)
    assert listed.returncode == 0 and "arch2021_table3" in listed.stdout
    run = subprocess.run(cmd + ["run", "arch2021_table3", "--observer", "FRad-A",
                                "--observer", "FRad-C", "--out", "t3", "--no-progress"],
                         capture_output=True, text=True, cwd=work, env=env, timeout=600)
    assert run.returncode == 0, run.stderr
    summary = pd.read_csv(work / "t3" / "summary.csv")
    # an observer named with --observer runs with its labelled variants (Table 3 shows FRad-C
    # in CORA's kernel-dependent PCA basis beside it)
    assert set(summary["observer"]) == {"FRad-A", "FRad-C", "FRad-C[pca-cora]"}
    assert (summary["contained"] == "yes").all()
