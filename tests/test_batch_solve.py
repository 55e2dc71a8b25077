"""The batched dual simplex as one compiled call (observers.lp.batch_solve_jit), paired with
the numpy-driven solve of observers.lp.dual_simplex: the same bounds (both made sound from
their dual points by weak duality) and the same problems finished, on random and degenerate
sets, on the hulls the observers compute, with pauses for refactorisation and a budget stop;
and the bounds never below the true maximum."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import linprog

import observers
import systems
from observers.lp import batch_solve_jit as bs
from observers.lp import dual_simplex as ds
from observers.lp import dual_simplex_jit
from observers.lp.hull import dual_bounds

from .test_dual_simplex import KINDS, _feasible, _instance

pytestmark = pytest.mark.skipif(not dual_simplex_jit.AVAILABLE,
                                reason="numba not installed or disabled")


def _pair(A, b, Gd, **kw):
    """The bounds of both solvers from their dual points, and both results."""
    ref, fast = ds.solve(A, b, Gd, kw.get("max_iter")), bs.solve(A, b, Gd, **kw)
    return dual_bounds(Gd, A, b, ref.mu), dual_bounds(Gd, A, b, fast.mu), ref, fast


def _assert_same(A, b, Gd, **kw):
    u0, u1, ref, fast = _pair(A, b, Gd, **kw)
    assert np.array_equal(ref.converged, fast.converged)
    done = ref.converged
    scale = np.abs(Gd).sum(axis=1).max() + np.abs(b).max(initial=0.0) + 1.0
    np.testing.assert_allclose(u1[done], u0[done], rtol=0, atol=1e-9 * scale)
    return u1, fast


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("seed", range(4))
def test_one_call_gives_the_bounds_of_the_numpy_driven_solve(kind, seed):
    A, b, Gd, xi0 = _instance(kind, seed)
    ub, fast = _assert_same(A, b, Gd)
    pts = _feasible(A, xi0, 300, np.random.default_rng(seed))
    assert np.all(ub >= (pts @ Gd.T).max(axis=0))  # no feasible point beyond a bound
    for k, g in enumerate(Gd):  # and tight where it finished: the exact maximum
        if fast.converged[k]:
            res = linprog(-g, A_eq=A, b_eq=b, bounds=(-1, 1), method="highs")
            assert ub[k] - (-res.fun) <= 1e-7 * (1 + abs(res.fun))


def _observer_hulls(scenario: str, name: str, steps: int, **options) -> list[tuple]:
    """The hull LPs ``(A, b, Gd)`` an observer solves over the first steps of a record."""
    seen = []
    solve = bs.solve

    hull = bs.hull

    def spy(A, b, Gd, *args, **kwargs):
        seen.append((np.array(A), np.array(b), np.array(Gd)))
        return solve(A, b, Gd, *args, **kwargs)

    def spy_hull(G, A, b, *args, **kwargs):  # the LPs of the hull: its constrained columns
        coupled = np.any(A != 0.0, axis=0)
        seen.append((np.array(A[:, coupled]), np.array(b),
                     np.vstack([G[:, coupled], -G[:, coupled]])))
        return hull(G, A, b, *args, **kwargs)

    sc = systems.scenario(scenario)
    bs.solve, bs.hull = spy, spy_hull  # the hulls call them where the kernels are compiled
    try:
        res = observers.run(observers.create(name, sc.system, **options), sc.u[:steps],
                            sc.y[:steps + 1])
    finally:
        bs.solve, bs.hull = solve, hull
    assert res.status == "ok" and seen
    return seen


@pytest.mark.parametrize(("scenario", "name", "options"), [
    ("vehicle6d-cora", "CZN-A", {"order": 100, "max_constraints": 4}),
    ("tank6-linear", "MHE", {"window": 5}),
    ("tank6-linear", "CZN-B", {}),
])
def test_one_call_gives_the_bounds_of_the_numpy_driven_solve_on_observer_hulls(
        scenario, name, options):
    hulls = _observer_hulls(scenario, name, 30, **options)
    for A, b, Gd in hulls[::3]:
        _assert_same(A, b, Gd)
    A, b, Gd = hulls[-1]
    # a pause for refactorisation after every 2 pivots: the same bounds
    ref = ds.REFACTOR_EVERY
    try:
        ds.REFACTOR_EVERY = 2  # read by both at the call
        _assert_same(A, b, Gd)
    finally:
        ds.REFACTOR_EVERY = ref
    # a budget too small: the same unfinished problems
    _, fast = _assert_same(A, b, Gd, max_iter=1)
    assert not fast.converged.all()


def test_an_empty_set_finishes_no_problem_and_no_rows_finish_all():
    A = np.array([[1.0, 1.0, 0.0], [1.0, -1.0, 0.0]])  # xi1 + xi2 = 2.5: outside the box
    res = bs.solve(A, np.array([2.5, 0.0]), np.eye(3))
    assert not res.converged.any()
    res = bs.solve(np.zeros((0, 3)), np.zeros(0), np.eye(3))
    assert res.converged.all() and res.mu.shape == (3, 0)


def test_the_crash_basis_is_the_numpy_paths():
    for kind in KINDS:
        A, _, _, _ = _instance(kind, 1)
        p, r = A.shape
        M = np.hstack([A, np.eye(p)])
        colnorm = np.sqrt((M * M).sum(axis=0))
        basis, Binv = ds.crash_basis(M, colnorm)
        basis_c, Binv_c = bs._crash(M, colnorm, r)
        assert np.array_equal(basis, basis_c), kind
        np.testing.assert_allclose(Binv_c, Binv, rtol=0, atol=1e-12 * np.abs(Binv).max())


def test_hulls_take_the_one_call_solve_where_the_kernels_are_compiled(monkeypatch):
    A, b, Gd, _ = _instance("generic", 2)
    calls = []
    solve = bs.solve
    monkeypatch.setattr(bs, "solve", lambda *a, **k: calls.append(1) or solve(*a, **k))
    from observers.sets import HullLP

    ub = HullLP("batched").maximize_many(Gd, A, b)
    assert calls == [1]
    old = ds.set_compiled(False)
    try:  # the numpy-driven solve otherwise: the same bounds
        np.testing.assert_allclose(HullLP("batched").maximize_many(Gd, A, b), ub, rtol=0,
                                   atol=1e-9 * np.abs(ub).max())
    finally:
        ds.set_compiled(old)
    assert calls == [1]


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("seed", range(4))
def test_the_bounds_evaluated_in_the_call_are_those_of_its_dual_points(kind, seed):
    """The one call evaluates the weak-duality bounds of its dual points itself (``bounds``,
    summed in index order): the bound :func:`dual_bounds` gives for the same points, up to
    the rounding both slacks cover, also for the problems re-solved in the clean-up."""
    A, b, Gd, _ = _instance(kind, seed)
    res = bs.solve(A, b, Gd)
    ref = dual_bounds(Gd, A, b, res.mu)
    p, r = A.shape
    rounding = (p + r + 4) * np.finfo(float).eps * (
        np.abs(res.mu) @ np.abs(b) + np.abs(Gd).sum(axis=1)
        + np.abs(res.mu) @ np.abs(A).sum(axis=1) + np.abs(ref))
    assert res.bounds is not None and res.bounds.shape == (Gd.shape[0],)
    assert np.all(np.abs(res.bounds - ref) <= 2 * rounding)


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("seed", range(3))
def test_the_hull_call_solves_the_lps_of_the_constrained_columns(kind, seed):
    """:func:`bs.hull` (split, perturb, solve and bound in one call) gives the bits of
    :func:`bs.solve` on the constrained columns with the costs ``[Gc; -Gc]``, and the free
    columns' radii; here with three columns in no constraint put among the others."""
    A, b, Gd, _ = _instance(kind, seed)
    rng = np.random.default_rng(seed)
    r = A.shape[1]
    G = rng.standard_normal((3, r + 3))
    free = np.sort(rng.choice(r + 3, 3, replace=False))
    cols = np.setdiff1d(np.arange(r + 3), free)
    Afull = np.zeros((A.shape[0], r + 3))
    Afull[:, cols] = A
    res = bs.hull(G, Afull, b)
    ref = bs.solve(A, b, np.vstack([G[:, cols], -G[:, cols]]))
    assert np.array_equal(res.cols, cols) and res.free == 3
    assert np.array_equal(res.bounds, ref.bounds)
    assert np.array_equal(res.converged, ref.converged)
    np.testing.assert_array_equal(res.rad_free, np.abs(G[:, free]).sum(axis=1))


def test_hull_lp_hull_hands_the_unfinished_lps_to_highs_and_takes_no_constraint(monkeypatch):
    """:meth:`HullLP.hull` with a budget of one pivot: the LPs left unfinished go to HiGHS
    (counted as fallbacks) and the hull is the one HiGHS gives for every LP, within HiGHS's
    tolerance; with no constraint row, the box of the generators."""
    from observers.lp.hull import HullLP

    A, b, Gd, _ = _instance("generic", 1)
    G = Gd[: Gd.shape[0] // 2]
    c = np.arange(G.shape[0], dtype=float)
    lo_ref, hi_ref = HullLP("highs").hull(c, G, A, b)
    monkeypatch.setattr(ds, "max_iterations", lambda p: 1)
    lp = HullLP("batched")
    lo, hi = lp.hull(c, G, A, b)
    assert lp.fallbacks > 0
    scale = np.abs(G).sum(axis=1)
    assert np.all(np.abs(lo - lo_ref) <= 1e-7 * scale)
    assert np.all(np.abs(hi - hi_ref) <= 1e-7 * scale)
    lo0, hi0 = HullLP("batched").hull(c, G, np.zeros((0, G.shape[1])), np.zeros(0))
    assert np.all(hi0 >= c + scale) and np.all(lo0 <= c - scale)
    np.testing.assert_allclose(hi0 - lo0, 2 * scale, rtol=1e-13)
