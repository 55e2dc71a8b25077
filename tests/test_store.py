"""The result store: AST digests, the module graph, row fingerprints, the incremental bench and
the store's integrity (half-written, corrupted, hand-edited, two writers, a kill)."""

from __future__ import annotations

import copy
import json
import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pandas as pd
import pytest

from benchmarks.errors import ConfigError
from benchmarks.run.config import inline_config
from benchmarks.store import bench, store
from benchmarks.store.fingerprint import Fingerprinter
from benchmarks.store.graph import ModuleGraph, code_digest
from benchmarks.store.store import StoreLock, load_store, write_store

ROOT = Path(__file__).resolve().parents[1]


# -- digests and the module graph ----------------------------------------------------------------
def test_docstrings_comments_and_layout_do_not_change_the_digest():
    a = 'def f(x):\n    return x + 1\n'
    b = ('"""Module doc."""\n\n\ndef f(x):  # a comment\n    """Adds one."""\n'
         '    return (x\n            + 1)\n')
    assert code_digest(a) == code_digest(b)
    assert code_digest(a) != code_digest('def f(x):\n    return x + 2\n')
    # a string that is not a docstring is code
    assert code_digest(a) != code_digest('def f(x):\n    y = "s"\n    return x + 1\n')


def _package(root: Path, files: dict[str, str]) -> None:
    for rel, text in files.items():
        path = root / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(textwrap.dedent(text))


def test_a_name_re_exported_by_a_package_depends_on_its_module_only(tmp_path):
    _package(tmp_path, {
        "pkg/__init__.py": "from .a import A\nfrom .b import B\n",
        "pkg/a.py": "A = 1\n",
        "pkg/b.py": "import pkg.c\nB = 2\n",
        "pkg/c.py": "C = 3\n",
        "pkg/user.py": "from pkg import A\n\ndef g():\n    from .lazy import L\n    return L\n",
        "pkg/lazy.py": "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n"
                       "    from pkg.c import C\nL = 4\n",
    })
    graph = ModuleGraph(tmp_path, ("pkg",))
    # the package's text counts (it binds A), not the other modules it imports
    assert graph.closure("pkg.user") == {"pkg.user", "pkg", "pkg.a", "pkg.lazy"}
    assert graph.closure("pkg.b") == {"pkg.b", "pkg.c"}
    assert graph.closure("pkg") >= {"pkg", "pkg.a", "pkg.b", "pkg.c"}


def test_the_ellipsoidal_numerics_belong_to_the_ellipsoidal_observers_only():
    graph = ModuleGraph()
    target = "observers.numerics.ellipsoidal"
    assert target in graph.closure("observers.builtin.ellipsoidal")
    for other in ("observers.builtin.frad", "observers.builtin.czn", "observers.builtin.exact",
                  "benchmarks.run.runner"):
        assert target not in graph.closure(other), other
    # every observer and the harness run on zonotopes
    assert "observers.sets.zonotope" in graph.closure("benchmarks.run.runner")


# -- a small store, made by a real run -------------------------------------------------------------
def _tiny(observers_=("FRad-A", "INT-CP")):
    return inline_config(["alamo2d-sim"], list(observers_), "tiny")


@pytest.fixture(scope="module")
def tiny_store(tmp_path_factory):
    """``results/tiny/`` and ``reports/tiny.md`` of a run of two observers on alamo2d-sim."""
    base = tmp_path_factory.mktemp("store")
    results, reports = base / "results", base / "reports"
    reports.mkdir()
    return results, reports, _bench(_tiny(), results, reports)


def _bench(cfg, results, reports):
    from benchmarks.run.executors import SerialExecutor

    with StoreLock(results):
        p = bench.plan(cfg, load_store(results / cfg.name), Fingerprinter())
        return bench.bench_config(p, results, reports, SerialExecutor(), progress=False,
                                  notify=lambda _: None)


def test_a_bench_runs_only_what_is_stale(tiny_store, tmp_path):
    results, reports, first = tiny_store
    assert (first.ran, first.total) == (2, 2)
    text = (reports / "tiny.md").read_text()
    assert "## alamo2d-sim" in text and "FRad-A" in text and "INT-CP" in text
    again = _bench(_tiny(), results, reports)
    assert again.ran == 0 and (reports / "tiny.md").read_text() == text
    # an observer more: its row runs, the stored ones stay (same run ids)
    before = load_store(results / "tiny")
    copy = tmp_path / "results"
    import shutil

    shutil.copytree(results, copy)
    more = _bench(_tiny(("FRad-A", "INT-CP", "FRad-B")), copy, reports)
    assert more.ran == 1
    after = load_store(copy / "tiny")
    old = before.summary.set_index(["observer", "state"])["run_id"]
    new = after.summary.set_index(["observer", "state"])["run_id"]
    assert (new.loc[old.index] == old).all()
    assert set(after.summary["observer"]) == {"FRad-A", "INT-CP", "FRad-B"}
    # rel_rms is recomputed over the merged rows: the best of each state is 1
    ok = after.summary[after.summary["status"] == "ok"]
    assert ok.groupby("state")["rel_rms"].min().round(12).eq(1).all()


def _copy_store(src: Path, dst: Path) -> Path:
    dst.mkdir(parents=True)
    for name in ("summary.csv", "meta.json"):
        (dst / name).write_bytes((src / name).read_bytes())
    return dst


def test_a_truncated_summary_is_refused(tiny_store, tmp_path):
    folder = _copy_store(tiny_store[0] / "tiny", tmp_path / "tiny")
    data = (folder / "summary.csv").read_bytes()
    (folder / "summary.csv").write_bytes(data[: len(data) // 2])
    with pytest.raises(ConfigError, match="truncated"):
        load_store(folder)


def test_a_hand_edited_value_is_refused(tiny_store, tmp_path):
    folder = _copy_store(tiny_store[0] / "tiny", tmp_path / "tiny")
    df = pd.read_csv(folder / "summary.csv", dtype=str, keep_default_na=False)
    df.loc[0, "rms_radius"] = "0.5"
    df.to_csv(folder / "summary.csv", index=False)
    with pytest.raises(ConfigError, match="hand-edited or corrupted"):
        load_store(folder)


def _resign(folder: Path) -> None:
    """Make meta.json's file checksum match the (edited) summary, as a careful hand would."""
    import hashlib

    data = (folder / "summary.csv").read_bytes()
    meta = json.loads((folder / "meta.json").read_text())
    meta["files"]["summary.csv"] = {"bytes": len(data),
                                    "sha256": hashlib.sha256(data).hexdigest()}
    (folder / "meta.json").write_text(json.dumps(meta))


def test_a_row_whose_content_does_not_match_its_record_is_refused(tiny_store, tmp_path):
    folder = _copy_store(tiny_store[0] / "tiny", tmp_path / "tiny")
    df = pd.read_csv(folder / "summary.csv", dtype=str, keep_default_na=False)
    df.loc[0, "rms_radius"] = "0.5"
    df.to_csv(folder / "summary.csv", index=False)
    _resign(folder)
    with pytest.raises(ConfigError, match="content of row alamo2d-sim.*does not match"):
        load_store(folder)


def test_a_row_with_another_fingerprint_is_refused(tiny_store, tmp_path):
    folder = _copy_store(tiny_store[0] / "tiny", tmp_path / "tiny")
    df = pd.read_csv(folder / "summary.csv", dtype=str, keep_default_na=False)
    df.loc[df["observer"] == "FRad-A", "fingerprint"] = "0123456789abcdef"
    df.to_csv(folder / "summary.csv", index=False)
    _resign(folder)
    with pytest.raises(ConfigError, match="has fingerprint 0123456789abcdef"):
        load_store(folder)


def test_a_missing_meta_is_one_line(tiny_store, tmp_path):
    folder = _copy_store(tiny_store[0] / "tiny", tmp_path / "tiny")
    (folder / "meta.json").unlink()
    with pytest.raises(ConfigError, match="meta.json is missing") as err:
        load_store(folder)
    assert "\n" not in str(err.value)


def test_a_second_writer_is_refused_naming_the_first(tmp_path):
    code = ("import sys, time; from benchmarks.store.store import StoreLock\n"
            f"with StoreLock({str(tmp_path)!r}):\n    print('held', flush=True)\n"
            "    time.sleep(60)\n")
    holder = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, text=True,
                              cwd=ROOT)
    try:
        assert holder.stdout.readline().strip() == "held"
        with pytest.raises(ConfigError, match=f"held by pid {holder.pid}"), StoreLock(tmp_path):
            pass
    finally:
        holder.kill()
        holder.wait()
    with StoreLock(tmp_path):  # free again once the holder is gone
        pass


def test_a_writer_killed_at_any_moment_leaves_one_whole_store(tiny_store, tmp_path):
    """A process rewriting a store in a loop (two versions in turn) is killed; the store is
    then one of the two versions, whole, and the next write removes what the dead one left."""
    folder = _copy_store(tiny_store[0] / "tiny", tmp_path / "tiny")
    good = load_store(folder)
    other = store.Store(good.summary.assign(message="second version"),
                        copy.deepcopy(good.meta))
    pickled = tmp_path / "versions.pkl"
    pd.to_pickle((good, other), pickled)
    code = ("import pandas as pd, sys; from benchmarks.store.store import write_store\n"
            f"a, b = pd.read_pickle({str(pickled)!r}); i = 0\n"
            "print('writing', flush=True)\n"
            f"while True:\n    write_store({str(folder)!r}, (a, b)[i % 2]); i += 1\n")
    for delay in (0.05, 0.3, 0.8):
        writer = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE,
                                  text=True, cwd=ROOT)
        assert writer.stdout.readline().strip() == "writing"
        time.sleep(delay)
        os.kill(writer.pid, signal.SIGKILL)
        writer.wait()
        msgs = load_store(folder).summary["message"]
        assert msgs.eq("second version").all() or msgs.equals(good.summary["message"])
    write_store(folder, good)
    assert not list(tmp_path.glob(".tiny.new-*"))  # the dead writers' folders are gone


def test_the_fingerprint_of_a_job_names_its_observer_module():
    cfg = _tiny(("ESO-A",))
    from benchmarks.run.runner import make_jobs

    (job,) = make_jobs(cfg)
    fp = Fingerprinter().job(job, cfg)
    assert "observers.numerics.ellipsoidal" in fp.code
    assert "observers.builtin.exact" in fp.code  # the floor of the record
    assert "systems/data/alamo2d.yaml" in fp.data


def test_a_run_never_writes_into_a_store(tiny_store, tmp_path, capsys):
    from benchmarks.cli import main

    folder = _copy_store(tiny_store[0] / "tiny", tmp_path / "tiny")
    before = {p.name: p.read_bytes() for p in folder.iterdir()}
    code = main(["run", "--scenario", "alamo2d-sim", "--observer", "FRad-A", "--out",
                 str(folder), "--no-progress"])
    err = capsys.readouterr().err
    assert code == 2 and "is a result store" in err and f"{folder}/run" in err
    assert {p.name: p.read_bytes() for p in folder.iterdir()} == before


def test_every_job_of_every_published_configuration_has_its_own_row_key():
    """The key of a job is the key of its rows in ``summary.csv``: the regression subset runs
    tank6-linear twice, once under the label tank6-linear-defaults (a collision of the two
    was caught by the store's check after the run, and is a test now)."""
    from benchmarks.run.config import load_config
    from benchmarks.run.runner import make_jobs
    from benchmarks.store.fingerprint import job_key

    for name in bench.published():
        cfg = load_config(name)
        jobs = make_jobs(cfg)
        keys = [job_key(j) for j in jobs]
        assert len(set(keys)) == len(keys), name
        built = {i.scenario.name for i in cfg.instances}
        assert {k.split("|")[0] for k in keys} <= built, name


def test_every_store_is_committed_and_local_runs_are_not():
    """The stores' two files are not ignored by git (a new published configuration needs its
    line in .gitignore); a run's or the gate's folder under results/ is."""
    root = Path(__file__).resolve().parents[1]
    names = [*bench.published(), "soundness"]
    wanted = [f"results/{n}/{f}" for n in names for f in ("summary.csv", "meta.json")]
    local = ["results/check/summary.csv", "results/quick/run/summary.csv",
             "results/arch2021_table3/index.html", "results/audit-short/soundness.csv"]
    done = subprocess.run(["git", "check-ignore", "--no-index", *wanted, *local], cwd=root,
                          capture_output=True, text=True)
    assert set(done.stdout.split()) == set(local)


def test_a_merge_keeps_the_text_of_the_rows_it_does_not_run(tmp_path):
    """Bug (found by an incremental ``make bench``): the rows a merge keeps were written back
    from ``pd.read_csv``'s reading, so a seed beside a record without one came back as
    ``0.0`` and every ``n/a`` of a verdict column as an empty cell.  The kept lines are now
    the same text, but for ``rel_rms`` (recomputed over the merged rows)."""
    from benchmarks.run.config import parse_config

    def cfg(names):
        raw = {"name": "mixed", "title": "mixed seeds",
               "scenarios": ["alamo2d", {"name": "alamo2d-sim", "seed": 0}],
               "observers": list(names)}
        return parse_config(raw, "mixed")

    results, reports = tmp_path / "results", tmp_path / "reports"
    reports.mkdir()
    assert _bench(cfg(["FRad-A", "Hinf-G"]), results, reports).ran == 4
    path = results / "mixed" / "summary.csv"
    before = pd.read_csv(path, dtype=str, keep_default_na=False)
    assert {"", "0"} <= set(before["seed"]) and (before == "n/a").any().any()
    assert _bench(cfg(["FRad-A", "Hinf-G", "FRad-B"]), results, reports).ran == 2
    after = pd.read_csv(path, dtype=str, keep_default_na=False)
    kept = after[after["observer"] != "FRad-B"].reset_index(drop=True)
    pd.testing.assert_frame_equal(kept.drop(columns="rel_rms"),
                                  before.drop(columns="rel_rms"))
    assert set(after["seed"]) == {"", "0"}
