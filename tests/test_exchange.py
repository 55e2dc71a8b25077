"""Exchange with outside tools: the problem export (no true state; the model and record read
back as the scenario's), the scoring of result files through the harness's own rows (our own
FRad-A sets score as the native FRad-A row; shrunk ones are caught), bad result files refused
in one line with nothing written, and the LaTeX tables of a report."""

from __future__ import annotations

import contextlib
import io
import json
import re

import numpy as np
import pytest
import scipy.io

import observers
from benchmarks.cli import main
from benchmarks.exchange.results import result_file
from benchmarks.io import load_results
from benchmarks.run.config import load_config
from benchmarks.run.runner import run_config
from observers import registry
from observers.sets import Zonotope

MINI = {"name": "mini", "observers": ["FRad-A"], "containment": "hull",
        "scenarios": [{"name": "alamo2d-sim", "steps": 20}]}
LABEL = "alamo2d-sim"


@pytest.fixture(autouse=True)
def _no_replay_left():
    """The replays a test's scoring registered (``ext:<tool>``) are removed after it: in a
    test process they would otherwise be listed beside the observers of every later test
    (tests/test_rankings.py failed on ``ext:own`` once)."""
    yield
    for name in [n for n in registry.names() if n.startswith("ext:")]:
        registry.unregister(name, missing_ok=True)


@pytest.fixture(scope="module")
def mini(tmp_path_factory):
    """The mini configuration's file, its scenario and FRad-A's sets on it."""
    folder = tmp_path_factory.mktemp("exchange")
    path = folder / "mini.yaml"
    path.write_text(json.dumps(MINI), encoding="utf-8")
    cfg = load_config(path)
    sc = cfg.scenarios[0]
    obs = observers.create("FRad-A", sc.system, **cfg.options_for("FRad-A", sc))
    res = observers.run(obs, sc.u, sc.y)
    return folder, path, cfg, sc, res.sets


def _write(path, content) -> str:
    path.write_text(json.dumps(content), encoding="utf-8")
    return str(path)


@pytest.fixture(scope="module")
def scored(mini):
    """A scored folder with our FRad-A sets (with per-step times) and the same sets shrunk by
    2 % about their centres, the verdict lines and the native FRad-A rows."""
    folder, cfg_path, cfg, sc, sets = mini
    own = _write(folder / "own.json", result_file(
        sets, LABEL, {"name": "own", "language": "Python"}, times=[2e-3] * sc.N))
    shrunk = _write(folder / "shrunk.json", result_file(
        [Zonotope(S.c, 0.98 * S.G) for S in sets], LABEL, {"name": "shrunk"}))
    out = folder / "scored"
    text = io.StringIO()
    with contextlib.redirect_stdout(text):
        code = main(["score", own, shrunk, "--config", str(cfg_path), "--out", str(out)])
    native = run_config(cfg, None, progress=False).summary
    return out, code, text.getvalue(), native


def test_export_json_and_mat_round_trip(mini, tmp_path):
    _, cfg_path, _, sc, _ = mini
    for fmt in ("json", "mat"):
        assert main(["export", str(cfg_path), "--out", str(tmp_path / fmt), "--format",
                     fmt]) == 0
    prob = json.loads((tmp_path / "json" / f"{LABEL}.json").read_text(encoding="utf-8"))
    mat = scipy.io.loadmat(tmp_path / "mat" / f"{LABEL}.mat", simplify_cells=True)
    for p in (prob, mat):
        assert p["schema"] == "setobs-problem" and int(p["version"]) == 1
        assert not {"x_true", "x"} & set(p)
        np.testing.assert_array_equal(np.reshape(p["model"]["A"], (2, 2)), sc.system.A)
        np.testing.assert_array_equal(np.reshape(p["model"]["C"], (1, 2)), sc.system.C)
        np.testing.assert_array_equal(np.reshape(p["y"], sc.y.shape), sc.y)
        assert int(p["N"]) == sc.N and int(p["n"]) == 2
    text = (tmp_path / "json" / f"{LABEL}.json").read_text(encoding="utf-8")
    assert not any(repr(float(v)) in text for v in sc.x_true[1:].ravel())  # no true state
    assert prob["sets"]["X0"]["lo"] == [-3.0, -3.0]  # a box: its bounds too


def test_own_sets_score_as_the_native_row(scored):
    out, code, text, native = scored
    summary, meta = load_results(out)
    own = summary[summary["observer"] == "ext:own"].sort_values("state")
    ref = native[native["observer"] == "FRad-A"].sort_values("state")
    np.testing.assert_allclose(own["rms_radius"], ref["rms_radius"], rtol=1e-9)
    assert set(own["contained_hull"]) == {"yes"}
    assert set(own["covers_exact"]) == set(ref["covers_exact"]) == {"yes"}
    assert np.allclose(own["step_ms"], 2.0) and set(own["timed"]) == {"tool"}
    assert f"ext:own on {LABEL}" in text and "contained yes; covers exact yes" in text
    assert meta["external"][0]["tool"]["language"] == "Python"


def test_shrunk_sets_are_caught_with_their_steps(scored):
    out, code, text, _ = scored
    line = next(x for x in text.splitlines() if x.startswith("ext:shrunk"))
    assert re.search(r"contained no \(first violating step \d+; steps \d", line) or \
        re.search(r"covers exact no \(steps \d", line), line
    assert code == 1  # a guaranteed result missing the truth or the floor fails as `run`


def _bad(sets, how: str) -> dict:
    content = result_file(sets, LABEL, {"name": "bad"})
    if how == "nan":
        content["steps"][3]["c"][1] = float("nan")
    elif how == "missing":
        content["steps"].pop()
    elif how == "dimension":
        content["steps"][4]["c"].append(0.0)
    elif how == "scenario":
        content["scenario"] = "no-such-scenario"
    return content


@pytest.mark.parametrize("how, step, field", [("nan", "3", "c"), ("missing", "19", "steps"),
                                               ("dimension", "4", "c"),
                                               ("scenario", "-", "scenario")])
def test_bad_results_are_refused_in_one_line(mini, tmp_path, capsys, how, step, field):
    _, cfg_path, _, _, sets = mini
    path = _write(tmp_path / "bad.json", _bad(sets, how))
    out = tmp_path / "out"
    assert main(["score", path, "--config", str(cfg_path), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err
    assert path in err and f"step {step}: field {field}" in err and "scenario " in err
    assert not out.exists()


def test_latex_tables_hold_the_markdown_rows(scored):
    out = scored[0]
    assert main(["report", str(out), "--no-figures", "--latex"]) == 0
    md = (out / "report.md").read_text(encoding="utf-8")
    tex = (out / "report.tex").read_text(encoding="utf-8")
    assert tex.count(r"\begin{tabular}") == tex.count(r"\end{tabular}") == sum(
        line.startswith("|---|") for line in md.splitlines())
    rows = [line for line in md.splitlines() if line.startswith("| ext:")
            or line.startswith("| **ext:")]
    assert rows
    for line in rows:  # every number of every Markdown row, in the same notation
        for cell in line.strip("|").split("|"):
            for number in re.findall(r"\d[\d.e+-]*", cell):
                assert number in tex
    assert r"v\_i" in tex and r"\toprule" in tex and r"\textbf{" in tex
    body = "\n".join(x for x in tex.splitlines() if not x.startswith("%"))
    assert not re.search(r"(?<!\\)[_%&#]", body.replace(" & ", " ").replace(r"\\", ""))
