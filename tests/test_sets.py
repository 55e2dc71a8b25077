"""Set core: operators, exact interval hulls and support functions, CORA's reduction rules,
and property tests (sampled points of a set stay inside its over-approximations)."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from observers.sets import ConZonotope, Ellipsoid, Interval, SetError, Zonotope, get_reduction

rng = np.random.default_rng(1234)


def random_zonotope(n: int, r: int, seed: int) -> Zonotope:
    g = np.random.default_rng(seed)
    return Zonotope(g.normal(size=n), g.normal(size=(n, r)))


def corners(Z: Zonotope) -> np.ndarray:
    """All 2^r points c + G s, s in {-1, 1}^r (small r only)."""
    S = np.array(list(itertools.product([-1.0, 1.0], repeat=Z.num_generators)))
    return Z.c + S @ Z.G.T


# -- operators ------------------------------------------------------------------------------------
def test_linear_map_and_minkowski_sum_act_on_points():
    Z1, Z2 = random_zonotope(3, 4, 1), random_zonotope(3, 2, 2)
    M = rng.normal(size=(2, 3))
    S = M @ (Z1 + Z2)
    xi1, xi2 = rng.uniform(-1, 1, 4), rng.uniform(-1, 1, 2)
    p = M @ (Z1.c + Z1.G @ xi1 + Z2.c + Z2.G @ xi2)
    assert S.contains(p, tol=1e-9)
    assert S.G.shape == (2, 6)
    np.testing.assert_array_equal((Z1 + Z2).G, np.hstack([Z1.G, Z2.G]))  # order preserved


def test_translation_negation_and_scalar_product():
    Z = Zonotope([1.0, 2.0], [[1.0, 0.5], [0.0, 1.0]])
    np.testing.assert_array_equal((Z + np.array([1.0, -1.0])).c, [2.0, 1.0])
    np.testing.assert_array_equal((-Z).c, [-1.0, -2.0])
    np.testing.assert_array_equal((2 * Z).G, 2 * Z.G)


def test_interval_hull_is_exact_for_zonotopes():
    Z = random_zonotope(3, 6, 3)
    pts = corners(Z)
    I = Z.interval()
    np.testing.assert_allclose(I.lo, pts.min(axis=0), atol=1e-12)
    np.testing.assert_allclose(I.hi, pts.max(axis=0), atol=1e-12)


def test_support_function_equals_max_over_corners():
    Z = random_zonotope(3, 7, 4)
    pts = corners(Z)
    for _ in range(10):
        d = rng.normal(size=3)
        assert Z.support(d) == pytest.approx(np.max(pts @ d), abs=1e-10)
    D = rng.normal(size=(3, 5))
    np.testing.assert_allclose(Z.support(D), [Z.support(d) for d in D.T])


def test_zonotope_membership_is_exact():
    Z = Zonotope([0.0, 0.0], [[1.0, 1.0], [0.0, 1.0]])  # parallelogram
    assert Z.contains([2.0, 1.0])  # vertex
    assert Z.contains([0.0, 0.0])
    assert not Z.contains([2.0, 0.0])  # inside the hull [-2,2]x[-1,1] but outside the set
    assert Z.contains([2.0, 0.5], tol=0.6)


# -- reduction ------------------------------------------------------------------------------------
def test_reduction_follows_cora_rules_hand_example():
    # zero column dropped; r = 5 > n*order = 4 -> keep floor(2*(2-1)) = 2 generators; the three
    # with the smallest ||g||_1 - ||g||_inf (0, 0, 0 for g1, g2, g4; ties by index) are boxed.
    G = np.array([[1.0, 0.0, 0.5, 0.1, 0.0, 0.3], [0.0, 1.0, 0.5, 0.0, 0.0, 0.1]])
    Z = Zonotope([0.0, 0.0], G)
    R = Z.reduce(2, "girard")
    np.testing.assert_allclose(R.G, [[0.5, 0.3, 1.1, 0.0], [0.5, 0.1, 0.0, 1.0]])


def test_no_reduction_below_order_only_drops_zero_generators():
    Z = Zonotope([0.0, 0.0], [[1.0, 0.0, 2.0], [0.0, 0.0, 1.0]])
    np.testing.assert_array_equal(Z.reduce(5, "pca").G, [[1.0, 2.0], [0.0, 1.0]])


def test_pca_reduction_is_exact_for_collinear_generators():
    # all reduced generators along (1, 1): the PCA box is the exact segment
    a = np.array([0.3, -0.5, 0.2])
    G = np.hstack([np.array([[3.0], [2.0]]), np.outer([1.0, 1.0], a)])  # h = 2 > 0.5
    R = Zonotope([0.0, 0.0], G).reduce(1.5, "pca")  # keep floor(2*0.5) = 1 generator
    assert R.num_generators <= 3
    np.testing.assert_allclose(R.G[:, 0], [3.0, 2.0])
    seg = R.G[:, 1:][:, np.abs(R.G[:, 1:]).sum(axis=0) > 1e-12]
    np.testing.assert_allclose(np.abs(seg).ravel(), [1.0, 1.0], atol=1e-12)


@pytest.mark.parametrize("method", ["girard", "pca"])
@pytest.mark.parametrize("seed", range(6))
def test_reduction_encloses_sampled_points(method, seed):
    n, r = 3, 14
    Z = random_zonotope(n, r, 100 + seed)
    R = Z.reduce(2, method)
    assert R.num_generators <= 2 * n
    g = np.random.default_rng(seed)
    pts = np.vstack([Z.sample(60, g), corners(Zonotope(Z.c, Z.G[:, :8]))[:20] * 0 + Z.c])
    for p in pts:
        assert R.contains(p, tol=1e-9)
    Ir, Iz = R.interval(), Z.interval()
    assert np.all(Ir.lo <= Iz.lo + 1e-12) and np.all(Ir.hi >= Iz.hi - 1e-12)


def test_reduction_rejects_bad_orders_and_names():
    Z = random_zonotope(2, 4, 5)
    with pytest.raises(SetError, match="order must be >= 1"):
        Z.reduce(0.5)
    with pytest.raises(SetError, match="order must be >= 1"):
        Z.reduce(-3)
    with pytest.raises(SetError, match="unknown reduction method 'foo'"):
        Z.reduce(2, "foo")
    assert get_reduction("pca").name == "pca"


# -- intervals ------------------------------------------------------------------------------------
def test_interval_arithmetic():
    I = Interval([-1.0, 0.0], [1.0, 2.0])
    J = np.array([[1.0, -1.0], [0.0, 2.0]]) @ I
    np.testing.assert_allclose(J.lo, [-3.0, 0.0])
    np.testing.assert_allclose(J.hi, [1.0, 4.0])
    assert (I + I).hi.tolist() == [2.0, 4.0]
    assert I.support([1.0, -1.0]) == pytest.approx(1.0)
    assert I.contains([1.0, 2.0]) and not I.contains([1.1, 0.0])
    with pytest.raises(SetError, match="empty interval"):
        Interval([1.0], [0.0])


def test_bad_input_names_the_problem():
    with pytest.raises(SetError, match="non-finite"):
        Zonotope([0.0, np.nan], np.eye(2))
    with pytest.raises(SetError, match="2 rows"):
        Zonotope([0.0, 0.0], np.eye(3))
    with pytest.raises(SetError, match="cannot map"):
        _ = np.eye(3) @ Zonotope([0.0, 0.0], np.eye(2))
    with pytest.raises(SetError, match="dimensions 2 and 3"):
        _ = Zonotope([0.0, 0.0]) + Zonotope([0.0, 0.0, 0.0])


def test_sets_are_immutable_values():
    Z = Zonotope([0.0, 1.0], np.eye(2))
    with pytest.raises(ValueError):
        Z.G[0, 0] = 5.0
    assert Z == Zonotope([0.0, 1.0], np.eye(2)) and hash(Z) == hash(Zonotope([0, 1], np.eye(2)))


# -- ellipsoids -----------------------------------------------------------------------------------
def test_ellipsoid_hull_support_and_membership():
    Q = np.array([[4.0, 1.0], [1.0, 2.0]])
    E = Ellipsoid([1.0, -1.0], Q)
    I = E.interval()
    np.testing.assert_allclose(I.hi, [3.0, -1.0 + np.sqrt(2.0)])
    d = np.array([0.3, -0.7])
    assert E.support(d) == pytest.approx(d @ E.q + np.sqrt(d @ Q @ d))
    L = np.linalg.cholesky(Q)
    for _ in range(50):
        v = rng.normal(size=2)
        v *= rng.uniform(0, 1) / np.linalg.norm(v)
        assert E.contains(E.q + L @ v)
    far = E.q + L @ np.array([2.0, 0.0])
    assert not E.contains(far)
    assert E.distance(far) > 0


def test_ellipsoid_sum_encloses_the_minkowski_sum():
    E1 = Ellipsoid([0.0, 0.0], np.diag([1.0, 0.25]))
    E2 = Ellipsoid([1.0, 0.0], np.array([[0.5, 0.2], [0.2, 0.3]]))
    S = E1 + E2
    L1, L2 = np.linalg.cholesky(E1.Q), np.linalg.cholesky(E2.Q)
    for _ in range(200):
        a, b = rng.normal(size=2), rng.normal(size=2)
        p = E1.q + L1 @ (a / np.linalg.norm(a)) + E2.q + L2 @ (b / np.linalg.norm(b))
        assert S.contains(p, tol=1e-9)


def test_degenerate_ellipsoid_and_psd_check():
    E = Ellipsoid([0.0, 0.0], np.outer([1.0, 1.0], [1.0, 1.0]))  # a segment
    assert E.contains([0.5, 0.5]) and not E.contains([0.5, -0.5])
    with pytest.raises(SetError, match="positive semi-definite"):
        Ellipsoid([0.0, 0.0], np.diag([1.0, -1.0]))


# -- constrained zonotopes ------------------------------------------------------------------------
def test_conzonotope_interval_is_a_sound_outer_bound_of_the_feasible_points():
    g = np.random.default_rng(7)
    n, r, nc = 3, 9, 2
    G, A = g.normal(size=(n, r)), g.normal(size=(nc, r))
    xi0 = g.uniform(-0.5, 0.5, r)
    CZ = ConZonotope(g.normal(size=n), G, A, A @ xi0)
    I = CZ.interval()
    # feasible points: xi0 plus null-space directions of A, scaled into the box
    N = np.linalg.svd(A)[2][nc:].T
    for _ in range(300):
        step = N @ g.normal(size=N.shape[1])
        t = np.max(np.abs(step) / (1 - np.abs(xi0)))
        xi = xi0 + step / t * g.uniform(0, 1)
        x = CZ.c + G @ xi
        assert np.all(x >= I.lo - 1e-9) and np.all(x <= I.hi + 1e-9)
        assert CZ.contains(x, tol=1e-9)
    # constraints tighten the hull of the unconstrained zonotope
    Iz = CZ.to_zonotope().interval()
    assert np.all(I.lo >= Iz.lo - 1e-9) and np.all(I.hi <= Iz.hi + 1e-9)


def test_conzonotope_hull_of_a_constrained_square():
    # square [-1,1]^2 with xi1 = xi2: the diagonal segment; its hull is the square again,
    # but the support in direction (1, -1) is 0
    CZ = ConZonotope([0.0, 0.0], np.eye(2), [[1.0, -1.0]], [0.0])
    I = CZ.interval()
    np.testing.assert_allclose(I.hi, [1.0, 1.0], atol=1e-7)
    assert CZ.support([1.0, -1.0]) == pytest.approx(0.0, abs=1e-7)
    assert CZ.support([1.0, -1.0]) >= 0.0  # sound: never below the true value
    assert not CZ.contains([1.0, -1.0])


def test_empty_conzonotope_is_reported():
    CZ = ConZonotope([0.0], [[1.0]], [[1.0]], [2.0])  # xi = 2 outside the box
    with pytest.raises(SetError, match="empty"):
        CZ.interval()


# -- rounding-independent reductions (issue 37) ---------------------------------------------------
@pytest.mark.parametrize("compiled", ["1", "0"])
def test_pca_box_width_of_an_unspanned_axis_is_exactly_zero(compiled, monkeypatch):
    # reduced generators along one line (rank 1) leave the other principal axis a width that
    # is zero in exact arithmetic; a rounding-level perturbation (1e-19) must not turn it into
    # a kept column on one machine and a dropped one on another
    monkeypatch.setenv("SETOBS_NUMBA", compiled)
    d = np.array([0.6, 0.8])
    base = np.outer(d, [4.0, 3.0, 1.0, 2.0, 0.5, 0.25])
    for tiny in (0.0, 1e-19, -1e-19):
        G = base.copy()
        G[1, 3] += tiny  # a generator nudged off the line by rounding
        out = get_reduction("pca").reduce(G, 2.0)  # keeps 4d and 3d, boxes the others
        box = out[:, 2:]
        widths = np.linalg.norm(box, axis=0)
        assert np.count_nonzero(widths) == 1
        assert widths.max() == pytest.approx(3.75)  # |1 + 2 + 0.5 + 0.25| along d


@pytest.mark.parametrize("compiled", ["1", "0"])
def test_reduction_ranks_generators_that_tie_to_rounding_by_index(compiled, monkeypatch):
    # two generators whose metric ||g||_1 - ||g||_inf ties in exact arithmetic but differs in
    # the last bit: the one with the lower index is reduced, whichever bit pattern we got
    monkeypatch.setenv("SETOBS_NUMBA", compiled)
    big = np.array([[4.0, 0.0], [0.0, 4.0]])
    for eps in (1e-15, -1e-15):
        g1 = np.array([1.0, 1.0])
        g2 = np.array([-1.0, 1.0 + eps])  # same metric up to rounding, another direction
        G = np.column_stack([big, g1, g2])
        out = get_reduction("girard").reduce(G, 1.5)  # keeps floor(2 * 0.5) = 1 column
        # the metrics are 0, 0 (the axis-aligned ones), 1 and 1 + eps: g1 (index 2) is
        # reduced and g2 kept whatever the sign of eps (without the tie band: the smaller)
        np.testing.assert_allclose(out[:, 0], [-1.0, 1.0], atol=1e-12)


def test_constraint_elimination_regresses_without_squaring_the_condition_number():
    # ||G - L A_S||_F minimised by L = G A_S' (A_S A_S')^+: with nearly dependent rows the
    # Gram route loses cond(A_S)^2 eps; the least-squares route matches the exact solution
    from observers.sets.conzono_ops import regress

    X = np.array([[1.0, 1.0, 0.0, 0.0], [1.0, 1.0 + 1e-7, 0.0, 0.0]])
    Y = np.array([[2.0, 3.0, 1.0, 0.0]])
    # exact (hand): X' K' = Y' in least squares; rows of X span e1 + e2 and e2 (1e-7 scaled)
    K_exact = Y @ np.linalg.pinv(X, rcond=1e-15)
    np.testing.assert_allclose(regress(Y, X), K_exact, rtol=1e-8)


def test_lifted_pca_uses_wider_clusters():
    from observers.sets.reduction import (
        CLUSTER_RTOL,
        DATA_DRIVEN_CLUSTER_RTOL,
        LIFTED_CLUSTER_RTOL,
        PCA,
        lifted_reduction,
    )

    assert CLUSTER_RTOL < LIFTED_CLUSTER_RTOL < DATA_DRIVEN_CLUSTER_RTOL
    assert lifted_reduction(get_reduction("pca")).cluster_rtol == LIFTED_CLUSTER_RTOL
    wide = lifted_reduction(get_reduction("pca"), cluster_rtol=DATA_DRIVEN_CLUSTER_RTOL)
    assert wide.cluster_rtol == DATA_DRIVEN_CLUSTER_RTOL
    assert lifted_reduction(wide).cluster_rtol == DATA_DRIVEN_CLUSTER_RTOL  # never narrower
    assert lifted_reduction(get_reduction("girard")) is get_reduction("girard")
    # within a cluster the axes depend on the subspace only: two singular values 1e-4 apart
    # (relative) give the coordinate axes under the lifted tolerance, whatever the rotation
    G = np.diag([1.0, 1.0 - 1e-4])
    R = np.array([[np.cos(0.3), -np.sin(0.3)], [np.sin(0.3), np.cos(0.3)]])
    from observers.sets.reduction import principal_axes
    U = principal_axes(G @ R, LIFTED_CLUSTER_RTOL)
    np.testing.assert_allclose(np.abs(U), np.eye(2), atol=1e-12)
    assert isinstance(wide, PCA)


def test_memory_of_the_set_types_by_hand():
    # the values that define each set: a zonotope in R^3 with 5 generators holds 3 + 15;
    # a constrained zonotope with 2 constraints on those 5 factors adds A (10) and b (2);
    # an ellipsoid in R^3 its centre and 3 x 3 shape matrix, 3 + 9; an interval 2 x 3;
    # a bundle of the zonotope twice, 36; memory_columns: the median over the steady steps
    # (from ceil(0.2 N) on) and the peak over all
    from benchmarks.metrics import memory_columns
    from observers.sets import ConZonotope, Ellipsoid, Interval, ZonotopeBundle, doubles

    rng = np.random.default_rng(0)
    Z = Zonotope(rng.normal(size=3), rng.normal(size=(3, 5)))
    assert doubles(Z) == 18
    S = ConZonotope(Z.c, Z.G, rng.normal(size=(2, 5)), np.zeros(2))
    assert doubles(S) == 30
    assert doubles(Ellipsoid(np.zeros(3), np.eye(3))) == 12
    assert doubles(Interval(-np.ones(3), np.ones(3))) == 6
    assert doubles(ZonotopeBundle([Z, Z])) == 36
    assert np.isnan(doubles(object()))
    cols = memory_columns(np.array([100.0, 50.0, 10.0, 20.0, 30.0, np.nan]))
    # N = 6: steady from ceil(1.2) = 2 on: median of (10, 20, 30) = 20; peak 100
    assert cols == {"memory": 20.0, "memory_peak": 100.0}


def test_step_reduction_takes_the_kernels_jacobi_axes():
    # issue 37: the order-one reduction of a linearisation's deviation set took LAPACK's SVD
    # (the stand-alone PCA), whose rounding depends on the BLAS kernel; inside a step it now
    # takes the step kernels' Jacobi axes, the same box up to rounding where the singular
    # values are distinct
    from observers.kernels import switch
    from observers.sets.reduction import PCA, jacobi_principal_axes, step_reduction

    assert step_reduction(get_reduction("girard")) is get_reduction("girard")
    stepwise = step_reduction(get_reduction("pca"))
    assert isinstance(stepwise, PCA) and stepwise.jacobi_dim > 0
    assert stepwise.cluster_rtol == get_reduction("pca").cluster_rtol
    rng = np.random.default_rng(7)
    G = rng.standard_normal((5, 40))
    for compiled in (True, False) if switch.AVAILABLE else (False,):
        old = switch.set_compiled(compiled)
        try:
            box = stepwise.reduce(G, 1.0)
            np.testing.assert_allclose(box, get_reduction("pca").reduce(G, 1.0), atol=1e-10)
        finally:
            switch.set_compiled(old)
        # the box's axes are the Jacobi axes: the hand formula U diag(|U' G| 1)
        U = jacobi_principal_axes(G)
        np.testing.assert_array_equal(box.shape, (5, 5))
        np.testing.assert_allclose(box, U * np.abs(U.T @ G).sum(axis=1), atol=1e-12)
