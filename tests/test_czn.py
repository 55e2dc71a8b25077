"""CZN-A/CZN-B and the constrained-zonotope core: conformance with CORA's stored results,
soundness of the dual-based LP bounds (property tests on random sets), the set operations
(exact intersection, lifted reduction, rescaling, constraint folding), containment of the true
state, and option errors."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import linprog

import observers
import systems
from observers import OptionError
from observers.lp.hull import HullLP, dual_bound
from observers.sets import ConZonotope, SetError, Zonotope

CZN = ["CZN-A", "CZN-B"]


# -- random constrained zonotopes with known feasible points ------------------------------------
def random_cz(n: int, r: int, nc: int, seed: int) -> tuple[ConZonotope, np.ndarray]:
    """A random non-empty set and one feasible xi (strictly inside the box)."""
    g = np.random.default_rng(seed)
    A = g.normal(size=(nc, r))
    xi0 = g.uniform(-0.6, 0.6, r)
    return ConZonotope(g.normal(size=n), g.normal(size=(n, r)), A, A @ xi0), xi0


def feasible_points(S: ConZonotope, xi0: np.ndarray, k: int, seed: int) -> np.ndarray:
    """``k`` points of ``S``: xi0 moved along null-space directions of A, up to the box."""
    g = np.random.default_rng(seed)
    c, G, A, _ = S.arrays()
    N = np.linalg.svd(A)[2][A.shape[0]:].T
    pts = []
    for _ in range(k):
        step = N @ g.normal(size=N.shape[1])
        t = np.max(np.abs(step) / np.where(step > 0, 1 - xi0, 1 + xi0))
        xi = xi0 + step / t * g.choice([1.0, g.uniform(0, 1)])  # boundary or inside
        pts.append(c + G @ xi)
    return np.array(pts)


def exact_support(S: ConZonotope, d: np.ndarray) -> float:
    """max d'x over S by an independent LP solve (scipy), primal value at solver tolerance."""
    c, G, A, b = S.arrays()
    res = linprog(-(G.T @ d), A_eq=A, b_eq=b, bounds=(-1, 1), method="highs")
    assert res.status == 0
    return float(d @ c - res.fun)


# -- soundness of the dual-based bounds ------------------------------------------------------------
@pytest.mark.parametrize("seed", range(8))
def test_dual_bound_is_never_inside_the_exact_hull(seed):
    S, xi0 = random_cz(3, 12, 4, seed)
    I = S.interval()
    pts = feasible_points(S, xi0, 200, seed)
    assert np.all(pts <= I.hi) and np.all(pts >= I.lo)  # no sampled point beyond the bound
    for i in range(3):  # the exact extreme points (vertices found by an LP) either
        e = np.eye(3)[i]
        assert I.hi[i] >= exact_support(S, e)
        assert -I.lo[i] >= exact_support(S, -e)
        assert I.hi[i] - exact_support(S, e) < 1e-6  # and tight
    d = np.random.default_rng(seed).normal(size=3)
    assert S.support(d) >= exact_support(S, d) and S.support(d) >= np.max(pts @ d)


@pytest.mark.parametrize("seed", range(4))
def test_any_dual_point_gives_an_upper_bound(seed):
    S, xi0 = random_cz(2, 8, 3, 50 + seed)
    _, G, A, b = S.arrays()
    g = G[0]
    opt = exact_support(S, np.eye(2)[0]) - S.c[0]
    rng = np.random.default_rng(seed)
    for mu in rng.normal(scale=3.0, size=(50, 3)):
        assert dual_bound(g, A, b, mu) >= opt
    assert dual_bound(g, A, b, np.zeros(3)) == pytest.approx(np.abs(g).sum())


def test_shared_warm_solver_gives_the_same_hulls():
    lp = HullLP()
    for seed in range(5):
        S, _ = random_cz(3, 10, 3, 200 + seed)
        warm = S.with_solver(lp)
        assert warm == S
        np.testing.assert_allclose(warm.interval().lo, S.interval().lo, atol=1e-9)
        np.testing.assert_allclose(warm.interval().hi, S.interval().hi, atol=1e-9)
    assert lp.solves == 5 * 6


# -- set operations ------------------------------------------------------------------------------
def test_intersection_with_measurement_set_is_exact():
    g = np.random.default_rng(3)
    Z = ConZonotope.from_zonotope(Zonotope(g.normal(size=2), g.normal(size=(2, 4))))
    C = np.array([[1.0, 2.0]])
    V = Zonotope([0.1], [[0.3]])
    y = C @ Z.c + 0.2
    S = Z.intersect((-V) + y, C)  # {x in Z : C x in y - V}
    n_in = 0
    for x in Z.to_zonotope().sample(300, g):
        dist = abs((C @ x)[0] - (y[0] - 0.1))  # v = y - C x must lie in [0.1 - 0.3, 0.1 + 0.3]
        if dist <= 0.3 - 1e-6:
            assert S.contains(x, tol=1e-9)
            n_in += 1
        elif dist >= 0.3 + 1e-6:
            assert not S.contains(x, tol=1e-9)
    assert n_in >= 5


@pytest.mark.parametrize("seed", range(3))
def test_strip_gain_changes_the_parametrisation_not_the_set(seed):
    g = np.random.default_rng(seed)
    Z = ConZonotope(g.normal(size=3), g.normal(size=(3, 6)))
    C, sigma = g.normal(size=(2, 3)), np.array([0.4, 0.7])
    y = C @ Z.c + g.uniform(-0.3, 0.3, 2)
    S0 = Z.intersect_strips(C, y, sigma)
    S1 = Z.intersect_strips(C, y, sigma, gain=g.normal(size=(3, 2)))
    S2 = Z.intersect(Zonotope(y, np.diag(sigma)), C)
    for S in (S1, S2):
        np.testing.assert_allclose(S.interval().lo, S0.interval().lo, atol=1e-7)
        np.testing.assert_allclose(S.interval().hi, S0.interval().hi, atol=1e-7)


def test_measurement_intersection_with_a_noise_zonotope_is_exact_for_any_gain():
    g = np.random.default_rng(8)
    Z = ConZonotope(g.normal(size=3), g.normal(size=(3, 6)))
    C = g.normal(size=(2, 3))
    V = Zonotope([0.1, -0.2], [[0.3, 0.1, 0.0], [0.0, 0.2, 0.4]])
    y = C @ Z.c + g.uniform(-0.3, 0.3, 2)
    ref = Z.intersect((-V) + y, C)  # {x in Z : C x in y - V}
    for gain in (None, g.normal(size=(3, 2))):
        S = Z.intersect_measurement(C, y, V, gain=gain)
        np.testing.assert_allclose(S.interval().lo, ref.interval().lo, atol=1e-7)
        np.testing.assert_allclose(S.interval().hi, ref.interval().hi, atol=1e-7)
    with pytest.raises(SetError, match="noise set V"):
        Z.intersect_measurement(C, y, Zonotope([0.0], [[1.0]]))


@pytest.mark.parametrize("method", ["girard", "pca"])
def test_lifted_reduction_encloses(method):
    S, xi0 = random_cz(2, 30, 3, 7)
    R = S.reduce(3, method)
    assert R.num_constraints == 3 and R.num_generators <= 3 * 2 + 3
    for p in feasible_points(S, xi0, 60, 1):
        assert R.contains(p, tol=1e-7)
    assert S.reduce(100, method) == S.compact()  # nothing to reduce


def test_rescaling_is_exact_and_folding_encloses():
    S, xi0 = random_cz(3, 14, 5, 11)
    R = S.rescale()
    np.testing.assert_allclose(R.interval().lo, S.interval().lo, atol=1e-7)
    np.testing.assert_allclose(R.interval().hi, S.interval().hi, atol=1e-7)
    F = S.reduce_constraints(2)
    assert F.num_constraints == 2
    pts = feasible_points(S, xi0, 100, 2)
    for p in pts:
        assert R.contains(p, tol=1e-7) and F.contains(p, tol=1e-7)
    If, Is = F.interval(), S.interval()
    assert np.all(If.lo <= Is.lo + 1e-9) and np.all(If.hi >= Is.hi - 1e-9)


def test_empty_and_malformed_sets_are_reported():
    S = ConZonotope([0.0], [[1.0]])
    with pytest.raises(SetError, match="empty"):
        S.intersect(ConZonotope([5.0], [[1.0]])).interval()
    with pytest.raises(SetError, match="rows but the set has dimension"):
        S.intersect(Zonotope([0.0, 0.0], np.eye(2)), np.eye(1))
    with pytest.raises(SetError, match="max_constraints"):
        S.reduce_constraints(-1)
    with pytest.raises(SetError, match="half-widths"):
        S.intersect_strips([[1.0]], [0.0], [-1.0])


# -- observers -------------------------------------------------------------------------------
@pytest.mark.parametrize("name", CZN)
def test_vehicle2d_final_hull_matches_cora(name, cora_vehicle2d_refs):
    sc = systems.scenario("vehicle2d-cora")
    obs = observers.create(name, sc.system, max_constraints=None, **sc.options)
    res = observers.run(obs, sc.u, sc.y)
    ref = cora_vehicle2d_refs[name]
    np.testing.assert_allclose(res.lo[-1], ref["lower"], rtol=0, atol=1e-6)
    np.testing.assert_allclose(res.hi[-1], ref["upper"], rtol=0, atol=1e-6)
    assert res.sets[-1].num_constraints == 100  # CORA keeps every constraint


def test_batched_hull_solver_matches_cora_with_all_constraints(cora_vehicle2d_refs):
    # the batched dual simplex forced (auto picks HiGHS once there are many constraints)
    sc = systems.scenario("vehicle2d-cora")
    obs = observers.create("CZN-B", sc.system, max_constraints=None, hull_solver="batched",
                           **sc.options)
    res = observers.run(obs, sc.u, sc.y)
    ref = cora_vehicle2d_refs["CZN-B"]
    np.testing.assert_allclose(res.lo[-1], ref["lower"], rtol=0, atol=1e-6)
    np.testing.assert_allclose(res.hi[-1], ref["upper"], rtol=0, atol=1e-6)
    assert obs._lp.fallbacks == 0


@pytest.mark.parametrize("name", CZN)
def test_bounded_constraints_stay_tighter_than_zonotopes_on_vehicle2d(name, cora_vehicle2d_refs):
    # the default keeps 2 m constraints: its final hull is wider than CORA's exact CZN one but
    # still narrower than CORA's zonotope observers' (FRad-A, FRad-B)
    sc = systems.scenario("vehicle2d-cora")
    res = observers.run(observers.create(name, sc.system, **sc.options), sc.u, sc.y)
    assert res.sets[-1].num_constraints == 2
    for zono in ("FRad-A", "FRad-B"):
        ref = cora_vehicle2d_refs[zono]
        rad_ref = 0.5 * (np.array(ref["upper"]) - np.array(ref["lower"]))
        assert np.all(res.radius[-1] <= rad_ref + 1e-9)


@pytest.mark.parametrize("name", CZN)
@pytest.mark.parametrize(("scenario", "steps"), [("vehicle6d-cora", 60), ("tank6-linear", 60),
                                                  ("alamo2d-sim", 20)])
def test_true_state_inside_every_set(name, scenario, steps):
    sc = systems.scenario(scenario)
    res = observers.run(observers.create(name, sc.system, **sc.options), sc.u[:steps],
                        sc.y[:steps])
    assert res.status == "ok"
    for k, S in enumerate(res.sets):
        assert S.contains(sc.x_true[k], tol=sc.tolerance), f"{name}: x_{k} outside"


def test_czn_b_textbook_variant_and_option_errors():
    sc = systems.scenario("alamo2d-sim")
    res = observers.run(observers.create("CZN-B", sc.system, variant="textbook",
                                         **sc.options), sc.u, sc.y)
    assert np.all(res.lo <= sc.x_true + sc.tolerance)
    assert np.all(res.hi >= sc.x_true - sc.tolerance)
    with pytest.raises(OptionError, match="variant"):
        observers.create("CZN-B", sc.system, variant="paper")
    with pytest.raises(OptionError, match="max_constraints"):
        observers.create("CZN-A", sc.system, max_constraints=-2)
    with pytest.raises(OptionError, match="max_constraints"):
        observers.create("CZN-A", sc.system, max_constraints="many")
    with pytest.raises(OptionError, match="hull_solver"):
        observers.create("CZN-A", sc.system, hull_solver="cplex")


def test_registry_entries():
    for name in CZN:
        info = observers.get(name)
        assert (info.family, info.set_type, info.ready_for_control) == (
            "strip", "conzonotope", False)


@pytest.fixture(params=["compiled", "numpy"])
def propagation_path(request):
    """Run a test with the compiled sweeps of implied_bounds and with the numpy ones."""
    from observers.kernels import switch

    if request.param == "compiled" and not switch.AVAILABLE:
        pytest.skip("numba not available")
    old = switch.set_compiled(request.param == "compiled")
    yield request.param
    switch.set_compiled(old)


def test_implied_bounds_ignore_a_subnormal_coefficient(propagation_path):
    """Bug: on the 200-tank record a constraint row held a subnormal coefficient; 1 / a
    overflowed, inf - inf made the candidate bounds NaN and the NaN spread through the
    propagation sweeps (numpy warned "overflow encountered in divide").  Such a coefficient
    now bounds nothing; the other rows still do.  Hand example: xi1 + 1e-310 xi2 = 0.5 and
    xi2 - xi3 = 0 in the unit box: xi1 in [0.5 - 1e-310, 0.5 + 1e-310] (rounded outward),
    xi2 and xi3 unchanged (the first row cannot bound xi2: |0.5 - xi1| / 1e-310 is huge)."""
    import warnings

    from observers.sets.conzono_ops import implied_bounds

    A = np.array([[1.0, 1e-310, 0.0], [0.0, 1.0, -1.0]])
    b = np.array([0.5, 0.0])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        lo, hi = implied_bounds(A, b)
    assert np.all(np.isfinite(lo)) and np.all(np.isfinite(hi))
    assert lo[0] <= 0.5 <= hi[0] and hi[0] - lo[0] < 1e-14
    np.testing.assert_array_equal(lo[1:], [-1.0, -1.0])
    np.testing.assert_array_equal(hi[1:], [1.0, 1.0])


def _exact_first_sweep(A, b):
    """One sweep of the propagation from the unit box in exact rational arithmetic (hand
    derivation: with mid = 0 and rad = 1, row i bounds xi_j by
    (b_i -+ sum_{k != j} |a_ik|) / a_ij, rounded nowhere)."""
    from fractions import Fraction

    p, r = A.shape
    lo, hi = [Fraction(-1)] * r, [Fraction(1)] * r
    for i in range(p):
        row = [Fraction(float(a)) for a in A[i]]
        total = sum(abs(a) for a in row)
        for j in range(r):
            if row[j] == 0:
                continue
            c, w = Fraction(float(b[i])) / row[j], (total - abs(row[j])) / abs(row[j])
            lo[j], hi[j] = max(lo[j], c - w), min(hi[j], c + w)
    return lo, hi


def _long_rows(seed):
    """Rows of 4000 terms, one dominant entry each and many small ones: the sums of the
    propagation carry rounding errors of many ulps (about sqrt(r) eps of the sum)."""
    rng = np.random.default_rng(seed)
    p, r = 3, 4000
    A = rng.uniform(-1.0, 1.0, (p, r)) * rng.uniform(0.0, 1e-4, (p, r))
    A[np.arange(p), np.arange(p)] = 1.0 + rng.uniform(0.0, 0.1, p)
    b = rng.uniform(-0.2, 0.2, p)
    return A, b


@pytest.mark.parametrize("seed", range(3))
def test_implied_bounds_round_outward_on_long_rows(propagation_path, seed):
    """Bug: the candidates were widened by 4 eps of their magnitudes, but a sum of r
    products can be off by about r eps of its terms (Higham, Sec. 3.1): on rows of 4000
    terms a bound came out tighter than the exact one (a shrunk box may cut off feasible
    points).  Each bound is now compared with one sweep in exact rational arithmetic."""
    from observers.sets.conzono_ops import implied_bounds

    A, b = _long_rows(seed)
    lo, hi = implied_bounds(A, b, sweeps=1)
    elo, ehi = _exact_first_sweep(A, b)
    assert all(float(lo[j]) <= elo[j] for j in range(A.shape[1]))
    assert all(float(hi[j]) >= ehi[j] for j in range(A.shape[1]))
    # and not loose: the dominant variables are bounded to within 1e-9 of the exact range
    for j in range(A.shape[0]):
        assert float(elo[j]) - lo[j] < 1e-9 and hi[j] - float(ehi[j]) < 1e-9


def test_the_old_slack_fails_the_exact_comparison(monkeypatch):
    """The check above can fail: with the former slack (4 eps, whatever the row's length)
    some bound of these rows is tighter than the exact one."""
    from observers.kernels import propagation
    from observers.sets.conzono_ops import implied_bounds

    monkeypatch.setattr(propagation, "slack_factor", lambda r: 4 * np.finfo(float).eps)
    inward = 0
    for seed in range(3):
        A, b = _long_rows(seed)
        lo, hi = implied_bounds(A, b, sweeps=1)
        elo, ehi = _exact_first_sweep(A, b)
        inward += sum(float(lo[j]) > elo[j] or float(hi[j]) < ehi[j] for j in range(3))
    assert inward > 0


def test_implied_bounds_compiled_and_numpy_agree_and_contain_the_projection():
    """Both paths give the same bounds up to rounding, and on small random feasible sets
    every bound contains the exact projection of the feasible set (min and max of each xi_j
    by linprog)."""
    from observers.kernels import switch
    from observers.sets.conzono_ops import implied_bounds

    if not switch.AVAILABLE:
        pytest.skip("numba not available")
    rng = np.random.default_rng(7)
    for _ in range(20):
        p, r = int(rng.integers(1, 4)), int(rng.integers(3, 9))
        A = rng.normal(size=(p, r))
        b = A @ rng.uniform(-1, 1, r)  # feasible: a point of the box satisfies it
        old = switch.set_compiled(True)
        try:
            lo1, hi1 = implied_bounds(A, b)
            switch.set_compiled(False)
            lo2, hi2 = implied_bounds(A, b)
        finally:
            switch.set_compiled(old)
        np.testing.assert_allclose(lo1, lo2, rtol=0, atol=1e-13)
        np.testing.assert_allclose(hi1, hi2, rtol=0, atol=1e-13)
        for j in range(r):
            e = np.zeros(r)
            e[j] = 1.0
            for sign, bound in ((1.0, lo1[j]), (-1.0, -hi1[j])):
                res = linprog(sign * e, A_eq=A, b_eq=b, bounds=[(-1, 1)] * r, method="highs")
                assert res.status == 0
                assert bound <= res.fun + 1e-9
