"""The exact reference ``Exact``: agreement with independent LP formulations, hand-derived
hulls, containment, the two floors, the cache, and its refusals."""

from __future__ import annotations

import numpy as np
import pytest

import observers
import systems
from observers import registry
from observers.builtin.exact import exact_hulls
from observers.errors import Unsupported
from observers.numerics.exact import ExactHullLP, ExactSet
from observers.numerics.exact_reference import dense_hulls, explicit_hulls
from observers.sets import EmptySet, Zonotope

#: agreement with the independent formulations, relative to the radius (issue 24)
RTOL = 1e-6


def _sets(s) -> tuple:
    return tuple((S.c, S.G) for S in (s.X0, s.W, s.V))


def _exact(s, u, y, cache: bool = False) -> dict[str, np.ndarray]:
    return exact_hulls(s, u, y, cache=cache)


def _assert_agree(got: dict, ref: dict, what: str) -> None:
    """Every step of ``ref`` (step -> pred_lo, pred_hi, filt_lo, filt_hi) within RTOL of the
    reference radius."""
    for k, (plo, phi, flo, fhi) in ref.items():
        for floor, lo, hi in (("pred", plo, phi), ("filt", flo, fhi)):
            r = 0.5 * (hi - lo)
            assert np.all(r > 0), (what, k, floor)
            err = np.maximum(np.abs(got[f"{floor}_lo"][k] - lo), np.abs(got[f"{floor}_hi"][k] - hi))
            assert np.all(err <= RTOL * r), (what, k, floor, (err / r).max())


# -- (a) agreement with the dense LP over the noise factors, from scratch ----------------------
@pytest.mark.slow
@pytest.mark.parametrize(("name", "steps"), [("tank6-linear", 40), ("vehicle6d-cora", 40)])
def test_agrees_with_the_dense_lp_at_every_step(name, steps):
    sc = systems.scenario(name)
    s, u, y = sc.system, sc.u[:steps], sc.y[:steps]
    got = _exact(s, u, y)
    ref = dense_hulls((s.A, s.B, s.C, *_sets(s)), u, y)
    assert sorted(ref) == list(range(steps))
    _assert_agree(got, ref, name)


def _general_system(seed: int = 3) -> systems.LinearSystem:
    """3 states, 2 outputs with a dense C; X0, W and V with generators that are not
    axis-aligned (the factor columns of the formulation) next to axis-aligned ones."""
    rng = np.random.default_rng(seed)
    A = np.array([[0.9, 0.2, 0.0], [-0.1, 0.8, 0.3], [0.05, 0.0, 0.95]])
    B = np.array([[1.0], [0.0], [0.5]])
    C = np.array([[1.0, 0.5, 0.0], [0.0, 1.0, -1.0]])
    X0 = Zonotope([0.5, -0.2, 0.1], np.hstack([np.eye(3), rng.uniform(-0.5, 0.5, (3, 2))]))
    W = Zonotope(np.zeros(3), np.hstack([np.diag([0.02, 0.0, 0.01]),
                                         rng.uniform(-0.03, 0.03, (3, 2))]))
    V = Zonotope(np.zeros(2), np.array([[0.05, 0.02], [-0.01, 0.04]]))
    return systems.LinearSystem(A, B, C, W, V, X0)


def test_agrees_with_both_formulations_on_general_sets():
    s = _general_system()
    sim = systems.simulate(s, 0.3 * np.sin(np.arange(15)).reshape(-1, 1), seed=4)
    got = _exact(s, sim.u, sim.y)
    _assert_agree(got, dense_hulls((s.A, s.B, s.C, *_sets(s)), sim.u, sim.y), "dense")
    _assert_agree(got, explicit_hulls((s.A, s.B, s.C, *_sets(s)), sim.u, sim.y), "explicit")


def test_agrees_with_the_dense_lp_on_the_alamo_example():
    sc = systems.scenario("alamo2d-sim")  # W is a segment: one general generator
    s = sc.system
    got = _exact(s, sc.u, sc.y)
    _assert_agree(got, dense_hulls((s.A, s.B, s.C, *_sets(s)), sc.u, sc.y), "alamo2d-sim")


# -- (b) hand-derived hulls --------------------------------------------------------------------
def test_scalar_random_walk_by_hand():
    """x+ = x + u + w, y = x + v in one dimension: intervals are exact there, so the hulls are
    the interval recursion F0 = X0 & S0, P_k = F_{k-1} + u + W, F_k = P_k & S_k."""
    s = systems.LinearSystem([[1.0]], [[1.0]], [[1.0]], W=Zonotope.box([0.1]),
                             V=Zonotope.box([0.2]), X0=Zonotope.box([1.0]))
    u = np.array([[0.0], [0.25], [0.0]])
    y = np.array([[0.5], [0.9], [0.7], [1.3]])
    h = _exact(s, u[:2], y[:3])
    # F0 = [-1, 1] & [0.3, 0.7]; P1 = [0.2, 0.8]; F1 = [0.7, 0.8]; P2 = [0.85, 1.15];
    # F2 = [0.85, 0.9]; P3 = [0.75, 1.0]; F3 = [1.1, 1.5] & P3 = empty -> see below
    expect_pred = [(-1.0, 1.0), (0.2, 0.8), (0.85, 1.15)]
    expect_filt = [(0.3, 0.7), (0.7, 0.8), (0.85, 0.9)]
    for k in range(3):
        np.testing.assert_allclose([h["pred_lo"][k, 0], h["pred_hi"][k, 0]], expect_pred[k],
                                   atol=1e-9)
        np.testing.assert_allclose([h["filt_lo"][k, 0], h["filt_hi"][k, 0]], expect_filt[k],
                                   atol=1e-9)
    # y[3] = 1.3: S3 = [1.1, 1.5] misses P3 = [0.75, 1.0]: no consistent state at step 3
    with pytest.raises(EmptySet, match=r"step 3.*inconsistent with the model"):
        _exact(s, np.vstack([u, [[0.0]]]), y)


def _double_integrator(C=((1.0, 0.0),)) -> systems.LinearSystem:
    """x+ = [[1, 1], [0, 1]] x, no process noise, y = x_1 + v with |v| <= 0.1, X0 = [-1, 1]^2."""
    return systems.LinearSystem([[1.0, 1.0], [0.0, 1.0]], np.zeros((2, 0)), np.array(C),
                                W=Zonotope.box([0.0, 0.0]), V=Zonotope.box([0.1] * len(C)),
                                X0=Zonotope.box([1.0, 1.0]))


def test_double_integrator_by_hand():
    """y = 0 three times: x_k = (a + k b, b) with |a| <= 0.1 (y0), |a + b| <= 0.1 (y1) and
    |a + 2 b| <= 0.1 (y2).  Filtered hulls: step 0 [-0.1, 0.1] x [-1, 1]; step 1 x_1 = a + b
    in [-0.1, 0.1], b in [-0.2, 0.2]; step 2 b in [-0.1, 0.1] (b = 0.1, a = -0.1 meets all).
    Predicted: step 1 (a + b, b) over |a| <= 0.1, |b| <= 1: [-1.1, 1.1] x [-1, 1]; step 2
    a + 2 b <= 0.3 (b = 0.2, a = -0.1) and b in [-0.2, 0.2].  An interval recursion never
    learns b (it stays [-1, 1]): the exact set keeps the coupling."""
    s = _double_integrator()
    h = _exact(s, np.zeros((3, 0)), np.zeros((3, 1)))
    np.testing.assert_allclose(h["filt_hi"], [[0.1, 1.0], [0.1, 0.2], [0.1, 0.1]], atol=1e-9)
    np.testing.assert_allclose(h["filt_lo"], -h["filt_hi"], atol=1e-9)
    np.testing.assert_allclose(h["pred_hi"], [[1.0, 1.0], [1.1, 1.0], [0.3, 0.2]], atol=1e-9)
    np.testing.assert_allclose(h["pred_lo"], -h["pred_hi"], atol=1e-9)


# -- (c) containment ---------------------------------------------------------------------------
@pytest.mark.parametrize("noise", ["uniform", "vertex"])
def test_simulated_trajectories_lie_in_every_hull(noise):
    """Records simulated with noise inside the bounds (vertex noise: on the boundary): the true
    state is in both hulls of every step, and in the set (its LP membership test)."""
    sc = systems.scenario("vehicle6d-cora")
    s = sc.system
    for seed in range(3):
        sim = systems.simulate(s, sc.u[:30], seed=seed, noise=noise)
        obs = observers.create("Exact", s, cache=False)
        res = observers.run(obs, sim.u, sim.y)
        h = obs.hull_arrays()
        x = sim.x_true
        tol = 1e-9 * (1 + np.abs(x))
        for floor in ("pred", "filt"):
            assert np.all(h[f"{floor}_lo"] <= x + tol) and np.all(x <= h[f"{floor}_hi"] + tol), (
                noise, seed, floor)
        for k in (0, 7, 29):
            assert res.sets[k].contains(x[k], 1e-9)


def test_scenario_true_states_lie_in_every_hull():
    for name in ("tank6-linear", "vehicle6d-cora"):
        sc = systems.scenario(name)
        h = _exact(sc.system, sc.u[:60], sc.y[:60])
        x = sc.x_true[:60]
        for floor in ("pred", "filt"):
            assert np.all(h[f"{floor}_lo"] <= x + sc.tolerance), (name, floor)
            assert np.all(x <= h[f"{floor}_hi"] + sc.tolerance), (name, floor)


def test_contains_rejects_a_point_in_the_hull_but_not_in_the_set():
    """Double integrator, step 1 (hand case): the hull is [-0.1, 0.1] x [-0.2, 0.2] but the
    set is {(a + b, b): |a| <= 0.1, |a + b| <= 0.1}, so (-0.1, 0.2) (needs a = -0.3) is out
    and (0.1, 0.2) (a = -0.1) is in."""
    s = _double_integrator()
    res = observers.run(observers.create("Exact", s, cache=False), np.zeros((2, 0)),
                        np.zeros((2, 1)))
    S = res.sets[1]
    assert isinstance(S, ExactSet) and S.dim == 2
    assert S.contains([0.1, 0.2], 1e-9)
    assert not S.contains([-0.1, 0.2], 1e-9)
    assert not S.contains([0.0, 0.5], 1e-9)  # outside the hull


# -- (d) the two floors ------------------------------------------------------------------------
def test_predicted_hull_contains_the_filtered_hull():
    sc = systems.scenario("tank6-linear")
    h = _exact(sc.system, sc.u[:40], sc.y[:40])
    assert np.all(h["pred_lo"] <= h["filt_lo"]) and np.all(h["filt_hi"] <= h["pred_hi"])
    assert np.any(h["pred_hi"] - h["pred_lo"] > h["filt_hi"] - h["filt_lo"] + 1e-6)


def test_predicted_hull_is_the_prediction_of_the_exact_filtered_set():
    """Step 1 of the double integrator: the filtered set of step 0 is the box
    [-0.1, 0.1] x [-1, 1] (X0 cut by y0), its image under A (no noise) has the hull
    [-1.1, 1.1] x [-1, 1]; the observer exposes it as predicted_hull() and S.predicted."""
    s = _double_integrator()
    obs = observers.create("Exact", s, cache=False)
    S0 = obs.step(None, np.zeros(1))
    np.testing.assert_allclose(S0.predicted.hi, [1.0, 1.0], atol=1e-12)  # step 0: X0
    S1 = obs.step(np.zeros(0), np.zeros(1))
    box = S0.interval()
    corners = np.array([[a, b] for a in (box.lo[0], box.hi[0]) for b in (box.lo[1], box.hi[1])])
    image = corners @ np.array(s.A).T
    np.testing.assert_allclose(obs.predicted_hull().lo, image.min(axis=0), atol=1e-9)
    np.testing.assert_allclose(obs.predicted_hull().hi, image.max(axis=0), atol=1e-9)
    assert obs.predicted_hull() == S1.predicted


def test_registry_entry_and_floors():
    info = observers.get("Exact")
    assert (info.family, info.guaranteed, info.floor) == ("reference", True, "filtered")
    assert observers.names()[0] == "Exact"
    for i in observers.available():
        assert i.floor in registry.FLOORS
        # the set of step k of an observer ready before y[k] cannot use y[k]; one that uses
        # y[k] (strips, contractors such as INT-CP of the interval family) is filtered
        assert (i.floor == "predicted") == i.ready_for_control, i.name
        if i.family == "propagation":
            assert i.floor == "predicted", i.name
    with pytest.raises(observers.ObserverError, match="unknown floor 'smoothed'"):
        observers.register("Test-Floor", family="strip", set_type="zonotope",
                           ready_for_control=False, floor="smoothed")


@pytest.mark.parametrize("name", ["FRad-C", "PRad-E", "Nom-G", "ESO-C", "ESO-D", "Hinf-G",
                                  "FRad-A", "FRad-B", "CZN-A", "CZN-B", "ESO-A", "ROPO"])
def test_floor_matches_what_the_step_reads(name):
    """Perturbing y[k] leaves the set of step k unchanged exactly for the observers held
    against the predicted floor, and changes it for those held against the filtered one."""
    sc = systems.scenario("vehicle2d-cora")
    obs = observers.create(name, sc.system)
    k = 4
    y = sc.y[: k + 1].copy()
    a = observers.run(obs, sc.u[: k + 1], y)
    y[k] += 0.05
    b = observers.run(obs, sc.u[: k + 1], y)
    same = np.array_equal(a.lo[k], b.lo[k]) and np.array_equal(a.hi[k], b.hi[k])
    assert same == (observers.get(name).floor == "predicted"), name


# -- (e) the cache -----------------------------------------------------------------------------
def test_cache_hit_and_miss(tmp_path, monkeypatch):
    monkeypatch.setenv("SETOBS_CACHE_DIR", str(tmp_path))
    sc = systems.scenario("vehicle2d-cora")
    s, u, y = sc.system, sc.u[:25], sc.y[:25]
    obs = observers.create("Exact", s)
    first = observers.run(obs, u, y)
    assert (obs.computed_steps, obs.cached_steps) == (25, 0)
    assert len(list(tmp_path.glob("Exact-*.npz"))) == 1
    second = observers.create("Exact", s)
    again = observers.run(second, u, y)
    assert (second.computed_steps, second.cached_steps) == (0, 25)
    assert second.lp_stats["solves"] == 0
    np.testing.assert_array_equal(again.lo, first.lo)
    np.testing.assert_array_equal(again.hi, first.hi)
    # a record changed at step 10: steps 0-9 from the cache, the rest computed
    y2 = y.copy()
    y2[10] += 1e-3
    changed = observers.create("Exact", s)
    res = observers.run(changed, u, y2)
    assert (changed.cached_steps, changed.computed_steps) == (10, 15)
    fresh = _exact(s, u, y2)
    np.testing.assert_allclose(res.lo, fresh["filt_lo"], rtol=0, atol=1e-9)
    np.testing.assert_allclose(res.hi, fresh["filt_hi"], rtol=0, atol=1e-9)
    # a changed first measurement misses entirely; a changed model too
    y3 = y.copy()
    y3[0] += 1e-3
    other = observers.create("Exact", s)
    observers.run(other, u, y3)
    assert other.cached_steps == 0
    s2 = systems.LinearSystem(s.A, s.B, s.C, W=Zonotope.box(1.5 * s.W.interval().hi), V=s.V,
                              X0=s.X0)
    model = observers.create("Exact", s2)
    observers.run(model, u, y)
    assert model.cached_steps == 0


def test_cache_off(tmp_path, monkeypatch):
    monkeypatch.setenv("SETOBS_CACHE_DIR", "off")
    sc = systems.scenario("vehicle2d-cora")
    obs = observers.create("Exact", sc.system)
    observers.run(obs, sc.u[:5], sc.y[:5])
    observers.run(obs, sc.u[:5], sc.y[:5])
    assert obs.cached_steps == 0 and obs.computed_steps == 5


# -- (f) nonlinear systems ---------------------------------------------------------------------
def test_nonlinear_system_is_refused_in_one_line():
    sc = systems.scenario("tank6-nonlinear-cora")
    with pytest.raises(Unsupported, match="Exact needs a linear system") as exc:
        observers.create("Exact", sc.system)
    assert "\n" not in str(exc.value)


# -- (g) inconsistent records ------------------------------------------------------------------
def test_measurement_outside_x0_plus_v_is_reported():
    sc = systems.scenario("vehicle6d-cora")
    y = sc.y[:5].copy()
    y[0, 0] = 1e3  # far outside C X0 + V
    res = observers.run(observers.create("Exact", sc.system, cache=False), sc.u[:5], y)
    assert res.status == "empty" and res.failed_step == 0
    assert "inconsistent with the model" in res.message and "step 0" in res.message


def test_inconsistent_later_measurement_is_reported_by_the_lp():
    """y = x_1 + x_2 (not a bound on one state, so the LP itself must find the record
    infeasible): y[2] contradicts y[0], y[1] and the dynamics."""
    s = _double_integrator(C=((1.0, 1.0),))
    y = np.array([[0.0], [0.0], [5.0]])
    res = observers.run(observers.create("Exact", s, cache=False), np.zeros((3, 0)), y)
    assert res.status == "empty" and res.failed_step == 2
    assert "step 2" in res.message and "inconsistent with the model" in res.message
    assert "proved by a Farkas certificate" in res.message  # HiGHS's verdict checked


def test_engine_needs_first_step():
    s = _double_integrator()
    E = ExactHullLP(s.A, s.B, s.C, *_sets(s))
    with pytest.raises(RuntimeError, match="first"):
        E.advance(np.zeros(0), np.zeros(1))


def test_a_stalled_warm_solve_is_finished_cold(monkeypatch):
    """Bug: the warm-started Dantzig simplex cycled for ever on a degenerate LP of the
    audit's vertex-noise realisations (vehicle6d-sim, seed 2, step 97), hanging the audit.
    Warm solves now stop at an iteration cap and the LP is solved again from scratch with
    steepest-edge pricing.  Forcing every warm solve to stall must give the same hulls as
    the dense reference, with no step marked inexact."""
    import observers.numerics.exact as engine

    monkeypatch.setattr(engine, "WARM_ITERATIONS", 1)
    monkeypatch.setattr(engine, "WARM_ITERATIONS_PER_ROW", 0)
    s = _general_system()
    sc = systems.simulate(s, 0.3 * np.cos(np.arange(12)).reshape(-1, 1), seed=5)
    lp = ExactHullLP(s.A, s.B, s.C, *_sets(s))
    got = {"pred_lo": [], "pred_hi": [], "filt_lo": [], "filt_hi": []}
    for k in range(12):
        h = lp.first(sc.y[0]) if k == 0 else lp.advance(sc.u[k - 1], sc.y[k])
        for key in got:
            got[key].append(getattr(h, key))
    assert lp.inexact == []
    ref = dense_hulls((s.A, s.B, s.C, *_sets(s)), sc.u, sc.y)
    _assert_agree({k: np.array(v) for k, v in got.items()}, ref, "cold fallback")


def _stalled_run(monkeypatch, cold_solves, steps: int = 12):
    """The hulls of a record with every warm solve stalled and ``cold_solves`` as the cold
    re-solves (real HiGHS solves; a time limit of zero makes one stop unfinished)."""
    import observers.numerics.exact as engine

    monkeypatch.setattr(engine, "WARM_ITERATIONS", 1)
    monkeypatch.setattr(engine, "WARM_ITERATIONS_PER_ROW", 0)
    monkeypatch.setattr(engine, "COLD_SOLVES", cold_solves)
    s = _general_system()
    sc = systems.simulate(s, 0.3 * np.cos(np.arange(steps)).reshape(-1, 1), seed=5)
    lp = ExactHullLP(s.A, s.B, s.C, *_sets(s))
    got = {"pred_lo": [], "pred_hi": [], "filt_lo": [], "filt_hi": []}
    for k in range(steps):
        h = lp.first(sc.y[0]) if k == 0 else lp.advance(sc.u[k - 1], sc.y[k])
        for key in got:
            got[key].append(getattr(h, key))
    ref = dense_hulls((s.A, s.B, s.C, *_sets(s)), sc.u, sc.y)
    return lp, {k: np.array(v) for k, v in got.items()}, ref


def test_a_failed_cold_solve_falls_back_to_the_next_strategy(monkeypatch):
    """Bug: on the 30-tank record of Table 5 HiGHS's cold steepest-edge dual simplex stopped
    with an error at its first iteration on one LP of step 243; its bound fell back to the
    predicted one (sound, 5.3e-3 loose), and the floor flagged ZB-A for a state it had
    rightly excluded.  The cold re-solves are now a chain: a strategy that does not finish
    (here: a zero time limit) hands over to the next, and the hulls are exact again."""
    import observers.numerics.exact as engine

    chain = (("unfinished", {"time_limit": 0.0}),) + engine.COLD_SOLVES[1:]
    lp, got, ref = _stalled_run(monkeypatch, chain)
    assert lp.inexact == []
    _assert_agree(got, ref, "fallback chain")
    # the zero time limit was the failed strategy's own: the warm solves ran without it
    assert all(h.getOptionValue("time_limit")[1] == np.inf for h in lp._models)


def test_steps_no_strategy_solves_are_listed_inexact_and_stay_sound(monkeypatch):
    """When no cold strategy finishes, the step is listed in ``inexact`` and its bounds are
    still sound (they contain the exact hulls)."""
    lp, got, ref = _stalled_run(monkeypatch, (("unfinished", {"time_limit": 0.0}),), steps=6)
    assert lp.inexact == list(range(6))
    for k, (plo, phi, flo, fhi) in ref.items():  # step -> the dense formulation's hulls
        for key, lo, hi in (("pred", plo, phi), ("filt", flo, fhi)):
            assert np.all(got[f"{key}_lo"][k] <= lo + 1e-9), (k, key)
            assert np.all(got[f"{key}_hi"][k] >= hi - 1e-9), (k, key)


def test_inexact_steps_are_kept_by_the_cache(tmp_path, monkeypatch):
    """A step no strategy solved to optimality stays marked when its hulls are read back
    from the cache (the floor must not hold observers to it on a warm run either)."""
    import observers.numerics.exact as engine

    monkeypatch.setenv("SETOBS_CACHE_DIR", str(tmp_path))
    sc = systems.scenario("vehicle2d-cora")
    u, y = sc.u[:4], sc.y[:4]
    monkeypatch.setattr(engine, "WARM_ITERATIONS", 1)
    monkeypatch.setattr(engine, "WARM_ITERATIONS_PER_ROW", 0)
    monkeypatch.setattr(engine, "COLD_SOLVES", (("unfinished", {"time_limit": 0.0}),))
    first = observers.create("Exact", sc.system)
    observers.run(first, u, y)
    marked = first.inexact_steps()
    assert marked and set(marked) <= {0, 1, 2, 3}
    monkeypatch.undo()
    monkeypatch.setenv("SETOBS_CACHE_DIR", str(tmp_path))
    again = observers.create("Exact", sc.system)
    observers.run(again, u, y)
    assert again.cached_steps == 4 and again.inexact_steps() == marked
    assert again.lp_stats["inexact_steps"] == marked


_REBUILT_PREFIX = """
import json, sys
import numpy as np
import observers
from benchmarks.gate.audit import realisation
sc = realisation("vehicle6d-sim", 4)[1]
prefix = observers.create("Exact", sc.system)  # writes a cache entry of 157 steps
observers.run(prefix, sc.u[:156], sc.y[:157], keep_sets=False)
obs = observers.create("Exact", sc.system)  # replays them, rebuilds the LPs, goes on
res = observers.run(obs, sc.u[:159], sc.y[:160], keep_sets=False)
h = obs.hull_arrays()
x = sc.x_true[:160]
inside = bool(np.all((h["filt_lo"] <= x + 1e-9) & (x <= h["filt_hi"] + 1e-9)))
print(json.dumps({"status": res.status, "inside": inside, **obs.lp_stats}))
"""


def test_an_engine_rebuilt_from_a_cached_prefix_does_not_cycle(tmp_path):
    """Bug: on the audit's 6-D vehicle realisation 4 (worst-case input), an engine rebuilt
    from a cached prefix of 157 steps (no basis: cold solves) never returned from HiGHS's
    cold steepest-edge dual simplex on the predicted LP of step 157 (it cycled; > 240 s),
    and the audit hung.  Every cold simplex strategy now runs under an iteration cap and
    hands over to the next (Devex pricing solves it).  Run in a child process so that a
    regression fails the test instead of hanging the suite."""
    import json
    import os
    import subprocess
    import sys

    env = {**os.environ, "SETOBS_CACHE_DIR": str(tmp_path)}
    try:
        proc = subprocess.run([sys.executable, "-c", _REBUILT_PREFIX], capture_output=True,
                              text=True, env=env, timeout=900)
    except subprocess.TimeoutExpired:
        pytest.fail("the rebuilt engine did not finish step 157 (a cold solve cycled)")
    assert proc.returncode == 0, proc.stderr[-2000:]
    out = json.loads(proc.stdout.strip().splitlines()[-1])
    assert out["status"] == "ok" and out["inside"]
    assert out["cached_steps"] == 157 and out["computed_steps"] == 3
    assert out["inexact_steps"] == []


def test_one_writer_per_cache_entry(tmp_path, monkeypatch):
    """A second process (here a thread) needing the floor of a record whose entry is being
    written waits for the writer and replays the whole entry: it never rebuilds the LPs
    from a partial prefix (the path that cycled above)."""
    import threading
    import time

    from benchmarks.run.floors import compute_floor

    monkeypatch.setenv("SETOBS_CACHE_DIR", str(tmp_path))
    sc = systems.scenario("vehicle2d-cora")
    writer = observers.create("Exact", sc.system)
    got = {}
    with writer.sole_writer(sc.y):
        second = threading.Thread(target=lambda: got.setdefault("floor", compute_floor(sc)))
        second.start()
        time.sleep(0.5)  # without the lock the thread would be computing steps by now
        observers.run(writer, sc.u, sc.y, keep_sets=False)
    second.join()
    floor = got["floor"]
    assert floor.kind == "exact"
    assert np.isnan(floor.step_seconds)  # no step computed: all replayed from the entry
    np.testing.assert_array_equal(floor.lo["filtered"], writer.hull_arrays()["filt_lo"])


def _predicted_iterations(lp: ExactHullLP, sc, steps: int) -> float:
    """Mean simplex iterations of the predicted LPs of ``steps`` steps of ``sc``'s record."""
    lp.first(sc.y[0])
    its = solves = 0
    for k in range(1, steps):
        lp._activate_prediction(k, np.asarray(sc.u[k - 1], float).reshape(-1))
        lp._move_objective(k)
        i0, s0 = lp.iterations, lp.solves
        plo, phi = lp._solve_all(k, "predicted")
        its, solves = its + lp.iterations - i0, solves + lp.solves - s0
        lp._filter(k, np.asarray(sc.y[k], float).reshape(-1), plo, phi,
                   np.full(lp.n, -np.inf), np.full(lp.n, np.inf), None)
    return its / solves


def test_blocks_allocated_ahead_start_with_their_states_basic(monkeypatch):
    """The blocks allocated ahead have their states basic and their rows nonbasic, so that an
    activated prediction block is primal feasible at once and the predicted LP's primal
    simplex only follows the objective.  HiGHS's own basis for appended blocks (slack rows
    basic, states nonbasic) is primal infeasible in every dynamics row once the block is
    active: about one pivot per state of every predicted LP.  The hulls are those of the
    dense reference either way (tests above); here the work: on the 6-tank record the placed
    basis needs fewer than n / 2 iterations per predicted LP, HiGHS's own basis more."""
    import highspy

    sc = systems.scenario("tank6-linear")
    s = sc.system
    lp = ExactHullLP(s.A, s.B, s.C, *_sets(s))
    lp.first(sc.y[0])
    lay = lp._lay(1)  # allocated ahead, not active yet
    for h in lp._models:
        basis = h.getBasis()
        assert basis.valid
        assert all(basis.col_status[lay.x + i] == highspy.HighsBasisStatus.kBasic
                   for i in range(lp.n))
        assert all(basis.row_status[lay.rows + i] != highspy.HighsBasisStatus.kBasic
                   for i in range(lp.n))
    placed = _predicted_iterations(ExactHullLP(s.A, s.B, s.C, *_sets(s)), sc, 60)
    monkeypatch.setattr(ExactHullLP, "_place_basis", lambda self, first: None)
    own = _predicted_iterations(ExactHullLP(s.A, s.B, s.C, *_sets(s)), sc, 60)
    assert placed < s.n / 2 < own, (placed, own)
