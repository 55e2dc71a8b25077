"""``python -m benchmarks time``: the table, the JSON file, failures as rows, bad input.

Timings are wall-clock measurements on a shared machine: the tests check that they are
finite and positive, never their values.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

import systems
from benchmarks.cli import main
from benchmarks.io import environment
from benchmarks.timing.steps import TimingRow, kalman_step_times
from observers.sets import ConZonotope, HullLP

ROW_FIELDS = set(TimingRow.__dataclass_fields__)


def table_rows(out: str, names: tuple[str, ...]) -> dict[str, list[str]]:
    """The table rows of ``names`` in the printed output, split into fields."""
    rows = {}
    for line in out.splitlines():
        fields = line.split()
        if fields and fields[0] in names:
            rows[fields[0]] = fields
    return rows


def test_time_prints_every_observer_and_writes_the_json(tmp_path, capsys):
    path = tmp_path / "timing.json"
    code = main(["time", "FRad-A", "CZN-A", "--scenario", "vehicle2d-cora", "--repeat", "1",
                 "--json", str(path)])
    out = capsys.readouterr().out
    assert code == 0
    rows = table_rows(out, ("FRad-A", "CZN-A"))
    assert set(rows) == {"FRad-A", "CZN-A"}
    for fields in rows.values():
        assert fields[1] == "ok"
        # step med, step p90, hull med, step+hull, steps, from, design s, KF step, ratio
        values = [float(x) for x in fields[2:]]
        assert len(values) == 9 and int(fields[7]) == 6
        assert all(math.isfinite(v) and v > 0 for v in values), fields
        assert int(fields[6]) == 100 - 5  # one run of 100 steps, 5 warm-up steps dropped
    assert "hull LPs of CZN-A per run" in out
    assert "hull LPs of FRad-A" not in out

    data = json.loads(path.read_text())
    assert {"scenario", "steps_per_run", "repeat", "warmup", "kalman_model", "environment",
            "results"} <= set(data)
    assert (data["scenario"], data["steps_per_run"], data["repeat"], data["warmup"]) == (
        "vehicle2d-cora", 100, 1, 5)
    assert data["environment"] == {**environment(), "git": data["environment"]["git"]}
    results = {r["observer"]: r for r in data["results"]}
    assert list(results) == ["FRad-A", "CZN-A"]
    for r in results.values():
        assert set(r) == ROW_FIELDS
        assert r["status"] == "ok"
        for key in ("step_ms_median", "step_ms_p90", "hull_ms_median", "step_hull_ms_median",
                    "design_s", "kalman_ms_median", "ratio"):
            assert math.isfinite(r[key]) and r[key] > 0, key
        assert r["step_ms_p90"] >= r["step_ms_median"]
        assert r["ratio"] == pytest.approx(r["step_ms_median"] / r["kalman_ms_median"])
    assert results["FRad-A"]["hull_lp"] is None
    lp = results["CZN-A"]["hull_lp"]
    assert set(lp) == {"solves", "iterations", "fallbacks", "iterations_per_solve"}
    assert lp["solves"] == 2 * 2 * 100  # 2n LPs per interval hull, one hull per step
    assert lp["fallbacks"] >= 0 and lp["iterations"] >= 0


def test_a_failing_observer_is_a_row_and_the_table_goes_on(tmp_path, capsys):
    path = tmp_path / "timing.json"
    code = main(["time", "PRad-A", "FRad-A", "--scenario", "vehicle6d-cora", "--repeat", "1",
                 "--json", str(path)])
    out = capsys.readouterr().out
    assert code == 0
    rows = table_rows(out, ("PRad-A", "FRad-A"))
    # PRad-A has no gain on the vehicle (0.5.0: the Riccati design; CHANGELOG, regression baseline)
    assert rows["PRad-A"][1] == "noGain"
    assert rows["FRad-A"][1] == "ok"
    assert "note: PRad-A: noGain: " in out
    results = {r["observer"]: r for r in json.loads(path.read_text())["results"]}
    assert results["PRad-A"]["status"] == "noGain"
    assert results["PRad-A"]["step_ms_median"] is None  # NaN is written as null
    assert results["PRad-A"]["timed_steps"] == 0
    assert results["FRad-A"]["timed_steps"] == 345


@pytest.mark.parametrize("argv, message", [
    (["FRad-X", "--scenario", "vehicle2d-cora"], "error: unknown observer 'FRad-X'"),
    (["FRad-A", "--scenario", "no-such-scenario"], "error: unknown scenario 'no-such-scenario'"),
    (["FRad-A", "--scenario", "vehicle2d-cora", "--repeat", "0"],
     "error: --repeat must be at least 1"),
    (["FRad-A", "--scenario", "vehicle2d-cora", "--warmup", "100"],
     "error: --warmup 100 leaves no step to time"),
])
def test_bad_input_is_a_one_line_error_with_exit_code_2(argv, message, tmp_path, capsys):
    path = tmp_path / "timing.json"
    assert main(["time", *argv, "--json", str(path)]) == 2
    captured = capsys.readouterr()
    assert captured.err.startswith(message)
    assert len(captured.err.strip().splitlines()) == 1
    assert "step med" not in captured.out  # nothing was timed
    assert not path.exists()


def test_kalman_step_times_one_per_step():
    sc = systems.scenario("vehicle6d-cora")
    t = kalman_step_times(sc.system, sc.u, sc.y)
    assert t.shape == (sc.N,)
    assert np.all(np.isfinite(t)) and np.all(t > 0)


@pytest.mark.parametrize("name", ["tank6-nonlinear", "robot-range"])
def test_a_nonlinear_system_gets_the_extended_kalman_filter(name):
    """No ``A`` on a nonlinear system: the extended filter's steps (linear output on the
    tank, range and bearing outputs ``h`` on the robot) are timed instead."""
    sc = systems.scenario(name, steps=30)
    t = kalman_step_times(sc.system, sc.u, sc.y)
    assert t.shape == (sc.N,)
    assert np.all(np.isfinite(t)) and np.all(t > 0)


def test_hull_lp_stats_count_the_lps_of_an_interval_hull():
    lp = HullLP()
    assert (lp.stats.solves, lp.stats.iterations, lp.stats.fallbacks) == (0, 0, 0)
    assert math.isnan(lp.stats.iterations_per_solve)
    S = ConZonotope([0.0, 0.0], [[1.0, 0.0, 1.0], [0.0, 1.0, 1.0]], [[1.0, 1.0, 0.0]], [0.5])
    S.with_solver(lp).interval()
    assert lp.stats.solves == 4  # 2n LPs
    with pytest.raises(AttributeError):
        lp.stats.solves = 0  # a read-only snapshot


# -- steady-state timing (issue 30) ------------------------------------------------------------
def test_steady_from_finds_where_the_set_size_stops_changing():
    from benchmarks.timing.steps import steady_from

    grow = [(10, 0), (20, 0), (30, 0), (30, 0), (30, 0), (30, 0)]
    assert steady_from(grow) == (2, True)
    assert steady_from(grow[:4]) == (2, False)  # two steps at the final size: not steady
    assert steady_from([(4, 2), (8, 4), (8, 4), (8, 4)]) == (1, True)  # constraints count
    assert steady_from([(), (), ()]) == (0, True)  # intervals: steady from the start
    assert steady_from([]) == (0, False)


def test_steady_timing_starts_where_the_zonotope_reaches_its_order(capsys):
    from benchmarks.run.rows import merge_options
    from benchmarks.timing.steps import set_size, time_observer

    sc = systems.scenario("vehicle2d-cora")
    # order 2 in 2-D: 4 generators; each step adds 2 (W) and 1 (the strip)
    opts = dict(merge_options("FRad-A", sc), order=2)
    sizes = []
    obs = __import__("observers").create("FRad-A", sc.system, **opts)
    for k in range(10):
        sizes.append(set_size(obs.step(sc.u[k - 1] if k else None, sc.y[k])))
    first = next(k for k in range(10) if all(s == sizes[-1] for s in sizes[k:]))
    row = time_observer("FRad-A", sc, opts, repeat=2, warmup=0, steady=True)
    assert row.status == "ok" and row.steady is True
    assert row.first_timed == first + 1
    assert row.timed_steps == 2 * (sc.N - first)  # the probe run is not timed
    assert main(["time", "FRad-A", "--scenario", "vehicle2d-cora", "--repeat", "1",
                 "--steady", "--steps", "3", "--warmup", "0"]) == 0
    assert "(growing)" in capsys.readouterr().out  # FRad-A's order 100 is not reached


def test_fast_forward_times_the_steps_after_the_steady_state():
    """The large constrained zonotopes are stepped to their steady state without hulls and
    timed from there: the first timed step is the first after MIN_STEADY_STEPS steps of
    one size, exactly ``timed`` steps are timed, each with its hull."""
    import observers
    from benchmarks.run.rows import merge_options
    from benchmarks.timing.steps import (
        MIN_STEADY_STEPS,
        set_size,
        time_observer_fast_forward,
    )

    sc = systems.scenario("vehicle2d-cora")
    opts = dict(merge_options("FRad-A", sc), order=2)
    obs = observers.create("FRad-A", sc.system, **opts)
    sizes = [set_size(obs.step(sc.u[k - 1] if k else None, sc.y[k])) for k in range(12)]
    first = next(k for k in range(MIN_STEADY_STEPS, 12)
                 if len(set(sizes[k - MIN_STEADY_STEPS:k])) == 1)
    row = time_observer_fast_forward("FRad-A", sc, opts, timed=4)
    assert row.status == "ok" and row.steady is True
    assert row.first_timed == first + 1 and row.timed_steps == 4
    assert math.isfinite(row.hull_ms_median) and row.step_hull_ms_median >= row.step_ms_median
    # a design failure is the row's status, not an exception
    bad = time_observer_fast_forward("PRad-A", systems.scenario("tank18-linear"),
                                     {}, timed=2)
    assert bad.status == "noGain"
