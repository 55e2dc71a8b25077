"""Data-driven set-based observers (Alanwar et al., ECC 2022) and their N4SID + Kalman
baseline: soundness of the learned set of models, containment, the no-A/B rule, errors."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

import observers
import systems
from benchmarks.run.config import parse_config
from benchmarks.run.runner import run_config
from observers.numerics.datadriven import (
    check_training,
    hbr_pinv,
    implicit_gain,
    implicit_update,
    paper_model_set,
    refined_model_set,
    reverse_map,
    sound_model_set,
    split_sensors,
)
from observers.sets import Ellipsoid, IntervalMatrix, Zonotope
from systems.rotating import INPUT_SET, rotating_target
from systems.training import offline_experiment

from .conftest import paper_table

DD = ("DD-Z-A1", "DD-Z-A2", "DD-CZ-A1", "DD-CZ-A2")
#: [A_tr B_tr] of the paper, eq. (31) (an independent source, not our code)
AB_PAPER = np.hstack([paper_table("alanwar2022_datadriven")["system"]["A_tr"],
                      paper_table("alanwar2022_datadriven")["system"]["B_tr"]])


def test_rotating_target_scenario_matches_the_paper():
    sc = systems.scenario("rotating-target", seed=3)
    np.testing.assert_allclose(np.hstack([sc.system.A, sc.system.B]), AB_PAPER)
    np.testing.assert_allclose(sc.x_true[0], [-10, 10])
    assert sc.training.T == 500 and sc.training.z.shape == (501, 2)
    assert np.all(np.abs(sc.u) <= 10) and np.all(np.abs(sc.training.u) <= 10)
    assert np.all(np.abs(sc.y - sc.x_true @ sc.system.C.T) <= 1 + 1e-12)
    other = systems.scenario("rotating-target", seed=4)
    assert not np.allclose(other.training.z, sc.training.z)


@pytest.mark.parametrize("T", [60, 500])
def test_sound_model_sets_contain_the_true_system_over_seeds(T):
    s = rotating_target()
    for seed in range(15):
        tr = offline_experiment(s, T, seed, INPUT_SET, C=np.eye(2),
                                Gamma=Zonotope.box([0.1, 0.1]))
        data = check_training(tr, 2, 1, "test")
        res = sound_model_set(data, s.W)
        assert res.rho < 1 and res.M.contains(AB_PAPER, 1e-12)
        refined = refined_model_set(data, s.W, res.M)
        assert refined.contains(AB_PAPER)
        assert np.all(refined.width() <= res.M.width() + 1e-12)


def test_paper_construction_with_the_published_settings_is_uninformative():
    # sensor 1 only, its noise <0, 1>, M = 100, T = 100 (as in the published code): the
    # notes report a width of about 375; the set is nowhere near A_tr
    s = rotating_target()
    tr = offline_experiment(s, 100, 0, INPUT_SET, C=[[1.0, 0.4]], Gamma=Zonotope.box([1.0]))
    data = check_training(tr, 2, 1, "test")
    M = paper_model_set(data, s.W, state_bound=100.0)
    assert M.width().max() > 50
    with pytest.raises(observers.DesignFailed, match="full column rank"):
        sound_model_set(data, s.W)


def test_paper_interval_pseudo_inverse_is_not_an_enclosure():
    rng = np.random.default_rng(0)
    Dc, Dr = rng.normal(size=(3, 40)), np.full((3, 40), 0.01)
    P = hbr_pinv(IntervalMatrix(Dc - Dr, Dc + Dr))
    outside = sum(not P.contains(np.linalg.pinv(Dc + Dr * rng.uniform(-1, 1, Dc.shape)))
                  for _ in range(20))
    assert outside > 0


def test_implicit_gain_is_the_frobenius_minimiser():
    rng = np.random.default_rng(1)
    G, C, Gv = rng.normal(size=(2, 5)), rng.normal(size=(3, 2)), np.diag([1.0, 0.5, 2.0])
    L = implicit_gain(G, C, Gv)

    def cost(L):
        _, Gn = implicit_update(np.zeros(2), G, L, C, np.zeros(3), np.zeros(3), Gv)
        return np.sum(Gn**2)

    for _ in range(20):
        assert cost(L) <= cost(L + 1e-3 * rng.normal(size=L.shape)) + 1e-12


def test_reverse_mapping_contains_every_consistent_state():
    rng = np.random.default_rng(2)
    s = rotating_target()
    sensors = split_sensors(s.C, s.V.c, s.V.G, None)
    assert [len(x.rows) for x in sensors] == [1, 1, 1, 1]
    sensors = split_sensors(s.C, s.V.c, s.V.G, [1, 1, 2])
    R = Zonotope([1.0, -2.0], [[3.0, 1.0], [0.0, 2.0]])
    for x in R.sample(20, rng):
        y = s.C @ x + rng.uniform(-1, 1, 4)
        for sensor in sensors:
            c, G = reverse_map(sensor, y, R.c, R.G)
            assert Zonotope(c, G).contains(x, 1e-9)


@pytest.mark.parametrize("name", DD)
def test_dd_observers_contain_the_true_state_over_20_seeds(name):
    for seed in range(20):
        sc = systems.scenario("rotating-target", seed=seed, steps=25)
        obs = observers.create(name, sc.system, training=sc.training, **sc.options)
        res = observers.run(obs, sc.u, sc.y)
        assert res.status == "ok"
        for k, (S, x) in enumerate(zip(res.sets, sc.x_true, strict=True)):
            assert S.contains(x, 1e-9), f"{name} seed {seed} step {k}"


class _NoModel:
    """A system that only has what the data-driven observers may read; A and B are NaN."""

    def __init__(self, s):
        self.C, self.W, self.V, self.X0, self.nu = s.C, s.W, s.V, s.X0, s.nu
        self.A = np.full_like(s.A, np.nan)
        self.B = np.full_like(s.B, np.nan)


@pytest.mark.parametrize("name", [*DD, "KF-N4SID"])
def test_observers_never_read_A_and_B(name):
    sc = systems.scenario("rotating-target", seed=1, steps=15)
    res_true = observers.run(
        observers.create(name, sc.system, training=sc.training, **_opts(name, sc)), sc.u, sc.y)
    blind = _NoModel(sc.system)
    res = observers.run(observers.create(name, blind, training=sc.training, **_opts(name, sc)),
                        sc.u, sc.y)
    assert res.status == "ok" and np.all(np.isfinite(res.lo))
    np.testing.assert_array_equal(res.lo, res_true.lo)
    # a namespace without A and B at all also works
    ns = SimpleNamespace(C=blind.C, W=blind.W, V=blind.V, X0=blind.X0, nu=blind.nu)
    assert observers.create(name, ns, training=sc.training).step(None, sc.y[0]).dim == 2


def _opts(name, sc):
    accepted = observers.get(name).cls.option_defaults()
    return {k: v for k, v in sc.options.items() if k in accepted}


def test_missing_or_bad_training_and_options():
    sc = systems.scenario("rotating-target", steps=5)
    with pytest.raises(observers.Unsupported, match="needs offline training data"):
        observers.create("DD-Z-A2", sc.system)
    bad = SimpleNamespace(u=sc.training.u, z=sc.training.z[:-1], C=sc.training.C,
                          Gamma=sc.training.Gamma)
    with pytest.raises(observers.DesignFailed, match=r"shape \(501, 2\)"):
        observers.create("DD-Z-A2", sc.system, training=bad)
    with pytest.raises(observers.OptionError, match="model must be one of"):
        observers.create("DD-Z-A1", sc.system, training=sc.training, model="exact")
    with pytest.raises(observers.OptionError, match="share noise generators|add up"):
        observers.create("DD-Z-A1", sc.system, training=sc.training, sensors=[3, 3])
    with pytest.raises(observers.Unsupported, match="needs offline training data"):
        observers.create("KF-N4SID", sc.system)


def test_kalman_baseline_identifies_the_model():
    sc = systems.scenario("rotating-target", seed=2)
    obs = observers.create("KF-N4SID", sc.system, training=sc.training)
    np.testing.assert_allclose(np.hstack([obs.A, obs.B]), AB_PAPER, atol=5e-3)
    S = obs.step(None, sc.y[0])
    assert isinstance(S, Ellipsoid) and S.contains(sc.x_true[0])
    assert not observers.get("KF-N4SID").guaranteed


def test_runner_passes_training_and_reports_no_training_as_unsupported():
    cfg = parse_config({
        "scenarios": [{"name": "rotating-target", "seed": 0, "steps": 20}, "alamo2d-sim"],
        "observers": ["DD-Z-A2", "DD-CZ-A2", "KF-N4SID"],
    }, "dd-test")
    assert "training" in cfg.options_for("DD-Z-A2", cfg.scenarios[0])
    _, summary = run_config(cfg, progress=False)
    rows = summary.drop_duplicates(["scenario", "observer"]).set_index(["scenario", "observer"])
    for name in ("DD-Z-A2", "DD-CZ-A2", "KF-N4SID"):
        assert rows.loc[("rotating-target", name), "status"] == "ok"
        assert rows.loc[("alamo2d-sim", name), "status"] == "unsupported"
    assert rows.loc[("rotating-target", "DD-Z-A2"), "violations"] == 0
    assert "training" in rows.loc[("alamo2d-sim", "DD-Z-A2"), "message"]
    assert not rows.loc[("rotating-target", "KF-N4SID"), "guaranteed"]


def test_planar_geometry_by_hand():
    from observers.sets import ConZonotope
    from observers.sets.planar import polygon, set_area

    G = [[1.0, 0.0, 1.0], [0.0, 1.0, 1.0]]  # box plus a diagonal segment: area 4 * 3 = 12
    assert set_area(Zonotope([5.0, -1.0], G)) == pytest.approx(12.0)
    assert set_area(ConZonotope([0.0, 0.0], G)) == pytest.approx(12.0, rel=1e-9)
    assert len(polygon(Zonotope([0.0, 0.0], G))) == 6
    assert set_area(Ellipsoid([0.0, 0.0], np.eye(2))) == pytest.approx(np.pi, rel=1e-3)
