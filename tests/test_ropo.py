"""ROPO (reduced-order parallelotopic observer): hand-derived strip cuts and time updates,
enclosure properties on random data, containment on the tank and vehicle records, bad input.

Every expected number below is derived by hand in the comments (no output of our code)."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

import observers
import systems
from observers.numerics.ropo import enclose, measurement_update, strip_cut, time_update
from observers.sets import EmptySet, Zonotope

from .conftest import paper_table


def _vertices(c, T):
    """The 2^n vertices of the parallelotope (c, T) as a set of rounded tuples."""
    n = T.shape[1]
    pts = [c + T @ np.array(s) for s in itertools.product((-1.0, 1.0), repeat=n)]
    return {tuple(np.round(p, 12) + 0.0) for p in pts}


def _inside(c, T, pts, tol=1e-9):
    """Whether every row of ``pts`` lies in the parallelotope (c, T) (T invertible)."""
    xi = np.linalg.solve(T, (pts - c).T)
    return bool(np.all(np.abs(xi) <= 1 + tol))


# -- measurement update: hand-derived examples -------------------------------------------------
def test_strip_cut_keeps_the_least_volume_of_the_three_candidates():
    # P = [-1,1] x [-2,2] (T = diag(1, 2)) cut by |x1 + x2| <= 0.5.  Tightened over the
    # intersection: x1 in [-1, 1] (x1 = 1 with x2 = -1), x2 in [-1.5, 1.5] (x2 = -x1 + s,
    # |s| <= .5, |x1| <= 1), x1 + x2 in [-0.5, 0.5].  Volumes (widths / |det normals|):
    # box 2 * 3 = 6; drop the x1 strip: 3 * 1 / 1 = 3; drop the x2 strip: 2 * 1 / 1 = 2.
    # The least is {|x1| <= 1, |x1 + x2| <= 0.5}, vertices (1, -0.5), (1, -1.5), (-1, 1.5),
    # (-1, 0.5).
    c, T = strip_cut(np.zeros(2), np.diag([1.0, 2.0]), np.array([1.0, 1.0]), -0.5, 0.5)
    assert 4 * abs(np.linalg.det(T)) == pytest.approx(2.0, rel=1e-12)  # volume 2^n |det T|
    assert _vertices(c, T) == {(1.0, -0.5), (1.0, -1.5), (-1.0, 1.5), (-1.0, 0.5)}


def test_strip_cut_unit_square_diagonal_strip():
    # [-1,1]^2 cut by |x1 + x2| <= 0.5: no strip of the square tightens (x1 = 1, x2 = -1 is
    # feasible); box 2 * 2 = 4, each other candidate 2 * 1 / 1 = 2.
    c, T = strip_cut(np.zeros(2), np.eye(2), np.array([1.0, 1.0]), -0.5, 0.5)
    assert 4 * abs(np.linalg.det(T)) == pytest.approx(2.0, rel=1e-12)  # volume 2^n |det T|
    np.testing.assert_allclose(c, 0.0, atol=1e-15)
    assert _vertices(c, T) in ({(1.0, -0.5), (1.0, -1.5), (-1.0, 1.5), (-1.0, 0.5)},
                               {(-0.5, 1.0), (-1.5, 1.0), (1.5, -1.0), (0.5, -1.0)})


def test_strip_cut_tightens_the_box_at_a_corner():
    # [-1,1]^2 cut by 1.5 <= x1 + x2 <= 2: the corner triangle; x1, x2 in [0.5, 1], the sum
    # in [1.5, 2].  Box 0.5 * 0.5 = 0.25 = each other candidate (0.5 * 0.5 / 1): on a tie
    # the measurement strip is dropped, so the result is the box [0.5, 1]^2.
    c, T = strip_cut(np.zeros(2), np.eye(2), np.array([1.0, 1.0]), 1.5, 2.0)
    np.testing.assert_allclose(c, [0.75, 0.75], rtol=1e-14)
    np.testing.assert_allclose(T, np.diag([0.25, 0.25]), rtol=1e-14)


def test_strip_that_contains_the_parallelotope_changes_nothing():
    T = np.array([[1.0, 0.5], [0.0, 1.0]])
    c, T2 = strip_cut(np.array([1.0, 0.0]), T, np.array([0.0, 1.0]), -3.0, 2.0)
    assert T2 is T and np.array_equal(c, [1.0, 0.0])


def test_exact_measurement_gives_the_segment():
    # [-1,1]^2 and x1 + x2 = 0.5 exactly: the segment from (1, -0.5) to (-0.5, 1), a flat
    # parallelotope (one zero generator), centre (0.25, 0.25).
    c, T = strip_cut(np.zeros(2), np.eye(2), np.array([1.0, 1.0]), 0.5, 0.5)
    np.testing.assert_allclose(c, [0.25, 0.25], rtol=1e-14)
    cols = [T[:, j] for j in range(2) if np.any(T[:, j] != 0)]
    assert len(cols) == 1
    np.testing.assert_allclose(np.abs(cols[0]), [0.75, 0.75], rtol=1e-14)
    assert cols[0][0] * cols[0][1] < 0


def test_strip_that_misses_is_an_empty_set():
    # [-1,1]^2 has x1 + x2 <= 2 < 3
    with pytest.raises(EmptySet, match="misses the estimate"):
        strip_cut(np.zeros(2), np.eye(2), np.array([1.0, 1.0]), 3.0, 4.0)


@pytest.mark.parametrize("seed", range(8))
def test_measurement_update_encloses_the_intersection(seed):
    rng = np.random.default_rng(seed)
    n, m = 4, 3
    T = rng.normal(size=(n, n)) + 2 * np.eye(n)
    c = rng.normal(size=n)
    C = rng.normal(size=(m, n))
    pts = c + rng.uniform(-1, 1, size=(20000, n)) @ T.T
    mid = C @ c + 0.3 * rng.normal(size=m)
    half = 0.4 * np.abs(C @ T).sum(axis=1) * rng.uniform(0.2, 1.0, size=m)
    lo, hi = mid - half, mid + half
    keep = np.all((pts @ C.T >= lo) & (pts @ C.T <= hi), axis=1)
    assert keep.sum() > 20  # the intersection is sampled
    c2, T2 = measurement_update(c, T, C, lo, hi)
    assert _inside(c2, T2, pts[keep])
    assert abs(np.linalg.det(T2)) <= abs(np.linalg.det(T)) * (1 + 1e-12)


# -- time update ---------------------------------------------------------------------------------
A_SHEAR = np.array([[1.0, 1.0], [0.0, 1.0]])


@pytest.mark.parametrize(("basis", "expected"), [
    # axes A T = A: A^-1 [A, 0.1 I] = [I, 0.1 A^-1], A^-1 = [[1, -1], [0, 1]]: row sums of
    # |.| are 1 + 0.1 + 0.1 = 1.2 and 1 + 0.1 = 1.1, so T+ = A diag(1.2, 1.1)
    ("propagated", [[1.2, 1.1], [0.0, 1.1]]),
    # coordinate axes: |[A, 0.1 I]| row sums 1 + 1 + 0.1 = 2.1 and 1 + 0.1 = 1.1
    ("box", [[2.1, 0.0], [0.0, 1.1]]),
    # least volume: propagated 4 * 1.2 * 1.1 = 5.28, box 4 * 2.31 = 9.24, PCA: the axes of
    # G G' = [[2.01, 1], [1, 1.01]] are (cos t, sin t), (-sin t, cos t) with tan t = 0.618
    # (eigenvalue (3.02 + sqrt 5) / 2); radii 2.365 and 0.988, volume 4 * 2.337 = 9.35
    ("min-volume", [[1.2, 1.1], [0.0, 1.1]]),
])
def test_time_update_hand_example(basis, expected):
    c, T = time_update(np.zeros(2), np.eye(2), A_SHEAR, np.array([0.5, 0.0]),
                       0.1 * np.eye(2), basis)
    np.testing.assert_allclose(c, [0.5, 0.0])
    np.testing.assert_allclose(T, expected, rtol=1e-13)


def test_pca_basis_radii_by_hand():
    # the PCA candidate of the example above: radii 2.365 and 0.988 (see the comment there)
    _, T = time_update(np.zeros(2), np.eye(2), A_SHEAR, np.zeros(2), 0.1 * np.eye(2), "pca")
    np.testing.assert_allclose(sorted(np.linalg.norm(T, axis=0)), [0.98829, 2.36467],
                               rtol=1e-4)


@pytest.mark.parametrize("basis", ["min-volume", "generators", "propagated", "pca", "box"])
@pytest.mark.parametrize("seed", range(4))
def test_time_update_encloses_the_prediction(basis, seed):
    rng = np.random.default_rng(100 + seed)
    n, nw = 4, 2
    T, A, E = rng.normal(size=(n, n)), rng.normal(size=(n, n)), rng.normal(size=(n, nw))
    c, d = rng.normal(size=n), rng.normal(size=n)
    c2, T2 = time_update(c, T, A, d, E, basis)
    k = 5000
    xi = rng.uniform(-1, 1, size=(k, n))
    xi[: k // 2] = np.sign(xi[: k // 2])  # vertices of P too
    w = np.sign(rng.uniform(-1, 1, size=(k, nw)))
    pts = (c + xi @ T.T) @ A.T + d + w @ E.T
    assert _inside(c2, T2, pts)


def test_singular_propagated_basis_falls_back():
    # A T of rank 1: the propagated axes cannot carry W; the coordinate axes enclose instead
    G = np.array([[1.0, 1.0, 0.1, 0.0], [1.0, 1.0, 0.0, 0.1]])
    T = enclose(G, "propagated", G[:, :2])
    np.testing.assert_allclose(T, np.diag([2.1, 2.1]))


# -- the observer ----------------------------------------------------------------------------
def _contained(sc, **options):
    res = observers.run(observers.create("ROPO", sc.system, **options), sc.u, sc.y)
    assert res.status == "ok", res.message
    for k, S in enumerate(res.sets):
        assert S.num_generators == sc.system.n  # a parallelotope at every step
        assert S.contains(sc.x_true[k], tol=sc.tolerance), f"x_{k} outside"
    return res


@pytest.mark.parametrize("scenario", ["tank6-linear", "vehicle6d-sim", "vehicle6d-cora"])
def test_ropo_contains_the_true_state(scenario):
    _contained(systems.scenario(scenario))


@pytest.mark.parametrize("basis", ["generators", "propagated", "pca", "box"])
def test_ropo_bases_contain_the_true_state(basis):
    _contained(systems.scenario("vehicle6d-sim", steps=100), basis=basis)


def test_ropo_is_registered_as_a_strip_observer():
    info = observers.get("ROPO")
    assert info.family == "strip" and info.guaranteed and not info.ready_for_control
    assert "Vicino" in info.reference and "Chisci" in info.reference


def test_ropo_handles_noise_centre_and_exact_sensor():
    # V off-centre: y1 = x1 + v with v in [-0.05, 0.15]; V1 = 0 (exact sensor) in the second
    A, B, C = [[0.9, 0.2], [-0.1, 0.8]], [[0.0], [1.0]], [[1.0, 0.0], [0.5, 1.0]]
    s = systems.LinearSystem(A, B, C, W=Zonotope.box([0.02, 0.01]),
                             V=Zonotope([0.05, 0.0], np.diag([0.1, 0.0])),
                             X0=Zonotope.box([1.0, 1.0]))
    sim = systems.simulate(s, np.zeros((60, 1)), seed=3)
    res = observers.run(observers.create("ROPO", s), sim.u, sim.y)
    assert res.status == "ok"
    for k, S in enumerate(res.sets):
        assert S.contains(sim.x_true[k], tol=1e-9), f"x_{k} outside"
        # the exact sensor pins 0.5 x1 + x2: the set is flat along it
        assert np.abs(np.array([0.5, 1.0]) @ S.G).sum() == pytest.approx(0.0, abs=1e-12)


def test_inconsistent_measurement_ends_the_run_as_empty():
    sc = systems.scenario("vehicle6d-sim", steps=5)
    y = sc.y.copy()
    y[2] += 1e3  # far outside every estimate
    res = observers.run(observers.create("ROPO", sc.system), sc.u, y)
    assert res.status == "empty" and res.failed_step == 2
    assert "misses the estimate" in res.message


def test_bad_options_and_systems_are_refused_by_name():
    sc = systems.scenario("vehicle6d-sim", steps=5)
    with pytest.raises(observers.OptionError, match="basis must be one of 'min-volume'"):
        observers.create("ROPO", sc.system, basis="volume")
    with pytest.raises(observers.OptionError, match="unknown option"):
        observers.create("ROPO", sc.system, order=100)
    nl = systems.scenario("tank6-nonlinear-cora")
    with pytest.raises(observers.errors.Unsupported, match="ROPO needs a system with attrib"):
        observers.create("ROPO", nl.system)


def test_generator_axes_hand_example():
    # A T = [[1, 1], [0, 0.1]] (a thin parallelogram), E = (0, 1)'.  Parallelotopes whose axes
    # are two of the three generators g1 = (1, 0), g2 = (1, 0.1), e = (0, 1) (|det T| =
    # |det B| prod_i sum_k |(B^-1 G)_ik|): {g1, g2}: B^-1 e = (-10, 10), 0.1 * 11 * 11 = 12.1;
    # {g1, e}: the box (2, 1.1), 2.2; {g2, e}: B^-1 g1 = (1, -0.1) (axes g2, e), r = (2, 1.1),
    # 1 * 2 * 1.1 = 2.2.  The exchange from A T reaches the least, 2.2.
    AT = np.array([[1.0, 1.0], [0.0, 0.1]])
    _, T = time_update(np.zeros(2), np.eye(2), AT, np.zeros(2), np.array([[0.0], [1.0]]),
                       "generators")
    assert abs(np.linalg.det(T)) == pytest.approx(2.2, rel=1e-12)
    corners = np.array([a * AT[:, 0] + b * AT[:, 1] + [0.0, e] for a in (-1, 1)
                        for b in (-1, 1) for e in (-1, 1)])
    assert _inside(np.zeros(2), T, corners)
    # the shear example above: every exchange is a tie or worse (volumes 1.32, 2.52, 2.31
    # against 1.32 for A diag(1.2, 1.1), in units of 4), so the generators keep A T
    _, T = time_update(np.zeros(2), np.eye(2), A_SHEAR, np.zeros(2), 0.1 * np.eye(2),
                       "generators")
    np.testing.assert_allclose(T, [[1.2, 1.1], [0.0, 1.1]], rtol=1e-13)


def test_near_ties_keep_the_first_candidate():
    # a relative difference of 1e-12 is a tie (TIE_RTOL = 1e-9): the first index wins
    from observers.numerics.linalg import first_best
    assert first_best(np.array([1.0 + 1e-12, 1.0, 2.0])) == 0
    assert first_best(np.array([1.0 + 1e-6, 1.0, 2.0])) == 1
    # the corner triangle above with a strip 1e-13 narrower: still the box (a near-tie)
    c, T = strip_cut(np.zeros(2), np.eye(2), np.array([1.0, 1.0]), 1.5 + 1e-13, 2.0)
    assert np.count_nonzero(T) == 2


def test_min_volume_skips_ill_conditioned_axes():
    # the zonotope with generators g1 = (1, 0), g2 = (1, 0.001) is itself a parallelotope:
    # the generator axes enclose it exactly (volume |det G| * 4 = 0.004) but their
    # column-normalised condition number is about 2 / 0.001 = 2000 > 100, so "min-volume"
    # must take the principal or coordinate axes; the box is diag(|1|+|1|, 0.001) = diag(2,
    # 0.001) (volume 4 * 0.002 = 0.008), the principal axes can only be as small or smaller
    G = np.array([[1.0, 1.0], [0.0, 0.001]])
    exact = enclose(G, "generators", G)
    np.testing.assert_allclose(np.abs(np.linalg.det(exact)), 0.001, rtol=1e-9)
    T = enclose(G, "min-volume", G)
    Tn = T / np.linalg.norm(T, axis=0)
    assert np.linalg.cond(Tn) <= 100
    assert np.abs(np.linalg.det(T)) <= 0.002 * (1 + 1e-9)
    corners = np.array([s1 * G[:, 0] + s2 * G[:, 1] for s1 in (-1, 1) for s2 in (-1, 1)])
    assert _inside(np.zeros(2), T, corners)


def test_ropo_tank6_radii_stay_near_the_published_smallest():
    # bug: least volume alone kept parallelotopes of condition 1e10 on the 6-tank record and
    # the unmeasured x6 reached an RMS radius of 1e7; with the conditioning bound of
    # "min-volume" every state stays within 2x the smallest RMS radius of ARCH 2021 Table 3
    # (0.3596, 0.2036, 1.940, 0.2019, 0.2004, 2.737)
    smallest = np.array(paper_table("arch2021_table3_tank6_linear")["smallest_absolute_radii"])
    sc = systems.scenario("tank6-linear")
    res = observers.run(observers.create("ROPO", sc.system), sc.u, sc.y)
    rms = np.sqrt(np.mean(res.radius**2, axis=0))
    assert np.all(rms < 2 * smallest), rms / smallest


# -- the compiled shortlist of the generator-axes search (issue 38) -----------------------------
def _direct_exchange_scores(M, out):
    """log volume after the pivot on (i, k) for every generator k of ``out`` and row i, as
    the definition: the tableau pivoted, its row sums' logarithms summed, plus log |M_ik|."""
    n = M.shape[0]
    S = np.full((out.size, n), np.inf)
    for kk, k in enumerate(out):
        for i in range(n):
            if M[i, k] == 0.0:
                continue
            with np.errstate(all="ignore"):  # a subnormal pivot overflows: not compared
                T = M - np.outer(M[:, k] / M[i, k], M[i])
                T[i] = M[i] / M[i, k]
                S[kk, i] = np.log(abs(M[i, k])) + np.log(np.abs(T).sum(axis=1)).sum()
    return S


@pytest.mark.parametrize("seed", range(4))
def test_exchange_scores_are_within_their_error_bounds(seed):
    """The compiled approximate scores (sorted breakpoints and prefix sums) are within their
    stated bounds of the pivoted tableau's scores, for tableaux with the axes as an identity
    block, repeated generators (tied breakpoints), zero and subnormal entries (a subnormal
    pivot-row entry made every pair of its row unbounded on the 200-tank record, and every
    exchange was scored directly)."""
    from observers.kernels import exchange, switch

    if not switch.AVAILABLE:
        pytest.skip("numba not available")
    rng = np.random.default_rng(seed)
    n, r = 7, 20
    M = np.hstack([np.eye(n), rng.normal(size=(n, r - n))])
    M[:, -1] = M[:, -2]  # a repeated generator: tied breakpoints
    M[2, -3] = 0.0
    M[3, 0] = 5e-320  # subnormal: its breakpoint would be infinite (bug at 200 tanks)
    M[4, -5] = 5e-320  # a subnormal pivot: that pair has no bound (scored directly)
    out = np.arange(n, r)
    ok = M[:, out].T != 0.0
    approx, err = exchange.exchange_scores(M, out.astype(np.int64), ok)
    direct = _direct_exchange_scores(M, out)
    unbounded = np.zeros_like(ok)
    unbounded[r - 5 - n, 4] = True
    assert np.isnan(approx[unbounded]).all()
    known = ok & ~unbounded
    assert np.array_equal(np.isfinite(approx), known)  # every other pair has a bound
    assert np.all(np.abs(approx[known] - direct[known]) <= err[known])
    assert np.all(err[known] < 1e-10)  # and the bounds are tight enough to shortlist


@pytest.mark.parametrize("seed", range(3))
def test_exchange_scores_bound_rounding_entries_left_out_of_the_breakpoints(seed):
    """After some exchanges the identity block of the tableau carries rounding entries
    (about 1e-17) in every row; at most NEGLIGIBLE of the row's 1-norm they are left out of
    the breakpoints and their share |t M_ij| is inside the bound, also for large pivot
    ratios t; entries just above the threshold stay breakpoints."""
    from observers.kernels import exchange, switch

    if not switch.AVAILABLE:
        pytest.skip("numba not available")
    rng = np.random.default_rng(40 + seed)
    n, r = 8, 24
    M = np.hstack([np.eye(n) + 1e-17 * rng.normal(size=(n, n)), rng.normal(size=(n, r - n))])
    M[:, n] *= 1e-6  # small pivots: pivot ratios t of about 1e6 on that generator
    row = np.abs(M).sum(axis=1)
    M[1, 2] = exchange.NEGLIGIBLE * row[1]  # at the threshold: left out
    M[2, 3] = 4.0 * exchange.NEGLIGIBLE * row[2]  # above it: a breakpoint
    out = np.arange(n, r)
    ok = M[:, out].T != 0.0
    approx, err = exchange.exchange_scores(M, out.astype(np.int64), ok)
    direct = _direct_exchange_scores(M, out)
    assert np.isfinite(approx[ok]).all()
    assert np.all(np.abs(approx[ok] - direct[ok]) <= err[ok])
    assert np.all(err[ok] < 1e-8)


@pytest.mark.parametrize("seed", range(3))
def test_generator_axes_with_the_shortlist_are_those_of_the_direct_scoring(seed):
    """The shortlist changes which exchanges are scored directly, never the axes chosen: the
    same axes (bits) with the compiled shortlist and with every exchange scored, on sets
    large enough for the shortlist, including exact ties (repeated generators)."""
    from observers.kernels import switch
    from observers.numerics.ropo import SHORTLIST_MIN_WORK, generator_axes

    if not switch.AVAILABLE:
        pytest.skip("numba not available")
    rng = np.random.default_rng(seed)
    n = 16
    G = rng.normal(size=(n, 3 * n))
    G[:, 2 * n:2 * n + 4] = G[:, n:n + 4]  # exact ties
    assert (2 * n) * n * n * (3 * n) >= SHORTLIST_MIN_WORK
    old = switch.set_compiled(True)
    try:
        fast = generator_axes(G, n)
        switch.set_compiled(False)
        slow = generator_axes(G, n)
    finally:
        switch.set_compiled(old)
    np.testing.assert_array_equal(fast, slow)
    assert not np.array_equal(fast, G[:, :n])  # the search did exchange axes


@pytest.mark.parametrize("order", [(0, 1, 2), (0, 2, 1)])
def test_generator_axes_refuse_a_numerically_singular_start_in_any_column_order(order):
    """Two starting columns parallel in exact arithmetic (one 1e-5 times the other, the
    rounding of A T): refused whatever the order, not only where LU meets an exact zero."""
    from observers.numerics.ropo import generator_axes

    v = np.array([5.06e-4, 0.4915, -3.37e-3])
    start = np.column_stack([[1e-3, 0.0, 0.0], v, v * 1.5e-5 * (1.0 + 1e-15)])
    G = np.hstack([start[:, list(order)], np.diag([1e-4, 5e-2, 1e-3])])
    assert generator_axes(G, 3) is None


def test_generator_axes_come_in_the_order_of_their_generators():
    from observers.numerics.ropo import generator_axes

    rng = np.random.default_rng(3)
    G = rng.normal(size=(4, 12))
    B = generator_axes(G, 4)
    cols = [int(np.flatnonzero(np.all(G == B[:, [j]], axis=0))[0]) for j in range(4)]
    assert cols == sorted(cols)


def test_only_a_strip_that_touches_a_face_is_widened():
    # Widening every strip by its rounding slack moved near-tied least-volume choices on 30
    # tanks differently under each BLAS kernel; a strip through the interior is kept as it is,
    # one within the slack of a face q'xi = +-s is widened by the slack on both sides.
    from observers.numerics.ropo import touching_faces

    assert touching_faces(-0.5, 0.5, 2.0, 1e-12) == (-0.5, 0.5)
    assert touching_faces(1.5, 2.5, 2.0, 1e-12) == (1.5, 2.5)  # crosses the face: a real cut
    assert touching_faces(2.0, 3.0, 2.0, 1e-12) == (2.0 - 1e-12, 3.0 + 1e-12)
    assert touching_faces(-3.0, -2.0 + 5e-13, 2.0, 1e-12) == (-3.0 - 1e-12, -2.0 + 5e-13 + 1e-12)
