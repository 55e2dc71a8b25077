"""The full soundness audit as a result store: only stale pairs run, the report is a view."""

from __future__ import annotations

import pytest

from benchmarks.gate import audit, audit_store


@pytest.fixture
def small_audit(monkeypatch, tmp_path):
    """The audit reduced to one scenario and two observers (the mechanism, not the evidence)."""
    monkeypatch.setattr(audit, "AUDIT_SCENARIOS", ("alamo2d-sim",))
    chosen = ["FRad-A", "INT-CP"]
    monkeypatch.setattr(audit_store, "audited_observers", lambda: list(chosen))
    (tmp_path / "reports").mkdir()
    return tmp_path, chosen


def _bench(root, **kw):
    return audit_store.bench_audit(2, 1, results=root / "results", reports=root / "reports",
                                   progress=False, notify=lambda _: None, **kw)


def test_the_audit_runs_only_its_stale_pairs(small_audit):
    root, chosen = small_audit
    store, df, ran = _bench(root)
    assert ran == 2 and set(df["observer"]) == {"FRad-A", "INT-CP"}
    text = (root / "reports" / "soundness.md").read_text()
    assert "| FRad-A | alamo2d-sim |" in text and "Rendered from the result store" in text
    assert audit_store.stale_lines(root) == []
    _, df, ran = _bench(root)
    assert (ran, df) == (0, None)
    assert (root / "reports" / "soundness.md").read_text() == text
    chosen.append("FRad-B")  # a new observer: only its pair runs
    store, df, ran = _bench(root)
    assert ran == 1 and set(df["observer"]) == {"FRad-B"}
    assert list(store.summary.drop_duplicates("observer")["observer"]) == [
        "FRad-A", "INT-CP", "FRad-B"]
    # the lines of a pair keep the audit's order of the realisation kinds
    kinds = store.summary[store.summary["observer"] == "FRad-A"]["kind"].tolist()
    assert kinds == [k for k in audit.KINDS if k in kinds]
    cold = audit_store.plan_audit(2, root / "results", cold=True)
    assert set(cold.stale.values()) == {"cold run"} and len(cold.stale) == 3


def test_a_stale_audit_is_named(small_audit):
    root, chosen = small_audit
    _bench(root)
    chosen.remove("INT-CP")
    report = root / "reports" / "soundness.md"
    report.write_text(report.read_text() + "edited\n")
    lines = [str(line) for line in audit_store.stale_lines(root)]
    assert lines == ["STALE ROW soundness: INT-CP on alamo2d-sim: no longer audited",
                     "STALE REPORT soundness: reports/soundness.md differs from its store "
                     "rendered now (`make reports` renders it)"]
