"""Exact membership tests with certified distances (benchmarks.run.membership).

Expected verdicts and distances come from hand geometry (boxes, a segment) or from an
independent LP (scipy's linprog on the textbook formulation), never from the code under test.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import linprog

from benchmarks.run.membership import (
    MembershipTester,
    dual_lower_bound,
    dual_polish,
    hull_distance,
    residual_bound,
)
from observers.sets import ConZonotope, Ellipsoid, Interval, Zonotope


def linprog_distance(G: np.ndarray, v: np.ndarray) -> float:
    """min t s.t. |G xi - v|_inf <= t, |xi|_inf <= 1 (independent formulation)."""
    n, r = G.shape
    c = np.r_[np.zeros(r), 1.0]
    A_ub = np.block([[G, -np.ones((n, 1))], [-G, -np.ones((n, 1))]])
    b_ub = np.r_[v, -v]
    res = linprog(c, A_ub=A_ub, b_ub=b_ub, bounds=[(-1, 1)] * r + [(0, None)])
    assert res.status == 0
    return float(res.fun)


def test_box_zonotope_distances_by_hand():
    # the box [-2, 2] x [-1, 1] written with redundant generators (sum of the columns = radii)
    Z = Zonotope([1.0, 0.0], [[1.0, 0.5, 0.5, 0.0], [0.0, 0.0, 0.0, 1.0]])
    T = MembershipTester()
    assert T.test(Z, [2.9, 0.99], 1e-9).inside is True
    m = T.test(Z, [3.25, 0.0], 1e-9)  # 0.25 beyond the right face: rejected by the hull
    assert m.inside is False and m.distance == pytest.approx(0.25, abs=1e-12)
    assert T.test(Z, [3.0 + 5e-10, 1.0], 1e-9).inside is True  # within the tolerance
    assert T.test(Z, [3.0 + 5e-9, 1.0], 1e-9).inside is False


def test_zonotope_points_outside_the_set_but_inside_its_hull():
    # a diamond |x1| + |x2| <= 1 (generators (1,1)/2 and (1,-1)/2 scaled to reach the axes)
    Z = Zonotope([0.0, 0.0], [[0.5, 0.5], [0.5, -0.5]])
    T = MembershipTester()
    m = T.test(Z, [0.6, 0.6], 1e-9)  # inside the hull [-1, 1]^2, outside the diamond
    # infinity-norm distance to the diamond: the nearest point is (0.5, 0.5) -> 0.1
    assert m.inside is False and m.method == "lp"
    assert m.distance == pytest.approx(0.1, abs=1e-9)
    assert T.test(Z, [0.5, 0.5], 1e-9).inside is True  # on the boundary
    assert T.test(Z, [0.5, -0.5 + 1e-3], 1e-9).inside is True


@pytest.mark.parametrize("seed", range(4))
def test_random_zonotopes_agree_with_an_independent_lp(seed):
    rng = np.random.default_rng(seed)
    n, r = 3, 15
    G = rng.normal(size=(n, r)) * rng.uniform(1e-3, 1.0, size=r)  # badly scaled generators
    Z = Zonotope(rng.normal(size=n), G)
    T = MembershipTester()
    for _ in range(40):
        x = Z.c + G @ rng.uniform(-1.3, 1.3, size=r) * rng.uniform(0.2, 1.0)
        exact = linprog_distance(G, x - Z.c)
        m = T.test(Z, x, 1e-9)
        if exact > 1e-6:
            assert m.inside is False
            assert exact - 1e-7 <= m.distance <= exact + 1e-9  # sound and tight
        elif exact == 0.0:
            assert m.inside is True
        assert m.inside is Z.contains(x, 1e-9) or abs(exact) < 1e-6


@pytest.mark.parametrize("seed", range(3))
def test_points_on_the_boundary_are_certified_inside(seed):
    """Vertex noise puts true states exactly on the sets' boundaries."""
    rng = np.random.default_rng(seed)
    G = rng.normal(size=(4, 40))
    Z = Zonotope(rng.normal(size=4), G)
    T = MembershipTester()
    for _ in range(20):
        xi = rng.choice([-1.0, 1.0], size=40)  # a vertex
        assert T.test(Z, Z.c + G @ xi, 1e-9).inside is True
        d = rng.normal(size=4)
        x_out = Z.c + G @ np.sign(G.T @ d) + 1e-4 * d / np.abs(d).max()  # beyond a face
        m = T.test(Z, x_out, 1e-9)
        assert m.inside is False and 0 < m.distance <= 1e-4 + 1e-12


@pytest.mark.parametrize("seed", range(5))
def test_badly_scaled_boundary_points_are_decided(seed):
    """Points on an edge of a 2-D zonotope whose generators span five orders of magnitude
    (as P-radius sets under worst-case inputs): the LP's primal bound pattern can be wrong
    at solver precision there; the dual-guided point (or the refinement) decides them."""
    rng = np.random.default_rng(100 + seed)
    G = rng.normal(size=(2, 180)) * 10.0 ** rng.uniform(-6, -1, size=180)
    Z = Zonotope(np.zeros(2), G)
    T = MembershipTester()
    for _ in range(20):
        j = rng.integers(180)
        normal = np.array([-G[1, j], G[0, j]])  # the edge of generator j faces this way
        xi = np.sign(G.T @ normal)
        xi[j] = rng.uniform(-1, 1)
        x = G @ xi  # a point of that edge (hand geometry: the support point plus g_j)
        assert T.test(Z, x, 1e-9 * max(1.0, np.abs(x).max())).inside is True
        # the dual direction of that edge alone yields the point's factors (hand derivation)
        d = normal / np.abs(normal).sum()
        found = dual_polish(G, x, np.zeros((0, 180)), np.zeros(0), d, np.zeros(0))
        assert found is not None and residual_bound(G, found, x) <= 1e-12


@pytest.mark.parametrize("constrained", [False, True])
def test_iterative_refinement_places_a_perturbed_lp_point_on_the_boundary(constrained):
    """A box point 1e-6 off a vertex of the set (as an LP point at solver tolerance on a
    badly scaled set) is corrected by the refinement to a point within rounding of the
    vertex: the vertex's own factors are one exact correction (hand derivation)."""
    rng = np.random.default_rng(7)
    r = 300
    G = rng.normal(size=(6, r)) * 10.0 ** rng.uniform(-4, 0, size=r)
    A = rng.normal(size=(3, r)) * 0.2 if constrained else np.zeros((0, r))
    xi_star = rng.choice([-1.0, 1.0], size=r)  # a vertex of the factor box
    xi_star[:9] = rng.uniform(-0.5, 0.5, size=9)  # and free factors for the constraints
    b = A @ xi_star
    v = G @ xi_star
    xi_lp = np.clip(xi_star + 1e-6 * rng.uniform(-1, 1, size=r), -1.0, 1.0)
    assert residual_bound(G, xi_lp, v) > 1e-7  # the LP-like point misses by far
    # within the rounding slack of the bound (~2e-12)
    assert MembershipTester()._refine(G, v, A, b, 1e-10, xi_lp) <= 1e-10


def test_conzonotope_segment_and_interval_and_ellipsoid():
    # {xi in [-1,1]^2 : xi1 + xi2 = 0} is the segment from (-1, 1) to (1, -1)
    S = ConZonotope([0.0, 0.0], np.eye(2), [[1.0, 1.0]], [0.0])
    T = MembershipTester()
    assert T.test(S, [0.5, -0.5], 1e-9).inside is True
    m = T.test(S, [0.5, 0.5], 1e-9)  # nearest point (0, 0) at infinity-distance 0.5
    assert m.inside is False and m.distance == pytest.approx(0.5, abs=1e-9)
    I = Interval([0.0, 0.0], [1.0, 2.0])
    assert T.test(I, [1.5, 1.0], 0.0).distance == pytest.approx(0.5)
    assert T.test(I, [1.0, 2.0], 0.0).inside is True
    E = Ellipsoid([0.0, 0.0], np.diag([4.0, 1.0]))
    assert T.test(E, [2.0, 0.0], 1e-9).inside is True
    m = T.test(E, [0.0, 1.5], 1e-9)
    assert m.inside is False and m.distance == pytest.approx(0.5, abs=1e-9)
    assert set(T.counts) == {"certificate", "lp", "closed-form", "distance"}


def test_other_set_types_fall_back_on_contains_and_the_hull():
    class Disc:  # a set type the tester does not know
        def interval(self):
            return Interval([-1.0, -1.0], [1.0, 1.0])

        def contains(self, x, tol=0.0):
            return float(np.hypot(*x)) <= 1.0 + tol

    T = MembershipTester()
    assert T.test(Disc(), [0.6, 0.6], 1e-9).inside is True
    assert T.test(Disc(), [0.8, 0.8], 1e-9).inside is False
    m = T.test(Disc(), [1.5, 0.0], 1e-9)
    assert m.inside is False and m.distance == pytest.approx(0.5) and m.method == "hull"


def test_bounds_are_rounded_outward():
    G = np.array([[1.0, 1e-8], [0.0, 1.0]])
    xi = np.array([1.0, -1.0])
    v = G @ xi
    assert residual_bound(G, xi, v) > 0.0  # never an optimistic exact zero
    assert hull_distance(np.zeros(2), np.ones(2), np.array([2.0, 0.5])) == 1.0
    # any direction gives a valid lower bound; d = e1 separates x = (3, 0) from the unit box
    lb = dual_lower_bound(np.eye(2), np.array([3.0, 0.0]), np.zeros((0, 2)), np.zeros(0),
                          np.array([1.0, 0.0]), np.zeros(0))
    assert 2.0 - 1e-12 < lb < 2.0


def test_lp_trouble_of_the_fast_settings_is_retried_with_robust_ones(monkeypatch):
    from benchmarks.run import membership

    # the fast settings fail at once (iteration limit 0); the robust ones lift the limit
    monkeypatch.setattr(membership, "FAST_LP", {"presolve": "off", "simplex_strategy": 4,
                                                "simplex_iteration_limit": 0})
    monkeypatch.setattr(membership, "ROBUST_LP", {"presolve": "on", "simplex_strategy": 1,
                                                  "simplex_iteration_limit": 10**6})
    Z = Zonotope([0.0, 0.0], [[0.5, 0.5], [0.5, -0.5]])
    m = MembershipTester().test(Z, [0.6, 0.6], 1e-9)
    assert m.inside is False and m.distance == pytest.approx(0.1, abs=1e-9)
