"""The files of an open research package (issue 42): ``CITATION.cff`` parses and names this
version, ``LICENSE`` is the BSD-3-Clause text the metadata declares, ``CHANGELOG.md`` has a
section for this version, ``setobs-bench --version`` prints the version, the commit and the
numerical libraries, and the golden files of the gate record the version that wrote them."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from datetime import date
from importlib import metadata
from pathlib import Path

import pytest
import yaml

from benchmarks import cli
from benchmarks.errors import ConfigError
from benchmarks.gate import regression
from benchmarks.io import blas_corename

ROOT = Path(__file__).resolve().parents[1]
#: the keys the Citation File Format 1.2.0 requires of a citation file
CFF_REQUIRED = ("cff-version", "message", "title", "authors")


def _pyproject_version() -> str:
    text = (ROOT / "pyproject.toml").read_text(encoding="utf-8")
    return re.search(r'^version = "([^"]+)"', text, re.M).group(1)


def _version_key(v: str) -> tuple[int, ...]:
    return tuple(int(p) for p in v.split("."))


@pytest.fixture(scope="module")
def citation() -> dict:
    return yaml.safe_load((ROOT / "CITATION.cff").read_text(encoding="utf-8"))


def test_citation_has_the_required_keys_and_this_version(citation):
    missing = [k for k in CFF_REQUIRED if k not in citation]
    assert not missing, f"CITATION.cff lacks {missing}"
    assert citation["cff-version"] == "1.2.0"
    assert citation["type"] == "software"
    assert str(citation["version"]) == _pyproject_version() == metadata.version("setobs-bench")
    assert citation["license"] == "BSD-3-Clause"
    assert isinstance(citation["date-released"], date)  # YAML date, as CFF wants it
    assert all(isinstance(a, dict) and a for a in citation["authors"])


def test_citation_references_the_reproduced_papers(citation):
    refs = citation["references"]
    for ref in refs:
        assert {"type", "title", "authors", "year"} <= set(ref), ref.get("title")
        assert all("family-names" in a or "name" in a for a in ref["authors"])
    titles = " | ".join(r["title"].lower() for r in refs)
    for words in ("comparison of guaranteed state estimators", "guaranteed state estimation in "
                  "cora 2021", "data-driven set-based estimation"):
        assert words in titles
    automatica = next(r for r in refs if r.get("journal") == "Automatica")
    assert (automatica["volume"], automatica["year"]) == (130, 2021)


def test_license_is_bsd3_and_declared():
    text = (ROOT / "LICENSE").read_text(encoding="utf-8")
    assert text.startswith("BSD 3-Clause License")
    assert "Copyright (c) 2026, the setobs-bench contributors" in text
    assert "Neither the name of the copyright holder" in text
    pyproject = (ROOT / "pyproject.toml").read_text(encoding="utf-8")
    assert 'license = "BSD-3-Clause"' in pyproject
    assert 'license-files = ["LICENSE"]' in pyproject


def test_changelog_has_a_section_for_this_version_and_the_policy():
    text = (ROOT / "CHANGELOG.md").read_text(encoding="utf-8")
    heads = re.findall(r"^## \[(\d+\.\d+\.\d+)\] - (\d{4}-\d{2}-\d{2})$", text, re.M)
    assert heads and heads[0][0] == _pyproject_version()  # newest first
    assert [v for v, _ in heads] == sorted((v for v, _ in heads), key=_version_key,
                                           reverse=True)
    assert "### Published numbers" in text
    policy = text.split("## [")[0]  # the version policy, above the versions
    assert re.search(r"golden number .*? at least a \**minor\**\s+version", policy, re.S)
    assert "setobs_bench_version" in policy


def _run_version(env: dict | None = None, cwd: Path = ROOT) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "benchmarks", "--version"], capture_output=True,
                          text=True, cwd=cwd, env=env, timeout=120)


def test_version_prints_package_commit_libraries_and_kernel():
    proc = _run_version()
    assert proc.returncode == 0, proc.stderr
    lines = proc.stdout.splitlines()
    assert lines[0] == f"setobs-bench {_pyproject_version()}"
    head = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True,
                          text=True, cwd=ROOT).stdout.strip()
    if head:  # a checkout (the tests may also run from an exported tree)
        assert re.fullmatch(rf"commit {head}( \(modified\))?", lines[1]), lines[1]
    names = [line.split()[0] for line in lines]
    for pkg in ("numpy", "scipy", "highspy", "clarabel", "cvxpy", "numba"):
        assert f"{pkg} {metadata.version(pkg)}" in lines, pkg
    assert names[-1] == "BLAS"
    kernel = blas_corename()
    assert lines[-1] == (f"BLAS OpenBLAS {kernel}" if kernel != "unknown" else "BLAS unknown")


def test_version_without_git_has_no_commit_line_and_no_traceback(tmp_path):
    # no git on PATH: the version is still printed, without the commit line
    env = {**os.environ, "PATH": str(tmp_path)}
    proc = _run_version(env=env, cwd=tmp_path)
    assert proc.returncode == 0 and "Traceback" not in proc.stderr, proc.stderr
    assert proc.stdout.splitlines()[0] == f"setobs-bench {_pyproject_version()}"
    assert not any(line.startswith("commit") for line in proc.stdout.splitlines())


def test_checkout_commit_is_empty_outside_a_checkout(tmp_path):
    assert cli._checkout_commit(tmp_path) == ""
    # a folder inside a checkout is not its top level (an installed copy inside a repository)
    assert cli._checkout_commit(ROOT / "benchmarks") == ""


def test_golden_meta_records_the_package_version(tmp_path):
    (tmp_path / "meta.json").write_text(json.dumps({"created": "x", "versions": {"git": "abc"}}))
    path = regression.record_version(tmp_path)
    meta = json.loads(path.read_text())
    assert meta == {"created": "x", "versions": {"git": "abc"},
                    regression.VERSION_KEY: metadata.version("setobs-bench")}
    # the writer of the golden files goes the same way
    cfg = regression.subset_config(plugins=False)
    assert regression._meta(cfg, "note")[regression.VERSION_KEY] == _pyproject_version()


@pytest.mark.parametrize("content", [None, "{not json", "[1, 2]"])
def test_record_version_refuses_a_missing_or_bad_meta(tmp_path, content):
    if content is not None:
        (tmp_path / "meta.json").write_text(content)
    with pytest.raises(ConfigError, match="meta|JSON"):
        regression.record_version(tmp_path)


def test_committed_golden_files_name_a_released_version():
    meta = json.loads((ROOT / "results" / "baseline" / "meta.json").read_text())
    stored = meta[regression.VERSION_KEY]
    # golden numbers cannot come from a version later than this one
    assert _version_key(stored) <= _version_key(_pyproject_version())
    changelog = (ROOT / "CHANGELOG.md").read_text(encoding="utf-8")
    assert f"## [{stored}]" in changelog


def test_baseline_overview_names_the_version_of_the_golden_files():
    frame, meta = regression.load_baseline(ROOT / "results" / "baseline")
    first = regression.baseline_overview(frame, meta).splitlines()[0]
    assert f"setobs-bench {meta[regression.VERSION_KEY]};" in first
    assert "setobs-bench ?;" in regression.baseline_overview(
        frame, {k: v for k, v in meta.items() if k != regression.VERSION_KEY}).splitlines()[0]
