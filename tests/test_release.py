"""The release artefacts (issue 42): the sdist and the wheel build offline, both carry
``LICENSE``, the wheel carries the shipped configurations and the model data, and the wheel,
installed outside the repository, runs ``setobs-bench --version`` and a shipped configuration
by name from a working directory outside the repository."""

from __future__ import annotations

import os
import re
import subprocess
import sys
import tarfile
import zipfile
from pathlib import Path

import pandas as pd
import pytest

from .test_store_add import _project

ROOT = Path(__file__).resolve().parents[1]

# the folder is read before the backend runs (setuptools rewrites sys.argv)
BUILD = ("import sys; from setuptools import build_meta as b; out = sys.argv[1]; "
         "b.build_sdist(out); b.build_wheel(out)")


def _version() -> str:
    text = (ROOT / "pyproject.toml").read_text(encoding="utf-8")
    return re.search(r'^version = "([^"]+)"', text, re.M).group(1)


@pytest.fixture(scope="module")
def release(tmp_path_factory) -> dict[str, Path]:
    """Build the sdist and the wheel from a copy of the sources (setuptools' backend in this
    environment: no build isolation, no network) and install the wheel into a folder."""
    tmp = tmp_path_factory.mktemp("release")
    src, dist, site = tmp / "src", tmp / "dist", tmp / "site"
    src.mkdir()
    _project(src)
    done = subprocess.run([sys.executable, "-c", BUILD, str(dist)], capture_output=True,
                          text=True, cwd=src, timeout=600)
    if done.returncode != 0 and "No module named 'setuptools'" in done.stderr:
        pytest.skip("no setuptools >= 77 to build the release (pip install -e '.[test]')")
    assert done.returncode == 0, done.stderr[-3000:]
    (sdist,), (wheel,) = sorted(dist.glob("*.tar.gz")), sorted(dist.glob("*.whl"))
    pip = [sys.executable, "-m", "pip", "install", "--quiet", "--no-deps", "--no-index",
           "--target", str(site), str(wheel)]
    done = subprocess.run(pip, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr
    return {"sdist": sdist, "wheel": wheel, "site": site, "tmp": tmp}


def test_archives_are_named_for_this_version(release):
    v = _version()
    assert release["sdist"].name == f"setobs_bench-{v}.tar.gz"
    assert release["wheel"].name == f"setobs_bench-{v}-py3-none-any.whl"


def test_sdist_carries_the_license(release):
    with tarfile.open(release["sdist"]) as tar:
        names = tar.getnames()
        top = f"setobs_bench-{_version()}"
        assert f"{top}/LICENSE" in names
        text = tar.extractfile(f"{top}/LICENSE").read().decode()
    assert text == (ROOT / "LICENSE").read_text(encoding="utf-8")


def test_wheel_carries_license_configs_and_model_data(release):
    with zipfile.ZipFile(release["wheel"]) as whl:
        names = set(whl.namelist())
        info = f"setobs_bench-{_version()}.dist-info"
        meta = whl.read(f"{info}/METADATA").decode()
    assert f"{info}/licenses/LICENSE" in names
    assert "License-Expression: BSD-3-Clause" in meta and "License-File: LICENSE" in meta
    configs = {f"benchmarks/configs/{p.name}" for p in (ROOT / "benchmarks/configs").glob("*.yaml")}
    assert configs and configs <= names, sorted(configs - names)
    data = {p.relative_to(ROOT).as_posix() for p in (ROOT / "systems" / "data").rglob("*")
            if p.is_file() and "__pycache__" not in p.parts}
    assert data and data <= names, sorted(data - names)


def test_installed_wheel_runs_outside_the_repository(release):
    site, work = release["site"], release["tmp"] / "work"
    work.mkdir()
    # SETOBS_NUMBA=0: the fresh copy has no compiled kernels cached (compiling them is not
    # what this test is about); an empty design cache of its own
    env = {**os.environ, "PYTHONPATH": str(site), "SETOBS_NUMBA": "0",
           "SETOBS_CACHE_DIR": str(release["tmp"] / "cache")}
    script = site / "bin" / "setobs-bench"
    assert script.is_file()
    cmd = [sys.executable, str(script)]
    where = subprocess.run([sys.executable, "-c", "import benchmarks; print(benchmarks.__file__)"],
                           capture_output=True, text=True, cwd=work, env=env, timeout=120)
    assert where.stdout.strip().startswith(str(site))  # the installed copy, not the repo's
    version = subprocess.run(cmd + ["--version"], capture_output=True, text=True, cwd=work,
                             env=env, timeout=120)
    assert version.returncode == 0, version.stderr
    lines = version.stdout.splitlines()
    assert lines[0] == f"setobs-bench {_version()}"
    assert not any(line.startswith("commit") for line in lines)  # not a checkout
    assert lines[-1].startswith("BLAS ")
    run = subprocess.run(cmd + ["run", "quick", "--observer", "FRad-A", "--out", "q",
                                "--no-progress"],
                         capture_output=True, text=True, cwd=work, env=env, timeout=600)
    assert run.returncode == 0, run.stderr
    summary = pd.read_csv(work / "q" / "summary.csv")
    assert set(summary["observer"]) == {"FRad-A"}
    assert set(summary["scenario"]) == {"vehicle2d-cora", "alamo2d", "tank6-linear"}
    assert (summary["status"] == "ok").all()
    known = summary["contained"].dropna()  # a record without the true state has no verdict
    assert len(known) and (known == "yes").all()


def test_a_release_entry_goes_above_the_newest_version_and_takes_the_unreleased_items():
    from benchmarks.gate.release import with_entry

    head = "# Changelog\n\npolicy\n\n"
    old = "## [1.2.0] - 2026-01-01\n\nold items\n"
    entry = "## [1.3.0] - 2026-02-02\n\nRelease: measured.\n\n"
    assert with_entry(head + old, entry) == head + entry + old
    unreleased = "## [Unreleased]\n\n### Added\n- a feature\n\n"
    assert with_entry(head + unreleased + old, entry) == (
        head + entry + "### Added\n- a feature\n\n" + old)
