"""The batched dual simplex of the constrained-zonotope hulls (observers.lp.dual_simplex):
its bounds are never below the true maximum (sampled feasible points) and never looser than
HiGHS's dual bounds, on random and degenerate sets, by its numpy and its compiled (numba)
iterations, which agree with each other; empty sets and sets without constraints."""

from __future__ import annotations

import os
import subprocess
import sys
import time

import numpy as np
import pytest
from scipy.optimize import linprog

import observers
import systems
from observers.lp import dual_simplex as ds
from observers.lp import dual_simplex_jit
from observers.lp.hull import dual_bounds
from observers.sets import ConZonotope, HullLP, SetError

needs_numba = pytest.mark.skipif(not dual_simplex_jit.AVAILABLE,
                                 reason="numba not installed or disabled")


def _feasible(A: np.ndarray, xi0: np.ndarray, k: int, g: np.random.Generator) -> np.ndarray:
    """``k`` feasible points: ``xi0`` moved along null-space directions of ``A`` up to the box
    (and ``xi0`` itself)."""
    N = np.linalg.svd(A)[2][np.linalg.matrix_rank(A):].T
    pts = [xi0]
    for _ in range(k):
        step = N @ g.normal(size=N.shape[1])
        with np.errstate(divide="ignore"):
            t = np.max(np.where(step > 0, step / (1 - xi0), -step / (1 + xi0)))
        pts.append(xi0 + step / t * g.choice([1.0, g.uniform(0, 1)]) if t > 0 else xi0)
    return np.array(pts)


def _instance(kind: str, seed: int):
    """``(A, b, Gd, xi0)``: constraints, 2n cost rows, a feasible point."""
    g = np.random.default_rng(seed)
    n, r, nc = 3, 24, 5
    A = g.normal(size=(nc, r))
    G = g.normal(size=(n, r)) * np.exp(g.uniform(-8, 0, r))  # magnitudes over 3 decades
    xi0 = g.uniform(-0.7, 0.7, r)
    if kind == "rank-deficient":  # redundant rows: copies and combinations of others
        A[3] = A[0]
        A[4] = 2.0 * A[1] - A[2]
    elif kind == "degenerate":  # costs in the row space of A, zero and repeated columns
        G[0] = 0.5 * A[0] - A[2]
        G[:, :4] = 0.0
        A[:, 4:8] = A[:, 8:12]
        G[:, 4:8] = G[:, 8:12]
    elif kind == "boundary":  # the feasible set touches the box (xi0 at vertices)
        xi0[: r // 2] = np.sign(g.normal(size=r // 2))
    elif kind == "unit-columns":  # measurement-like rows with their own noise generators
        A[:, r - nc:] = 0.1 * np.eye(nc)
        G[:, r - nc:] = 0.0
    b = A @ xi0
    return A, b, np.vstack([G, -G]), xi0


KINDS = ["generic", "rank-deficient", "degenerate", "boundary", "unit-columns"]
PATHS = [pytest.param(True, id="compiled", marks=needs_numba), pytest.param(False, id="numpy")]


@pytest.fixture(params=PATHS)
def compiled(request):
    """Run the test with the compiled and with the numpy iterations."""
    old = ds.set_compiled(request.param)
    yield request.param
    ds.set_compiled(old)


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("seed", range(4))
def test_batched_bounds_are_sound_and_as_tight_as_highs(kind, seed, compiled):
    assert ds.use_compiled() == compiled
    A, b, Gd, xi0 = _instance(kind, seed)
    batched, highs = HullLP("batched"), HullLP("highs")
    ub = batched.maximize_many(Gd, A, b)
    ub_highs = highs.maximize_many(Gd, A, b)
    pts = _feasible(A, xi0, 300, np.random.default_rng(seed))
    assert np.all(np.abs(pts @ A.T - b) < 1e-9) and np.all(np.abs(pts) <= 1 + 1e-12)
    assert np.all(ub >= (pts @ Gd.T).max(axis=0))  # no feasible point beyond the bound
    for k, g in enumerate(Gd):  # tight: the exact maximum (independent LP, primal value)
        res = linprog(-g, A_eq=A, b_eq=b, bounds=(-1, 1), method="highs")
        assert res.status == 0
        assert ub[k] - (-res.fun) <= 1e-7 * (1 + abs(res.fun))
    # never looser than HiGHS's dual points (relative 1e-9)
    assert np.all(ub <= ub_highs + 1e-9 * (1 + np.abs(ub_highs)))
    if kind in ("generic", "boundary", "unit-columns"):
        assert batched.fallbacks == 0  # solved by the batched dual simplex itself


def _both_paths(A, b, Gd, max_iter=None):
    """Results of the numpy and of the compiled iterations (and the setting restored)."""
    old = ds.set_compiled(False)
    try:
        ref = ds.solve(A, b, Gd, max_iter)
        ds.set_compiled(True)
        assert ds.use_compiled()
        return ref, ds.solve(A, b, Gd, max_iter)
    finally:
        ds.set_compiled(old)


def _assert_same_bounds(A, b, Gd, ref, fast):
    u0, u1 = dual_bounds(Gd, A, b, ref.mu), dual_bounds(Gd, A, b, fast.mu)
    np.testing.assert_allclose(u1, u0, rtol=1e-12, atol=1e-12 * np.abs(u0).max())
    assert np.array_equal(ref.converged, fast.converged)


@needs_numba
@pytest.mark.parametrize("kind", KINDS)
def test_compiled_iterations_give_the_numpy_bounds(kind):
    for seed in range(6):
        A, b, Gd, _ = _instance(kind, seed)
        ref, fast = _both_paths(A, b, Gd)
        _assert_same_bounds(A, b, Gd, ref, fast)
        # same pivoting rules: the same work up to ties decided by rounding
        assert abs(fast.problem_iterations - ref.problem_iterations) <= 2


@needs_numba
def test_compiled_iterations_give_the_numpy_bounds_on_czn_observer_sets():
    # the sets whose hulls the CZN observers report (6-state vehicle, 2 m constraints,
    # hundreds of generators), including a pause for refactorisation and a budget stop
    sc = systems.scenario("vehicle6d-cora")
    obs = observers.create("CZN-A", sc.system, **sc.options)
    res = observers.run(obs, sc.u[:40], sc.y[:40])
    assert res.status == "ok"
    for S in res.sets[::6]:
        _, G, A, b = S.arrays()
        Gd = np.vstack([G, -G])
        ref, fast = _both_paths(A, b, Gd)
        _assert_same_bounds(A, b, Gd, ref, fast)
    saved = ds.REFACTOR_EVERY
    try:  # refactorise after every 2 pivots: the kernel pauses for numpy's refactorisation
        ds.REFACTOR_EVERY = 2
        ref, fast = _both_paths(A, b, Gd)
    finally:
        ds.REFACTOR_EVERY = saved
    _assert_same_bounds(A, b, Gd, ref, fast)
    # an iteration budget too small: both paths report the same unfinished LPs
    ref, fast = _both_paths(A, b, Gd, max_iter=2)
    assert not ref.converged.all() and np.array_equal(ref.converged, fast.converged)


def test_numba_can_be_disabled_by_the_environment():
    code = "from observers.lp import dual_simplex as d; print(d.use_compiled())"
    env = dict(os.environ, SETOBS_NUMBA="0")
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True,
                         check=True)
    assert out.stdout.strip() == "False"


def test_solver_result_reports_optimality_and_work():
    A, b, Gd, _ = _instance("generic", 11)
    res = ds.solve(A, b, Gd)
    assert res.converged.all() and res.mu.shape == (Gd.shape[0], A.shape[0])
    assert res.problem_iterations >= Gd.shape[0]  # every LP needed at least one pivot
    assert ds.solve(A, b, Gd, max_iter=1).converged.sum() < Gd.shape[0]  # budget respected


def test_hulls_of_random_sets_match_highs():
    g = np.random.default_rng(5)
    for _ in range(4):
        A = g.normal(size=(4, 15))
        S = ConZonotope(g.normal(size=2), g.normal(size=(2, 15)), A, A @ g.uniform(-.5, .5, 15))
        fast, slow = S.with_solver(HullLP("batched")).interval(), S.with_solver(
            HullLP("highs")).interval()
        np.testing.assert_allclose(fast.lo, slow.lo, rtol=0, atol=1e-8)
        np.testing.assert_allclose(fast.hi, slow.hi, rtol=0, atol=1e-8)
        d = g.normal(size=(2, 3))
        np.testing.assert_allclose(S.support(d), S.with_solver(HullLP("highs")).support(d),
                                   atol=1e-8)


def test_empty_sets_and_sets_without_constraints():
    A = np.array([[1.0, 1.0, 0.0], [1.0, -1.0, 0.0]])
    with pytest.raises(SetError, match="empty"):  # xi1 + xi2 = 2.5 is outside the box
        HullLP().maximize_many(np.eye(3), A, np.array([2.5, 0.0]))
    with pytest.raises(SetError, match="empty"):  # constraints on no generator: 0 = 1
        ConZonotope([0.0], [[1.0, 2.0]], np.zeros((1, 2)), [1.0]).interval()
    # 0 = 0 on no generator: the zonotope itself
    S = ConZonotope([0.0], [[1.0, 2.0]], np.zeros((1, 2)), [0.0])
    np.testing.assert_allclose(S.interval().hi, [3.0])
    Z = ConZonotope([1.0, 0.0], [[1.0, 0.5], [0.0, 2.0]])  # no constraints at all
    np.testing.assert_allclose(Z.interval().lo, [-0.5, -2.0])
    assert HullLP().maximize_many(np.array([[1.0, -2.0]]), np.zeros((0, 2)), np.zeros(0)
                                  )[0] == pytest.approx(3.0)
    with pytest.raises(SetError, match="unknown LP solver"):
        HullLP("simplex")


def test_unfinished_lps_fall_back_to_highs(monkeypatch):
    A, b, Gd, _ = _instance("generic", 3)
    exact = HullLP("highs").maximize_many(Gd, A, b)
    monkeypatch.setattr(ds, "max_iterations", lambda p: 2)  # too few pivots for most LPs
    lp = HullLP("batched")
    ub = lp.maximize_many(Gd, A, b)
    assert lp.fallbacks > 0
    assert np.all(ub <= exact)  # the better of two valid bounds
    for k, g in enumerate(Gd):
        res = linprog(-g, A_eq=A, b_eq=b, bounds=(-1, 1), method="highs")
        assert -res.fun - 1e-7 <= ub[k] <= -res.fun + 1e-7


def test_solver_choice_follows_the_cost_model():
    from observers.lp.hull import batched_is_cheaper
    assert batched_is_cheaper(12, 8)  # interval hull of the 6-state vehicle, 2 m constraints
    assert not batched_is_cheaper(4, 100)  # 2-state vehicle with all of CORA's constraints
    assert batched_is_cheaper(36, 22)  # 18 tanks (measured: 4x faster than HiGHS)
    assert not batched_is_cheaper(200, 160)  # 100 tanks (measured: 30x slower than HiGHS)
    # 30 and 44 tanks over long records (HiGHS's warm starts degrade; measured 9x and 8x)
    assert batched_is_cheaper(60, 42)
    assert batched_is_cheaper(88, 66)


def test_phase_seconds_are_exclusive_and_add_up_to_at_most_the_solve():
    # a refactorisation inside the pivots counts as "refactor" only (never twice)
    A, b, Gd, _ = _instance("generic", 0)
    t0 = time.perf_counter()
    res = ds.solve(A, b, Gd)
    elapsed = time.perf_counter() - t0
    assert set(res.seconds) >= {"setup", "pivots", "refactor", "certify"}
    assert all(s >= 0.0 for s in res.seconds.values())
    assert sum(res.seconds.values()) <= elapsed
    clock = ds.Clock()
    t0 = time.perf_counter()
    with clock.phase("outer"):
        time.sleep(0.01)
        with clock.phase("inner"):
            time.sleep(0.02)
    total = time.perf_counter() - t0
    inner, outer = clock.seconds["inner"], clock.seconds["outer"]
    assert inner >= 0.02 and outer >= 0.01 and outer + inner <= total
