"""Every report ends with what to cite: the paper whose table it reproduces (where there is
one), the papers whose published values it shows, and the project with its version."""

from __future__ import annotations

import json
from importlib import metadata
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from benchmarks.gate import audit_store
from benchmarks.report import citation
from benchmarks.report.html import write_html, write_index
from benchmarks.report.markdown import render_report, write_report
from benchmarks.run.shipped import shipped_configs
from benchmarks.store.store import load_store
from benchmarks.studies import frontier

ROOT = Path(__file__).resolve().parents[1]
VERSION = metadata.version("setobs-bench")
PROJECT_LINE = f"setobs-bench {VERSION} (CITATION.cff)."

#: the title of the paper each configuration reproduces (written out here, independently of
#: benchmarks.report.citation)
REPRODUCED = {
    "arch2021_table3": ("Guaranteed State Estimation in CORA 2021", "Table 3"),
    "arch2021_table4": ("Guaranteed State Estimation in CORA 2021", "Table 4"),
    "arch2021_table5": ("Guaranteed State Estimation in CORA 2021", "Table 5"),
    "arch2021_table6": ("Guaranteed State Estimation in CORA 2021", "Table 6"),
    "arch2021_table6_12tanks": ("Guaranteed State Estimation in CORA 2021", "Table 6"),
    "automatica2021_table3": ("Comparison of Guaranteed State Estimators for Linear "
                              "Time-Invariant Systems", "Table 3"),
    "alanwar2022": ("Data-Driven Set-Based Estimation using Matrix Zonotopes", "Sec. IV"),
}


def _stores() -> list[str]:
    return sorted(m.parent.name for m in (ROOT / "results").glob("*/meta.json")
                  if m.parent.name in shipped_configs() and (m.parent / "summary.csv").is_file())


def _citation_block(text: str) -> list[str]:
    """The last paragraph of a Markdown text: its lines from the one starting with Cite:."""
    lines = text.rstrip("\n").split("\n")
    starts = [i for i, line in enumerate(lines) if line.startswith("Cite: ")]
    assert starts, text[-500:]
    return lines[starts[-1]:]


def test_the_stores_are_found():
    assert set(REPRODUCED) <= set(_stores())


@pytest.mark.parametrize("name", _stores())
def test_a_report_rendered_from_a_store_ends_with_its_citation_lines(name, tmp_path):
    store = load_store(ROOT / "results" / name)
    out = write_report(ROOT / "results" / name, tmp_path / f"{name}.md", figures=False,
                       data=store.view())
    text = out.read_text(encoding="utf-8")
    block = _citation_block(text)
    assert text.endswith("\n".join(block) + "\n")  # nothing after the citation lines
    assert block[-1].removeprefix("Cite: ") == PROJECT_LINE
    if name in REPRODUCED:
        title, what = REPRODUCED[name]
        assert block[0].startswith("Cite: ") and title in block[0] and what in block[0]
        assert "reproduced" in block[0]
    else:
        assert not any("reproduced" in line for line in block)
    # a paper named for its published values is one whose table the report names
    for line in block[:-1]:
        if "published values" in line:
            paper = next(p for p in citation.PAPERS.values() if p.title in line)
            assert str(paper.year) in line
            assert "In parentheses:" in text


def test_a_report_without_a_paper_cites_the_project_alone(tmp_path):
    store = load_store(ROOT / "results" / "volmin_a")
    text = render_report(*store.view(), tmp_path / "volmin_a.md")
    assert _citation_block(text) == [f"Cite: {PROJECT_LINE}"]


def test_the_paper_lines_follow_the_configuration_not_its_title(tmp_path):
    summary, meta = load_store(ROOT / "results" / "arch2021_table3").view()
    meta = {**meta, "config": {**meta["config"], "name": "automatica2021_table3"}}
    block = _citation_block(render_report(summary, meta, tmp_path / "x.md"))
    assert "Comparison of Guaranteed State Estimators" in block[0]
    assert any("CORA 2021" in line and "published values" in line for line in block)


def test_a_run_report_has_its_citation_lines_before_its_stamp(tmp_path):
    summary, meta = load_store(ROOT / "results" / "automatica2021_table3").view()
    meta = {k: v for k, v in meta.items() if k != "runs"}  # a run's meta, not a store's
    lines = render_report(summary, meta, tmp_path / "report.md").rstrip("\n").split("\n")
    assert lines[-1].startswith("<!-- freshness: ")
    assert lines[-3] == PROJECT_LINE and lines[-2] == ""
    assert "Comparison of Guaranteed State Estimators" in lines[-4]


def test_the_html_report_ends_with_the_citation(tmp_path):
    folder = ROOT / "results" / "arch2021_table4"
    page = write_html(folder, tmp_path / "index.html", figures=False,
                      data=load_store(folder).view()).read_text(encoding="utf-8")
    body = page[:page.rindex("</body>")].rstrip()
    assert body.endswith("</p>")
    last = body[body.rindex('<p class="cite">'):]
    assert "Cite: M. Althoff, &quot;Guaranteed State Estimation in CORA 2021&quot;" in last
    assert "Table 4" in last and f"setobs-bench {VERSION} (CITATION.cff)" in last


def test_the_index_page_ends_with_the_project_line(tmp_path):
    reports = tmp_path / "reports"
    reports.mkdir()
    (reports / "a.md").write_text("# A\n")
    page = write_index(reports).read_text(encoding="utf-8")
    last = page[page.rindex('<p class="cite">'):page.rindex("</body>")]
    assert f"Cite: setobs-bench {VERSION} (CITATION.cff)." in last


def test_the_soundness_report_cites_the_project(tmp_path):
    store = load_store(ROOT / "results" / "soundness", audit_store.LAYOUT)
    text = audit_store.render(store)
    assert _citation_block(text) == [f"Cite: {PROJECT_LINE}"]
    assert text.endswith(PROJECT_LINE + "\n")


def test_a_study_report_ends_with_the_project_line(tmp_path):
    df = pd.DataFrame({
        "record": ["alamo2d-sim"], "steps": [20], "kalman_ms": [0.01], "observer": ["FRad-A"],
        "knob": ["order"], "value": [5], "status": ["ok"], "message": [""], "gap": [1.5],
        "cost_ms": [0.1], "cost_ratio": [10.0], "covers_exact": ["yes"], "violations": [0],
        "pareto": [True]})
    fig = tmp_path / "frontier.png"
    fig.write_bytes(b"")
    text = frontier.report(df, fig, tmp_path / "frontier.md", budget=1.0, elapsed=np.float64(1))
    assert _citation_block(text) == [f"Cite: {PROJECT_LINE}"]


def test_every_published_table_and_reproduced_report_has_its_paper():
    tables = {p.stem for p in (ROOT / "systems" / "data" / "paper_tables").glob("*.yaml")}
    assert tables == set(citation.TABLE_PAPERS)
    assert set(citation.TABLE_PAPERS.values()) <= set(citation.PAPERS)
    assert {key for key, _ in citation.REPRODUCES.values()} <= set(citation.PAPERS)
    studies = {"datadriven"}
    assert set(citation.REPRODUCES) <= set(shipped_configs()) | studies


def test_the_project_line_carries_the_installed_version(monkeypatch):
    assert citation.project_line() == f"setobs-bench {VERSION} (CITATION.cff)"

    def missing(name):
        raise metadata.PackageNotFoundError(name)

    monkeypatch.setattr(citation.metadata, "version", missing)
    assert citation.project_line() == "setobs-bench unknown (CITATION.cff)"


def test_the_committed_reports_of_the_stores_carry_the_citation():
    for name in _stores():
        text = (ROOT / "reports" / f"{name}.md").read_text(encoding="utf-8")
        assert text.endswith(PROJECT_LINE + "\n"), name
    meta = json.loads((ROOT / "results" / "soundness" / "meta.json").read_text())
    assert meta  # the audit's store is there, and so is its report's line:
    assert (ROOT / "reports" / "soundness.md").read_text().endswith(PROJECT_LINE + "\n")


def test_every_committed_report_ends_with_the_project_line():
    """Issue 42: every committed report (stores, audit, studies and timing reports) ends with
    what to cite; a measured report keeps its provenance stamp as the very last line."""
    from benchmarks.gate import dated

    records = dated.read_records(ROOT)
    reports = sorted(p for p in (ROOT / "reports").glob("*.md") if p.name != "README.md")
    assert len(reports) >= 18
    for path in reports:
        lines = [ln for ln in path.read_text(encoding="utf-8").splitlines()
                 if ln.strip() and not ln.startswith("<!--")]
        if path.stem in dated.DATED or path.stem == "kernels":
            # a dated measurement cites the version that measured it (its dated block's)
            line = f"setobs-bench {records[path.stem]['version']} (CITATION.cff)"
        else:
            line = citation.project_line()
        assert line in lines[-1], path.name
