"""The HTML report: same cells as the Markdown tables, figures as PNG and PDF, every table and
figure naming its reference, and a real headless Chromium (Debian's chromium +
chromium-driver, driven by selenium) that loads the page from the file system, finds the
tables and figures, sorts a table by a click, hides an observer's curves by a click on the
legend and logs no console error."""

from __future__ import annotations

import re
import shutil
import tempfile
from pathlib import Path

import pandas as pd
import pytest

from benchmarks import load_config, run_config, write_report
from benchmarks.cli import main
from benchmarks.report.html import ranking, write_html, write_index
from benchmarks.report.tables import scenario_table_data

OBSERVERS = ["FRad-A", "FRad-C", "CZN-A", "PRad-E"]


@pytest.fixture(scope="module")
def results(tmp_path_factory) -> Path:
    """A small run: four observers on the 6-tank record (paper table) and the Alamo example."""
    tmp = tmp_path_factory.mktemp("html")
    cfg_path = tmp / "cfg.yaml"
    cfg_path.write_text("name: small\ntitle: Small HTML test\n"
                        "scenarios: [tank6-linear, alamo2d]\n"
                        f"observers: [{', '.join(OBSERVERS)}]\ncontainment: hull\n")
    out = tmp / "res"
    run_config(load_config(cfg_path), out, progress=False)
    write_report(out, figures=False)  # the Markdown's per-observer figures are not tested here
    write_html(out)
    return out


def test_html_has_the_markdown_cells_and_figures(results):
    page = (results / "index.html").read_text()
    plain = re.sub(r"<td[^>]*>", "<td>", page)  # cells without their alignment class
    md = (results / "report.md").read_text()
    summary = pd.read_csv(results / "summary.csv")
    meta = __import__("json").loads((results / "meta.json").read_text())
    for sc in ("tank6-linear", "alamo2d"):
        head, rows = scenario_table_data(summary[summary["scenario"] == sc], meta)
        for cells in rows:
            assert "| " + " | ".join(cells) + " |" in md  # the Markdown renders these cells
            assert "<tr>" + "".join(f"<td>{c}</td>" for c in cells) + "</tr>" in plain
        assert f'id="table-{sc}"' in page
        for name in ("bounds", "rel_rms_heatmap", "gap_heatmap", "step_time"):
            for ext in ("png", "pdf"):
                assert (results / "html_figures" / sc / f"{name}.{ext}").stat().st_size > 1000
                assert f'href="html_figures/{sc}/{name}.{ext}" download' in page
        assert f'id="bounds-{sc}"' in page  # the inline SVG of every state's bounds
    assert "(1.06)" in page  # FRad-A v1 of ARCH 2021 Table 3, as in the Markdown
    # every state's bounds and radius panel of the 6-tank record, each observer a layer
    svg = page[page.index('id="bounds-tank6-linear"'):]
    svg = svg[:svg.index("</svg>")]
    for i in range(1, 7):
        assert f"x{i}: bounds" in svg and f"x{i}: interval radius (log scale)" in svg
    # + the two exact floors (after and before y_k, drawn as bands) + the true state
    assert len(set(re.findall(r'<g class="layer (layer-\d+)"', svg))) == len(OBSERVERS) + 3
    legend = page[page.index('data-figure="bounds-tank6-linear"'):]
    names = re.findall(r'data-name="([^"]+)"', legend[:legend.index("</div>")])
    assert sorted(names) == sorted([*OBSERVERS, "exact set (after y_k)",
                                    "exact set (before y_k)", "true state"])
    # every table and figure names its reference; no "paper's" time where none is published
    assert "among the observers compared in Althoff, ARCH 2021, Table 3" in page
    assert "among all guaranteed observers of this run" in page  # alamo2d: no paper table
    assert "no published times for this scenario" in page
    assert "beside the published times of Althoff, ARCH 2021, Table 3" in page
    assert page.count("reference:") >= 6
    assert "Record: 261 steps of 0.5 s" in page and "measurement noise V: |v_i| ≤" in page
    assert "<code>contained</code>" in page and "`" not in page.split("<body>")[1].split(
        "<pre>")[0]  # the intro's Markdown code is rendered
    assert "git commit of the run" in page and "numpy" in page and "observers:" in page
    assert not re.search(r"(src|href)=\"https?://", page)  # nothing to fetch at view time


def test_ranking_hand_example():
    # two scenarios; a is tightest in s1 (rank 1), b in s2; c fails in s2
    s = pd.DataFrame({
        "scenario": ["s1"] * 6 + ["s2"] * 6, "observer": ["a", "a", "b", "b", "c", "c"] * 2,
        "state": [0, 1] * 6,
        "rel_rms": [1.0, 1.0, 2.0, 1.0, 3.0, 3.0, 1.5, 2.5, 1.0, 1.0, None, None],
        "status": ["ok"] * 10 + ["diverged"] * 2, "violations": [0] * 10 + [None] * 2})
    rk = ranking(s)
    assert list(rk.index) == ["b", "a", "c"]  # ranks a: 1, 2; b: 2, 1; ties by mean rel. RMS
    assert rk.loc["a", "mean_rank"] == 1.5 and rk.loc["b", "mean_rank"] == 1.5
    assert rk.loc["c", "mean_rank"] == 3 and rk.loc["c", "failed"] == 1
    assert rk.loc["a", "mean_rel_rms"] == pytest.approx((1.0 + 2.0) / 2)
    assert rk.loc["b", "mean_rel_rms"] == pytest.approx((1.5 + 1.0) / 2)


def test_ranking_gap_steady_and_memory_by_hand():
    # one observer on two linear scenarios and a nonlinear one (one state each): mean gap over
    # the linear ones (2 + 4) / 2 = 3, mean steady gap (3 + 5) / 2 = 4 (the nonlinear
    # scenario's upper-bound gap is not averaged in); memory the median of (10, 30, 50) = 30
    s = pd.DataFrame({
        "scenario": ["s1", "s2", "s3"], "observer": ["a"] * 3, "state": [0, 0, 0],
        "rel_rms": [1.0, 1.0, 1.0], "status": ["ok"] * 3, "violations": [0, 0, 0],
        "gap": [2.0, 4.0, 9.0], "gap_steady": [3.0, 5.0, 9.0],
        "gap_kind": ["exact", "exact", "upper bound"], "memory": [10.0, 30.0, 50.0]})
    rk = ranking(s)
    assert rk.loc["a", "mean_gap"] == 3.0 and rk.loc["a", "mean_gap_steady"] == 4.0
    assert rk.loc["a", "memory"] == 30.0  # the median over the three scenarios


def test_index_links_reports_and_html(tmp_path, results):
    reports = tmp_path / "reports"
    reports.mkdir()
    (reports / "res.md").write_text("# Small HTML test\n")
    (reports / "README.md").write_text("# not a table\n")
    out = tmp_path / "local" / "index.html"
    page = write_index(reports, results.parent, out).read_text()
    assert 'href="../reports/res.md"' in page and "Small HTML test" in page
    assert "res/index.html" in page and "README" not in page
    assert main(["index", str(tmp_path / "none")]) == 2


def test_index_never_writes_local_runs_into_the_reports_folder(tmp_path, results):
    reports = tmp_path / "reports"
    reports.mkdir()
    (reports / "a.md").write_text("# Same title\n")
    (reports / "b.md").write_text("# Same title\n<!-- freshness: sha256=0 config=- command=x "
                                  "--out reports/b.md -->\n")
    local = tmp_path / "results"
    (local / "a").mkdir(parents=True)
    (local / "a" / "index.html").write_text("<html></html>")
    # default: the page goes to the results folder, the reports folder is not touched
    assert main(["index", str(reports), "--results", str(local)]) == 0
    assert not (reports / "index.html").exists()
    page = (local / "index.html").read_text()
    assert 'href="a/index.html"' in page
    # --committed: the Markdown reports only, the same bytes whatever results/ holds
    assert main(["index", str(reports), "--committed"]) == 0
    first = (reports / "index.html").read_bytes()
    (local / "b").mkdir()
    (local / "b" / "index.html").write_text("<html></html>")
    assert main(["index", str(reports), "--committed", "--results", str(local)]) == 0
    assert (reports / "index.html").read_bytes() == first
    committed = first.decode()
    assert "index.html" not in committed.split("<table")[1]  # no link to a local run
    # two reports with one title are told apart by their file name; how each was made
    assert "Same title (a)" in committed and "Same title (b)" in committed
    assert "--out reports/b.md" in committed


# -- a real browser ------------------------------------------------------------------------

CHROMIUM_FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic",
                  "--no-first-run", "--disable-background-networking",
                  "--disable-component-update", "--disable-sync", "--disable-dev-shm-usage",
                  "--window-size=1280,1600"]


def _find(*names: str) -> str | None:
    for name in names:
        path = shutil.which(name)
        if path:
            return path
    return None


@pytest.fixture(scope="module")
def browser():
    webdriver = pytest.importorskip("selenium.webdriver",
                                    reason="selenium is not installed (pip install -e '.[test]')")
    chrome = _find("chromium", "chromium-browser", "google-chrome")
    driver_path = _find("chromedriver")
    if not chrome or not driver_path:
        pytest.skip("no headless browser found: install Debian's chromium and chromium-driver "
                    "(apt-get install chromium chromium-driver; .ci/run does)")
    opts = webdriver.ChromeOptions()
    opts.binary_location = chrome
    profile = tempfile.mkdtemp(prefix="setobs-chromium-")
    for flag in CHROMIUM_FLAGS + [f"--user-data-dir={profile}"]:
        opts.add_argument(flag)
    opts.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    drv = webdriver.Chrome(options=opts, service=webdriver.ChromeService(driver_path))
    drv.set_page_load_timeout(60)
    yield drv
    drv.quit()
    shutil.rmtree(profile, ignore_errors=True)


def _column(drv, table_id: str, idx: int) -> list[str]:
    return drv.execute_script(
        "return Array.from(document.getElementById(arguments[0]).tBodies[0].rows)"
        ".map(r => r.cells[arguments[1]].textContent.trim())", table_id, idx)


def _leading_number(text: str) -> float:
    return float(re.match(r"[-+]?\d*\.?\d+(e[-+]?\d+)?", text, re.I).group(0))


def test_page_in_headless_chromium(browser, results):
    from selenium.webdriver.common.by import By

    browser.get((results / "index.html").resolve().as_uri())
    assert browser.title == "Small HTML test"
    tables = browser.find_elements(By.CSS_SELECTOR, "table.sortable")
    assert len(tables) >= 5  # 2 scenario tables, 2 absolute tables, ranking, environment
    images = browser.find_elements(By.CSS_SELECTOR, "figure img")
    # relative-RMS heat map, gap heat map and times of two scenarios; bounds are inline SVG
    assert len(images) == 6
    for img in images:  # every figure loaded from the file system and decoded
        assert browser.execute_script("return arguments[0].complete && "
                                      "arguments[0].naturalWidth", img) > 100
    # sort the tank table by its avg column: one click ascending, a second descending
    table_id = "table-tank6-linear"
    head = [th.text.strip() for th in browser.find_elements(
        By.CSS_SELECTOR, f"#{table_id} thead th")]
    idx = head.index("avg")
    before = _column(browser, table_id, 0)
    header = browser.find_elements(By.CSS_SELECTOR, f"#{table_id} thead th")[idx]
    header.click()
    values = [_leading_number(c) for c in _column(browser, table_id, idx)]
    assert values == sorted(values)
    assert header.get_attribute("aria-sort") == "ascending"
    header.click()
    values = [_leading_number(c) for c in _column(browser, table_id, idx)]
    assert values == sorted(values, reverse=True)
    assert sorted(_column(browser, table_id, 0)) == sorted(before)  # rows moved, none lost
    # the ranking table sorts by observer name (text)
    browser.find_elements(By.CSS_SELECTOR, "#ranking-table thead th")[0].click()
    names = _column(browser, "ranking-table", 0)
    assert names == sorted(names) and set(names) == set(OBSERVERS)
    errors = [e for e in browser.get_log("browser") if e["level"] == "SEVERE"]
    assert errors == []


def _layer_shown(drv, fig_id: str, key: str) -> list[bool]:
    return drv.execute_script(
        "return Array.from(document.querySelectorAll('#'+arguments[0]+' g.layer.'+arguments[1]))"
        ".map(g => getComputedStyle(g).display !== 'none' && g.getBBox().width > 0)",
        fig_id, key)


def test_legend_click_hides_and_shows_a_curve(browser, results):
    from selenium.webdriver.common.by import By

    browser.get((results / "index.html").resolve().as_uri())
    fig = "bounds-tank6-linear"
    labels = browser.find_elements(By.CSS_SELECTOR, f'.legend[data-figure="{fig}"] label')
    names = [lab.get_attribute("data-name") for lab in labels]
    assert set(OBSERVERS) <= set(names) and "true state" in names
    label = labels[names.index("FRad-A")]
    key = label.find_element(By.CSS_SELECTOR, "input").get_attribute("data-layer")
    shown = _layer_shown(browser, fig, key)
    assert len(shown) >= 3 * 6 and all(shown)  # lo, hi and radius curves in every panel
    label.click()  # the legend entry: its curves disappear from every panel
    assert not any(_layer_shown(browser, fig, key))
    assert not label.find_element(By.CSS_SELECTOR, "input").is_selected()
    other = labels[names.index("FRad-C")].find_element(By.CSS_SELECTOR, "input")
    other_key = other.get_attribute("data-layer")
    assert all(_layer_shown(browser, fig, other_key))  # the others stay
    label.find_element(By.CSS_SELECTOR, "input").click()  # the check box brings it back
    assert all(_layer_shown(browser, fig, key))
    legend = browser.find_element(By.CSS_SELECTOR, f'.legend[data-figure="{fig}"]')
    legend.find_element(By.CSS_SELECTOR, 'button[data-select="none"]').click()
    assert not any(_layer_shown(browser, fig, key))
    truth = labels[names.index("true state")].find_element(By.CSS_SELECTOR, "input")
    assert all(_layer_shown(browser, fig, truth.get_attribute("data-layer")))
    legend.find_element(By.CSS_SELECTOR, 'button[data-select="all"]').click()
    assert all(_layer_shown(browser, fig, key)) and all(_layer_shown(browser, fig, other_key))
    assert [e for e in browser.get_log("browser") if e["level"] == "SEVERE"] == []


def test_report_command_writes_index_html_beside_report_md(tmp_path, results):
    out = tmp_path / "copy"
    shutil.copytree(results, out)
    (out / "index.html").unlink()
    assert main(["report", str(out), "--no-figures"]) == 0
    assert (out / "report.md").is_file() and (out / "index.html").is_file()
    assert main(["report", str(out), "--out", str(tmp_path / "r.md")]) == 0
    assert not (tmp_path / "index.html").exists()  # --out: the Markdown file only


def test_reports_index_in_headless_chromium(browser, results, tmp_path):
    from selenium.webdriver.common.by import By

    reports = tmp_path / "reports"
    reports.mkdir()
    (reports / "res.md").write_text("# Small HTML test\n")
    browser.get(write_index(reports, results.parent).resolve().as_uri())
    links = [a.get_attribute("href") for a in browser.find_elements(By.CSS_SELECTOR, "#reports a")]
    assert links == [(reports / "res.md").resolve().as_uri(),
                     (results / "index.html").resolve().as_uri()]
    browser.find_elements(By.CSS_SELECTOR, "#reports a")[1].click()  # follow it offline
    assert browser.title == "Small HTML test"
    assert [e for e in browser.get_log("browser") if e["level"] == "SEVERE"] == []


def test_markdown_tables_of_a_sweep_become_sortable_html():
    from benchmarks.report.html import markdown_to_html

    lines = ["## tank6-linear (3 seeds)", "", "| Observer | rel. RMS mean |", "|---|---|",
             "| FRad-A | 1.25 |", "| CZN-A | **2** |", ""]
    out = markdown_to_html(lines)
    assert out[0] == "<h2>tank6-linear (3 seeds)</h2>"
    assert out[1].startswith('<table class="sortable">') and "<th>rel. RMS mean</th>" in out[1]
    assert "<td>FRad-A</td><td>1.25</td>" in out[1] and "<strong>2</strong>" in out[1]
    assert "---" not in out[1] and len(out) == 2


def test_sweep_report_has_the_aggregated_tables(tmp_path):
    cfg = tmp_path / "sweep.yaml"
    cfg.write_text("name: sweep\nscenarios: [{name: alamo2d-sim, steps: 12}]\n"
                   "observers: [FRad-A, FRad-C]\ncontainment: hull\n"
                   "sweep: {seeds: [0, 1], grid: {FRad-A: {order: [5, 20]}}}\n")
    out = tmp_path / "o"
    assert main(["run", str(cfg), "--out", str(out), "--no-progress"]) == 0
    assert main(["report", str(out)]) == 0
    page = (out / "index.html").read_text()
    assert "<h2>alamo2d-sim (2 seeds)</h2>" in page and "<th>rel. RMS mean</th>" in page
    assert "Ranking summary" not in page  # per-seed rankings are not mixed into one


def test_one_more_band_per_state_is_one_argument(results, tmp_path):
    # the lead's "exact band": a (lo, hi) pair per scenario, drawn filled and as a radius curve,
    # a selectable layer of its own
    runs = pd.read_csv(results / "runs.csv")
    g = runs[(runs["scenario"] == "tank6-linear") & (runs["observer"] == "CZN-A")]
    lo = g.pivot(index="t", columns="state", values="lo").to_numpy()
    hi = g.pivot(index="t", columns="state", values="hi").to_numpy()
    mid, rad = (lo + hi) / 2, 0.5 * (hi - lo) / 2
    page = write_html(results, out=tmp_path / "bands.html",
                      bands={"tank6-linear": {"exact": (mid - rad, mid + rad)}}).read_text()
    legend = page[page.index('data-figure="bounds-tank6-linear"'):]
    legend = legend[:legend.index("</div>")]
    assert 'data-name="exact"' in legend and 'data-kind="band"' in legend
    key = re.search(r'data-name="exact"><input type="checkbox" data-layer="(layer-\d+)"',
                    legend).group(1)
    svg = page[page.index('id="bounds-tank6-linear"'):]
    assert svg[:svg.index("</svg>")].count(f'class="layer {key}"') == 2 * 6  # band + radius
    assert "filled bands: exact" in page
