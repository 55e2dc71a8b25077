"""Matrix zonotopes, interval matrices and the constrained-zonotope tools of the data-driven
observers: exact constructions checked by hand, enclosures checked on sampled points."""

from __future__ import annotations

import numpy as np
import pytest

from observers.sets import ConZonotope, IntervalMatrix, MatrixZonotope, SetError, Zonotope


def _random_mz(rng, shape=(2, 3), h=3) -> MatrixZonotope:
    return MatrixZonotope(rng.normal(size=shape), 0.3 * rng.normal(size=(h, *shape)))


def test_interval_hull_and_sum_by_hand():
    M = MatrixZonotope([[1.0, 2.0]], [[[0.5, -1.0]], [[0.25, 0.0]]])
    I = M.interval_matrix()
    np.testing.assert_allclose(I.lo, [[0.25, 1.0]])
    np.testing.assert_allclose(I.hi, [[1.75, 3.0]])
    S = M + IntervalMatrix([[0.0, -1.0]], [[1.0, 1.0]])
    np.testing.assert_allclose(S.interval_matrix().lo, [[0.25, 0.0]])
    np.testing.assert_allclose(S.interval_matrix().hi, [[2.75, 4.0]])
    np.testing.assert_allclose((M - M).C, 0.0)
    assert (M - M).num_generators == 4


def test_from_sequence_is_the_noise_matrix_zonotope():
    Z = Zonotope([1.0, 0.0], [[0.1, 0.0], [0.0, 0.2]])
    M = MatrixZonotope.from_sequence(Z, 3)
    assert M.shape == (2, 3) and M.num_generators == 6
    np.testing.assert_allclose(M.C, [[1, 1, 1], [0, 0, 0]])
    # generator i*T + k puts generator i of Z into column k
    np.testing.assert_allclose(M.G[4], [[0, 0, 0], [0, 0.2, 0]])
    np.testing.assert_allclose(M.radius(), [[0.1] * 3, [0.2] * 3])
    with pytest.raises(SetError, match="at least one column"):
        MatrixZonotope.from_sequence(Z, 0)


@pytest.mark.parametrize("seed", range(3))
def test_product_with_zonotope_encloses_sampled_images(seed):
    rng = np.random.default_rng(seed)
    M = _random_mz(rng)
    Z = Zonotope(rng.normal(size=3), rng.normal(size=(3, 4)))
    R = M @ Z
    mats, pts = M.sample(20, rng), Z.sample(20, rng)
    for A, x in zip(mats, pts, strict=True):
        assert R.contains(A @ x, 1e-9)
    RI = M.interval_matrix() @ Z
    for A, x in zip(mats, pts, strict=True):
        assert RI.contains(A @ x, 1e-9)


def test_product_with_conzonotope_keeps_constraints_and_encloses():
    rng = np.random.default_rng(4)
    M = _random_mz(rng)
    CZ = ConZonotope.from_set(Zonotope(np.zeros(3), np.eye(3))).intersect(
        Zonotope([0.5, 0.5, 0.0], np.eye(3)))
    R = M @ CZ
    assert isinstance(R, ConZonotope) and R.num_constraints == CZ.num_constraints
    pts = [x for x in Zonotope(np.zeros(3), np.eye(3)).sample(200, rng)
           if np.all(np.abs(x - [0.5, 0.5, 0.0]) <= 1)][:15]
    assert len(pts) >= 10
    for A, x in zip(M.sample(len(pts), rng), pts, strict=True):
        assert R.contains(A @ x, 1e-8)


def test_interval_matrix_products_enclose_samples():
    rng = np.random.default_rng(5)
    I = IntervalMatrix.from_center_radius(rng.normal(size=(2, 3)), 0.2 * rng.random((2, 3)))
    J = IntervalMatrix.from_center_radius(rng.normal(size=(3, 2)), 0.2 * rng.random((3, 2)))
    K = I @ J
    for _ in range(50):
        A = I.lo + (I.hi - I.lo) * rng.random(I.shape)
        B = J.lo + (J.hi - J.lo) * rng.random(J.shape)
        assert K.contains(A @ B)
        assert (A @ J).contains(A @ B) and (I @ B).contains(A @ B)


def test_reduce_encloses_and_contains_is_exact():
    rng = np.random.default_rng(6)
    M = _random_mz(rng, h=30)
    R = M.reduce(1.0, "pca")
    assert R.num_generators <= 6
    for A in M.sample(20, rng):
        assert M.contains(A, 1e-9) and R.contains(A, 1e-9)
    assert not M.contains(M.C + 10.0)
    back = MatrixZonotope.from_vector(M.vectorize(), M.shape)
    assert back == M


def test_bad_matrix_sets_are_rejected():
    with pytest.raises(SetError, match="generators must have shape"):
        MatrixZonotope(np.eye(2), np.zeros((3, 2, 3)))
    with pytest.raises(SetError, match="empty"):
        IntervalMatrix([[1.0]], [[0.0]])
    with pytest.raises(SetError, match="cannot map"):
        MatrixZonotope(np.eye(2)) @ Zonotope(np.zeros(3))


def test_conzonotope_intersection_is_exact_and_enclosures_are_sound():
    rng = np.random.default_rng(7)
    Z1 = Zonotope([0.0, 0.0], [[1.0, 0.5, 0.0], [0.0, 0.5, 1.0]])
    Z2 = Zonotope([0.8, 0.3], [[1.0, 0.2], [-0.3, 0.6]])
    X = ConZonotope.from_set(Z1).intersect(Z2)
    E = X.to_zonotope("frobenius")
    R = X.reduce_constraints(1, "frobenius").normalize_constraints().reduce(1.0, per="lifted")
    assert R.num_constraints <= 1 and R.num_generators <= 3 * 2
    pts = Z1.c + rng.uniform(-1, 1, size=(200, 3)) @ Z1.G.T  # interior points of Z1
    agree = 0
    for x in pts:
        in2 = Z2.contains(x, 0.0)
        assert X.contains(x, 1e-9) == in2 or not Z2.contains(x, 1e-6) == in2
        agree += in2
        if in2:
            assert E.contains(x, 1e-8) and R.contains(x, 1e-8)
    assert 20 < agree < 180  # both cases occur
