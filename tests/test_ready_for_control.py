"""PRad-E, Nom-G (set propagation) and Hinf-G (interval observer): CORA's stored results, the
ARCH 2021 tank table, the interval observer's exactness and conventions, and containment of
the true state on every shipped scenario with a trajectory."""

from __future__ import annotations

import numpy as np
import pytest

import observers
import systems
from benchmarks.metrics import rms_radius
from observers.families import interval_bound, luenberger_step
from observers.sets import Interval

from .conftest import paper_table

NAMES = ["PRad-E", "Nom-G", "Hinf-G"]


def _options(name, sc, **extra):
    """Scenario options the observer accepts (the interval observer has no order/reduction)."""
    accepted = observers.get(name).cls.option_defaults()
    return {**{k: v for k, v in sc.options.items() if k in accepted}, **extra}


@pytest.mark.parametrize("name", NAMES)
def test_vehicle2d_final_hull_with_cora_gain_matches_cora(name, cora_refs, cora_vehicle2d_refs):
    sc = systems.scenario("vehicle2d-cora")
    gain = cora_refs["gains_vehicle2D_sdpt3"][name]
    extra = {"convention": "cora-lagged"} if name == "Hinf-G" else {}
    obs = observers.create(name, sc.system, **_options(name, sc, gain=gain, **extra))
    res = observers.run(obs, sc.u, sc.y)
    ref = cora_vehicle2d_refs[name]
    np.testing.assert_allclose(res.lo[-1], ref["lower"], rtol=0, atol=1e-6)
    np.testing.assert_allclose(res.hi[-1], ref["upper"], rtol=0, atol=1e-6)


# ARCH 2021 Table 3 (relative value x smallest absolute radius).  PRad-E's gain is the unique
# optimum of its SDP and its radii do not depend on the noise realisation, so the table is
# reproducible (measured with the closed-form optimum: < 0.1 %).  The SDP route is
# ill-conditioned on this system: tank 6's mode (eigenvalue 0.996) sits at the contraction
# bound sqrt(beta) = 0.99609, P's smallest eigenvalue is 1.7e-4 and barely moves trace(P), so
# Clarabel's gain is accurate only to ~3e-2 in that direction, and tank 6's radius with it
# is 4.7 % above the table (Haswell BLAS kernels; 0.4 % with AVX-512 kernels).  Its objective
# is well determined (test below).  Nom-G and Hinf-G are feasibility points of SDPT3 in CORA;
# our principled objectives land within 4 % (Nom-G, analytic centre) and 23 % (Hinf-G, with
# CORA's lagged convention as in the table).  Interval-observer radii never depend on y.
@pytest.mark.parametrize(("name", "extra", "rtol"), [
    ("PRad-E", {}, 0.02),
    ("PRad-E", {"solver": "sdp"}, 0.06),
    ("Nom-G", {}, 0.05),
    ("Hinf-G", {"convention": "cora-lagged"}, 0.25),
])
def test_tank6_rms_radii_match_arch2021_table3(name, extra, rtol):
    tab = paper_table("arch2021_table3_tank6_linear")
    expected = np.array(tab["rows"][name]["v"]) * np.array(tab["smallest_absolute_radii"])
    for seed in (0, 1):
        sc = systems.scenario("tank6-linear", seed=seed)
        obs = observers.create(name, sc.system, **_options(name, sc, **extra))
        res = observers.run(obs, sc.u, sc.y)
        np.testing.assert_allclose(rms_radius(res.radius), expected, rtol=rtol)


def test_prad_e_sdp_and_closed_form_reach_the_same_optimum_on_the_tank():
    """Both routes maximise trace(P) over the same LMI: the objective agrees to solver
    accuracy even where the gain is ill-determined (see the comment above)."""
    from observers.numerics.lmi import cora_bisection_end
    from observers.numerics.luenberger import prad_e_design

    s = systems.scenario("tank6-linear").system
    beta = cora_bisection_end(0.0, 1.0, 0.01)
    ric = prad_e_design(s.A, s.C, s.W.G, s.V.G, beta, "riccati")
    sdp = prad_e_design(s.A, s.C, s.W.G, s.V.G, beta, "sdp")
    assert np.trace(sdp.P) == pytest.approx(np.trace(ric.P), rel=1e-5)
    assert max(ric.info["rho"], sdp.info["rho"]) <= np.sqrt(beta) * (1 + 1e-6)


def test_interval_observer_bound_is_the_hull_of_unreduced_set_propagation():
    # Alg. 1 boxes every term of the exact error set before summing: its bound equals the
    # interval hull of the set-propagation estimate with the same gain and no reduction
    for name, gain in [("alamo2d-sim", None), ("vehicle2d-sim", [0.05, 0.07])]:
        sc = systems.scenario(name)
        hinf = observers.create("Hinf-G", sc.system, **({} if gain is None else {"gain": gain}))
        prop = observers.create("PRad-E", sc.system, gain=hinf.L, order=1e9)
        a = observers.run(hinf, sc.u, sc.y)
        b = observers.run(prop, sc.u, sc.y)
        scale = np.abs(b.hi).max()
        np.testing.assert_allclose(a.lo, b.lo, rtol=0, atol=1e-12 * scale)
        np.testing.assert_allclose(a.hi, b.hi, rtol=0, atol=1e-12 * scale)


def test_interval_kernel_by_hand():
    A, B, C, L = np.array([[0.5, 1.0], [0.0, 0.5]]), np.array([[1.0], [0.0]]), \
        np.array([[1.0, 0.0]]), np.array([[0.5], [0.25]])
    x = luenberger_step(np.array([1.0, 2.0]), A, B, C, L, np.array([1.0]), np.array([3.0]))
    # A x = [2.5, 1], B u = [1, 0], L (y - C x) = [1, 0.5]
    np.testing.assert_allclose(x, [4.5, 1.5])
    lo, hi = interval_bound(np.array([1.0, 0.0]), np.array([[1.0, -2.0], [0.5, 0.0]]),
                            np.array([0.1, 0.0]), np.array([0.5, 1.0]))
    np.testing.assert_allclose(lo, [1.1 - 3.5, -1.5])
    np.testing.assert_allclose(hi, [1.1 + 3.5, 1.5])


def test_cora_lagged_sets_are_the_aligned_sets_one_step_late():
    sc = systems.scenario("vehicle6d-cora")
    aligned = observers.run(observers.create("Hinf-G", sc.system), sc.u, sc.y)
    lagged = observers.run(observers.create("Hinf-G", sc.system, convention="cora-lagged"),
                           sc.u, sc.y)
    X0 = sc.system.X0.interval()
    for res in (aligned, lagged):  # step 0: X0 itself
        assert res.sets[0] is sc.system.X0
    np.testing.assert_array_equal(lagged.lo[1], X0.lo)  # step 1: CORA's R{2} = box(X0)
    np.testing.assert_array_equal(lagged.lo[2:], aligned.lo[1:-1])
    np.testing.assert_array_equal(lagged.hi[2:], aligned.hi[1:-1])
    assert all(isinstance(S, Interval) for S in aligned.sets[1:])
    # CORA's convention misses the true state (by up to 15 on this record: the set of step
    # k bounds x_{k-1})
    miss = np.maximum(lagged.lo - sc.x_true, sc.x_true - lagged.hi).max()
    assert miss > 1.0


def _assert_contained(sc, name, res):
    assert res.status == "ok", res.message
    for k, S in enumerate(res.sets):
        assert S.contains(sc.x_true[k], tol=sc.tolerance), f"{name}: x_{k} outside"


@pytest.mark.parametrize("name", NAMES)
@pytest.mark.parametrize("scenario", ["vehicle6d-cora", "tank6-linear", "vehicle2d-sim",
                                      "vehicle4d-sim", "vehicle6d-sim", "alamo2d-sim"])
def test_true_state_inside_every_set(name, scenario):
    sc = systems.scenario(scenario)
    obs = observers.create(name, sc.system, **_options(name, sc))
    _assert_contained(sc, name, observers.run(obs, sc.u, sc.y))


def test_true_state_inside_hulls_on_cora_tank30():
    # PRad-E designs in milliseconds here (Riccati route); the Nom-G and Hinf-G SDPs take
    # minutes for 30 states, so the interval loop runs with PRad-E's gain (its containment
    # holds for any gain) and the designed Nom-G/Hinf-G are checked by `make bench`
    # (cora_records.yaml).
    sc = systems.scenario("tank30-linear-cora")
    prad = observers.create("PRad-E", sc.system, **sc.options)
    hinf = observers.create("Hinf-G", sc.system, gain=prad.L)
    for obs in (prad, hinf):
        res = observers.run(obs, sc.u, sc.y, keep_sets=False)
        assert res.status == "ok"
        assert np.all(sc.x_true >= res.lo - sc.tolerance), obs.name
        assert np.all(sc.x_true <= res.hi + sc.tolerance), obs.name
