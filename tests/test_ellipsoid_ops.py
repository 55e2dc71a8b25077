"""Ellipsoid operations used by the ellipsoidal observers: zonotope conversions, outer
Minkowski sums, strip intersections and the OBE weight (property tests on sampled points and
hand derivations)."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from observers.sets import Ellipsoid, Interval, SetError, Zonotope
from observers.sets.ellipsoid import (
    max_quadratic_on_zonotope,
    obe_weight,
    outer_sum,
    quadratic_update,
)

rng = np.random.default_rng(11)


def _vertices(Z: Zonotope) -> np.ndarray:
    signs = np.array(list(itertools.product((-1.0, 1.0), repeat=Z.num_generators)))
    return Z.c + signs @ Z.G.T


# -- conversions ----------------------------------------------------------------------------------
def test_conversions_of_a_parallelotope_follow_cora():
    # CORA's conversion of a zonotope to an ellipsoid: inner:norm gives G G', outer n G G'
    G = np.array([[1.0, 0.5], [0.0, 2.0]])
    Z = Zonotope([1.0, -1.0], G)
    inner = Ellipsoid.from_zonotope(Z, "inner:norm")
    outer = Ellipsoid.from_zonotope(Z, "outer:norm")
    np.testing.assert_allclose(inner.Q, G @ G.T)
    np.testing.assert_allclose(outer.Q, 2 * G @ G.T)
    np.testing.assert_array_equal(outer.q, Z.c)
    for x in inner.sample(300, rng):
        assert Z.contains(x, tol=1e-9)
    for v in _vertices(Z):
        assert outer.contains(v, tol=1e-9)


def test_outer_conversion_contains_a_zonotope_with_many_generators():
    Z = Zonotope(rng.normal(size=3), rng.normal(size=(3, 7)))
    E = Ellipsoid.from_zonotope(Z)  # outer:norm is the default
    for v in _vertices(Z):
        assert E.contains(v, tol=1e-9)
    for x in Ellipsoid.from_zonotope(Z, "inner:norm").sample(200, rng):
        assert Z.contains(x, tol=1e-9)


def test_degenerate_conversion_is_rank_deficient_and_boxes_are_accepted():
    E = Ellipsoid.from_zonotope(Zonotope([0.0, 0.0], [[-0.12], [0.02]]), "inner:norm")
    assert np.linalg.matrix_rank(E.Q) == 1
    np.testing.assert_allclose(E.Q, np.outer([-0.12, 0.02], [-0.12, 0.02]))
    B = Ellipsoid.from_zonotope(Interval([-1.0, -2.0], [1.0, 2.0]), "outer:norm")
    np.testing.assert_allclose(B.Q, 2 * np.diag([1.0, 4.0]))
    with pytest.raises(SetError, match="conversion mode"):
        Ellipsoid.from_zonotope(Zonotope([0.0], [[1.0]]), "i:norm")


# -- Minkowski sums -------------------------------------------------------------------------------
def _sum_points(E1: Ellipsoid, E2: Ellipsoid, k: int) -> np.ndarray:
    return E1.sample(k, rng) + E2.sample(k, rng)


@pytest.mark.parametrize("weight", ["min-trace", 0.1, 0.5, 0.9])
def test_every_weight_gives_an_outer_minkowski_sum(weight):
    E1 = Ellipsoid([0.0, 1.0, 0.0], np.diag([1.0, 0.2, 0.05]))
    A = rng.normal(size=(3, 3))
    E2 = Ellipsoid([1.0, 0.0, -1.0], A @ A.T)
    S = E1.plus(E2, weight)
    for x in _sum_points(E1, E2, 400):
        assert S.contains(x, tol=1e-9)


def test_min_trace_is_the_minimal_trace_member_and_the_operator():
    Q1, Q2 = np.diag([1.0, 0.25]), np.array([[0.5, 0.2], [0.2, 0.3]])
    best = np.trace(outer_sum(Q1, Q2, "min-trace"))
    grid = [np.trace(outer_sum(Q1, Q2, p)) for p in np.linspace(0.01, 0.99, 99)]
    assert best <= min(grid) + 1e-12
    E1, E2 = Ellipsoid([0, 0], Q1), Ellipsoid([1, 1], Q2)
    assert E1 + E2 == E1.plus(E2, "min-trace")
    with pytest.raises(SetError, match="weight"):
        E1.plus(E2, 1.5)
    with pytest.raises(SetError, match="unknown Minkowski-sum weight"):
        E1.plus(E2, "min-volume-ish")


# -- strip intersection ---------------------------------------------------------------------------
def _inside_strip(x, C, y, V) -> bool:
    d = y - C @ x
    return float(d @ np.linalg.solve(V, d)) <= 1.0


@pytest.mark.parametrize("lam", ["min-trace", "obe", 0.05, 0.5, 0.95])
def test_strip_intersection_encloses_the_intersection(lam):
    E = Ellipsoid([0.5, -0.2], np.array([[2.0, 0.6], [0.6, 1.0]]))
    C = np.array([[1.0, 1.0], [0.0, 2.0]])
    V = np.diag([0.3, 0.5])
    y = np.array([0.4, 0.1])
    R = E.intersect_strip(C, y, V, lam)
    pts = [x for x in E.sample(4000, rng) if _inside_strip(x, C, y, V)]
    assert len(pts) > 100
    for x in pts:
        assert R.contains(x, tol=1e-9)


def test_single_strip_result_is_tighter_than_the_prior_in_the_measured_direction():
    E = Ellipsoid([0.0, 0.0], np.eye(2))
    R = E.intersect_strip([[1.0, 0.0]], [0.0], [[0.01]])  # strip |x1| <= 0.1, min-trace
    assert R.interval().hi[0] < 0.5
    assert E.intersect_strip([[1.0, 0.0]], [0.0], [[0.01]], "obe") is E  # level cannot drop
    with pytest.raises(SetError, match="does not intersect"):
        E.intersect_strip([[1.0, 0.0]], [3.0], [[0.01]], 0.5)


def test_quadratic_update_is_the_weighted_information_form():
    # hand derivation: P+^-1 = (1-lam) P^-1 + lam C'C, q+ = P+ ((1-lam) P^-1 q + lam C'y)
    P = np.array([[2.0, 0.3], [0.3, 0.5]])
    q, C, y = np.array([0.2, -0.1]), np.array([[1.0, 2.0]]), np.array([0.7])
    lam, s2, rho = 0.3, 0.8, 0.04
    qn, Pn, s2n = quadratic_update(q, P, s2, C, rho, y, lam)
    info = (1 - lam) * np.linalg.inv(P) + lam * C.T @ C
    np.testing.assert_allclose(np.linalg.inv(Pn), info, rtol=1e-12)
    np.testing.assert_allclose(qn, np.linalg.solve(info, (1 - lam) * np.linalg.solve(P, q)
                                                   + lam * C.T @ y), rtol=1e-12)
    # s2+ = min over x of the combined quadratic's constant part
    const = (1 - lam) * s2 + lam * rho - ((1 - lam) * q @ np.linalg.solve(P, q) + lam * y @ y
                                          - qn @ info @ qn)
    assert s2n == pytest.approx(const, rel=1e-12)


@pytest.mark.parametrize(("g", "beta"), [(0.3, 0.2), (2.5, -0.1), (1.0, 0.4), (8.0, 0.9)])
def test_obe_weight_minimises_the_upper_bound_of_the_level(g, beta):
    # bound of s2+ / ||delta||^2 up to a constant: lam beta - lam (1-lam) / (1 - lam + lam g)
    lams = np.linspace(1e-4, 1 - 1e-4, 20001)
    bound = lams * beta - lams * (1 - lams) / (1 - lams + lams * g)
    assert obe_weight(g, beta) == pytest.approx(lams[np.argmin(bound)], abs=2e-4)


def test_max_quadratic_on_zonotope_is_exact_or_an_upper_bound():
    G = rng.normal(size=(3, 5))
    A = rng.normal(size=(3, 3))
    M = A @ A.T
    brute = max(v @ M @ v for v in _vertices(Zonotope(np.zeros(3), G)))
    assert max_quadratic_on_zonotope(M, G) == pytest.approx(brute, rel=1e-12)
    assert max_quadratic_on_zonotope(M, G, exact_up_to=2) >= brute * (1 - 1e-12)
