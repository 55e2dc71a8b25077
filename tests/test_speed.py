"""Speed work (issue 15): the lean hot paths give the numbers of the plain formulas, and the
speed report (``python -m benchmarks speed``) compares with the previous measurement.

No test asserts on a time: the report's cells are checked for form and for the arithmetic of
the comparison columns only.
"""

from __future__ import annotations

import json
import math
import re

import numpy as np
import pytest

import systems
from benchmarks.cli import main
from benchmarks.errors import ConfigError
from benchmarks.report import freshness
from benchmarks.timing import speed
from benchmarks.timing.exact_cost import ExactCase
from benchmarks.timing.hull_profile import HullCase
from benchmarks.timing.step_profile import StepCase
from benchmarks.timing.steps import TimingPlan, first_steps, time_observers
from observers.families import strip_update
from observers.numerics.frad import alamo_frad_gain, alamo_frad_strips
from observers.sets import get_reduction
from observers.sets.reduction import split_generators


def reference_split(G: np.ndarray, order: float):
    """The reduction split as the module docstring defines it, written plainly: zero columns
    dropped, then the ``r - floor(n (order - 1))`` columns of smallest ``||g||_1 - ||g||_inf``
    (stable order) reduced, the others kept in their order."""
    G = G[:, [j for j in range(G.shape[1]) if np.any(G[:, j] != 0.0)]]
    n, r = G.shape
    if r <= n * order:
        return G, G[:, :0]
    n_red = r - math.floor(n * (order - 1))
    h = [np.abs(G[:, j]).sum() - np.abs(G[:, j]).max() for j in range(r)]
    ranked = sorted(range(r), key=lambda j: (h[j], j))
    picked = ranked[:n_red]
    kept = sorted(ranked[n_red:])
    return G[:, kept], G[:, picked]


@pytest.mark.parametrize("seed", range(40))
def test_split_generators_equals_the_plain_definition(seed):
    rng = np.random.default_rng(seed)
    n, r = int(rng.integers(1, 7)), int(rng.integers(0, 60))
    G = rng.standard_normal((n, r))
    G[:, rng.random(r) < 0.2] = 0.0  # zero columns
    if seed % 2:
        G = np.round(G)  # many ties of the metric
    order = float(rng.choice([1.0, 1.5, 2.0, 4.0]))
    keep, red = split_generators(G, order)
    keep_ref, red_ref = reference_split(G, order)
    assert np.array_equal(keep, keep_ref) and np.array_equal(red, red_ref)
    box = np.hstack([keep_ref, np.diag(np.abs(red_ref).sum(axis=1))]) if red_ref.shape[1] \
        else keep_ref
    assert np.array_equal(get_reduction("girard").reduce(G, order), box)


def test_reduction_keeps_ties_in_column_order():
    # metrics 1, 1, 0, 1 and a zero column; in R^2 with order 1.5 one generator is kept
    G = np.array([[1.0, 1.0, 2.0, 1.0, 0.0],
                  [1.0, 1.0, 0.0, 1.0, 0.0]])
    keep, red = split_generators(G, 1.5)  # zero column dropped, 4 left, keep floor(2 * 0.5)
    assert np.array_equal(keep, G[:, [3]])  # metric 1, 1, 0, 1: the last tie is kept
    assert np.array_equal(red, G[:, [2, 0, 1]])


def strip_by_strip(c, G, C, y, sigma):
    for i in range(C.shape[0]):
        lam = alamo_frad_gain(G, C[i], sigma[i]).reshape(-1, 1)
        c, G = strip_update(c, G, lam, C[i:i + 1], y[i:i + 1], sigma[i:i + 1])
    return c, G


@pytest.mark.parametrize("seed", range(5))
def test_frad_strips_on_the_gram_matrix_equal_the_strip_loop(seed):
    rng = np.random.default_rng(seed)
    n, r, m = 5, 40, 3
    c, G = rng.standard_normal(n), rng.standard_normal((n, r))
    C, y, sigma = rng.standard_normal((m, n)), rng.standard_normal(m), rng.random(m) + 0.1
    c1, G1 = strip_by_strip(c, G, C, y, sigma)
    c2, G2 = alamo_frad_strips(c, G, C, y, sigma)
    assert G2.shape == G1.shape
    np.testing.assert_allclose(c2, c1, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(G2, G1, rtol=1e-10, atol=1e-12)


def test_first_steps_cuts_the_record():
    import systems

    sc = systems.scenario("vehicle2d-cora")
    short = first_steps(sc, 10)
    assert short.N == 10 and np.array_equal(short.y, sc.y[:10])
    assert first_steps(sc, None) is sc


def test_time_steps_option_and_its_bad_value(capsys):
    assert main(["time", "FRad-A", "--scenario", "vehicle2d-cora", "--repeat", "1",
                 "--steps", "12", "--warmup", "2"]) == 0
    fields = [ln.split() for ln in capsys.readouterr().out.splitlines()
              if ln.startswith("FRad-A")][0]
    assert fields[1] == "ok" and int(fields[6]) == 10
    assert main(["time", "FRad-A", "--scenario", "vehicle2d-cora", "--steps", "0"]) == 2
    assert capsys.readouterr().err.startswith("error: --steps must be at least 1")


def test_a_cases_options_reach_the_observers_it_times():
    # MHE's window is an option of the speed case (window 5 in the table): a window out of
    # its range is refused by name, an accepted one times
    plan = TimingPlan(repeat=1, steps=8, warmup=2)
    with pytest.raises(ConfigError, match="MHE: window must be an integer in"):
        time_observers(["MHE"], "vehicle2d-cora", plan, own={"window": 0})
    _, _, (row,) = time_observers(["MHE"], "vehicle2d-cora", plan, own={"window": 2})
    assert row.status == "ok" and row.timed_steps == 6
    assert all(c.options == (("window", 5),) for c in speed.CASES if c.observers == ("MHE",))


def test_speed_report_compares_with_the_previous_json(tmp_path):
    cases = (speed.Case("FRad-A, 2-D vehicle", "vehicle2d-cora", ("FRad-A", "PRad-A"), "ratio",
                        3.0, repeat=1, steps=20, warmup=2),
             speed.Case("FRad-A, 2-D vehicle, ms", "vehicle2d-cora", ("FRad-A",), "ms", 1e9,
                        repeat=1, steps=20, warmup=2))
    out, js = tmp_path / "speed.md", tmp_path / "speed.json"
    js.write_text(json.dumps({"environment": {"git": "abc1234"}, "results": [
        {"case": "FRad-A, 2-D vehicle, ms", "observer": "FRad-A", "value": 2.0}]}))
    speed.write_speed_report(out, js, cases, progress=False,
                             exact_cases=(ExactCase("alamo2d", 1e9),),
                             hull_cases=(HullCase("vehicle6d-cora", "CZN-A", repeat=1),),
                             step_cases=(StepCase("vehicle6d-cora", "CZN-A", steps=5),
                                         StepCase("vehicle6d-cora", "CZN-B", steps=1000)))
    text = out.read_text()
    steps_section, hull_section = text.split("## Where a constrained zonotope's interval hull")
    # the step profile: parts that add up to the step, a too short record said as such
    parts = json.loads(js.read_text())["steps"]
    assert parts[0]["status"] == "ok" and parts[0]["ms"] > 0
    assert parts[0]["n"] == systems.scenario("vehicle6d-cora").system.n
    assert sum(parts[0]["shares"].values()) == pytest.approx(1.0, abs=1e-9)
    assert all(v >= 0 for v in parts[0]["shares"].values())
    assert parts[0]["shares"]["propagation"] > 0 and parts[0]["shares"]["reduction"] > 0
    assert parts[1]["status"] == "n/a" and "needed" in parts[1]["message"]
    assert "| CZN-B, vehicle6d-cora | n/a: the record ends" in steps_section
    # the hull profile: every strategy on the steady set, the batched and sifted bounds never
    # looser than HiGHS's by more than 1e-9 of the radius, phase shares that add up to at
    # most 1
    prof = [ln.split("|") for ln in hull_section.splitlines()
            if ln.startswith("| CZN-A, vehicle6d")]
    assert [r[6].strip() for r in prof] == ["batched", "highs", "sifting", "sifting-highs"]
    n = systems.scenario("vehicle6d-cora").system.n
    for r in json.loads(js.read_text())["hulls"]:
        assert r["status"] == "ok" and r["lps"] == 2 * n and r["looser"] <= 1e-9
        assert 0.0 < sum(r["shares"].values()) <= 1.0 + 1e-9
    # the exact reference's cold cost: every step of the record, solved to optimality
    exact = [ln.split("|") for ln in text.splitlines() if ln.startswith("| alamo2d |")]
    assert len(exact) == 1 and exact[0][3].strip() == str(systems.scenario("alamo2d").N)
    assert exact[0][7].strip() == "yes" and exact[0][11].strip() == "none"
    assert json.loads(js.read_text())["exact"][0]["status"] == "ok"
    assert "commit `abc1234`" in text
    rows = {ln.split("|")[1].strip() + "/" + ln.split("|")[2].strip(): ln.split("|")
            for ln in text.splitlines() if ln.startswith("| FRad-A, 2-D")}
    ms_row = rows["FRad-A, 2-D vehicle, ms/FRad-A"]
    data = json.loads(js.read_text())
    now = {(r["case"], r["observer"]): r for r in data["results"]}
    value = now[("FRad-A, 2-D vehicle, ms", "FRad-A")]["value"]
    assert math.isfinite(value) and value > 0
    assert ms_row[10].strip() == "2 ms"  # previous
    assert float(ms_row[11]) == pytest.approx(value / 2.0, rel=5e-3)  # now / previous
    assert ms_row[5].strip() == "yes"  # target 1e9 ms
    # the 2-D vehicle has no published time and no previous ratio: n/a, never a number
    ratio_row = rows["FRad-A, 2-D vehicle/FRad-A"]
    assert [ratio_row[i].strip() for i in (8, 9, 10, 11)] == ["n/a"] * 4
    # PRad-A has no gain on the 2-D vehicle or diverges: its status, not a time
    prad = now[("FRad-A, 2-D vehicle", "PRad-A")]
    if prad["status"] != "ok":
        assert prad["value"] is None
        assert rows["FRad-A, 2-D vehicle/PRad-A"][3].strip() == prad["status"]
    assert "`make bench-cold`" in text
    # a measurement of this machine: stamped with its commit and machine, not a code hash
    stamp = text.splitlines()[-1]
    assert stamp.startswith("<!-- measured: commit=") and "command=python -m benchmarks " \
        "speed --out " in stamp
    assert freshness.machine()["blas_coretype"] in stamp


def test_designs_fill_the_cache_in_parallel_with_the_same_gains(tmp_path, monkeypatch, capsys):
    import observers
    import systems
    from benchmarks.run import designs

    cfg = tmp_path / "small.yaml"
    cfg.write_text("name: small\ntitle: small\nscenarios: [vehicle2d-cora]\n"
                   "observers: [FRad-A, Nom-G, PRad-B]\n")
    monkeypatch.setenv("SETOBS_CACHE_DIR", str(tmp_path / "cache"))
    tasks = designs.design_tasks([cfg])
    assert [t[2] for t in tasks] == ["Nom-G", "PRad-B"]  # FRad-A has no offline design
    assert main(["designs", str(cfg), "--jobs", "2", "--no-progress", "--top", "1"]) == 0
    out = capsys.readouterr().out
    assert "2 designs in the cache (0 failed" in out
    # the per-design times: a header, its rule and the slowest design only (--top 1)
    lines = out.splitlines()
    assert lines[0].split() == ["design", "status", "seconds"]
    assert set(lines[1]) == {"-", " "}
    assert re.fullmatch(r"vehicle2d-cora: (Nom-G|PRad-B) +ok +[0-9.e+-]+", lines[2])
    assert lines[3].startswith("2 designs")
    assert len(list((tmp_path / "cache").glob("*.npz"))) == 2
    system = systems.scenario("vehicle2d-cora").system
    cached = {n: observers.create(n, system).L for n in ("Nom-G", "PRad-B")}
    monkeypatch.setenv("SETOBS_CACHE_DIR", "off")
    for name, L in cached.items():
        assert np.array_equal(observers.create(name, system).L, L)
    assert main(["designs", str(cfg), "--jobs", "0"]) == 2
    assert capsys.readouterr().err.startswith("error: --jobs must be at least 1")


@pytest.mark.parametrize("n, m", [(6, 2), (4, 4)])  # both ways of applying I - L C
def test_frad_strips_with_few_and_many_strips(n, m):
    rng = np.random.default_rng(n + m)
    c, G = rng.standard_normal(n), rng.standard_normal((n, 30))
    C, y, sigma = rng.standard_normal((m, n)), rng.standard_normal(m), rng.random(m) + 0.1
    c1, G1 = strip_by_strip(c, G, C, y, sigma)
    c2, G2 = alamo_frad_strips(c, G, C, y, sigma)
    np.testing.assert_allclose(c2, c1, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(G2, G1, rtol=1e-10, atol=1e-12)


def test_designs_of_labelled_variants_are_computed_under_their_observer(tmp_path, monkeypatch):
    # bug: `designs` looked up a variant's label ("PRad-B[tight]") in the registry and stopped
    # with "unknown observer"; a variant's design is its observer's, with the variant's options
    from benchmarks.run import designs

    cfg = tmp_path / "variants.yaml"
    cfg.write_text("name: v\ntitle: v\nscenarios: [vehicle2d-cora]\nobservers: [PRad-B]\n"
                   "variants:\n  PRad-B[tight]: {observer: PRad-B, options: {beta_tol: 0.001}}\n")
    monkeypatch.setenv("SETOBS_CACHE_DIR", str(tmp_path / "cache"))
    tasks = designs.design_tasks([cfg])
    assert sorted(t[2] for t in tasks) == ["PRad-B", "PRad-B[tight]"]
    assert sorted(r[1:3] for r in designs.prewarm([cfg], jobs=1, progress=False)) == [
        ("PRad-B", "ok"), ("PRad-B[tight]", "ok")]
    assert len(list((tmp_path / "cache").glob("*.npz"))) == 2  # two options, two designs


def test_hull_profile_rows_have_the_headers_cells():
    from benchmarks.timing.hull_profile import PHASES, render_hulls
    from tests.test_freshness import _cells

    ok = {"observer": "CZN-A", "scenario": "tank6-linear", "status": "ok", "step": 3, "n": 6,
          "p": 8, "r": 40, "solver": "batched", "ms": 1.0, "lps": 12, "iterations": 5.0,
          "fallbacks": 0, "shares": dict.fromkeys(PHASES, 0.05), "looser": 0.0,
          "tighter": 0.0}
    failed = {"observer": "CZN-B", "scenario": "tank6-linear", "status": "error",
              "message": "step 2: EmptySet"}
    table = [ln for ln in render_hulls([ok, failed]) if ln.startswith("|")]
    assert len(table) == 4 and {_cells(ln) for ln in table} == {_cells(table[0])}
    assert "| batched | 1 | 0.0833 | 5 | 0 | 5 % |" in table[2]
