"""`setobs-bench run CONFIG --add NAME`: a plugin ranked beside the stored rows, from a
non-editable install outside the repository, running only the plugin's rows."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import pandas as pd
import pytest

ROOT = Path(__file__).resolve().parents[1]

PLUGIN = '''
"""My-Obs: FRad-A with every set scaled by 1.5 about its centre (sound, and looser)."""
import observers
from observers.builtin.frad import FRadA
from observers.sets import Zonotope


@observers.register("My-Obs", family="strip", set_type="zonotope",
                    ready_for_control=False)
class MyObs(FRadA):
    def step(self, u_prev, y):
        Z = super().step(u_prev, y)
        return Zonotope(Z.c, 1.5 * Z.G)
'''


def _project(dst: Path) -> None:
    """The files the project's wheel is built from, with the committed stores."""
    for name in ("pyproject.toml", "README.md", "LICENSE"):
        shutil.copy2(ROOT / name, dst / name)
    for pkg in ("observers", "systems", "benchmarks"):
        shutil.copytree(ROOT / pkg, dst / pkg, symlinks=True, ignore=shutil.ignore_patterns(
            "__pycache__", "*.nbi", "*.nbc", "*.pyc"))
    for meta in (ROOT / "results").glob("*/meta.json"):
        if not (meta.parent / "summary.csv").is_file():
            continue  # the golden files of the gate, not a store
        (dst / "results" / meta.parent.name).mkdir(parents=True)
        for name in ("meta.json", "summary.csv"):
            shutil.copy2(meta.parent / name, dst / "results" / meta.parent.name / name)


def _plugin(dst: Path) -> None:
    (dst / "myplug").mkdir(parents=True)
    (dst / "myplug" / "__init__.py").write_text("")
    (dst / "myplug" / "obs.py").write_text(textwrap.dedent(PLUGIN))
    (dst / "pyproject.toml").write_text(textwrap.dedent('''
        [build-system]
        requires = ["setuptools>=77"]
        build-backend = "setuptools.build_meta"
        [project]
        name = "myplug"
        version = "0.1"
        [project.entry-points."setobs_bench.observers"]
        my-obs = "myplug.obs"
        [tool.setuptools.packages.find]
        include = ["myplug*"]
    '''))


@pytest.mark.slow
def test_a_plugin_is_ranked_beside_the_stored_rows_running_only_its_own(tmp_path):
    src, plug, site, work = (tmp_path / d for d in ("src", "plug", "site", "work"))
    for d in (src, plug, work):
        d.mkdir()
    _project(src)
    _plugin(plug)
    for what in (src, plug):
        done = subprocess.run([sys.executable, "-m", "pip", "install", "--quiet", "--no-deps",
                               "--no-build-isolation", "--no-index", "--target", str(site),
                               str(what)], capture_output=True, text=True, timeout=600)
        assert done.returncode == 0, done.stderr
    shipped = site / "benchmarks" / "stores" / "arch2021_table3"
    assert (shipped / "summary.csv").is_file() and (shipped / "meta.json").is_file()
    assert not (site / "benchmarks" / "stores" / "arch2021_table3" / "run").exists()
    env = {**os.environ, "PYTHONPATH": str(site), "SETOBS_NUMBA": "0"}
    cmd = [sys.executable, "-c", "import sys; from benchmarks.cli import main; sys.exit(main())"]
    where = subprocess.run([sys.executable, "-c", "import benchmarks; print(benchmarks.__file__)"],
                           capture_output=True, text=True, cwd=work, env=env, timeout=120)
    assert where.stdout.strip().startswith(str(site))  # the installed copy, not the repo's
    run = subprocess.run(cmd + ["run", "arch2021_table3", "--add", "My-Obs", "--out", "t3",
                                "--no-progress"],
                         capture_output=True, text=True, cwd=work, env=env, timeout=900)
    assert run.returncode == 0, run.stderr
    stored = pd.read_csv(ROOT / "results" / "arch2021_table3" / "summary.csv")
    total = stored.drop_duplicates(["scenario", "seed", "observer", "variant"]).shape[0] + 1
    assert f"ran 1 of {total} rows" in run.stdout, run.stdout + run.stderr
    assert "not current here" not in run.stderr
    ranked = pd.read_csv(work / "t3" / "summary.csv")
    assert set(ranked["observer"]) == set(stored["observer"]) | {"My-Obs"}
    # the other rows are the stored ones, unchanged (their relative RMS may move only if the
    # new observer were the best, which a looser FRad-A cannot be)
    cols = ["scenario", "observer", "state", "rms_radius", "rel_rms", "run_id"]
    mine = ranked[ranked["observer"] != "My-Obs"][cols].reset_index(drop=True)
    pd.testing.assert_frame_equal(mine, stored[cols].reset_index(drop=True))
    # scaling a zonotope by 1.5 about its centre scales every radius by 1.5
    frad = stored[stored["observer"] == "FRad-A"].set_index("state")["rms_radius"]
    my = ranked[ranked["observer"] == "My-Obs"].set_index("state")["rms_radius"]
    pd.testing.assert_series_equal(my, 1.5 * frad, rtol=1e-9, check_names=False)
    report = (work / "t3" / "report.md").read_text()
    assert "| My-Obs |" in report and "| FRad-A |" in report
