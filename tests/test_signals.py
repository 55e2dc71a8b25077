"""Honest signals (containment yes/no/n/a, eq. (9) without violators, exit codes, any object
with ``step``) and nothing lost or mixed (output folder checked first, one generation of
result files with one run id, umask)."""

from __future__ import annotations

import os
import re
import stat

import numpy as np
import pandas as pd
import pytest
import yaml

import benchmarks.io as bio
import benchmarks.run.rows as rows
import observers
from benchmarks.cli import build_parser, main
from benchmarks.metrics import add_relative_rms
from observers import registry
from observers.builtin.frad import FRadA
from observers.sets import Interval, Zonotope

SYSTEM = {"A": [[0.9, 0.1], [0.0, 0.8]], "B": [[0.0], [1.0]], "C": [[1.0, 0.0]],
          "W": {"box": [0.01, 0.01]}, "V": {"box": [0.1]},
          "X0": {"center": [0, 0], "generators": [[1, 0], [0, 1]]}}
TOY = {"name": "toy", "system": SYSTEM, "simulate": {"steps": 20, "seed": 1},
       "options": {"order": 10}}


def write_cfg(tmp_path, observers_, scenarios=(TOY,), name="cfg.yaml", **top):
    path = tmp_path / name
    path.write_text(yaml.safe_dump({"scenarios": list(scenarios), "observers": observers_,
                                    **top}))
    return path


def literal(path) -> pd.DataFrame:
    """A result CSV with ``n/a`` kept as text (pandas reads it as NaN by default)."""
    return pd.read_csv(path, keep_default_na=False)


@pytest.fixture
def plugins():
    """Test plugins: FRad-A with sets shrunk to half (unsound), one whose sets contain the
    true state's hull but not the state (a thin diagonal zonotope), one crashing at step 5."""

    @observers.register("Test-Half", family="strip", set_type="zonotope",
                        ready_for_control=False)
    class Half(FRadA):
        """FRad-A with its sets shrunk to half about their centre (unsound, test only)."""

        def step(self, u_prev, y):
            Z = super().step(u_prev, y)
            return Zonotope(Z.c, 0.5 * Z.G)

    @observers.register("Test-Diagonal", family="strip", set_type="zonotope",
                        ready_for_control=False)
    class Diagonal(FRadA):
        """A set whose hull is the FRad-A hull but which is only its diagonal (test only)."""

        def step(self, u_prev, y):
            I = super().step(u_prev, y).interval()
            r = 0.5 * (I.hi - I.lo)
            return Zonotope(0.5 * (I.hi + I.lo), r.reshape(-1, 1))

    @observers.register("Test-Crash", family="strip", set_type="zonotope",
                        ready_for_control=False)
    class Crash(FRadA):
        """FRad-A that raises at step 5 (test only)."""

        def step(self, u_prev, y):
            if self.k == 5:
                raise RuntimeError("boom")
            return super().step(u_prev, y)

    names = ("Test-Half", "Test-Diagonal", "Test-Crash")
    yield names
    for n in names:
        registry.unregister(n)


# -- honest signals ------------------------------------------------------------------------
def test_record_without_true_states_says_na_not_ok(tmp_path, capsys, plugins):
    """CORA's record has no true states: a plugin with sets of half the size cannot be
    checked against the truth, so its `contained` says n/a (not ok), and the report's column
    too.  Without the exact floor (``exact: false``) nothing else checks it and the run
    passes; with it (the default), the floor catches it: `covers_exact` no, exit 1."""
    cfg = write_cfg(tmp_path, ["FRad-A", "Test-Half"], ["vehicle2d-cora"], exact=False)
    out = tmp_path / "r"
    assert main(["run", str(cfg), "--out", str(out), "--no-progress"]) == 0
    s = literal(out / "summary.csv")
    assert set(s["contained"]) == {"n/a"} and "contained_all" not in s.columns
    assert set(s["covers_exact"]) == {"n/a"}
    assert main(["report", str(out), "--no-figures"]) == 0
    rows = [ln for ln in (out / "report.md").read_text().splitlines() if "Test-Half" in ln]
    assert rows and all(ln.rstrip(" |").endswith("n/a") for ln in rows[:1])
    cfg = write_cfg(tmp_path, ["FRad-A", "Test-Half"], ["vehicle2d-cora"], name="floor.yaml")
    out = tmp_path / "floor"
    assert main(["run", str(cfg), "--out", str(out), "--no-progress"]) == 1
    s = literal(out / "summary.csv").set_index("observer")
    assert set(s.loc["Test-Half", "covers_exact"]) == {"no"}
    assert set(s.loc["FRad-A", "covers_exact"]) == {"yes"}
    assert set(s["contained"]) == {"n/a"}
    assert "Test-Half on vehicle2d-cora (misses states consistent with the data" in \
        capsys.readouterr().err


def test_contained_is_one_verdict_from_the_exact_test(tmp_path, capsys, plugins):
    """The hull of Test-Diagonal contains the true state, the set does not: one column
    `contained` says no, beside the violations (no `contained_all = True` beside them);
    with `containment: hull` the column is `contained_hull` and says yes."""
    out = tmp_path / "exact"
    cfg = write_cfg(tmp_path, ["FRad-A", "Test-Diagonal"])
    assert main(["run", str(cfg), "--out", str(out), "--no-progress"]) == 1
    s = literal(out / "summary.csv").set_index("observer")
    assert s.loc["Test-Diagonal", "contained"].tolist() == ["no", "no"]
    assert (s.loc["Test-Diagonal", "violations"] > 0).all()
    assert s.loc["FRad-A", "contained"].tolist() == ["yes", "yes"]
    assert "CONTAINMENT VIOLATIONS: Test-Diagonal on toy" in capsys.readouterr().err
    out = tmp_path / "hull"
    cfg = write_cfg(tmp_path, ["FRad-A", "Test-Diagonal"], containment="hull", name="h.yaml")
    assert main(["run", str(cfg), "--out", str(out), "--no-progress"]) == 0
    s = literal(out / "summary.csv")
    assert "contained" not in s.columns and set(s["contained_hull"]) == {"yes"}
    assert main(["report", str(out), "--no-figures"]) == 0
    assert "| contained (hull only) |" in (out / "report.md").read_text()


def test_violating_observer_is_not_the_reference_of_eq9(tmp_path, capsys, plugins):
    cfg = write_cfg(tmp_path, ["FRad-A", "FRad-C", "Test-Half"])
    out = tmp_path / "r"
    assert main(["run", str(cfg), "--out", str(out), "--no-progress"]) == 1
    s = pd.read_csv(out / "summary.csv")
    half = s[s["observer"] == "Test-Half"]
    assert (half["violations"] > 0).all()
    assert (half["rel_rms"] < 1).all()  # below the reference, which it is not
    best = s[s["observer"] != "Test-Half"].groupby("state")["rel_rms"].min()
    np.testing.assert_allclose(best, 1.0)
    assert main(["report", str(out), "--no-figures"]) == 0
    assert "| **Test-Half** (unsound) |" in (out / "report.md").read_text()


def test_eq9_hand_example_skips_violators():
    s = pd.DataFrame({"scenario": "s", "observer": ["a", "a", "b", "b"], "state": [0, 1] * 2,
                      "rms_radius": [2.0, 4.0, 1.0, 1.0], "status": "ok", "guaranteed": True,
                      "contained": ["yes", "yes", "no", "no"]})
    np.testing.assert_allclose(add_relative_rms(s)["rel_rms"], [1.0, 1.0, 0.5, 0.25])


def test_crash_exits_3_after_the_others_with_its_step(tmp_path, capsys, plugins):
    cfg = write_cfg(tmp_path, ["Test-Crash", "FRad-A"])
    out = tmp_path / "r"
    assert main(["run", str(cfg), "--out", str(out), "--no-progress"]) == 3
    err = capsys.readouterr().err
    assert "CRASHED: Test-Crash on toy (at step 5)" in err
    s = pd.read_csv(out / "summary.csv").set_index("observer")
    assert (s.loc["Test-Crash", "status"] == "error").all()
    assert (s.loc["Test-Crash", "failed_step"] == 5).all()
    assert "RuntimeError: boom" in s.loc["Test-Crash", "message"].iloc[0]
    assert (s.loc["FRad-A", "status"] == "ok").all()  # the run went on
    lit = literal(out / "summary.csv").set_index("observer")
    assert (lit.loc["Test-Crash", "contained"] == "n/a").all()  # checked only up to step 4
    assert (lit.loc["Test-Crash", "violations"] == 0).all()
    # a containment violation weighs more than a crash
    cfg = write_cfg(tmp_path, ["Test-Crash", "Test-Half"], name="both.yaml")
    assert main(["run", str(cfg), "--out", str(tmp_path / "b"), "--no-progress"]) == 1


def test_exit_codes_are_documented():
    help_text = " ".join(build_parser()._subparsers._group_actions[0].choices["run"]
                         .format_help().split())
    for code in ("0 every observer ran", "1 a guaranteed observer", "2 bad input",
                 "3 an observer crashed"):
        assert code in help_text
    # the exit-code table of the documentation (docs/guide/cli.rst, a list-table)
    page = " ".join((bio.Path(__file__).parents[1] / "docs" / "guide" / "cli.rst")
                    .read_text().split())
    for code in ("* - 0 - every observer ran", "* - 1 - a guaranteed observer",
                 "* - 2 - bad input", "* - 3 - an observer crashed"):
        assert code in page


class Plain:
    """Only ``step`` and a set with ``interval()``: no reset, options, name or system."""

    def __init__(self, system=None):
        self.k = 0

    def step(self, u_prev, y):
        self.k += 1
        y = np.asarray(y, float)
        return Interval(np.array([y[0] - 1.0, -5.0]), np.array([y[0] + 1.0, 5.0]))


def test_any_object_with_step_runs_in_run_and_in_the_runner(tmp_path, capsys):
    res = observers.run(Plain(), None, np.array([[0.1], [0.2], [0.3]]))
    assert res.status == "ok" and res.observer == "Plain" and res.lo.shape == (3, 2)
    np.testing.assert_allclose(res.hi[:, 0], [1.1, 1.2, 1.3])
    s = _run_plugin(tmp_path, "Test-Plain", Plain, "interval", exit_code=0)
    assert (s.loc["Test-Plain", "status"] == "ok").all()
    assert (s.loc["Test-Plain", "contained"] == "yes").all()


def _run_plugin(tmp_path, name, cls, set_type, exit_code):
    """``cls`` registered as ``name`` and run beside FRad-A by ``setobs-bench run`` (then
    unregistered): the summary, indexed by observer, with ``n/a`` kept as text."""
    observers.register(name, family="strip", set_type=set_type, ready_for_control=False)(cls)
    try:
        cfg = write_cfg(tmp_path, [name, "FRad-A"])
        out = tmp_path / "r"
        assert main(["run", str(cfg), "--out", str(out), "--no-progress"]) == exit_code
        return literal(out / "summary.csv").set_index("observer")
    finally:
        registry.unregister(name)


# -- nothing lost, nothing mixed -------------------------------------------------------------
@pytest.fixture
def no_work(monkeypatch):
    """Fail the test if any observer runs."""
    def forbidden(*args, **kwargs):
        raise AssertionError("an observer ran before the output folder was checked")
    monkeypatch.setattr(rows, "run_observer", forbidden)


@pytest.mark.parametrize("where", ["under a file", "proc", "not a results folder"])
def test_output_folder_is_checked_before_any_work(tmp_path, capsys, no_work, where):
    if where == "under a file":
        (tmp_path / "f").write_text("x")
        out = tmp_path / "f" / "sub"
    elif where == "proc":
        out = "/proc/setobs-results"
    else:
        (tmp_path / "mine").mkdir()
        (tmp_path / "mine" / "thesis.tex").write_text("x")
        out = tmp_path / "mine"
    cfg = write_cfg(tmp_path, ["FRad-A"])
    assert main(["run", str(cfg), "--out", str(out), "--no-progress"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("error: output folder") and len(err.splitlines()) == 1, err


@pytest.mark.skipif(os.geteuid() == 0, reason="root may write in any folder")
def test_read_only_output_folder_is_refused_first(tmp_path, capsys, no_work):
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o500)
    cfg = write_cfg(tmp_path, ["FRad-A"])
    try:
        assert main(["run", str(cfg), "--out", str(ro / "r"), "--no-progress"]) == 2
    finally:
        ro.chmod(0o700)
    assert "cannot write" in capsys.readouterr().err


def _run(tmp_path, out, observers_=("FRad-A",), name="cfg.yaml"):
    assert main(["run", str(write_cfg(tmp_path, list(observers_), name=name)), "--out",
                 str(out), "--no-progress"]) == 0


def test_result_files_are_one_generation_with_one_run_id(tmp_path):
    out = tmp_path / "r"
    _run(tmp_path, out)
    meta = yaml.safe_load((out / "meta.json").read_text())
    for name in ("runs.csv", "summary.csv"):
        # the project's reader keeps the id as text (pd.read_csv read "3643681614e0" as a float
        # and failed this test once: an identifier is never parsed as a number)
        assert set(bio.read_table(out / name)["run_id"]) == {meta["run_id"]}
    assert sorted(meta["files"]) == ["runs.csv", "summary.csv"]
    assert sorted(p.name for p in tmp_path.iterdir() if p.name.startswith(".")) == []


@pytest.mark.parametrize("fail_at", ["writing", "moving extras", "swap"])
def test_an_interrupted_write_leaves_the_old_generation(tmp_path, monkeypatch, fail_at):
    out = tmp_path / "r"
    _run(tmp_path, out)
    assert main(["report", str(out), "--no-figures"]) == 0
    (out / "notes.txt").write_text("the user's own file")  # moved into a new generation
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    if fail_at == "writing":
        real = bio.csv_text
        calls = []

        def interrupted(df):
            calls.append(1)
            if len(calls) == 2:  # after runs.csv, before summary.csv
                raise KeyboardInterrupt
            return real(df)
        monkeypatch.setattr(bio, "csv_text", interrupted)
    elif fail_at == "moving extras":
        real_rename = os.rename

        def interrupted(a, b):
            if str(a).endswith("notes.txt"):
                real_rename(a, b)
                raise KeyboardInterrupt
            return real_rename(a, b)
        monkeypatch.setattr(bio.os, "rename", interrupted)
    else:
        def interrupted(a, b):
            raise KeyboardInterrupt
        monkeypatch.setattr(bio, "_exchange", interrupted)
    cfg = write_cfg(tmp_path, ["FRad-A", "FRad-B"], name="new.yaml")
    assert main(["run", str(cfg), "--out", str(out), "--no-progress"]) == 130  # interrupted
    monkeypatch.undo()
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []
    assert main(["report", str(out), "--no-figures"]) == 0


def test_a_new_generation_replaces_the_old_and_drops_its_reports(tmp_path):
    """The old report described the old CSVs: it goes with them (issue 27, defect 5)."""
    out = tmp_path / "r"
    _run(tmp_path, out)
    assert main(["report", str(out), "--no-figures"]) == 0
    old_id = yaml.safe_load((out / "meta.json").read_text())["run_id"]
    _run(tmp_path, out, ("FRad-A", "FRad-B"), "new.yaml")
    meta = yaml.safe_load((out / "meta.json").read_text())
    assert meta["run_id"] != old_id and not (out / "report.md").exists()
    assert set(pd.read_csv(out / "summary.csv")["observer"]) == {"FRad-A", "FRad-B"}


@pytest.mark.parametrize("damage", ["mixed", "truncated", "broken meta", "broken summary",
                                    "no meta", "old meta"])
def test_report_refuses_mixed_truncated_or_broken_sets(tmp_path, capsys, damage):
    a, b = tmp_path / "a", tmp_path / "b"
    _run(tmp_path, a)
    if damage == "mixed":
        _run(tmp_path, b, ("FRad-A", "FRad-B"), "b.yaml")
        (a / "summary.csv").write_bytes((b / "summary.csv").read_bytes())
    elif damage == "truncated":
        data = (a / "runs.csv").read_bytes()
        (a / "runs.csv").write_bytes(data[: len(data) // 2])
    elif damage == "broken meta":
        (a / "meta.json").write_text('{"run_id": ')
    elif damage == "broken summary":
        (a / "summary.csv").write_bytes(b"\x00\xff garbage")
    elif damage == "no meta":
        (a / "meta.json").unlink()
    else:
        (a / "meta.json").write_text("{}")
    capsys.readouterr()
    assert main(["report", str(a), "--no-figures"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("error: ") and len(err.splitlines()) == 1, err
    assert not (a / "report.md").exists()


def test_files_get_the_users_umask(tmp_path):
    old = os.umask(0o022)
    try:
        out = tmp_path / "r"
        _run(tmp_path, out)
        assert main(["report", str(out)]) == 0
    finally:
        os.umask(old)
    for p in [out, *out.rglob("*")]:
        mode = stat.S_IMODE(p.stat().st_mode)
        assert mode == (0o755 if p.is_dir() else 0o644), (p, oct(mode))


def test_check_output_dir_messages(tmp_path):
    (tmp_path / "file").write_text("x")
    with pytest.raises(Exception, match=re.escape(f"{tmp_path / 'file'} is not a folder")):
        bio.check_output_dir(tmp_path / "file" / "x")
    assert bio.check_output_dir(tmp_path / "new" / "deeper") == tmp_path / "new" / "deeper"
    assert not (tmp_path / "new").exists()  # checking writes nothing


class BoxOnly:
    """A plugin's set with nothing but ``interval()``."""

    def __init__(self, lo, hi):
        self.box = Interval(lo, hi)

    def interval(self):
        return self.box


class PlainBoxes(Plain):
    def step(self, u_prev, y):
        I = super().step(u_prev, y)
        return BoxOnly(I.lo, I.hi)


def test_a_set_without_contains_is_undecided_not_contained(tmp_path):
    from benchmarks.run.membership import MembershipTester

    tester = MembershipTester()
    S = BoxOnly(np.zeros(2), np.ones(2))
    assert tester.test(S, np.array([0.5, 0.5]), 1e-9).inside is None
    assert tester.test(S, np.array([2.0, 0.5]), 1e-9).inside is False
    observers.register("Test-BoxOnly", family="strip", set_type="box",
                       ready_for_control=False)(PlainBoxes)
    try:
        cfg = write_cfg(tmp_path, ["Test-BoxOnly"])
        assert main(["run", str(cfg), "--out", str(tmp_path / "r"), "--no-progress"]) == 0
        assert set(literal(tmp_path / "r" / "summary.csv")["contained"]) == {"n/a"}
    finally:
        registry.unregister("Test-BoxOnly")


def test_temporary_folders_of_killed_writers_are_removed(tmp_path):
    """A writer killed by SIGKILL leaves its temporary folder; the next write removes it,
    but never the folder of a writer that is still running."""
    dead = tmp_path / ".r.new-999999999-0123456789ab"  # no such process
    running = tmp_path / f".r.new-{os.getpid()}-0123456789ab"
    for d in (dead, running):
        d.mkdir()
        (d / "runs.csv").write_text("half")
    _run(tmp_path, tmp_path / "r")
    assert not dead.exists() and running.is_dir()


def test_an_empty_estimate_on_a_true_trajectory_is_a_violation_at_its_step(tmp_path, capsys):
    """Issue 62: the record comes from a true trajectory, which no empty set contains, so an
    estimate that becomes empty is ``contained: no`` at that step (it was ``n/a``: a neutral
    status), counted as a violation, and ``run`` says so."""
    from observers.sets import EmptySet

    class EmptyAtFive(Plain):
        """Plain's boxes (they hold the true state), then an empty estimate at step 5."""

        def step(self, u_prev, y):
            if self.k == 5:
                raise EmptySet("the measurement strip misses the estimate (test)")
            return super().step(u_prev, y)

    s = _run_plugin(tmp_path, "Test-EmptyAtFive", EmptyAtFive, "interval", exit_code=1)
    row = s.loc["Test-EmptyAtFive"]
    assert (row["status"] == "empty").all()
    assert (row["failed_step"].astype(str) == "5").all()
    assert (row["contained"] == "no").all() and (row["violations"].astype(str) == "1").all()
    assert (row["first_violation_step"].astype(str) == "5").all()
    assert (s.loc["FRad-A", "contained"] == "yes").all()
    assert "Test-EmptyAtFive" in capsys.readouterr().err
