"""The README's examples are real: its example configuration is a file of the repository,
byte for byte, and its Python snippet (your own system, every observer) runs."""

from __future__ import annotations

import re
from pathlib import Path

import pandas as pd

import observers

ROOT = Path(__file__).resolve().parents[1]
README = (ROOT / "README.md").read_text(encoding="utf-8")


def test_example_configuration_is_a_file():
    shown = re.findall(r"`(benchmarks/configs/[\w.-]+\.yaml)`:\n\n```yaml\n(.*?)```", README,
                       re.S)
    assert shown, "the README shows no configuration file"
    for path, text in shown:
        assert (ROOT / path).read_text(encoding="utf-8") == text, path


def test_own_system_snippet_runs_every_observer(tmp_path, monkeypatch):
    section = README.split("### Your own system in Python", 1)[1]
    code = re.search(r"```python\n(.*?)```", section, re.S).group(1)
    monkeypatch.chdir(tmp_path)
    exec(compile(code, "README.md", "exec"), {"__name__": "readme"})
    out = tmp_path / "results" / "my-plant"
    summary = pd.read_csv(out / "summary.csv")
    assert set(summary["observer"]) == {i.name for i in observers.available()}
    ok = summary[summary["guaranteed"] & (summary["status"] == "ok")]
    assert len(ok) and (ok["violations"] == 0).all()  # true state in every guaranteed set
    assert (out / "report.md").is_file() and (out / "index.html").is_file()
