"""Plugin discovery through the entry-point group ``setobs_bench.observers``; the old group
``observers`` is still read, with a one-line deprecation warning per plugin."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
import warnings
from pathlib import Path

import pytest

import observers
from observers import registry

ROOT = Path(__file__).resolve().parents[1]

PLUGIN = '''
import observers
from observers.builtin.frad import FRadA


@observers.register("{name}", family="strip", set_type="zonotope", ready_for_control=False,
                    reference="plugin test")
class PluginObs(FRadA):
    """FRad-A under another name."""
'''


def _site(tmp_path: Path, groups: tuple[str, ...], name: str = "Grp-Obs") -> Path:
    """A folder for ``PYTHONPATH`` holding the distribution ``grpplug`` whose module is
    announced in each entry-point group of ``groups``."""
    site = tmp_path / "site"
    (site / "grpplug").mkdir(parents=True)
    (site / "grpplug" / "__init__.py").write_text(textwrap.dedent(PLUGIN.format(name=name)))
    info = site / "grpplug-0.1.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: grpplug\nVersion: 0.1\n")
    (info / "entry_points.txt").write_text(
        "".join(f"[{group}]\ngrp-obs = grpplug\n\n" for group in groups))
    return site


def _list(site: Path) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(site), str(ROOT)]),
           "SETOBS_NUMBA": "0"}
    env.pop("PYTHONWARNINGS", None)  # the default warning filters, as a user has them
    cmd = [sys.executable, "-c",
           "import sys; from benchmarks.cli import main; sys.exit(main())", "list", "observers"]
    return subprocess.run(cmd, capture_output=True, text=True, cwd=site, env=env, timeout=300)


def _deprecation_lines(stderr: str) -> list[str]:
    return [line for line in stderr.splitlines() if "deprecated entry-point group" in line]


def test_a_plugin_of_the_new_group_is_listed_without_a_warning(tmp_path):
    done = _list(_site(tmp_path, (registry.ENTRY_POINT_GROUP,)))
    assert done.returncode == 0, done.stderr
    assert [ln for ln in done.stdout.splitlines() if ln.startswith("Grp-Obs ")]
    assert not _deprecation_lines(done.stderr), done.stderr


def test_a_plugin_of_the_old_group_is_listed_with_one_deprecation_line(tmp_path):
    done = _list(_site(tmp_path, ("observers",)))
    assert done.returncode == 0, done.stderr
    assert [ln for ln in done.stdout.splitlines() if ln.startswith("Grp-Obs ")]
    lines = _deprecation_lines(done.stderr)
    assert len(lines) == 1, done.stderr
    assert "'grp-obs'" in lines[0] and "'grpplug'" in lines[0]
    assert "move it to 'setobs_bench.observers'" in lines[0]
    assert "Traceback" not in done.stderr
    # one line in all: no source line of the harness under it (the command line's format)
    assert lines[0].startswith("warning: ")
    assert "for i in" not in done.stderr and "warnings.warn" not in done.stderr, done.stderr


def test_a_plugin_in_both_groups_counts_once_without_a_warning(tmp_path):
    done = _list(_site(tmp_path, ("observers", registry.ENTRY_POINT_GROUP)))
    assert done.returncode == 0, done.stderr
    assert len([ln for ln in done.stdout.splitlines() if ln.startswith("Grp-Obs ")]) == 1
    assert not _deprecation_lines(done.stderr), done.stderr


class _EP:
    """A stand-in for :class:`importlib.metadata.EntryPoint`."""

    def __init__(self, name: str, value: str, dist: str, loads: list[str]):
        self.name, self.value = name, value
        self.dist = type("Dist", (), {"name": dist})()
        self._loads = loads

    def load(self):
        self._loads.append(self.value)
        return None


def test_each_plugin_is_loaded_once_and_warned_about_once(monkeypatch):
    loads: list[str] = []
    groups = {
        registry.ENTRY_POINT_GROUP: [_EP("new", "pkg_new", "dist-new", loads),
                                     _EP("both", "pkg_both", "dist-both", loads)],
        "observers": [_EP("both", "pkg_both", "dist-both", loads),
                      _EP("old", "pkg_old", "dist-old", loads)],
    }
    monkeypatch.setattr(registry, "entry_points", lambda group: groups.get(group, []))
    monkeypatch.setattr(registry, "_loaded", False)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        observers.available()
        observers.available()
    assert sorted(loads) == ["pkg_both", "pkg_new", "pkg_old"]
    deprecations = [w for w in caught if issubclass(w.category, registry.PluginGroupDeprecation)]
    assert len(deprecations) == 1
    message = str(deprecations[0].message)
    assert "'old'" in message and "'dist-old'" in message and "\n" not in message
    assert issubclass(registry.PluginGroupDeprecation, FutureWarning)  # shown by default


@pytest.mark.parametrize("path", ["docs/guide/plugins.rst", "tests/test_store_add.py"])
def test_the_documented_group_is_the_new_one(path):
    text = (ROOT / path).read_text(encoding="utf-8")
    assert '[project.entry-points."setobs_bench.observers"]' in text
    assert "[project.entry-points.observers]" not in text
