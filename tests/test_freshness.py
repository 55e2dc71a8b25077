"""Freshness of committed reports: content-hash stamps, and `check --reports` failing on stale."""

from __future__ import annotations

from pathlib import Path

from benchmarks.cli import main
from benchmarks.report import freshness
from tests.test_regression import gate, subset

ROOT = Path(__file__).resolve().parents[1]


def fake_tree(tmp_path: Path) -> Path:
    root = tmp_path / "tree"
    for d in ("observers", "systems/data", "benchmarks/configs"):
        (root / d).mkdir(parents=True)
    (root / "observers" / "a.py").write_text("x = 1\n")
    (root / "systems" / "data" / "m.csv").write_text("1,2\n")
    (root / "benchmarks" / "configs" / "t.yaml").write_text("name: t\n")
    (root / "benchmarks" / "b.py").write_text("y = 2\n")
    return root


def write_report(root: Path, folder: Path, config: str | None) -> Path:
    folder.mkdir(exist_ok=True)
    path = folder / "t.md"
    path.write_text("# t\n\n" + freshness.stamp("make t", config, root) + "\n")
    return path


def test_hash_covers_code_data_and_config_only(tmp_path):
    root = fake_tree(tmp_path)
    h = freshness.content_hash("benchmarks/configs/t.yaml", root)
    assert h == freshness.content_hash("benchmarks/configs/t.yaml", root)  # deterministic
    (root / "notes.txt").write_text("outside the hashed set")
    (root / "observers" / "__pycache__").mkdir()
    (root / "observers" / "__pycache__" / "a.pyc").write_bytes(b"\0")
    assert freshness.content_hash("benchmarks/configs/t.yaml", root) == h
    for rel, text in (("observers/a.py", "x = 2\n"), ("systems/data/m.csv", "1,3\n"),
                      ("benchmarks/configs/t.yaml", "name: u\n")):
        old = (root / rel).read_text()
        (root / rel).write_text(text)
        assert freshness.content_hash("benchmarks/configs/t.yaml", root) != h, rel
        (root / rel).write_text(old)
    assert freshness.content_hash("benchmarks/configs/t.yaml", root) == h
    # another configuration does not enter this report's hash
    (root / "benchmarks" / "configs" / "other.yaml").write_text("name: other\n")
    assert freshness.content_hash("benchmarks/configs/t.yaml", root) == h


def test_stale_report_is_named_with_its_command_and_fresh_after_regeneration(tmp_path):
    root = fake_tree(tmp_path)
    reports = tmp_path / "reports"
    path = write_report(root, reports, "benchmarks/configs/t.yaml")
    (reports / "README.md").write_text("index, never stamped\n")
    assert freshness.stale_reports(reports, root) == []
    (root / "observers" / "a.py").write_text("x = 3\n")
    stale = freshness.stale_reports(reports, root)
    assert [s.report for s in stale] == [path] and stale[0].command == "make t"
    assert "t.md" in freshness.format_stale(stale) and "make t" in freshness.format_stale(stale)
    write_report(root, reports, "benchmarks/configs/t.yaml")  # regenerated
    assert freshness.stale_reports(reports, root) == []
    (reports / "old.md").write_text("# no stamp\n")
    assert [s.reason for s in freshness.stale_reports(reports, root)] == ["no freshness stamp"]


def test_check_fails_on_a_stale_report_and_passes_after_regeneration(tmp_path, capsys):
    cfg = subset(tmp_path, observers_=("FRad-A",), scenarios=["alamo2d"])
    assert gate(tmp_path, "baseline", cfg, "--update") == 0
    reports = tmp_path / "reports"
    reports.mkdir()
    stale = reports / "x.md"
    stale.write_text("# x\n<!-- freshness: sha256=00 config=- command=regen-x -->\n")
    assert gate(tmp_path, "check", cfg, "--reports", str(reports)) == 1
    err = capsys.readouterr().err
    assert "STALE REPORT" in err and "x.md" in err and "regen-x" in err
    stale.write_text("# x\n" + freshness.stamp("regen-x") + "\n")
    assert gate(tmp_path, "check", cfg, "--reports", str(reports)) == 0


def test_report_command_writes_a_fresh_stamp(tmp_path):
    out = tmp_path / "r"
    cfg = subset(tmp_path, observers_=("FRad-A",), scenarios=["alamo2d"])
    assert main(["run", str(cfg), "--out", str(out), "--no-progress"]) == 0
    md = tmp_path / "reports" / "mini.md"
    md.parent.mkdir()
    assert main(["report", str(out), "--no-figures", "--out", str(md)]) == 0
    assert "<!-- freshness: sha256=" in md.read_text()
    assert freshness.stale_reports(md.parent) == []


def test_committed_reports_have_a_regeneration_command():
    for s in freshness.stale_reports(ROOT / "reports"):
        assert s.command.startswith("python -m benchmarks"), s
