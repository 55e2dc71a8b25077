"""Sifting with a compiled dual simplex for the restricted LPs (the hulls of large sets).

Solves, as :func:`observers.lp.sifting.solve`, for the rows ``g_k`` of a cost matrix ``Gd``
(K x r),

    max  g_k' xi   s.t.   A xi = b,   -1 <= xi <= 1          (A: p x r, r >> p),

and returns one dual point ``mu_k`` per problem; the caller turns each into a sound bound by
weak duality on the full problem (:func:`observers.lp.hull.dual_bounds`), so this solver
decides tightness and speed only.

Same sifting scheme (Bixby et al., Operations Research 40(5), 1992, as in
:mod:`.sifting`): one vertex ``xi0`` of the feasible set from a cold HiGHS solve; each
problem keeps a working set of columns, the others fixed at their values in ``xi0``, so every
restricted LP is feasible; the restricted duals of a chunk of problems are priced against all
columns by one matrix product, and the columns whose gap terms ``|d_j| - d_j xi0_j`` are
largest join the working set until they add at most ``gap_tol`` times ``||g_k||_1`` to the
gap.  What differs is the restricted LP, which HiGHS solved there (about 150 us per simplex
iteration on the dense 160-row LP of 100 tanks, three quarters of the hull's time):

* every problem starts from the *same* basis, the optimal basis of ``xi0`` (its structural
  columns and the logicals of its basic rows), whose inverse is computed once; with the
  boxed variables any basis is dual feasible (each nonbasic column at the bound its reduced
  cost wants), so a bounded dual simplex (:mod:`.dual_simplex`'s method: dual steepest-edge
  leaving rows, Fourer's bound-flipping ratio test over a binary heap) runs from it with no
  phase 1.  The working set's columns start at the bounds their reduced costs want, the
  primal infeasibility of that move is what the dual simplex removes;
* a column that joins the working set enters nonbasic at the bound its reduced cost wants,
  the basis and its inverse stay: the dual simplex continues from where it stopped instead of
  starting again (no refactorisation, no new model);
* the dual steepest-edge weights (squared row norms of ``B^-1``) are updated with each pivot
  (Forrest and Goldfarb, Mathematical Programming 57, 1992) instead of recomputed, and the
  ``p x p`` products are BLAS calls inside the compiled code, not the sums in a fixed order
  of :mod:`.dual_simplex_jit` (which run at a fifth of BLAS's rate at ``p = 160``);
* the state of a problem is kept by working-set position (the columns of the working set
  copied contiguously), so a pivot touches ``|W| p + O(p^2)`` numbers in order.

The costs are perturbed as in :mod:`.dual_simplex` (relative 1e-11, the same factors) against
stalling; the returned duals are those of the exact costs on the final bases.  A problem is
reported as not converged (the caller solves it in full) if its restricted LP fails
numerically (no entering column, a tiny pivot element, a singular refactorisation), if its
working set would exceed its capacity, or after the iteration budget
(:func:`.dual_simplex.max_iterations`) or :data:`MAX_ROUNDS` pricing rounds.

The kernels are plain Python in numba's subset: compiled where numba is available
(:data:`observers.kernels.switch.AVAILABLE`), and the same functions run interpreted
otherwise (the same pivots, much slower: :class:`observers.lp.hull.HullLP` then takes the
HiGHS sifting of :mod:`.sifting`).
"""

from __future__ import annotations

from time import perf_counter

import numpy as np

from ..kernels.switch import AVAILABLE, njit
from . import sifting
from .dual_simplex import (
    PERTURBATION,
    PIVOT_TOL,
    PRIMAL_TOL,
    _jitter,
    max_iterations,
    use_compiled,
)
from .sifting import SiftResult, Start

#: a problem is finished when the columns outside its working set add at most this times
#: ``||g_k||_1`` to its duality gap (as :data:`.sifting.GAP_TOL`)
GAP_TOL = sifting.GAP_TOL
#: most pricing rounds per problem
MAX_ROUNDS = 40
#: columns per problem in the first working set besides the start's basic columns (those
#: with the largest gap terms against the start basis's duals)
FIRST = 300
#: columns added per round and problem (at most)
ADD = 160
#: problems sifted together (one pricing product per round)
CHUNK = 16
#: the basis inverse is recomputed from scratch after this many updates
REFACTOR_EVERY = 50
#: columns a working set may hold (at least ``20 p``; a problem that would need more is
#: reported as not converged)
CAPACITY = 4000
#: status of a problem after :func:`restricted`
RUNNING, OPTIMAL, FAILED = 0, 1, 2


def _sift_down(h, i, n):
    """Restore the min-heap order of ``h[:n]`` below position ``i``."""
    x = h[i]
    while True:
        c = 2 * i + 1
        if c >= n:
            break
        if c + 1 < n and h[c + 1] < h[c]:
            c += 1
        if h[c] >= x:
            break
        h[i] = h[c]
        i = c
    h[i] = x


def _refactor(AWT, k, basis, Binv, wts):
    """Recompute ``B^-1`` of problem ``k`` and its steepest-edge weights; ``False`` where the
    basis is singular or the inverse not finite."""
    p = Binv.shape[1]
    B = np.zeros((p, p))
    for i in range(p):
        a = basis[k, i]
        if a >= 0:
            B[:, i] = AWT[k, a]
        else:
            B[-1 - a, i] = 1.0
    try:
        inv = np.linalg.inv(B)
    except Exception:  # singular (numba raises on a zero pivot of the LU factorisation)
        return False
    if not np.all(np.isfinite(inv)):
        return False
    for i in range(p):
        s = 0.0
        for j in range(p):
            v = inv[i, j]
            Binv[k, i, j] = v
            s += v * v
        wts[k, i] = s
    return True


def _restricted(k, AWT, nrm2, zW, DW, isb, nW, basis, Binv, wts, t, its, upd, max_iter,
                refactor_every, primal_tol, pivot_tol):
    """Dual simplex iterations of problem ``k`` over its working set until its restricted LP
    is optimal (``OPTIMAL``), fails (``FAILED``) or reaches ``max_iter`` (``RUNNING``).

    State by working-set position ``a``: ``AWT[k, a]`` the column, ``nrm2`` its squared norm,
    ``zW`` the value of a nonbasic column (``-1``/``+1``; 0 if basic), ``DW`` its dual slack
    ``|d_a|``, ``isb`` whether it is basic.  ``basis[k, i]`` is the position of row ``i``'s
    basic column, or ``-1 - i'`` for the logical of row ``i'`` (fixed at 0).  ``t = b - (the
    nonbasic columns times their values, the fixed columns included)``, so the basic values
    are ``B^-1 t``."""
    p = Binv.shape[1]
    nw = nW[k]
    AW = AWT[k, :nw]
    Bk, bk, wk, tk = Binv[k], basis[k], wts[k], t[k]
    zk, Dk, ib, nk = zW[k], DW[k], isb[k], nrm2[k]
    alpha = np.empty(nw)
    keys = np.empty(nw, np.uint64)
    flips = np.empty(nw, np.int64)
    rho = np.empty(p)
    ratio = np.empty(1)
    rbits = ratio.view(np.uint64)
    bits = 1
    while (1 << bits) < AWT.shape[1]:
        bits += 1
    low = np.uint64((1 << bits) - 1)
    high = ~low
    while its[k] < max_iter:
        if upd[k] >= refactor_every:
            if not _refactor(AWT, k, basis, Binv, wts):
                return FAILED
            upd[k] = 0
        xB = Bk @ tk
        rr = -1
        best = 0.0
        delta = 0.0
        for i in range(p):
            v = abs(xB[i]) - (1.0 if bk[i] >= 0 else 0.0)
            if v > primal_tol:
                score = v * v / wk[i]
                if score > best:
                    best = score
                    rr = i
                    delta = v
        if rr < 0:
            return OPTIMAL
        its[k] += 1
        sgn = 1.0 if xB[rr] > 0.0 else -1.0  # above the upper bound: leaves at it
        for i in range(p):
            rho[i] = Bk[rr, i]
        alpha[:] = AW @ rho
        # ratio test with bound flipping: candidates w_a = -sgn alpha_a z_a > 0, ordered by
        # keys holding the high bits of the ratio D_a / w_a (non-negative floats order like
        # their bit patterns) and the position a in the low bits
        nc = 0
        for a in range(nw):
            if ib[a]:
                alpha[a] = 0.0
                continue
            w = -sgn * alpha[a] * zk[a]
            alpha[a] = w
            if w > 0.0:
                ratio[0] = Dk[a] / w
                keys[nc] = (rbits[0] & high) | np.uint64(a)
                nc += 1
        for i in range(nc // 2 - 1, -1, -1):
            _sift_down(keys, i, nc)
        passed = 0.0
        aq = -1
        npass = 0
        while nc > 0:
            kq = keys[0]
            nc -= 1
            keys[0] = keys[nc]
            _sift_down(keys, 0, nc)
            a = np.int64(kq & low)
            passed += alpha[a]
            if passed >= 0.5 * delta:  # slope lost per breakpoint: 2 w_a
                aq = a
                break
            flips[npass] = a
            npass += 1
        if aq < 0 or alpha[aq] * alpha[aq] < pivot_tol * pivot_tol * wk[rr] * nk[aq]:
            return FAILED  # dual unbounded (cannot be: the restricted LP is feasible) or trouble
        tq = Dk[aq] / alpha[aq]
        for a in range(nw):
            if not ib[a]:
                Dk[a] = abs(Dk[a] - tq * alpha[a])
        for f in range(npass):
            a = flips[f]
            za = zk[a]
            col = AW[a]
            for i in range(p):
                tk[i] += 2.0 * col[i] * za
            zk[a] = -za
        la = bk[rr]
        col = AW[aq]
        zq = zk[aq]
        for i in range(p):
            tk[i] += col[i] * zq
        if la >= 0:
            cl = AW[la]
            for i in range(p):
                tk[i] -= cl[i] * sgn
            zk[la] = sgn
            Dk[la] = tq
            ib[la] = False
        ib[aq] = True
        zk[aq] = 0.0
        Dk[aq] = 0.0
        bk[rr] = aq
        # update B^-1 and the steepest-edge weights (tau = B^-1 rho' of the old inverse)
        colq = Bk @ col
        tau = Bk @ rho
        piv = colq[rr]
        wrr = wk[rr]
        for i in range(p):
            if i != rr:
                f = colq[i] / piv
                if f != 0.0:
                    wi = wk[i] - 2.0 * f * tau[i] + f * f * wrr
                    wk[i] = max(wi, 1e-12 * wk[i])
                    for j in range(p):
                        Bk[i, j] -= f * rho[j]
        wk[rr] = wrr / (piv * piv)
        for j in range(p):
            Bk[rr, j] = rho[j] / piv
        upd[k] += 1
    return RUNNING


def _grow(k, new, AT, xi0, cost, dp, Wc, AWT, nrm2, cW, zW, DW, isb, nW, t):
    """Add the fixed columns ``new`` to problem ``k``'s working set, each nonbasic at the bound
    its reduced cost ``dp`` wants (moving its contribution in ``t``); ``False`` if the working
    set is full."""
    p = AWT.shape[2]
    cap = Wc.shape[1]
    tk = t[k]
    for j in new:
        a = nW[k]
        if a == cap:
            return False
        col = AT[j]
        Wc[k, a] = j
        s = 0.0
        for i in range(p):
            AWT[k, a, i] = col[i]
            s += col[i] * col[i]
        nrm2[k, a] = s
        cW[k, a] = cost[j]
        z = 1.0 if dp[j] >= 0.0 else -1.0
        dz = z - xi0[j]
        if dz != 0.0:
            for i in range(p):
                tk[i] -= col[i] * dz
        zW[k, a] = z
        DW[k, a] = abs(dp[j])
        isb[k, a] = False
        nW[k] = a + 1
    return True


def _duals(rows, basis, cW, Binv):
    """``y_k = B_k^-T c_B`` of the problems ``rows`` (one row each; the costs of the basic
    working-set positions, 0 for logicals)."""
    n, p = rows.shape[0], Binv.shape[1]
    Y = np.empty((n, p))
    cB = np.empty(p)
    for i in range(n):
        k = rows[i]
        for j in range(p):
            a = basis[k, j]
            cB[j] = cW[k, a] if a >= 0 else 0.0
        Y[i] = Binv[k].T @ cB
    return Y


def _price(Dp, xi0, inW, rows, limits, m, picked, counts):
    """For each problem ``rows[i]`` with reduced costs ``Dp[i]``: the gap terms
    ``|d_j| - d_j xi0_j`` of the columns outside its working set; ``True`` where they add up
    to at most ``limits[i]`` (finished), else the (at most) ``m`` columns with the largest
    terms in ``picked[i, :counts[i]]`` (ties to the lower index, in column order)."""
    n, r = Dp.shape
    fin = np.zeros(n, np.bool_)
    T = np.empty(r)
    idx = np.empty(r, np.int64)
    for i in range(n):
        k = rows[i]
        d = Dp[i]
        total = 0.0
        c = 0
        for j in range(r):
            if inW[k, j]:
                continue
            v = abs(d[j]) - d[j] * xi0[j]
            if v > 0.0:
                total += v
                T[c] = v
                idx[c] = j
                c += 1
        if total <= limits[i]:
            fin[i] = True
            counts[i] = 0
            continue
        if c <= m:
            picked[i, :c] = idx[:c]
            counts[i] = c
            continue
        kth = np.partition(T[:c], c - m)[c - m]  # the m-th largest term
        n_pick = 0
        for e in range(c):
            if T[e] > kth:
                picked[i, n_pick] = idx[e]
                n_pick += 1
        for e in range(c):
            if n_pick == m:
                break
            if T[e] == kth:
                picked[i, n_pick] = idx[e]
                n_pick += 1
        picked[i, :n_pick] = np.sort(picked[i, :n_pick])
        counts[i] = n_pick
    return fin


def _top(T: np.ndarray, m: int) -> np.ndarray:
    """Indices of the (at most) ``m`` largest positive entries of ``T``, ties to the lower
    index (deterministic)."""
    pos = np.flatnonzero(T > 0.0)
    if pos.size <= m:
        return pos
    vals = T[pos]
    kth = np.partition(vals, pos.size - m)[pos.size - m]  # the m-th largest value
    above = pos[vals > kth]
    ties = pos[vals == kth][:m - above.size]  # pos is ascending: the lowest indices
    return np.sort(np.concatenate([above, ties]))


#: the kernels run as plain Python (the same pivots, for tests and installations without
#: numba) ...
_PYTHON = {"restricted": _restricted, "grow": _grow, "price": _price, "duals": _duals}
#: ... and compiled (the module's names rebound to the compiled functions, which call each
#: other compiled)
if AVAILABLE:
    _sift_down = njit(_sift_down)
    _refactor = njit(_refactor)
    _restricted = njit(_restricted, error_model="numpy")
    _grow = njit(_grow)
    _price = njit(_price)
    _duals = njit(_duals)


def _kernels():
    """``(restricted, grow, price, duals)``: compiled where
    :func:`.dual_simplex.use_compiled`, else the plain Python functions."""
    if use_compiled():
        return _restricted, _grow, _price, _duals
    return tuple(_PYTHON[name] for name in ("restricted", "grow", "price", "duals"))


def start_basis(A: np.ndarray, st: Start) -> tuple[np.ndarray, np.ndarray] | None:
    """The start vertex's basis as columns of ``[A, I]`` (its basic structurals, then the
    logicals of its basic rows) and its inverse; ``None`` if it does not have ``p`` columns or
    is singular."""
    p, r = A.shape
    B0 = np.concatenate([np.flatnonzero(st.col_status == 1),
                         r + np.flatnonzero(st.row_status == 1)])
    if B0.size != p:
        return None
    B = np.zeros((p, p))
    structural = B0 < r
    B[:, structural] = A[:, B0[structural]]
    B[B0[~structural] - r, np.flatnonzero(~structural)] = 1.0
    try:
        Binv = np.linalg.inv(B)
    except np.linalg.LinAlgError:
        return None
    if not np.all(np.isfinite(Binv)):
        return None
    return B0, Binv


def solve(A: np.ndarray, b: np.ndarray, Gd: np.ndarray, st: Start | None = None,
          gap_tol: float | None = None, max_rounds: int | None = None) -> SiftResult:
    """Dual points of ``max Gd[k]' xi  s.t.  A xi = b, |xi| <= 1`` for every row ``k`` (see
    the module docstring); ``st`` is a start vertex (:func:`.sifting.start` of the first
    row's cost if not given).

    Raises
    ------
    EmptySet
        If the start solve finds the feasible set empty.
    observers.lp.sifting.NoStart
        If HiGHS gives no optimal basis for the start, or that basis is singular.
    """
    A = np.ascontiguousarray(A, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    Gd = np.atleast_2d(np.asarray(Gd, dtype=np.float64))
    K, (p, r) = Gd.shape[0], A.shape
    restricted, grow, price, duals = _kernels()
    gap_tol = GAP_TOL if gap_tol is None else gap_tol
    max_rounds = MAX_ROUNDS if max_rounds is None else max_rounds
    seconds = {"start": 0.0, "models": 0.0, "restricted": 0.0, "pricing": 0.0}
    t0 = perf_counter()
    st = sifting.start(A, b, Gd[0]) if st is None else st
    basis0 = start_basis(A, st)
    if basis0 is None:
        raise sifting.NoStart("the start vertex's basis is not a basis of the constraints")
    B0, Binv0 = basis0
    AT = np.ascontiguousarray(A.T)
    xi0 = st.xi.copy()
    basic = B0[B0 < r]
    xi0[basic] = 0.0  # basic values live in B^-1 t
    t_start = b - A @ xi0
    xi0[basic] = st.xi[basic]
    pert = Gd * (1.0 + PERTURBATION * _jitter(Gd.shape, 0))
    w0 = np.einsum("ij,ij->i", Binv0, Binv0)
    # positions 0..m-1 of every working set: the start's basic structurals, in column order
    basic_sorted = np.sort(basic)
    pos0 = np.where(B0 < r, np.searchsorted(basic_sorted, B0), -1 - (B0 - r))
    cap = int(min(r, max(CAPACITY, 12 * p)))
    max_iter = max_iterations(p)
    seconds["start"] = perf_counter() - t0
    mu = np.zeros((K, p))
    conv = np.zeros(K, bool)
    rounds_all, iterations, sizes = 0, st.iterations, []
    radius = np.abs(Gd).sum(axis=1)
    m = basic_sorted.size
    AWT_all = np.empty((min(K, CHUNK), cap, p))  # the working sets' columns, chunk by chunk
    for lo in range(0, K, CHUNK):
        t0 = perf_counter()
        G, P = Gd[lo:lo + CHUNK], pert[lo:lo + CHUNK]
        Kc = G.shape[0]
        Wc = np.zeros((Kc, cap), np.int64)
        AWT = AWT_all[:Kc]
        nrm2 = np.zeros((Kc, cap))
        cW = np.zeros((Kc, cap))
        zW = np.zeros((Kc, cap))
        DW = np.zeros((Kc, cap))
        isb = np.zeros((Kc, cap), bool)
        Wc[:, :m] = basic_sorted
        AWT[:, :m] = AT[basic_sorted]
        nrm2[:, :m] = np.einsum("ij,ij->i", AT[basic_sorted], AT[basic_sorted])
        cW[:, :m] = P[:, basic_sorted]
        isb[:, :m] = True
        nW = np.full(Kc, m, np.int64)
        basis = np.tile(pos0, (Kc, 1))
        Binv = np.tile(Binv0, (Kc, 1, 1))
        wts = np.tile(w0, (Kc, 1))
        t = np.tile(t_start, (Kc, 1))
        inW = np.zeros((Kc, r), bool)
        inW[:, basic_sorted] = True
        its = np.zeros(Kc, np.int64)
        upd = np.zeros(Kc, np.int64)
        status = np.full(Kc, RUNNING)
        picked = np.zeros((Kc, ADD), np.int64)
        counts = np.zeros(Kc, np.int64)
        # the first working sets: the columns pricing worst against the start basis's duals
        Y = np.where(B0 < r, P[:, np.minimum(B0, r - 1)], 0.0) @ Binv0
        Dp = P - Y @ A
        T = np.maximum(np.abs(Dp) - Dp * xi0, 0.0)
        T[:, basic_sorted] = 0.0
        for k in range(Kc):
            new = _top(T[k], FIRST)
            inW[k, new] = True
            grow(k, new, AT, xi0, P[k], Dp[k], Wc, AWT, nrm2, cW, zW, DW, isb, nW, t)
        seconds["models"] += perf_counter() - t0
        active = np.arange(Kc)
        rounds = 0
        while active.size and rounds < max_rounds:
            rounds += 1
            t0 = perf_counter()
            for k in active:  # each round's restricted LP with its own iteration budget
                status[k] = restricted(k, AWT, nrm2, zW, DW, isb, nW, basis, Binv, wts, t,
                                        its, upd, its[k] + max_iter, REFACTOR_EVERY,
                                        PRIMAL_TOL, PIVOT_TOL)
            t1 = perf_counter()
            seconds["restricted"] += t1 - t0
            ok = active[status[active] == OPTIMAL]
            if not ok.size:
                break
            # price every column against the restricted duals of the problems at an optimum
            Y = duals(ok, basis, cW, Binv)
            Dp = P[ok] - Y @ A
            fin = price(Dp, xi0, inW, ok, gap_tol * radius[lo + ok], ADD, picked, counts)
            conv[lo + ok[fin]] = True
            t2 = perf_counter()
            seconds["pricing"] += t2 - t1
            for i in np.flatnonzero(~fin):
                k = ok[i]
                new = picked[i, :counts[i]]
                inW[k, new] = True
                if not grow(k, new, AT, xi0, P[k], Dp[i], Wc, AWT, nrm2, cW, zW, DW, isb,
                             nW, t):
                    status[k] = FAILED
            seconds["restricted"] += perf_counter() - t2
            active = ok[~fin]
            active = active[status[active] != FAILED]
        rounds_all = max(rounds_all, rounds)
        iterations += int(its.sum())
        sizes += nW.tolist()
        # the duals of the exact costs on the final bases
        cols = np.take_along_axis(Wc, np.maximum(basis, 0), axis=1)
        gB = np.where(basis >= 0, np.take_along_axis(G, cols, axis=1), 0.0)
        mu[lo:lo + Kc] = np.einsum("kji,kj->ki", Binv, gB)
    return SiftResult(mu, conv, rounds_all, iterations, float(np.mean(sizes)) if K else 0.0,
                      seconds)
