"""The edge-case audit (issue: soundness at the edges): degenerate systems a user writes in a
YAML file, every guaranteed observer on them, and every refusal a one-line ``create()`` error
naming the degenerate property."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

import observers
from benchmarks.gate import audit
from systems import ModelError, edge


def _width(Z, direction) -> float:
    """Width of the zonotope ``Z`` along ``direction`` (twice its support radius)."""
    return 2.0 * float(np.abs(np.asarray(direction, float) @ Z.G).sum())


def test_each_case_has_the_degenerate_property_it_names():
    s = {name: edge.system(name) for name in edge.NAMES}
    assert _width(s["edge-flat-w"].W, [0, 0, 1]) == 0 < _width(s["edge-flat-w"].W, [1, 0, 0])
    assert _width(s["edge-zero-v"].V, [1, 0]) == 0 < _width(s["edge-zero-v"].V, [0, 1])
    C = s["edge-repeated-output"].C
    assert np.array_equal(C[0], C[1]) and np.linalg.matrix_rank(C) == 2
    assert np.linalg.matrix_rank(s["edge-dependent-outputs"].C) == 1
    assert _width(s["edge-known-state"].X0, [0, 0, 1]) == 0
    # the same plant in other units: x' = T x, so A' = T A T^-1 has A's eigenvalues
    base = np.sort_complex(np.linalg.eigvals(edge.A))
    for name in ("edge-magnitudes", "edge-units-micro", "edge-units-mega"):
        np.testing.assert_allclose(np.sort_complex(np.linalg.eigvals(s[name].A)), base,
                                   rtol=1e-9)
    assert _width(s["edge-magnitudes"].X0, [0, 0, 1]) == pytest.approx(2 * 0.5e-9)
    assert _width(s["edge-units-mega"].V, [1, 0]) == pytest.approx(2 * 0.05e6)
    uni = s["edge-unicycle-known-heading"]
    assert not uni.is_linear if hasattr(uni, "is_linear") else True
    assert _width(uni.X0, [0, 0, 1]) == 0 == _width(uni.W, [0, 0, 1])


def test_the_records_come_from_true_trajectories_in_the_sets():
    for name in edge.NAMES:
        sc = edge.scenario(name, seed=2, noise="vertex")
        s = sc.system
        assert sc.N == edge.SHORT_STEPS and s.X0.contains(sc.x_true[0], tol=1e-9)
        v = sc.y - s.outputs(sc.x_true)
        w = sc.x_true[1:] - np.array([s.dynamics(x, u) for x, u in
                                      zip(sc.x_true[:-1], sc.u[:-1], strict=True)])
        for k in range(0, sc.N, 37):
            assert s.V.contains(v[k], tol=1e-9 * max(1.0, np.abs(sc.y[k]).max()))
        for k in range(0, sc.N - 1, 37):
            assert s.W.contains(w[k], tol=1e-9 * max(1.0, np.abs(sc.x_true[k]).max()))
    assert edge.scenario("edge-flat-w-long", steps=300).N == 300
    assert edge.scenario("edge-flat-w-long").N == edge.LONG_STEPS
    with pytest.raises(ModelError, match="unknown edge case 'edge-nope'"):
        edge.scenario("edge-nope")


def _violations(name: str, scenario: str, index: int) -> tuple[str, int]:
    """``(status, steps whose set misses the true state)`` of ``name`` on realisation
    ``index`` of the edge case ``scenario`` (the audit's exact membership test)."""
    from benchmarks.run.membership import MembershipTester
    from benchmarks.run.rows import merge_options, run_observer

    _, sc = audit.realisation(scenario, index)
    run = run_observer(name, sc, merge_options(name, sc), "hull", keep_sets=True)
    tester = MembershipTester()
    missed = sum(1 for k, S in enumerate(run.result.sets)
                 if tester.test(S, sc.x_true[k], audit.tolerance(sc, sc.x_true[k]),
                                hull=(run.result.lo[k], run.result.hi[k])).inside is False)
    return run.status, missed


def test_ropo_keeps_the_true_state_with_two_sensors_of_one_quantity():
    # bug: where the two sensors' strips met in a hyperplane (vertex noise of opposite signs)
    # the cut pinned every factor with a rounding-level weight to a vertex, and the true
    # state fell out by up to 0.04 (realisation 2: 6 steps; 3: empty at step 138)
    for index in (2, 3, 4):
        assert _violations("ROPO", "edge-repeated-output", index) == ("ok", 0), index


def test_a_strip_that_only_touches_the_parallelotope_keeps_its_face():
    from observers.numerics.ropo import strip_cut

    # the unit box cut by x1 in [1, 2]: the face x1 = 1 (x2, x3 free); a rounding-level
    # weight of x2 and x3 in the strip's normal must not pin them to a vertex
    T = np.eye(3)
    g = np.array([1.0, 1e-17, -1e-17])
    c, T2 = strip_cut(np.zeros(3), T, g, 1.0, 2.0)
    for x in ([1.0, 0.0, 0.0], [1.0, -1.0, 1.0], [1.0, 1.0, -1.0]):
        z = np.linalg.lstsq(T2, np.array(x) - c, rcond=None)[0]
        assert np.abs(z).max() <= 1 + 1e-9 and np.allclose(T2 @ z, np.array(x) - c), x


def test_zb_a_meets_an_output_measured_without_noise():
    # bug: every member pinned to the noise-free output crossed the others by rounding
    # (1e-16) and the bundle ended empty (realisation 0 at step 12, 2 at step 76)
    for index in (0, 2):
        assert _violations("ZB-A", "edge-zero-v", index) == ("ok", 0), index


def test_a_flat_bundle_is_not_empty_but_two_disjoint_members_are():
    from observers.errors import EmptySet
    from observers.sets import Zonotope, ZonotopeBundle

    flat = ZonotopeBundle([Zonotope([0.1, 0.0], [[0.0, 0.0], [0.0, 1.0]]),
                           Zonotope([0.1 + 2e-17, 0.0], [[0.0, 0.0], [0.5, -0.5]])])
    H = flat.interval()
    assert H.lo[0] <= 0.1 <= H.hi[0] and H.hi[0] - H.lo[0] < 1e-15
    with pytest.raises(EmptySet, match="do not intersect"):
        ZonotopeBundle([Zonotope([0.0, 0.0], np.eye(2)),
                        Zonotope([3.0, 0.0], [[0.5, 0.5], [0.5, -0.5]])]).interval()


def test_membership_of_a_vertex_of_a_micro_box_with_a_tolerance():
    from observers.sets import Zonotope

    # bug: HiGHS called the vertex of the box of radius 5e-7 infeasible with tol = 1e-9
    # (slack bounds far below its tolerances on unscaled rows), feasible with tol = 0
    Z = Zonotope.box([5e-7] * 3)
    vertex = np.array([5e-7, -5e-7, -5e-7])
    assert Z.contains(vertex, tol=1e-9) and Z.contains(vertex)
    assert not Z.contains(vertex * 1.01, tol=1e-9) and Z.contains(vertex * 1.0001, tol=1e-9)
    assert Zonotope.box([5e5] * 3).contains(vertex * 1e12, tol=1e-3)


@pytest.mark.parametrize("name", ["PRad-C-I", "PRad-C-II", "PRad-D", "Nom-G"])
@pytest.mark.parametrize("case", ["edge-repeated-output", "edge-dependent-outputs"])
def test_the_analytic_centre_designs_refuse_dependent_outputs_in_one_line(name, case,
                                                                          monkeypatch):
    # bug: "the Newton iteration of the analytic centre did not converge" (and PRad-D's
    # message named PRad-C-I): the gain of dependent outputs is not determined, so the
    # centre does not exist; the refusal names the property
    monkeypatch.setenv("SETOBS_CACHE_DIR", "off")
    with pytest.raises(observers.Unsupported) as err:
        observers.create(name, edge.system(case))
    text = str(err.value)
    assert "\n" not in text and text.startswith(f"{name}: ")
    assert "outputs are linearly dependent" in text and "rank" in text


def test_the_edge_audit_lists_runs_and_refusals_with_their_reasons(tmp_path, capsys,
                                                                   monkeypatch):
    from benchmarks.cli import main

    monkeypatch.setenv("SETOBS_CACHE_DIR", "off")
    out = tmp_path / "edge"
    argv = ["audit", "--edge", "--short", "--scenarios", "edge-dependent-outputs",
            "edge-zero-v", "--observers", "FRad-A", "PRad-C-I", "--jobs", "1",
            "--no-progress", "--out", str(out)]
    assert main(argv) == 0, capsys.readouterr()
    df = audit.aggregate(pd.read_csv(out / "soundness.csv"))
    assert set(df["scenario"]) == {"edge-dependent-outputs", "edge-zero-v"}
    assert (df["violations"] == 0).all() and (df["runs"] == 1).all()
    refused = df[(df["observer"] == "PRad-C-I") & (df["scenario"] == "edge-dependent-outputs")]
    assert refused["failed"].iloc[0] == "unsupported 1"
    assert "outputs are linearly dependent" in refused["reasons"].iloc[0]
    report = (out / "soundness.md").read_text()
    assert "## The edge cases" in report and "## Refusals and failures" in report
    assert "| PRad-C-I | edge-dependent-outputs | unsupported 1 |" in report


def test_a_long_edge_record_is_held_to_the_true_state_and_its_short_one_to_the_floor():
    # the exact reference of a 2,000-step record did not end (step 568 after 20 min on the
    # repeated output): the full edge audit holds a long record to the true state only, says
    # why, and keeps the floor of the short record of the same case
    from systems import edge

    assert edge.no_floor("edge-repeated-output") == ""
    assert edge.no_floor("edge-repeated-output-long") == edge.LONG_NO_FLOOR
    assert "floor is held on the short one" in edge.LONG_NO_FLOOR
    # a case without a floor keeps its own reason on both records
    assert edge.no_floor("edge-magnitudes-long") == edge.case("edge-magnitudes").no_floor != ""
