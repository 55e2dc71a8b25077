"""The ranking studies: the noise-level grid's scaled records and family curves, and the
robustness study's ranks, win tables and sentences, on small hand-made inputs and a tiny run."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from benchmarks.studies import noise_grid, robustness


def test_scaled_scenario_scales_one_set_and_keeps_the_input():
    base = noise_grid.scaled_scenario("alamo2d-sim", ("W",), 1.0)
    W3 = noise_grid.scaled_scenario("alamo2d-sim", ("W",), 3.0)
    np.testing.assert_allclose(W3.system.W.G, 3.0 * base.system.W.G)
    np.testing.assert_allclose(W3.system.V.G, base.system.V.G)
    np.testing.assert_allclose(W3.system.X0.G, base.system.X0.G)
    np.testing.assert_array_equal(W3.u, base.u)
    # the record lies in the scaled sets: y - C x in V
    resid = W3.y - W3.x_true @ W3.system.C.T - W3.system.V.c
    assert np.all(np.abs(resid) <= np.abs(W3.system.V.G).sum(axis=1) + 1e-12)
    assert "W x3" in W3.name


def test_grid_points_and_family_curves_by_hand():
    pts = noise_grid.grid_points(("r",), (0.1, 1.0, 10.0))
    # 4 axes x 2 off-nominal scales + the nominal record once
    assert len(pts) == 9 and ("r", "all", 1.0) in pts and ("r", "W", 1.0) not in pts
    df = pd.DataFrame({
        "record": "r", "axis": ["W", "W", "all", "all"], "scale": [0.1, 0.1, 1.0, 1.0],
        "observer": ["a", "b", "a", "b"], "family": ["f", "f", "f", "g"],
        "status": "ok", "violations": 0, "covers_exact": "yes", "gap": [3.0, 2.0, 1.5, 1.2]})
    curves = noise_grid.family_curves(df, "gap")
    w = curves[(curves["axis"] == "W") & (curves["family"] == "f")].set_index("scale")["gap"]
    assert w[0.1] == 2.0 and w[1.0] == 1.5  # the best member; the nominal point on every axis
    assert "x0.1: f (gap 2)" in noise_grid.winners_sentence(curves, "r", "W")


def test_scale_dependence_is_named():
    df = pd.DataFrame({"record": "r", "axis": "all", "scale": [0.1, 1.0, 0.1, 1.0],
                       "observer": ["a", "a", "b", "b"], "status": ["ok", "ok", "noGain", "ok"],
                       "gap": [2.0, 2.0, np.nan, 3.0]})
    assert noise_grid.scale_dependent(df, "r") == {"b": float("inf")}
    same = df.assign(status="noGain", gap=np.nan)  # no gain at every scale: not a move
    assert noise_grid.scale_dependent(same, "r") == {}
    moved = pd.DataFrame({"record": "r", "axis": "all", "scale": [0.1, 1.0, 10.0],
                          "observer": "ESO-A", "status": "ok", "gap": [2.2, 2.0, 2.0]})
    assert noise_grid.scale_dependent(moved, "r") == pytest.approx({"ESO-A": 0.1})
    text = noise_grid.scale_sentence({"ESO-A": 0.1, "x": 2e-5, "y": float("inf")})
    assert "ESO-A (gap moves by 0.1: the level" in text
    assert "x (gap moves by 2.0e-05: the SDP solver's tolerance)" in text
    assert "y (a status changes: cause not known)" in text


def test_ranks_and_win_table_by_hand():
    # two realisations: a < b < c in the first, b < a in the second (c fails there)
    df = pd.DataFrame({
        "scenario": "s", "realisation": [0, 0, 0, 1, 1, 1], "kind": "uniform",
        "observer": ["a", "b", "c"] * 2, "status": ["ok"] * 5 + ["diverged"],
        "violations": [0] * 6, "rms": [1.0, 2.0, 4.0, 3.0, 1.5, np.nan],
        "gap": np.nan, "gap_steady": np.nan})
    out = robustness.add_ranks(df)
    assert out["rank"].tolist()[:5] == [1.0, 2.0, 3.0, 2.0, 1.0]
    assert out["rel_rms"].tolist()[:5] == pytest.approx([1.0, 2.0, 4.0, 2.0, 1.0])
    w = robustness.win_table(out, "s", ["a", "b", "c"])
    assert w.loc["a", "b"] == 0.5 and w.loc["b", "a"] == 0.5
    assert w.loc["a", "c"] == 1.0 and w.loc["c", "a"] == 0.0  # only realisation 0 counts
    per = robustness.per_observer(out, "s").set_index("observer")
    assert per.loc["c", "failed"] == 1 and per.loc["a", "rank_median"] == 1.5


def test_tiny_robustness_run_and_report(tmp_path):
    names = ("FRad-A", "CZN-A", "MHE")
    df = robustness.run_study(1, scenarios=("alamo2d-sim",), count=3, names=names,
                              scaling=False)
    assert len(df) == 9 and set(df["kind"]) == {"uniform", "gaussian", "vertex"}
    assert (df["violations"].fillna(0) == 0).all()
    ok = df[df["status"] == "ok"]
    assert (ok["gap"] >= 1 - 1e-6).all() and (ok["rel_rms"] >= 1 - 1e-12).all()
    text = robustness.report(df, None, tmp_path / "robustness.md", tmp_path, 1.0)
    assert "containment violations: 0**" in text
    assert "Floor: the exact consistent set of each of the 3 realisations." in text
    assert "## alamo2d-sim" in text and "How often the row is tighter" in text


def test_scaling_records_run_the_observers_their_published_column_compares():
    # ARCH 2021 Table 5, 18 tanks: PRad-A has no gain there (no value), VolMin-B no entry;
    # the published PRad-C stands for our two PRad-C variants; Table 6: the three FRad
    t5 = robustness.scaling_observers("tank18-linear", "linear")
    assert "PRad-A" not in t5 and "VolMin-B" not in t5
    assert {"FRad-A", "PRad-C-I", "PRad-C-II", "ESO-B", "Hinf-G"} <= set(t5)
    assert "PRad-A" in robustness.scaling_observers("tank12-linear", "linear")  # published inf
    assert set(robustness.scaling_observers("tank30-nonlinear", "nonlinear")) == {
        "FRad-A", "FRad-B", "FRad-C"}
    tasks = robustness.study_tasks(2, names=("FRad-A",), scenarios=("tank6-linear",))
    with_floor = [t for t in tasks if t[3]]
    assert [t[:2] for t in with_floor] == [("tank6-linear", 0), ("tank6-linear", 1)]
    assert {t[0] for t in tasks if not t[3]} == {
        f"tank{n}-linear" for n in (12, 18, 24, 30)} | {
        f"tank{n}-nonlinear" for n in (12, 18, 24, 30)}


def test_the_holds_sentence_counts_the_pairs_of_every_record(tmp_path):
    # the store ranks a < b < c on both records; realisations keep a < b, swap b and c on r2
    store = tmp_path / "t"
    store.mkdir()
    pd.DataFrame({"scenario": ["r1"] * 3 + ["r2"] * 3, "observer": ["a", "b", "c"] * 2,
                  "variant": np.nan, "status": "ok", "contained": "yes",
                  "rms_radius": [1.0, 2.0, 3.0] * 2}).to_csv(store / "summary.csv")
    rows = []
    for sc, order in (("r1", {"a": 1.0, "b": 2.0, "c": 3.0}),
                      ("r2", {"a": 1.0, "b": 3.0, "c": 2.0})):
        for i in range(3):
            rows += [{"scenario": sc, "realisation": i, "observer": o, "status": "ok",
                      "violations": 0, "rms": v} for o, v in order.items()]
    text = robustness.holds_sentence("t", ("r1", "r2"), pd.DataFrame(rows), tmp_path)
    # pairs: r1 (a,b) (a,c) (b,c) kept; r2 (a,b) (a,c) kept, (b,c) not: 5 of 6 (0.83)
    assert "holds in the main" in text and "5 of 6 pairs" in text
    assert "a on r1 in 100 %" in text and "a on r2 in 100 %" in text


def test_the_studies_fingerprints_cover_every_guaranteed_observer():
    # the noise grid and the robustness study run every guaranteed observer: their rows'
    # fingerprints (the dated block of their reports) must cover each one's module
    import observers
    from benchmarks.gate.dated import DATED

    guaranteed = {i.name for i in observers.available() if i.guaranteed} - {"Exact"}
    for study in ("noise_grid", "robustness"):
        assert set(DATED[study].observers) == guaranteed, study


def test_an_incremental_run_replaces_the_changed_observers_rows_and_ranks_again():
    """``make robustness`` measures again only the observers whose code changed: their rows
    are replaced, the others kept, the order and the ranks those of a full run."""
    def table(rms_czn):
        return robustness.add_ranks(pd.DataFrame({
            "scenario": "s", "realisation": [0, 0, 0, 1, 1, 1], "kind": "uniform",
            "observer": ["FRad-A", "CZN-A", "MHE"] * 2, "status": "ok", "violations": 0,
            "rms": [2.0, rms_czn[0], 3.0, 2.0, rms_czn[1], 1.0], "gap": np.nan,
            "gap_steady": np.nan, "floor": "exact", "floor_steps": 10}))[robustness.COLUMNS]

    old, full = table([1.0, 4.0]), table([5.0, 1.5])
    new = full[full["observer"] == "CZN-A"]
    merged = robustness.merge_changed(old, new, ["CZN-A"])
    pd.testing.assert_frame_equal(merged, full)
    # by hand: CZN-A 5.0 is now the loosest of realisation 0, 1.5 the second of realisation 1
    assert merged["rank"].tolist() == [1.0, 3.0, 2.0, 3.0, 2.0, 1.0]
