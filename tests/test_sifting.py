"""Sifting for the hull LPs with many columns, its restricted LPs by the compiled dual simplex
(observers.lp.sifting_jit, HullLP(solver="sifting")) or by HiGHS (observers.lp.sifting,
HullLP(solver="sifting-highs")): on random constrained zonotopes with many columns and few
rows (with zero, parallel and duplicate columns, degenerate costs) the bounds equal the plain
HiGHS hull's to 1e-9 of the radius and are never below the true maximum (scipy's linprog on
the same LP); working sets too small to finish still give sound bounds; empty sets raise
EmptySet; HullLP("auto") routes many-column LPs through it.  The compiled kernels and the
same functions run as plain Python give the same bounds; refactorisations and full working
sets keep them."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import linprog

from observers.errors import EmptySet
from observers.lp import dual_simplex, dual_simplex_jit, sifting, sifting_jit
from observers.lp.hull import SIFTING_MIN_COLUMNS, HullLP, dual_bounds, sifting_is_cheaper


def _instance(kind: str, seed: int, r: int = 600, nc: int = 8, n: int = 4):
    """``(A, b, Gd)``: constraints with a feasible point inside the box and 2n cost rows."""
    g = np.random.default_rng(seed)
    A = g.normal(size=(nc, r)) * np.exp(g.uniform(-6, 0, r))  # column sizes over 2.6 decades
    G = g.normal(size=(n, r)) * np.exp(g.uniform(-6, 0, r))
    xi0 = g.uniform(-0.8, 0.8, r)
    if kind == "zero-columns":  # generators in no constraint (closed form)
        A[:, : r // 3] = 0.0
    elif kind == "parallel":  # duplicate and parallel columns, costs in A's row space
        A[:, 10:110] = A[:, 110:210]
        G[:, 10:110] = G[:, 110:210]
        A[:, 210:260] = -2.0 * A[:, 260:310]
        G[:, 210:260] = -2.0 * G[:, 260:310]
        G[0] = A[0] - 0.5 * A[3]
    elif kind == "boundary":  # the feasible set touches the box
        xi0[: r // 2] = np.sign(g.normal(size=r // 2))
    elif kind == "unit-columns":  # measurement-like rows with their own noise generators
        A[:, r - nc:] = 0.05 * np.eye(nc)
        G[:, r - nc:] = 0.0
    return A, A @ xi0, np.vstack([G, -G])


def _true_max(g: np.ndarray, A: np.ndarray, b: np.ndarray) -> float:
    res = linprog(-g, A_eq=A, b_eq=b, bounds=(-1, 1), method="highs")
    assert res.status == 0
    return -res.fun


KINDS = ["generic", "zero-columns", "parallel", "boundary", "unit-columns"]


SOLVERS = ["sifting", "sifting-highs"]


def _small_steps(monkeypatch, first=1, add=4, rounds=200):
    """Small first working sets and additions for both sifting solvers: several rounds of
    sifting per LP."""
    for module in (sifting, sifting_jit):
        monkeypatch.setattr(module, "FIRST", first)
        monkeypatch.setattr(module, "ADD", add)
        monkeypatch.setattr(module, "MAX_ROUNDS", rounds)


@pytest.mark.parametrize("solver", SOLVERS)
@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("seed", range(3))
def test_sifting_hull_equals_plain_hull_and_is_sound(solver, kind, seed, monkeypatch):
    _small_steps(monkeypatch)
    A, b, Gd = _instance(kind, seed)
    sift = HullLP(solver)
    ub = sift.maximize_many(Gd, A, b)
    plain = HullLP("highs").maximize_many(Gd, A, b)
    radius = np.abs(Gd).sum(axis=1)
    assert sift.stats.fallbacks == 0
    assert "pricing" in sift.stats.seconds  # the sifting path ran
    np.testing.assert_array_less(np.abs(ub - plain), 1e-9 * radius)
    for k in range(Gd.shape[0]):
        assert ub[k] >= _true_max(Gd[k], A, b) - 1e-9 * radius[k]


@pytest.mark.parametrize("module", [sifting, sifting_jit])
@pytest.mark.parametrize("seed", range(3))
def test_unfinished_working_sets_still_give_sound_bounds(module, seed):
    A, b, Gd = _instance("generic", seed)
    res = module.solve(A, b, Gd, max_rounds=1)
    ub = dual_bounds(Gd, A, b, res.mu)
    for k in range(Gd.shape[0]):
        assert ub[k] >= _true_max(Gd[k], A, b)  # any dual point bounds the maximum


@pytest.mark.parametrize("solver", SOLVERS)
def test_unconverged_problems_are_solved_by_highs(solver, monkeypatch):
    _small_steps(monkeypatch, 1, 1, 1)
    A, b, Gd = _instance("generic", 7)
    lp = HullLP(solver)
    ub = lp.maximize_many(Gd, A, b)
    assert lp.stats.fallbacks > 0
    plain = HullLP("highs").maximize_many(Gd, A, b)
    np.testing.assert_array_less(np.abs(ub - plain), 1e-9 * np.abs(Gd).sum(axis=1))


@pytest.mark.parametrize("solver", SOLVERS)
def test_sifting_reports_empty_sets(solver):
    g = np.random.default_rng(3)
    A = g.normal(size=(4, 300))
    b = A @ g.uniform(-1, 1, 300)
    A[3] = A[2]
    b[3] = b[2] + 1.0  # contradicting copies of a row
    with pytest.raises(EmptySet):
        HullLP(solver).maximize_many(g.normal(size=(6, 300)), A, b)
    with pytest.raises(EmptySet):  # no variable in any constraint: 0 = b
        HullLP(solver).maximize_many(g.normal(size=(6, 300)), np.zeros((2, 300)), np.ones(2))


@pytest.mark.parametrize("solver", SOLVERS)
def test_columns_in_no_constraint_count_in_closed_form(solver):
    A, b, Gd = _instance("zero-columns", 11)
    cols = sifting.constrained_columns(A)
    assert cols.size == A.shape[1] - A.shape[1] // 3
    ub = HullLP(solver).maximize_many(Gd, A, b)
    free = np.abs(Gd[:, : A.shape[1] // 3]).sum(axis=1)
    rest = HullLP("highs").maximize_many(Gd[:, cols], A[:, cols], b)
    np.testing.assert_array_less(np.abs(ub - (rest + free)), 1e-9 * np.abs(Gd).sum(axis=1))


def test_auto_routes_many_columns_to_sifting():
    assert sifting_is_cheaper(200, 160, 10240) and sifting_is_cheaper(400, 326, 20489)
    assert sifting_is_cheaper(60, 42, 3063, compiled=True)  # 30 tanks, steady (measured)
    assert not sifting_is_cheaper(60, 42, 3063, compiled=False)  # batched, without numba
    assert not sifting_is_cheaper(12, 8, 612)  # the vehicle: the batched dual simplex
    assert not sifting_is_cheaper(200, 160, 1260)  # 100 tanks, first steps: HiGHS
    assert not sifting_is_cheaper(200, 400, 4000)  # too few columns per row
    A, b, Gd = _instance("generic", 5, r=SIFTING_MIN_COLUMNS, nc=6, n=2)
    lp = HullLP("auto")
    ub = lp.maximize_many(Gd, A, b)
    assert "pricing" in lp.stats.seconds
    plain = HullLP("highs").maximize_many(Gd, A, b)
    np.testing.assert_array_less(np.abs(ub - plain), 1e-9 * np.abs(Gd).sum(axis=1))



@pytest.mark.parametrize("kind", KINDS)
def test_compiled_and_plain_python_kernels_give_the_same_bounds(kind, monkeypatch):
    # the same functions interpreted: the same method, BLAS's rounding aside
    _small_steps(monkeypatch, 2, 8)
    A, b, Gd = _instance(kind, 21, r=400, nc=6, n=3)
    compiled = sifting_jit.solve(A, b, Gd)
    old = dual_simplex.set_compiled(False)
    try:
        plain = sifting_jit.solve(A, b, Gd)
    finally:
        dual_simplex.set_compiled(old)
    assert compiled.converged.all() and plain.converged.all()
    radius = np.abs(Gd).sum(axis=1)
    np.testing.assert_array_less(
        np.abs(dual_bounds(Gd, A, b, compiled.mu) - dual_bounds(Gd, A, b, plain.mu)),
        1e-12 * radius)


def test_refactorisations_and_full_working_sets_keep_the_bounds(monkeypatch):
    A, b, Gd = _instance("generic", 4, r=1200, nc=24, n=4)
    plain = HullLP("highs").maximize_many(Gd, A, b)
    radius = np.abs(Gd).sum(axis=1)
    _small_steps(monkeypatch, 1, 24)
    monkeypatch.setattr(sifting_jit, "REFACTOR_EVERY", 3)  # the inverse rebuilt often
    lp = HullLP("sifting")
    np.testing.assert_array_less(np.abs(lp.maximize_many(Gd, A, b) - plain), 1e-9 * radius)
    assert lp.stats.fallbacks == 0
    # working sets that cannot hold what the LPs need: reported unfinished, solved by HiGHS
    monkeypatch.setattr(sifting_jit, "CAPACITY", 0)
    res = sifting_jit.solve(A, b, Gd)
    assert not res.converged.all() and res.columns <= 12 * A.shape[0]
    lp = HullLP("sifting")
    np.testing.assert_array_less(np.abs(lp.maximize_many(Gd, A, b) - plain), 1e-9 * radius)
    assert lp.stats.fallbacks > 0


def _keys(ratios: np.ndarray, mask: int) -> np.ndarray:
    """Ratio-test keys: the high bits of each (non-negative) ratio, its index in ``mask``."""
    bits = np.asarray(ratios, dtype=np.float64).view(np.uint64)
    return (bits & ~np.uint64(mask)) | np.arange(len(ratios), dtype=np.uint64)


@pytest.mark.parametrize("compiled", [True, False])
def test_the_breakpoint_pass_is_one_shared_function(compiled):
    # sifting's restricted LPs pass the breakpoints with the dual simplex's own pass (no heap
    # of their own), so both take the same pivots
    assert not hasattr(sifting_jit, "_sift_down")
    assert sifting_jit._pass_breakpoints is dual_simplex_jit._pass_breakpoints
    run = (dual_simplex_jit._pass_breakpoints if compiled
           else dual_simplex_jit._pass_breakpoints.py_func if dual_simplex_jit.AVAILABLE
           else dual_simplex_jit._pass_breakpoints)
    # by hand: ratios 3, 1, 2 (the order 1, 2, 0), w = 0.5, 1, 2 and delta = 2.5, so half the
    # slope is 1.25: column 1 is passed (1 < 1.25), column 2 enters (1 + 2 >= 1.25)
    w, flips = np.array([0.5, 1.0, 2.0]), np.full(3, -7, np.int64)
    q, passed = run(_keys(np.array([3.0, 1.0, 2.0]), 3), 3, np.uint64(3), w, 2.5, flips)
    assert (q, passed, flips[0]) == (2, 1, 1)
    # delta = 8 (half: 4 > 0.5 + 1 + 2): every breakpoint is passed, none enters
    q, passed = run(_keys(np.array([3.0, 1.0, 2.0]), 3), 3, np.uint64(3), w, 8.0, flips)
    assert (q, passed, list(flips)) == (-1, 3, [1, 2, 0])
    # equal ratios: the lower index first (the index is the key's low bits)
    q, passed = run(_keys(np.array([1.0, 1.0, 1.0]), 3), 3, np.uint64(3), w, 2.0, flips)
    assert (q, passed, flips[0]) == (1, 1, 0)


def test_first_working_sets_take_the_largest_gap_terms_ties_to_the_lower_column():
    # one constraint sum(xi) = 0, start cost (5, 1, 4, 2, 0): the start vertex is
    # xi0 = (1, -1, 1, 0, -1) (the two largest costs up, the two smallest down), column 3
    # basic.  Costs c = (-1, 1, -1, 0, 3): duals y = c_3 = 0, d = c, gap terms
    # |d_j| - d_j xi0_j = (2, 2, 2, -, 6).  With FIRST = 2 the first set is the basic column,
    # column 4 (6) and of the tied columns 0, 1, 2 the lowest, column 0.
    A, b = np.ones((1, 5)), np.zeros(1)
    st = sifting.start(A, b, np.array([5.0, 1.0, 4.0, 2.0, 0.0]))
    s0 = sifting_jit._prepare(A, b, st)
    assert np.array_equal(st.xi, [1.0, -1.0, 1.0, 0.0, -1.0]) and list(s0.basic) == [3]
    old = sifting_jit.FIRST
    try:
        sifting_jit.FIRST = 2
        S = sifting_jit._new_chunk(A, np.ascontiguousarray(A.T),
                                   np.array([[-1.0, 1.0, -1.0, 0.0, 3.0]]), s0,
                                   np.empty((1, s0.cap, 1)), sifting_jit._kernels())
    finally:
        sifting_jit.FIRST = old
    assert S.Wc[0, :S.nW[0]].tolist() == [3, 0, 4]  # the basic column first, then in order
