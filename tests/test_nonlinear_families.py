"""The interval, ellipsoidal and zonotope-bundle families of nonlinear observers (issue 26):
the interval contractors on hand examples, soundness properties, the observers' containment."""

from __future__ import annotations

import numpy as np
import pytest

import observers
import systems
from observers.numerics.bundle import box_gain, member_gain, sequential_frad_gain
from observers.numerics.interval import ForwardBackward, contract_linear, linear_box
from observers.numerics.relaxation import Factorable
from observers.sets import EmptySet, SetError, Zonotope, ZonotopeBundle
from systems.derivatives import SymbolicDerivatives


def _contractor(h, n: int, m: int) -> ForwardBackward:
    d = SymbolicDerivatives(lambda x, u, mm: h(x, mm), n, 0, outputs=m, what="h")
    return ForwardBackward(Factorable(d.expressions, d.symbols[0], (), "h"), n)


# -- interval contractors ---------------------------------------------------------------------
def test_linear_contractor_hand_example():
    # x1 + x2 in [3, 3.5] on [0, 2]^2: x1 in [3 - 2, 3.5 - 0] & [0, 2] = [1, 2], the same for x2
    lo, hi = contract_linear(np.zeros(2), np.full(2, 2.0), np.array([[1.0, 1.0]]),
                             np.array([3.0]), np.array([3.5]))
    assert np.all(lo <= 1.0) and np.allclose(lo, 1.0, atol=1e-12)
    assert np.all(hi >= 2.0) and np.allclose(hi, 2.0, atol=1e-12)


def test_linear_contractor_negative_coefficient():
    # x1 - 2 x2 in [0, 1] on [0, 4] x [0, 4]: x1 in [0, 1] + 2 [0, 4] -> [0, 4] (no change);
    # x2 in (x1 - [0, 1]) / 2 = [-1, 4] / 2 = [-0.5, 2] -> [0, 2]
    lo, hi = contract_linear(np.zeros(2), np.full(2, 4.0), np.array([[1.0, -2.0]]),
                             np.array([0.0]), np.array([1.0]))
    assert np.allclose([lo, hi], [[0, 0], [4, 2]], atol=1e-12)
    assert hi[1] >= 2.0


def test_linear_contractor_empty():
    with pytest.raises(EmptySet):
        contract_linear(np.zeros(2), np.ones(2), np.array([[1.0, 1.0]]), np.array([3.0]),
                        np.array([4.0]))


def test_forward_backward_hand_examples():
    # y = x1^2 + x2 in [0, 1] on [-2, 3] x [0, 1]: x1^2 in [0, 1] - [0, 1] & [0, 9] = [0, 1],
    # so x1 in [-1, 1]; x2 in [0, 1] - [0, 1] & [0, 1] = [0, 1]
    fb = _contractor(lambda x, m: np.array([x[0] ** 2 + x[1]]), 2, 1)
    lo, hi = fb.contract(np.array([-2.0, 0.0]), np.array([3.0, 1.0]), np.zeros(1), np.ones(1))
    assert np.allclose([lo, hi], [[-1, 0], [1, 1]], atol=1e-12)
    assert lo[0] <= -1.0 and hi[0] >= 1.0
    # y = x1 x2 in [3, 4] on [1, 4] x [2, 3]: x1 in [3, 4] / [2, 3] = [1, 2]; then
    # x2 in [3, 4] / [1, 2] = [1.5, 4] & [2, 3] = [2, 3]
    fb = _contractor(lambda x, m: np.array([x[0] * x[1]]), 2, 1)
    lo, hi = fb.contract(np.array([1.0, 2.0]), np.array([4.0, 3.0]), np.array([3.0]),
                         np.array([4.0]))
    assert np.allclose([lo, hi], [[1, 2], [2, 3]], atol=1e-12)
    # y = exp(x1) in [1, e] on [-5, 5]: x1 in [0, 1]
    fb = _contractor(lambda x, m: np.array([m.exp(x[0])]), 1, 1)
    lo, hi = fb.contract(np.array([-5.0]), np.array([5.0]), np.array([1.0]), np.array([np.e]))
    assert np.allclose([lo, hi], [[0], [1]], atol=1e-12) and lo[0] <= 0 and hi[0] >= 1
    with pytest.raises(EmptySet):
        fb.contract(np.array([-5.0]), np.array([5.0]), np.array([-2.0]), np.array([-1.0]))


def test_contractors_keep_every_consistent_state():
    """Sampled states of the box whose output lies in [y] stay in the contracted box."""
    rng = np.random.default_rng(3)

    def h(x, m):
        return np.array([x[0] - m.sin(x[1] / 2), (1 - x[0]) * x[1], m.sqrt(x[0] ** 2 + 1) * x[2]])

    fb = _contractor(h, 3, 3)
    for _ in range(30):
        lo = rng.uniform(-2, 1, 3)
        hi = lo + rng.uniform(0.1, 2, 3)
        X = rng.uniform(lo, hi, size=(4000, 3))
        Y = np.array([h(x, np) for x in X])
        x0 = X[0]
        width = rng.uniform(0.05, 0.5, 3)
        ylo, yhi = Y[0] - width, Y[0] + width
        keep = np.all((Y >= ylo) & (Y <= yhi), axis=1)
        clo, chi = fb.contract(lo, hi, ylo, yhi)
        assert np.all((X[keep] >= clo) & (X[keep] <= chi)) and np.all(clo <= x0)
        C = rng.normal(size=(2, 3))
        Yl = X @ C.T
        keep = np.all(np.abs(Yl - Yl[0]) <= width[:2], axis=1)
        clo, chi = contract_linear(lo, hi, C, Yl[0] - width[:2], Yl[0] + width[:2])
        assert np.all((X[keep] >= clo) & (X[keep] <= chi))


def test_linear_box_is_the_hull_of_the_image():
    A = np.array([[1.0, -2.0], [0.5, 3.0]])
    lo, hi = linear_box(A, np.array([-1.0, 0.0]), np.array([1.0, 2.0]), np.array([0.1, 0.0]))
    # A p + shift = [1 - 2 + 0.1... ]: p = (0, 1): (-2 + 0.1, 3); |A| r = (1 + 2, 0.5 + 3)
    assert np.allclose(lo, [-1.9 - 3, 3 - 3.5]) and np.allclose(hi, [-1.9 + 3, 3 + 3.5])


# -- observers --------------------------------------------------------------------------------
NEW = ["INT-CP", "ESMF", "ZB-A"]
DIVERGES = {("ESMF", "rego2d-nonlinear")}


@pytest.mark.parametrize("name", NEW)
@pytest.mark.parametrize("scenario,steps", [("rego2d-nonlinear", 40), ("vanderpol-sim", 60),
                                            ("alamo2d-sim", 20), ("robot-range", 25)])
def test_true_state_inside(name, scenario, steps):
    sc = systems.scenario(scenario, seed=1, noise="vertex", steps=steps)
    obs = observers.create(name, sc.system)
    res = observers.run(obs, sc.u, sc.y)
    # ESMF's ellipsoid grows past the domain of Rego et al.'s example within 10 steps (its
    # box, over which the remainder is bounded, is much wider than the consistent set)
    assert res.status == ("diverged" if (name, scenario) in DIVERGES else "ok"), res.message
    k = len(res.sets)
    assert k > 3 and all(S.contains(x, tol=1e-9)
                         for S, x in zip(res.sets, sc.x_true[:k], strict=True))


# -- ESMF ---------------------------------------------------------------------------------------
def _linear_as_nonlinear(s):
    A, B = np.array(s.A), np.array(s.B)
    return systems.NonlinearSystem(lambda x, u, m: A @ x + B @ u, s.n, s.nu, s.C, W=s.W, V=s.V,
                                   X0=s.X0)


def test_esmf_is_eso_b_on_a_linear_system():
    """With linear f and h nothing is absorbed: every step is ESO-B's (the same formulas),
    on a LinearSystem exactly, on the same model written as a NonlinearSystem up to the
    rounding margins of the enclosure (absorbed remainders of ~1e-16)."""
    sc = systems.scenario("alamo2d-sim", seed=2, steps=20)
    eso = observers.run(observers.create("ESO-B", sc.system), sc.u, sc.y)
    esmf = observers.run(observers.create("ESMF", sc.system, weight="obe"), sc.u, sc.y)
    for a, b in zip(eso.sets, esmf.sets, strict=True):
        assert np.array_equal(a.q, b.q) and np.array_equal(a.Q, b.Q)
    nl = observers.run(observers.create("ESMF", _linear_as_nonlinear(sc.system), weight="obe"),
                       sc.u, sc.y)
    for a, b in zip(eso.sets, nl.sets, strict=True):
        assert np.allclose(a.q, b.q, rtol=1e-6, atol=1e-9)
        assert np.allclose(a.Q, b.Q, rtol=1e-5, atol=1e-9)


# -- ZonotopeBundle -------------------------------------------------------------------------------
def _diamonds():
    # |x1| + |x2| <= 1 and |x1 - 1| + |x2| <= 1: their intersection is the diamond with the
    # vertices (0, 0), (1, 0), (0.5, +-0.5)
    D = np.array([[0.5, 0.5], [0.5, -0.5]])
    return ZonotopeBundle([Zonotope([0.0, 0.0], D), Zonotope([1.0, 0.0], D)])


def test_bundle_hull_is_exact_on_a_hand_example():
    H = _diamonds().interval()
    # the members' boxes only give [0, 1] x [-1, 1]
    assert np.allclose(H.lo, [0.0, -0.5], atol=1e-9) and np.allclose(H.hi, [1.0, 0.5], atol=1e-9)
    assert np.all(H.lo <= [0.0, -0.5]) and np.all(H.hi >= [1.0, 0.5])


def test_bundle_membership_agrees_with_an_lp():
    B = _diamonds()
    cz = B.as_conzonotope()
    rng = np.random.default_rng(0)
    pts = rng.uniform([-0.5, -1.0], [1.5, 1.0], size=(60, 2))
    for x in pts:
        assert B.contains(x, 1e-9) == cz.contains(x, 1e-9)
    assert B.contains([0.5, 0.49]) and not B.contains([0.5, 0.51])


def _random_bundle(rng, n=2, k=3):
    members = [Zonotope(rng.normal(scale=0.2, size=n), rng.normal(size=(n, n + 2)))
               for _ in range(k)]
    return ZonotopeBundle(members)


def _points_in(B, rng, count=25):
    """Points of the intersection: samples of the first member kept if in all members."""
    pts = B.members[0].sample(count * 6, rng)
    inside = [x for x in pts if B.contains(x, 0.0)]
    assert len(inside) >= 5
    return np.array(inside[:count])


def test_bundle_operations_keep_the_points_of_the_intersection():
    rng = np.random.default_rng(7)
    for _ in range(2):
        B = _random_bundle(rng)
        X = _points_in(B, rng)
        H = B.interval()
        assert np.all((X >= H.lo - 1e-9) & (X <= H.hi + 1e-9))
        M = rng.normal(size=(2, 2))
        MB = M @ B
        Z = Zonotope(rng.normal(size=2), rng.normal(size=(2, 2)))
        BZ = B + Z
        zs = Z.sample(len(X), rng)
        C = rng.normal(size=(1, 2))
        y = C @ X[0]
        sigma = np.array([0.3])
        S = B.intersect_strips(C, y, sigma,
                               [member_gain("wang", Z.G, C, sigma) for Z in B.members])
        R = B.reduce(1.0, "girard")
        for i, x in enumerate(X):
            assert MB.contains(M @ x, 1e-9)
            assert BZ.contains(x + zs[i], 1e-9)
            assert R.contains(x, 1e-9)
            if abs(C @ x - y)[0] <= sigma[0]:
                assert S.contains(x, 1e-9)
        for Bo in (MB, BZ, S, R):
            assert Bo.size == B.size and Bo.dim == 2


def test_bundle_bad_input():
    with pytest.raises(SetError, match="at least one member"):
        ZonotopeBundle([])
    with pytest.raises(SetError, match="different dimensions"):
        ZonotopeBundle([Zonotope([0.0]), Zonotope([0.0, 0.0])])
    with pytest.raises(SetError, match="gains"):
        _diamonds().intersect_strips([[1.0, 0.0]], [0.0], [1.0], gains=[np.zeros((2, 1))])


def test_box_gain_hand_example_and_optimality():
    # the unit box and the strip |x1 - y| <= 0.5: row 1 of the gain is the weighted median
    # of {1 (weight 1), 0 (weight 0.5)} = 1, row 2 of {0, 0} = 0: the member becomes the strip
    L = box_gain(np.eye(2), np.array([[1.0, 0.0]]), np.array([0.5]))
    assert np.allclose(L, [[1.0], [0.0]])
    # one strip: every component of the updated hull is the least over all gains
    rng = np.random.default_rng(5)
    for _ in range(20):
        G = rng.normal(size=(3, 5))
        c, sigma = rng.normal(size=(1, 3)), np.array([rng.uniform(0.1, 1)])

        def radius(L, G=G, c=c, sigma=sigma):
            return np.abs(np.hstack([G - L @ (c @ G), L * sigma])).sum(axis=1)

        best = radius(box_gain(G, c, sigma))
        for L in [sequential_frad_gain(G, c, sigma), *rng.normal(size=(10, 3, 1))]:
            assert np.all(best <= radius(L) + 1e-12)
