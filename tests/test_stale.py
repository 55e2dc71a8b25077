"""`setobs-bench stale` on the committed stores: exit 0 on the committed tree, and after an edit
exactly the rows whose code the edit touched (the acceptance of the result-store issue).

Each case edits a copy of the tree and runs ``python -m benchmarks stale`` there (the command
line of the copy: its code, its stores, its reports)."""

from __future__ import annotations

import json
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest

import observers
from benchmarks.cli import main
from benchmarks.store.bench import render_all

ROOT = Path(__file__).resolve().parents[1]
ROW = re.compile(r"^STALE ROW (\S+): (\S+) on (\S+)")


def _stored_rows() -> pd.DataFrame:
    """``config, observer`` of every stored row (one per key), read from the stores' files
    (the published configurations' and the soundness audit's)."""
    out = []
    for meta in sorted((ROOT / "results").glob("*/meta.json")):
        rows = json.loads(meta.read_text()).get("rows")
        if rows is None:
            continue
        # a configuration's key is scenario|seed|observer|variant, the audit's scenario|observer
        out += [(meta.parent.name, key.split("|")[2 if key.count("|") == 3 else 1])
                for key in rows]
    return pd.DataFrame(out, columns=["config", "observer"])


@pytest.fixture(scope="module")
def stored():
    rows = _stored_rows()
    assert len(rows) > 500 and rows["config"].nunique() >= 15  # every table and the audit
    return rows


def _tree(dst: Path) -> Path:
    for pkg in ("observers", "systems", "benchmarks"):
        shutil.copytree(ROOT / pkg, dst / pkg, symlinks=True, ignore=shutil.ignore_patterns(
            "__pycache__", "*.nbi", "*.nbc", "*.pyc"))
    (dst / "reports").mkdir()
    for md in (ROOT / "reports").glob("*.md"):
        shutil.copy2(md, dst / "reports" / md.name)
    (dst / "results").mkdir()
    shutil.copy2(ROOT / "results" / "reports.json", dst / "results" / "reports.json")
    # the golden files: the measured kernel spreads printed in the cells of PRad-A
    shutil.copytree(ROOT / "results" / "baseline", dst / "results" / "baseline")
    # the kernel study: the spreads printed beside the cells of the paper tables
    shutil.copytree(ROOT / "results" / "kernels", dst / "results" / "kernels")
    for meta in (ROOT / "results").glob("*/meta.json"):
        if not (meta.parent / "summary.csv").is_file():
            continue  # the golden files of the gate, not a store
        (dst / "results" / meta.parent.name).mkdir()
        for name in ("meta.json", "summary.csv"):
            shutil.copy2(meta.parent / name, dst / "results" / meta.parent.name / name)
    return dst


def _stale(tree: Path) -> tuple[int, list[str]]:
    done = subprocess.run([sys.executable, "-m", "benchmarks", "stale"], cwd=tree,
                          capture_output=True, text=True, timeout=300)
    assert done.returncode in (0, 1), done.stderr
    return done.returncode, done.stdout.splitlines()


def _first_tier(lines: list[str]) -> list[str]:
    """The lines of ``stale`` that a landing waits for (not the dated reports' ``DATED``)."""
    return [line for line in lines if not line.startswith("DATED")]


def _edit(path: Path, old: str, new: str) -> None:
    text = path.read_text()
    assert old in text
    path.write_text(text.replace(old, new, 1))


_IMPORT = re.compile(r"^[ \t]*from[ \t]+(\.*)([\w.]*)[ \t]+import[ \t]+"
                     r"(?:\(([^)]*)\)|([\w \t,]+))", re.M)


def _importers_of(target: str) -> set[str]:
    """The modules of ``observers`` whose ``from ... import`` lines reach ``target``, by text
    (every line, at any depth: a lazy import runs too)."""
    files = {".".join(p.relative_to(ROOT).with_suffix("").parts).removesuffix(".__init__"): p
             for p in (ROOT / "observers").rglob("*.py") if "__pycache__" not in p.parts}
    edges: dict[str, set[str]] = {}
    for mod, path in files.items():
        pkg = mod.split(".") if path.name == "__init__.py" else mod.split(".")[:-1]
        for dots, base, inside, plain in _IMPORT.findall(path.read_text()):
            names = inside or plain
            anchor = pkg[: len(pkg) - (len(dots) - 1)] if dots else []
            base = ".".join([*anchor, *([base] if base else [])])
            for name in re.findall(r"\w+", names):
                edges.setdefault(mod, set()).add(f"{base}.{name}" if f"{base}.{name}" in files
                                                 else base)
    reach, grew = {target}, True
    while grew:
        new = {m for m, deps in edges.items() if deps & reach} - reach
        reach |= new
        grew = bool(new)
    return reach


def _all_observer_studies() -> set[str]:
    """The committed study reports that run every guaranteed observer."""
    return {name for name in ("noise_grid", "robustness")
            if (ROOT / "reports" / f"{name}.md").is_file()}


def _base(name: str) -> str:
    return name.split("[")[0]  # a labelled variant runs its observer


def test_nothing_is_stale_on_the_committed_tree(capsys, stored):
    assert main(["stale"]) == 0, capsys.readouterr().out


def test_make_reports_on_the_committed_tree_changes_no_file(tmp_path):
    reports = tmp_path / "reports"
    shutil.copytree(ROOT / "reports", reports)
    assert render_all(ROOT / "results", reports) == []


@pytest.mark.heavy
def test_a_docstring_edit_stales_nothing(tmp_path):
    tree = _tree(tmp_path)
    path = tree / "observers" / "numerics" / "frad.py"
    text = path.read_text()
    first = text.index('"""') + 3
    path.write_text(text[:first] + "An edited line of the docstring.\n" + text[first:]
                    + "\n# a comment at the end\n")
    code, lines = _stale(tree)
    assert code == 0 and _first_tier(lines) == []
    assert lines == _stale(_tree(tmp_path / "unedited"))[1]  # nor a dated report's rows


def test_an_edit_of_the_ellipsoidal_numerics_stales_their_observers_only(tmp_path, stored):
    tree = _tree(tmp_path)
    path = tree / "observers" / "numerics" / "ellipsoidal.py"
    path.write_text(path.read_text() + "\n_EDITED = 1\n")
    code, lines = _stale(tree)
    assert code == 1
    # independently of the graph (text, not syntax trees): the observers whose module reaches
    # the ellipsoidal numerics through import lines (Nom-G, Hinf-G and PRad-E through a lazy
    # import in the Luenberger numerics)
    reach = _importers_of("observers.numerics.ellipsoidal")
    expected = {i.name for i in observers.available() if i.cls.__module__ in reach}
    assert {"ESO-A", "ESO-B", "ESO-C", "ESO-D", "ESMF"} <= expected
    assert "FRad-A" not in expected and "CZN-A" not in expected
    # besides the rows, only dated blocks (second tier) say something changed
    others = [line for line in _first_tier(lines) if not line.startswith("STALE ROW")]
    assert all("dated block" in line for line in others), others
    rows = [line for line in lines if line.startswith("STALE ROW")]
    named = [ROW.match(line) for line in rows]
    assert all(named), [line for line, m in zip(rows, named, strict=True) if not m]
    assert {_base(m.group(2)) for m in named} <= expected
    assert {m.group(1) for m in named} <= set(stored["config"]) - {"soundness"}
    tables = stored[stored["config"] != "soundness"]
    assert len(named) == len(tables[tables["observer"].map(_base).isin(expected)])
    assert all("observers/numerics/ellipsoidal.py" in line for line in rows)


@pytest.mark.heavy
def test_the_robustness_report_names_the_rows_changed_since(tmp_path):
    """A dated report says which of its rows the code has changed since it was measured
    (rendered by `make reports`), without being stale itself."""
    tree = _tree(tmp_path)
    path = tree / "observers" / "numerics" / "ellipsoidal.py"
    path.write_text(path.read_text() + "\n_EDITED = 1\n")
    done = subprocess.run([sys.executable, "-m", "benchmarks", "reports"], cwd=tree,
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    text = (tree / "reports" / "robustness.md").read_text()
    block = text[text.index("<!-- dated -->"):text.index("<!-- /dated -->")]
    assert "Measured by setobs-bench" in block and "at commit" in block
    # the rows of the block, with their modules (the block shows the first 12 of them)
    code = ("import json; from benchmarks.gate import dated; "
            "print(json.dumps(dated.changed_rows('robustness')))")
    done = subprocess.run([sys.executable, "-c", code], cwd=tree, capture_output=True,
                          text=True, timeout=300)
    changed = json.loads(done.stdout)
    for name in ("ESO-A", "ESO-B", "ESO-C", "ESO-D"):
        assert "observers/numerics/ellipsoidal.py" in changed[name], name
    assert "observers/numerics/ellipsoidal.py" not in changed.get("FRad-A", [])
    assert "observers/numerics/ellipsoidal.py" not in changed.get("CZN-A", [])
    _, lines = _stale(tree)  # its block is current again; the rows of the tables are stale
    assert not [line for line in lines if "dated block" in line], lines
    assert any(line.startswith("DATED robustness") for line in lines), lines


@pytest.mark.parametrize("edited", ["benchmarks/run/executors.py", "benchmarks/io.py",
                                    "benchmarks/run/falsifier/search.py"])
def test_an_edit_of_orchestration_or_the_falsifier_stales_no_linear_row(tmp_path, edited):
    """The executors and ``io`` are in no row's code, the falsifier only in the nonlinear
    rows' (issue: each of them staled every row)."""
    tree = _tree(tmp_path)
    path = tree / edited
    path.write_text(path.read_text() + "\n_EDITED = 1\n")
    _, lines = _stale(tree)
    rows = [ROW.match(line) for line in lines if line.startswith("STALE ROW")]
    if "falsifier" not in edited:
        assert rows == [], lines
        return
    # the linearity of each stored row's record, from its configuration's scenarios
    from benchmarks.run.config import load_config
    from benchmarks.run.shipped import shipped_configs

    linear = {}
    for name in {m.group(1) for m in rows}:
        for sc in load_config(shipped_configs()[name]).scenarios:
            linear[(name, sc.name)] = getattr(sc.system, "is_linear", False)
    assert rows  # the nonlinear rows with a falsifier floor, and only those
    assert not [m.group(0) for m in rows if linear[(m.group(1), m.group(3).rstrip(":"))]]


#: the set types whose interval hull is computed by the hull LPs (``observers.lp.hull``)
LP_HULL_SETS = {"conzonotope", "bundle"}
#: observers of the papers' tables whose sets need no LP hull (their hull is closed-form)
NO_LP_HULL = {"VolMin-A", "VolMin-B", "FRad-A", "FRad-B", "FRad-C", "PRad-A", "PRad-B",
              "PRad-C-I", "PRad-C-II", "PRad-D", "PRad-E", "Nom-G", "Hinf-G", "ESO-A", "ESO-B",
              "ESO-C", "ESO-D", "ESMF", "ROPO", "INT-CP", "Exact"}


def test_an_edit_of_the_hull_lps_stales_only_rows_with_an_lp_hull(tmp_path, stored):
    """The hull LPs (dual simplex, sifting) are in the code of the rows whose sets have an LP
    hull only: the zonotope types' membership test is apart from them (``observers.lp.
    feasible``), the harness tells set types apart by what they offer and the exact floor
    solves its LPs by HiGHS (issue: an edit of ``observers/lp/`` staled 1028 of 1231 rows)."""
    tree = _tree(tmp_path)
    path = tree / "observers" / "lp" / "sifting_jit.py"  # the example: the sifting
    path.write_text(path.read_text() + "\n_EDITED = 1\n")
    _, lines = _stale(tree)
    named = [ROW.match(line) for line in lines if line.startswith("STALE ROW")]
    assert all(named)
    assert all("observers/lp/sifting_jit.py" in m.string for m in named)
    stale = {_base(m.group(2)) for m in named}
    with_hull = {i.name for i in observers.available() if i.set_type in LP_HULL_SETS}
    tables = stored[stored["config"] != "soundness"]
    # every stored row of an observer with an LP hull is stale, and no row of the others
    assert with_hull & set(tables["observer"].map(_base)) <= stale
    assert not stale & NO_LP_HULL, sorted(stale & NO_LP_HULL)
    assert len(named) < len(tables) / 2


def test_an_edit_of_the_zonotope_stales_every_row_that_uses_zonotopes(tmp_path, stored):
    tree = _tree(tmp_path)
    path = tree / "observers" / "sets" / "zonotope.py"
    path.write_text(path.read_text() + "\n_EDITED = 1\n")
    code, lines = _stale(tree)
    assert code == 1
    rows = [line for line in lines if line.startswith("STALE ROW")]
    named = [ROW.match(line) for line in rows]
    assert all(named)
    # the harness builds every record's sets as zonotopes and intervals: every row of every
    # table (the audit's are a dated measurement: its block says they changed)
    assert len(named) == len(stored[stored["config"] != "soundness"])
    assert all("observers/sets/zonotope.py" in line for line in rows)
    assert all("dated block" in line for line in _first_tier(lines) if line not in rows)


def test_a_report_rendered_from_another_store_is_named(tmp_path):
    tree = _tree(tmp_path)
    _edit(tree / "reports" / "arch2021_table3.md", "FRad-A", "FRad-Z")
    code, lines = _stale(tree)
    assert code == 1
    assert _first_tier(lines) == [
        "STALE REPORT arch2021_table3: reports/arch2021_table3.md differs from its store "
        "rendered now (`make reports` renders it)"]


def test_the_study_record_names_the_observers_the_study_runs():
    from benchmarks.gate.dated import DATED
    from benchmarks.studies import alanwar2022

    assert set(DATED["datadriven"].observers) == {*alanwar2022.DD, alanwar2022.KF}
