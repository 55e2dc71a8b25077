"""The command line the table-producing studies share (:mod:`benchmarks.studies.cli`): bad
input is one line and exit code 2 before any work, and ``--render`` re-renders a committed
table without running the study."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from benchmarks.io import read_table
from benchmarks.studies import kernels, noise_grid, robustness

ROOT = Path(__file__).resolve().parents[1]
STUDIES = {"robustness": robustness.main, "noise_grid": noise_grid.main, "kernels": kernels.main}


def _one_error_line(capsys) -> str:
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: "), err
    return err[0]


@pytest.mark.parametrize("study", sorted(STUDIES))
def test_a_count_below_one_is_refused_in_one_line(study, tmp_path, capsys):
    capsys.readouterr()
    assert STUDIES[study](["--jobs", "0", "--out", str(tmp_path / "r.md"),
                           "--results", str(tmp_path)]) == 2
    assert "--jobs must be >= 1" in _one_error_line(capsys)
    assert not (tmp_path / "r.md").exists()


def test_both_bad_counts_are_named(tmp_path, capsys):
    capsys.readouterr()
    assert robustness.main(["--jobs", "0", "--realisations", "0", "--results",
                            str(tmp_path)]) == 2
    assert "--jobs and --realisations must be >= 1" in _one_error_line(capsys)


@pytest.mark.parametrize("study", sorted(STUDIES))
def test_render_without_a_table_is_one_line(study, tmp_path, capsys):
    capsys.readouterr()
    assert STUDIES[study](["--render", "--out", str(tmp_path / "r.md"),
                           "--results", str(tmp_path / "none")]) == 2
    line = _one_error_line(capsys)
    assert "no table" in line and "run the study first" in line


def test_render_of_the_committed_kernel_table_names_what_it_compared(tmp_path, capsys):
    """``--render`` reads the committed table (nothing is run) and writes the report: the
    number of cells compared is the table's own count."""
    table = ROOT / kernels.TABLE
    dest = tmp_path / kernels.TABLE
    dest.parent.mkdir(parents=True)
    shutil.copy(table, dest)
    out = tmp_path / "kernels.md"
    assert kernels.main(["--render", "--out", str(out), "--results",
                         str(tmp_path / "results")]) == 0
    df = read_table(dest, dtype={"status_other": str})
    ok = df[(df["status_here"] == "ok") & (df["status_other"].fillna("") == "")]
    assert f"**{len(ok)} accuracy cells compared" in out.read_text()
    assert capsys.readouterr().err.strip().startswith("wrote ")
