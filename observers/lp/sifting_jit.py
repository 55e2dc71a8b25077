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
working set would exceed its capacity, when a round's restricted LP exceeds the iteration
budget (:func:`.dual_simplex.max_iterations`), or after :data:`MAX_ROUNDS` pricing rounds.

Measured on the steady CZN-A hulls (per hull, 2026-12-06): 30 tanks (42 rows, 3063 columns,
60 LPs) 66 ms against 104 ms by the batched dual simplex; 60 tanks (92 rows, 6138 columns)
242 ms against 1324 ms batched and 1189 ms by sifting with HiGHS; 100 tanks (160 rows,
10,240 columns) 0.68 s against 2.9 s, 18 pivots per LP against HiGHS's 88; 200 tanks (326
rows, 20,489 columns) 4.3 s against 9.0 s.

The kernels are plain Python in numba's subset: compiled where numba is available
(:data:`observers.kernels.switch.AVAILABLE`), and the same functions run interpreted
otherwise (the same pivots, much slower: :class:`observers.lp.hull.HullLP` then takes the
HiGHS sifting of :mod:`.sifting`).
"""

from __future__ import annotations

from time import perf_counter
from typing import NamedTuple

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
from .dual_simplex_jit import _pass_breakpoints
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
#: columns a working set may hold (at least ``12 p``; a problem that would need more is
#: reported as not converged)
CAPACITY = 4000
#: status of a problem after :func:`_restricted`
RUNNING, OPTIMAL, FAILED = 0, 1, 2


class Chunk(NamedTuple):
    """The state of a chunk of problems (row ``k`` of every array is problem ``k``), by
    working-set position ``a``: ``Wc`` the column, ``AWT[k, a]`` its entries, ``nrm2`` its
    squared norm, ``cW`` its (perturbed) cost, ``zW`` the value of a nonbasic column
    (``-1``/``+1``; 0 if basic), ``DW`` its dual slack ``|d_a|``, ``isb`` whether it is
    basic; ``nW`` the working-set sizes; ``basis[k, i]`` the position of row ``i``'s basic
    column, or ``-1 - i'`` for the logical of row ``i'`` (fixed at 0); ``Binv`` the basis
    inverses, ``wts`` their squared row norms (the dual steepest-edge weights); ``t = b -``
    the nonbasic columns times their values (the fixed columns included), so the basic
    values are ``B^-1 t``; ``inW`` which of all columns are in the working set; ``its`` the
    pivots and ``upd`` the updates of ``B^-1`` since its last refactorisation."""

    Wc: np.ndarray
    AWT: np.ndarray
    nrm2: np.ndarray
    cW: np.ndarray
    zW: np.ndarray
    DW: np.ndarray
    isb: np.ndarray
    nW: np.ndarray
    basis: np.ndarray
    Binv: np.ndarray
    wts: np.ndarray
    t: np.ndarray
    inW: np.ndarray
    its: np.ndarray
    upd: np.ndarray


def _refactor(S, k):
    """Recompute ``B^-1`` of problem ``k`` and its steepest-edge weights; ``False`` where the
    basis is singular or the inverse not finite."""
    p = S.Binv.shape[1]
    B = np.zeros((p, p))
    for i in range(p):
        a = S.basis[k, i]
        if a >= 0:
            B[:, i] = S.AWT[k, a]
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
            S.Binv[k, i, j] = v
            s += v * v
        S.wts[k, i] = s
    S.upd[k] = 0
    return True


def _leaving_row(xB, bk, wk, primal_tol):
    """``(row, infeasibility)`` of the basic value that leaves: the largest primal
    infeasibility weighted by the steepest-edge weights (``-1`` if none exceeds
    ``primal_tol``: the restricted LP is optimal)."""
    rr = -1
    best = 0.0
    delta = 0.0
    for i in range(xB.shape[0]):
        v = abs(xB[i]) - (1.0 if bk[i] >= 0 else 0.0)
        if v > primal_tol:
            score = v * v / wk[i]
            if score > best:
                best = score
                rr = i
                delta = v
    return rr, delta


def _ratio_test(alpha, ib, zk, Dk, sgn, delta, keys, flips):
    """Bound-flipping ratio test over the nonbasic positions: ``(entering, breakpoints
    passed)`` (``-1`` if none).  ``alpha`` enters as ``rho' a`` and leaves as ``w_a = -sgn
    alpha_a z_a`` (0 for basic positions); candidates ``w_a > 0`` are ordered by keys holding
    the high bits of the ratio ``D_a / w_a`` (non-negative floats order like their bit
    patterns) and the position in the low bits, in a binary heap (usually only a few of
    them are passed: :func:`.dual_simplex_jit._pass_breakpoints`, the dual simplex's own
    pass); the passed ones are ``flips[:passed]``."""
    nw = alpha.shape[0]
    bits = 1
    while (1 << bits) < nw:
        bits += 1
    low = np.uint64((1 << bits) - 1)
    high = ~low
    ratio = np.empty(1)
    rbits = ratio.view(np.uint64)
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
    return _pass_breakpoints(keys, nc, low, alpha, delta, flips)


def _pivot(S, k, rr, aq, sgn, alpha, flips, npass, rho):
    """Problem ``k``'s dual step and pivot: the dual slacks move along ``alpha`` (the ``w``
    of :func:`_ratio_test`), the passed breakpoints flip to their other bound, position
    ``aq`` enters row ``rr`` (whose variable leaves at its bound on side ``sgn``); ``B^-1``
    and its steepest-edge weights are updated (Forrest and Goldfarb), ``rho`` being row
    ``rr`` of the old inverse."""
    p = S.Binv.shape[1]
    nw = alpha.shape[0]
    AW, Bk, bk, wk, tk = S.AWT[k], S.Binv[k], S.basis[k], S.wts[k], S.t[k]
    zk, Dk, ib = S.zW[k], S.DW[k], S.isb[k]
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
    colq = Bk @ col
    tau = Bk @ rho
    piv = colq[rr]
    wrr = wk[rr]
    for i in range(p):
        if i != rr:
            f = colq[i] / piv
            if f != 0.0:
                wk[i] = max(wk[i] - 2.0 * f * tau[i] + f * f * wrr, 1e-12 * wk[i])
                for j in range(p):
                    Bk[i, j] -= f * rho[j]
    wk[rr] = wrr / (piv * piv)
    for j in range(p):
        Bk[rr, j] = rho[j] / piv
    S.upd[k] += 1


def _restricted(S, k, budget, refactor_every, primal_tol, pivot_tol):
    """Dual simplex iterations of problem ``k`` of the chunk ``S`` (:class:`Chunk`) over its
    working set until its restricted LP is optimal (``OPTIMAL``), fails (``FAILED``: no
    entering column, a tiny pivot element, a singular basis) or its pivots reach ``budget``
    (``RUNNING``)."""
    p = S.Binv.shape[1]
    nw = S.nW[k]
    AW = S.AWT[k, :nw]
    Bk = S.Binv[k]
    alpha = np.empty(nw)
    keys = np.empty(nw, np.uint64)
    flips = np.empty(nw, np.int64)
    rho = np.empty(p)
    while S.its[k] < budget:
        if S.upd[k] >= refactor_every and not _refactor(S, k):
            return FAILED
        xB = Bk @ S.t[k]
        rr, delta = _leaving_row(xB, S.basis[k], S.wts[k], primal_tol)
        if rr < 0:
            return OPTIMAL
        S.its[k] += 1
        sgn = 1.0 if xB[rr] > 0.0 else -1.0  # above the upper bound: leaves at it
        for i in range(p):
            rho[i] = Bk[rr, i]
        alpha[:] = AW @ rho
        aq, npass = _ratio_test(alpha, S.isb[k, :nw], S.zW[k, :nw], S.DW[k, :nw], sgn, delta,
                                keys, flips)
        if aq < 0 or alpha[aq] ** 2 < pivot_tol ** 2 * S.wts[k, rr] * S.nrm2[k, aq]:
            return FAILED  # dual unbounded (cannot be: the restricted LP is feasible) or trouble
        _pivot(S, k, rr, aq, sgn, alpha, flips, npass, rho)
    return RUNNING


def _grow(S, k, new, AT, xi0, cost, dp):
    """Add the fixed columns ``new`` to problem ``k``'s working set, each nonbasic at the bound
    its reduced cost ``dp`` wants (moving its contribution in ``t``); ``False`` if the working
    set is full."""
    p = S.AWT.shape[2]
    cap = S.Wc.shape[1]
    tk = S.t[k]
    for j in new:
        a = S.nW[k]
        if a == cap:
            return False
        col = AT[j]
        S.Wc[k, a] = j
        s = 0.0
        for i in range(p):
            S.AWT[k, a, i] = col[i]
            s += col[i] * col[i]
        S.nrm2[k, a] = s
        S.cW[k, a] = cost[j]
        z = 1.0 if dp[j] >= 0.0 else -1.0
        dz = z - xi0[j]
        if dz != 0.0:
            for i in range(p):
                tk[i] -= col[i] * dz
        S.zW[k, a] = z
        S.DW[k, a] = abs(dp[j])
        S.isb[k, a] = False
        S.inW[k, j] = True
        S.nW[k] = a + 1
    return True


def _duals(S, rows):
    """``y_k = B_k^-T c_B`` of the problems ``rows`` (one row each; the costs of the basic
    working-set positions, 0 for logicals)."""
    n, p = rows.shape[0], S.Binv.shape[1]
    Y = np.empty((n, p))
    cB = np.empty(p)
    for i in range(n):
        k = rows[i]
        for j in range(p):
            a = S.basis[k, j]
            cB[j] = S.cW[k, a] if a >= 0 else 0.0
        Y[i] = S.Binv[k].T @ cB
    return Y


def _price(S, Dp, xi0, rows, limits, picked, counts):
    """For each problem ``rows[i]`` with reduced costs ``Dp[i]``: the gap terms
    ``|d_j| - d_j xi0_j`` of the columns outside its working set; ``True`` where they add up
    to at most ``limits[i]`` (finished), else the (at most) ``m`` (``picked``'s width)
    columns with the largest terms in ``picked[i, :counts[i]]`` (ties to the lower index, in
    column order)."""
    n, r = Dp.shape
    m = picked.shape[1]
    fin = np.zeros(n, np.bool_)
    T = np.empty(r)
    idx = np.empty(r, np.int64)
    for i in range(n):
        k = rows[i]
        d = Dp[i]
        total = 0.0
        c = 0
        for j in range(r):
            if S.inW[k, j]:
                continue
            v = abs(d[j]) - d[j] * xi0[j]
            if v > 0.0:
                total += v
                T[c] = v
                idx[c] = j
                c += 1
        counts[i] = 0
        if total <= limits[i]:
            fin[i] = True
        elif c <= m:
            picked[i, :c] = idx[:c]
            counts[i] = c
        else:
            counts[i] = _largest(T[:c], idx[:c], m, picked[i])
    return fin


def _largest(T, idx, m, out):
    """Write the ``idx`` of the ``m`` largest of ``T`` to ``out`` in increasing order (ties
    to the earlier entry); returns ``m``."""
    c = T.shape[0]
    kth = np.partition(T, c - m)[c - m]  # the m-th largest term
    n_pick = 0
    for e in range(c):
        if T[e] > kth:
            out[n_pick] = idx[e]
            n_pick += 1
    for e in range(c):
        if n_pick == m:
            break
        if T[e] == kth:
            out[n_pick] = idx[e]
            n_pick += 1
    out[:n_pick] = np.sort(out[:n_pick])
    return n_pick


#: the kernels as plain Python (the same pivots, for tests and installations without numba)
_PYTHON = {"restricted": _restricted, "grow": _grow, "price": _price, "duals": _duals}
if AVAILABLE:  # the module's names rebound to the compiled functions, which call each other
    _refactor = njit(_refactor)
    _leaving_row = njit(_leaving_row)
    _ratio_test = njit(_ratio_test)
    _pivot = njit(_pivot)
    _restricted = njit(_restricted, error_model="numpy")
    _grow = njit(_grow)
    _largest = njit(_largest)
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


class _Start(NamedTuple):
    """What every chunk starts from: the start vertex ``xi0``, its basis ``B0`` (columns of
    ``[A, I]``) with inverse ``Binv0`` and weights ``w0``, its basic structurals ``basic`` (in
    column order: the first working-set positions) and the basis as positions ``pos0``,
    ``t0 = b - A xi0`` without the basic columns, and the working-set capacity ``cap``."""

    xi0: np.ndarray
    B0: np.ndarray
    Binv0: np.ndarray
    w0: np.ndarray
    basic: np.ndarray
    pos0: np.ndarray
    t0: np.ndarray
    cap: int


def _prepare(A: np.ndarray, b: np.ndarray, st: Start) -> _Start:
    """The :class:`_Start` of the vertex ``st`` (raises :class:`.sifting.NoStart` if its basis
    is not a basis of the constraints)."""
    p, r = A.shape
    basis0 = start_basis(A, st)
    if basis0 is None:
        raise sifting.NoStart("the start vertex's basis is not a basis of the constraints")
    B0, Binv0 = basis0
    basic = np.sort(B0[B0 < r])
    xi_n = st.xi.copy()
    xi_n[basic] = 0.0  # basic values live in B^-1 t
    pos0 = np.where(B0 < r, np.searchsorted(basic, B0), -1 - (B0 - r))
    return _Start(st.xi, B0, Binv0, np.einsum("ij,ij->i", Binv0, Binv0), basic, pos0,
                  b - A @ xi_n, int(min(r, max(CAPACITY, 12 * p))))


def _new_chunk(A: np.ndarray, AT: np.ndarray, P: np.ndarray, s0: _Start, AWT: np.ndarray,
               kernels) -> Chunk:
    """The chunk of problems with perturbed costs ``P``: each at the start basis, its working
    set the start's basic columns and the :data:`FIRST` columns whose gap terms are largest
    against the start basis's duals (``AWT``: the buffer of the working sets' columns;
    ``kernels`` as :func:`_kernels`).  The first columns are chosen by the pricing kernel of
    the later rounds (:func:`_price`, the same selection and tie rule), with no limit that
    would finish a problem."""
    _, grow, price, _ = kernels
    Kc, r = P.shape
    cap, m, basic = s0.cap, s0.basic.size, s0.basic
    S = Chunk(Wc=np.zeros((Kc, cap), np.int64), AWT=AWT, nrm2=np.zeros((Kc, cap)),
              cW=np.zeros((Kc, cap)), zW=np.zeros((Kc, cap)), DW=np.zeros((Kc, cap)),
              isb=np.zeros((Kc, cap), bool), nW=np.full(Kc, m, np.int64),
              basis=np.tile(s0.pos0, (Kc, 1)), Binv=np.tile(s0.Binv0, (Kc, 1, 1)),
              wts=np.tile(s0.w0, (Kc, 1)), t=np.tile(s0.t0, (Kc, 1)),
              inW=np.zeros((Kc, r), bool), its=np.zeros(Kc, np.int64),
              upd=np.zeros(Kc, np.int64))
    S.Wc[:, :m] = basic
    AWT[:, :m] = AT[basic]
    S.nrm2[:, :m] = np.einsum("ij,ij->i", AT[basic], AT[basic])
    S.cW[:, :m] = P[:, basic]
    S.isb[:, :m] = True
    S.inW[:, basic] = True
    Y = np.where(s0.B0 < r, P[:, np.minimum(s0.B0, r - 1)], 0.0) @ s0.Binv0
    Dp = P - Y @ A
    picked, counts = np.zeros((Kc, FIRST), np.int64), np.zeros(Kc, np.int64)
    price(S, Dp, s0.xi0, np.arange(Kc), np.full(Kc, -1.0), picked, counts)
    for k in range(Kc):
        grow(S, k, picked[k, :counts[k]], AT, s0.xi0, P[k], Dp[k])
    return S


def _sift_chunk(A, AT, G, P, s0, S, radius, opts, kernels, seconds):
    """Sift the chunk ``S`` (costs ``G``, perturbed ``P``) until every problem is finished
    or failed or the rounds run out: ``(converged, rounds)``; ``opts = (gap_tol,
    max_rounds)``."""
    restricted, grow, price, duals = kernels
    gap_tol, max_rounds = opts
    Kc, p = G.shape[0], A.shape[0]
    budget = max_iterations(p)
    conv = np.zeros(Kc, bool)
    status = np.full(Kc, RUNNING)
    picked = np.zeros((Kc, ADD), np.int64)
    counts = np.zeros(Kc, np.int64)
    active, rounds = np.arange(Kc), 0
    while active.size and rounds < max_rounds:
        rounds += 1
        t0 = perf_counter()
        for k in active:  # each round's restricted LP with its own iteration budget
            status[k] = restricted(S, k, S.its[k] + budget, REFACTOR_EVERY, PRIMAL_TOL,
                                   PIVOT_TOL)
        t1 = perf_counter()
        seconds["restricted"] += t1 - t0
        ok = active[status[active] == OPTIMAL]
        if not ok.size:
            break
        # price every column against the restricted duals of the problems at an optimum
        Dp = P[ok] - duals(S, ok) @ A
        fin = price(S, Dp, s0.xi0, ok, gap_tol * radius[ok], picked, counts)
        conv[ok[fin]] = True
        t2 = perf_counter()
        seconds["pricing"] += t2 - t1
        for i in np.flatnonzero(~fin):
            k = ok[i]
            if not grow(S, k, picked[i, :counts[i]], AT, s0.xi0, P[k], Dp[i]):
                status[k] = FAILED
        seconds["restricted"] += perf_counter() - t2
        active = ok[~fin]
        active = active[status[active] != FAILED]
    return conv, rounds


def solve(A: np.ndarray, b: np.ndarray, Gd: np.ndarray, st: Start | None = None,
          gap_tol: float | None = None, max_rounds: int | None = None) -> SiftResult:
    """Dual points of ``max Gd[k]' xi  s.t.  A xi = b, |xi| <= 1`` for every row ``k`` (see
    the module docstring); ``st`` is a start vertex (:func:`.sifting.start` of the first
    row's cost if not given); ``gap_tol`` and ``max_rounds`` default to :data:`GAP_TOL` and
    :data:`MAX_ROUNDS`.  The problems are sifted in chunks of :data:`CHUNK` (one pricing
    product per round and chunk).

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
    K, p = Gd.shape[0], A.shape[0]
    kernels = _kernels()
    opts = (GAP_TOL if gap_tol is None else gap_tol,
            MAX_ROUNDS if max_rounds is None else max_rounds)
    seconds = {"start": 0.0, "models": 0.0, "restricted": 0.0, "pricing": 0.0}
    t0 = perf_counter()
    st = sifting.start(A, b, Gd[0]) if st is None else st
    s0 = _prepare(A, b, st)
    AT = np.ascontiguousarray(A.T)
    pert = Gd * (1.0 + PERTURBATION * _jitter(Gd.shape, 0))
    seconds["start"] = perf_counter() - t0
    mu, conv = np.zeros((K, p)), np.zeros(K, bool)
    rounds, iterations, sizes = 0, st.iterations, []
    radius = np.abs(Gd).sum(axis=1)
    AWT = np.empty((min(K, CHUNK), s0.cap, p))  # the working sets' columns, chunk by chunk
    for lo in range(0, K, CHUNK):
        sl = slice(lo, min(K, lo + CHUNK))
        t0 = perf_counter()
        S = _new_chunk(A, AT, pert[sl], s0, AWT[:sl.stop - lo], kernels)
        seconds["models"] += perf_counter() - t0
        conv[sl], r_ = _sift_chunk(A, AT, Gd[sl], pert[sl], s0, S, radius[sl], opts, kernels,
                                   seconds)
        rounds, iterations = max(rounds, r_), iterations + int(S.its.sum())
        sizes += S.nW.tolist()
        # the duals of the exact costs on the final bases
        cols = np.take_along_axis(S.Wc, np.maximum(S.basis, 0), axis=1)
        gB = np.where(S.basis >= 0, np.take_along_axis(Gd[sl], cols, axis=1), 0.0)
        mu[sl] = np.einsum("kji,kj->ki", S.Binv, gB)
    return SiftResult(mu, conv, rounds, iterations, float(np.mean(sizes)) if K else 0.0,
                      seconds)
