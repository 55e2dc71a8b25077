"""Command-line conventions: ``setobs-bench --version`` from the package metadata, a run without
a YAML file, tqdm progress bars that stay out of pipes, and the accuracy history read from git."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest

from benchmarks import load_config, run_config
from benchmarks.cli import main
from benchmarks.gate import history

ROOT = Path(__file__).resolve().parents[1]


def _pyproject_version() -> str:
    text = (ROOT / "pyproject.toml").read_text()
    return re.search(r'^version = "([^"]+)"', text, re.M).group(1)


def test_version_of_the_installed_command():
    exe = Path(sys.executable).parent / "setobs-bench"
    assert exe.is_file(), "setobs-bench is not installed (pip install -e .)"
    proc = subprocess.run([str(exe), "--version"], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0
    assert proc.stdout.splitlines()[0] == f"setobs-bench {_pyproject_version()}"


def test_run_without_a_config(tmp_path, capsys):
    out = tmp_path / "o"
    assert main(["run", "--observer", "FRad-A", "--scenario", "alamo2d", "--out", str(out)]) == 0
    summary = pd.read_csv(out / "summary.csv")
    assert set(summary["observer"]) == {"FRad-A"} and set(summary["scenario"]) == {"alamo2d"}
    assert capsys.readouterr().err == ""  # not a terminal: no progress bar in the output


@pytest.mark.parametrize(("argv", "message"), [
    (["run"], "give a YAML config or at least one --scenario"),
    (["run", "x.yaml", "--scenario", "alamo2d"], "not both"),
    (["run", "--scenario", "nowhere"], "nowhere"),
    (["run", "--scenario", "alamo2d", "--observer", "FRad-Z"], "FRad-Z"),
])
def test_run_without_a_config_bad_input(argv, message, capsys, tmp_path):
    assert main(argv + ["--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and message in err and len(err.strip().splitlines()) == 1


def test_progress_bar_only_when_asked(tmp_path, capsys):
    path = tmp_path / "c.yaml"
    path.write_text("scenarios: [alamo2d]\nobservers: [FRad-A, FRad-B]\ncontainment: hull\n")
    cfg = load_config(path)
    run_config(cfg, progress=True)
    err = capsys.readouterr().err
    assert "2/2" in err and "alamo2d: FRad-B ok" in err  # tqdm's counter and our note
    run_config(cfg)  # default: only on a terminal, and pytest's stderr is not one
    assert capsys.readouterr().err == ""


def _git(cwd: Path, *args: str) -> None:
    subprocess.run(["git", "-c", "user.name=t", "-c", "user.email=t@example.org", *args],
                   cwd=cwd, check=True, capture_output=True)


GOLDEN = ("scenario,observer,state,state_name,status,guaranteed,rms_radius,rel_rms,violations,"
          "rtol\n")


def test_history_from_a_small_repository(tmp_path):
    base = tmp_path / "results" / "baseline"
    base.mkdir(parents=True)
    _git(tmp_path, "init", "-q")
    rows = ["s,A,0,x1,ok,True,1.0,1.0,0,1e-6", "s,A,1,x2,ok,True,2.0,1.0,0,1e-6",
            "s,B,0,x1,ok,True,2.0,2.0,0,1e-6", "s,B,1,x2,ok,True,6.0,3.0,0,1e-6"]
    (base / "s.csv").write_text(GOLDEN + "\n".join(rows) + "\n")
    _git(tmp_path, "add", ".")
    _git(tmp_path, "commit", "-q", "-m", "first")
    (tmp_path / "other.txt").write_text("not a baseline change\n")
    _git(tmp_path, "add", ".")
    _git(tmp_path, "commit", "-q", "-m", "unrelated")
    rows[3] = "s,B,1,x2,ok,True,8.0,4.0,2,1e-6"  # B got looser in x2 and lost containment
    (base / "s.csv").write_text(GOLDEN + "\n".join(rows) + "\n")
    _git(tmp_path, "commit", "-q", "-am", "looser")
    page, table = history.write_history(base, tmp_path / "h")
    assert list(dict.fromkeys(table["subject"])) == ["first", "looser"]
    b = table[table["observer"] == "B"]
    assert b["rel_rms"].tolist() == [2.5, 3.0] and b["violations"].tolist() == [0, 2]
    ch = history.changes(table)
    assert ch["observer"].tolist() == ["B"] and ch["after"].iloc[0] == 3.0
    text = page.read_text()
    assert "looser" in text and (tmp_path / "h" / "figures" / "s_history.pdf").is_file()


def test_history_of_this_repository(tmp_path):
    if subprocess.run(["git", "rev-parse"], cwd=ROOT, capture_output=True).returncode:
        pytest.skip("not a git checkout")
    assert main(["history", "--baseline", str(ROOT / "results" / "baseline"),
                 "--out", str(tmp_path)]) == 0
    table = pd.read_csv(tmp_path / "history.csv")
    current = pd.concat(pd.read_csv(p) for p in (ROOT / "results" / "baseline").glob("*.csv"))
    assert table["commit"].nunique() >= 1
    last = table[table["commit"] == table["commit"].iloc[-1]]
    assert set(last["observer"]) == set(current["observer"])
    assert (tmp_path / "index.html").is_file()


def test_history_outside_git(tmp_path):
    (tmp_path / "b").mkdir()
    assert main(["history", "--baseline", str(tmp_path / "b"), "--out", str(tmp_path)]) == 2


def test_progress_shown_in_a_notebook(monkeypatch):
    from benchmarks.run.progress import progress_enabled

    monkeypatch.delitem(sys.modules, "ipykernel", raising=False)
    assert progress_enabled(None) is sys.stderr.isatty()
    assert progress_enabled(True) and not progress_enabled(False)
    monkeypatch.setitem(sys.modules, "ipykernel", object())  # as inside a Jupyter kernel
    assert progress_enabled(None) and not progress_enabled(False)


@pytest.mark.parametrize(("argv", "bad"), [
    (["run", "arch2021_table3", "--add", "NC-Good", "--addr", "tcp://127.0.0.1:1"], "--addr"),
    (["run", "arch2021_table3", "--obs", "FRad-A"], "--obs"),
    (["bench", "--col"], "--col"),
])
def test_options_are_never_abbreviated(argv, bad, capsys):
    """``--add`` was once read as an abbreviation of ``--address``; a prefix is now an error
    naming the option, before any work."""
    with pytest.raises(SystemExit) as exc:
        main(argv)
    err = capsys.readouterr().err
    assert exc.value.code == 2 and "unrecognized arguments" in err and bad in err


def test_add_is_its_own_option():
    from benchmarks.cli import build_parser

    args = build_parser().parse_args(["run", "arch2021_table3", "--add", "My-Obs"])
    assert args.add == "My-Obs" and args.address is None


def test_a_reader_that_leaves_early_ends_the_command_quietly():
    # ``setobs-bench list | head -1``: the pipe closes before the command writes; it stops
    # with 141 (128 + SIGPIPE) and no traceback
    proc = subprocess.Popen([sys.executable, "-m", "benchmarks", "list"], cwd=ROOT,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    proc.stdout.close()
    err = proc.stderr.read().decode()
    assert proc.wait(timeout=120) == 141
    assert "Traceback" not in err and "Exception ignored" not in err
