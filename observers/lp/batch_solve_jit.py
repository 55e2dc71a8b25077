"""The whole batched dual simplex of :mod:`.dual_simplex` as one compiled (numba) call.

:func:`.dual_simplex.solve` runs its iterations compiled (:func:`.dual_simplex_jit.iterate`)
but sets the problems up, refactorises their bases, evaluates their duals and certifies them
with numpy: about fifty numpy calls per hull, each a microsecond or more.  On the small hulls
of the moving-horizon estimator and of the constrained zonotopes of the 6-state vehicle (12
LPs of 8-20 rows and 40-600 columns) those calls are most of the hull's time.
:func:`solve` here runs the same method in one call:

1. the costs perturbed as in :func:`.dual_simplex.solve` (the same factors);
2. one crash basis for all problems (:func:`.dual_simplex.crash_basis`'s rule: per row the
   column most aligned with it among those with at least half the row's largest entry; the
   logical basis where that basis is singular or its 1-norm condition number exceeds 1e6);
3. the iterations of :func:`.dual_simplex_jit.iterate`, the bases refactorised every
   :data:`~.dual_simplex.REFACTOR_EVERY` updates;
4. the duals of the exact costs, the certificate (primal feasible basis, negligible duality
   gap), and clean-up iterations with the exact costs for the problems not certified, as
   :func:`.dual_simplex.solve`.

The inverses are Gauss-Jordan eliminations with partial pivoting in plain loops instead of
LAPACK's ``getrf``/``getri``, so the iterates are those of :func:`.dual_simplex.solve` up to
rounding.  As there, the result is a dual point per problem and a flag; the caller turns every
dual point into a sound bound by weak duality (:func:`observers.lp.hull.dual_bounds`) and
solves the problems not converged with HiGHS, so this solver decides tightness and speed only.

The call also evaluates those weak-duality bounds itself (``DualSimplexResult.bounds``: the
formula of :func:`observers.lp.hull.dual_bounds` with its outward rounding, summed in index
order), and :func:`hull` does the whole interval hull of a constrained zonotope in one call:
the split into columns in some constraint and free ones, the perturbed costs ``[Gc; -Gc]``,
the solve and the bounds.

:class:`observers.lp.hull.HullLP` calls them for its batched hulls where the kernels are
compiled (:func:`.dual_simplex.use_compiled`), :func:`.dual_simplex.solve` otherwise.  The
tests pair the two on random hulls and on the observers' own, and :func:`hull` with
:func:`solve` on the constrained columns (the same bits).  Measured on the hulls of the
first 80 steps (per hull, same machine and load): MHE on the 6 tanks (18 rows, 46 columns,
12 LPs) 581 -> 122 us; CZN-B on the 6 tanks (6 rows, 609 columns) 699 -> 395 us; CZN-A on
the 6-state vehicle (8 rows, 612 columns) 1282 -> 912 us, where the pivots themselves
dominate.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..kernels.switch import AVAILABLE, numba
from . import dual_simplex, dual_simplex_jit
from .dual_simplex import (
    DUAL_TOL,
    GAP_TOL,
    PERTURBATION,
    PIVOT_TOL,
    PRIMAL_TOL,
    DualSimplexResult,
    _jitter,
)

#: crash basis: a column qualifies for a row with at least this share of the row's largest
#: entry; the logical basis where the crash basis's condition number exceeds ``CRASH_COND``
CRASH_SHARE = 0.5
CRASH_COND = 1e6


def _inverse(B, out):
    """``out = B^-1`` by Gauss-Jordan elimination with partial pivoting; ``False`` (``out``
    unspecified) where a pivot is zero or not finite."""
    p = B.shape[0]
    a = B.copy()
    for i in range(p):
        for j in range(p):
            out[i, j] = 1.0 if i == j else 0.0
    for col in range(p):
        piv = col
        best = abs(a[col, col])
        for i in range(col + 1, p):
            v = abs(a[i, col])
            if v > best:
                best = v
                piv = i
        if not (best > 0.0 and best < np.inf):
            return False
        if piv != col:
            for j in range(p):
                t = a[col, j]
                a[col, j] = a[piv, j]
                a[piv, j] = t
                t = out[col, j]
                out[col, j] = out[piv, j]
                out[piv, j] = t
        f = 1.0 / a[col, col]
        for j in range(p):
            a[col, j] *= f
            out[col, j] *= f
        for i in range(p):
            if i == col:
                continue
            m = a[i, col]
            if m != 0.0:
                for j in range(p):
                    a[i, j] -= m * a[col, j]
                    out[i, j] -= m * out[col, j]
    return True


def _basis_matrix(M, basis):
    p = M.shape[0]
    B = np.empty((p, p))
    for i in range(p):
        for j in range(p):
            B[i, j] = M[i, basis[j]]
    return B


def _crash(M, colnorm, r):
    """:func:`.dual_simplex.crash_basis` of ``M = [A, I]``: ``(basis, B^-1)``."""
    p, N = M.shape
    basis = np.arange(r, N)
    Binv = np.eye(p)
    if r == 0:
        return basis, Binv
    tiny = np.finfo(np.float64).tiny
    seen = np.zeros(r, dtype=np.bool_)
    cand = basis.copy()
    for i in range(p):
        rowmax = 0.0
        for j in range(r):
            v = abs(M[i, j])
            if v > rowmax:
                rowmax = v
        best = -1.0
        pick = 0
        for j in range(r):
            v = abs(M[i, j])
            s = v if v >= CRASH_SHARE * rowmax else 0.0
            s = s / (colnorm[j] + tiny)
            if s > best:
                best = s
                pick = j
        if best > 0.0 and not seen[pick]:
            seen[pick] = True
            cand[i] = pick
    B = _basis_matrix(M, cand)
    inv = np.empty((p, p))
    if not _inverse(B, inv):
        return basis, Binv
    nb = 0.0
    ni = 0.0
    for j in range(p):
        sb = 0.0
        si = 0.0
        for i in range(p):
            sb += abs(B[i, j])
            si += abs(inv[i, j])
        nb = max(nb, sb)
        ni = max(ni, si)
    if not nb * ni <= CRASH_COND:
        return basis, Binv
    return cand, inv


def _refactor(M, basis, Binv):
    """Every problem's ``B^-1`` from its basis columns; a singular basis keeps its updated
    inverse (as the numpy path where the condition number is huge)."""
    p = M.shape[0]
    inv = np.empty((p, p))
    for k in range(basis.shape[0]):
        if _inverse(_basis_matrix(M, basis[k]), inv):
            Binv[k] = inv


def _duals(c, basis, Binv):
    """``mu_k = B_k^-T c_B`` of every problem."""
    K, p = basis.shape
    mu = np.zeros((K, p))
    for k in range(K):
        for j in range(p):
            cb = c[k, basis[k, j]]
            if cb != 0.0:
                for i in range(p):
                    mu[k, i] += Binv[k, j, i] * cb
    return mu


def _start(M, c, basis, Binv, z_old, use_old):
    """Nonbasic bounds ``z`` and dual slacks ``D`` of the bases (the signs of the reduced
    costs; with ``use_old``, a reduced cost zero up to rounding keeps its bound of ``z_old``)."""
    p, N = M.shape
    r = N - p
    K = c.shape[0]
    mu = _duals(c, basis, Binv)
    z = np.zeros((K, N))
    D = np.zeros((K, N))
    sv = np.empty(r)
    tv = np.empty(r)
    for k in range(K):
        # mu'M and |mu|'|M| over the columns, each entry summed in row order (row by row:
        # the loops run along the rows of M, the same sums as column by column)
        sv[:] = 0.0
        tv[:] = 0.0
        for i in range(p):
            m = mu[k, i]
            am = abs(m)
            row = M[i]
            for j in range(r):
                sv[j] += m * row[j]
                tv[j] += am * abs(row[j])
        for j in range(r):
            s = sv[j]
            t = tv[j]
            d = c[k, j] - s
            zj = math.copysign(1.0, d)
            if use_old and abs(d) <= DUAL_TOL * (abs(c[k, j]) + t) and z_old[k, j] != 0.0:
                zj = z_old[k, j]
            z[k, j] = zj
            D[k, j] = abs(d)
        for i in range(p):
            q = basis[k, i]
            z[k, q] = 0.0
            D[k, q] = 0.0
    return z, D


def _run(M, MT, b, up, colnorm2, key_mask, z, D, Binv, basis, uB, status, its, max_iter,
         refactor_every):
    """Iterations until every problem stops, refactorising at the pauses; the pivots done."""
    work = 0
    updates = 0
    while True:
        work += dual_simplex_jit.iterate(
            M, MT, b, up, colnorm2, key_mask, PRIMAL_TOL, PIVOT_TOL, refactor_every, z, D,
            Binv, basis, uB, status, its, updates, max_iter)
        paused = False
        for k in range(status.shape[0]):
            if status[k] == dual_simplex_jit.PAUSED:
                paused = True
        if not paused:
            return work
        _refactor(M, basis, Binv)
        updates = 0


def _certified(M, b, c, r, mu, z, Binv, uB, status, bounds):
    """:meth:`.dual_simplex._BatchLP.certified`: primal feasible bases with a negligible
    duality gap at ``mu``; ``bounds[k]`` the weak-duality bound of ``mu[k]`` for the costs
    ``c[k]`` (:func:`observers.lp.hull.dual_bounds`' formula and outward rounding: the slack
    bounds the rounding of any order of summation)."""
    p, N = M.shape
    K = mu.shape[0]
    good = np.zeros(K, dtype=np.bool_)
    t = np.empty(p)
    eps = np.finfo(np.float64).eps
    rowsum = np.zeros(p)
    for i in range(p):
        for j in range(r):
            rowsum[i] += abs(M[i, j])
    sv = np.empty(r)
    for k in range(K):
        for i in range(p):
            s = b[i]
            zk = z[k]
            row = M[i]
            for j in range(N):
                if zk[j] != 0.0:
                    s -= row[j] * zk[j]
            t[i] = s
        feasible = True
        for i in range(p):
            x = 0.0
            for j in range(p):
                x += Binv[k, i, j] * t[j]
            if not abs(x) - uB[k, i] <= PRIMAL_TOL:
                feasible = False
        gap = 0.0
        size = 0.0
        t1 = 0.0
        t2 = 0.0
        mu_a = 0.0
        for i in range(p):
            size += abs(b[i]) * abs(mu[k, i])
            t1 += mu[k, i] * b[i]
            mu_a += abs(mu[k, i]) * rowsum[i]
        scale_b = size
        sv[:] = 0.0  # mu'M over the columns, each entry summed in row order
        for i in range(p):
            m = mu[k, i]
            row = M[i]
            for j in range(r):
                sv[j] += m * row[j]
        for j in range(r):
            d = c[k, j] - sv[j]
            dz = d * z[k, j]
            if dz < 0.0:
                gap -= dz
            size += abs(c[k, j])
            t2 += abs(d)
        good[k] = (feasible and status[k] != dual_simplex_jit.UNBOUNDED
                   and 2.0 * gap <= GAP_TOL * size)
        # size - scale_b is sum |c_j|: the scale of dual_bounds' slack
        scale = scale_b + (size - scale_b) + mu_a + abs(t1) + t2
        bounds[k] = t1 + t2 + (p + r + 4) * eps * scale
    return good


def _solve_py(A, b, Gd, pert, max_iter, refactor_every):
    p, r = A.shape
    K = Gd.shape[0]
    N = r + p
    M = np.zeros((p, N))
    M[:, :r] = A
    for i in range(p):
        M[i, r + i] = 1.0
    MT = np.ascontiguousarray(M.T)
    colnorm = np.empty(N)
    for j in range(N):
        s = 0.0
        for i in range(p):
            s += M[i, j] * M[i, j]
        colnorm[j] = np.sqrt(s)
    colnorm2 = colnorm * colnorm
    up = np.zeros(N)
    up[:r] = 1.0
    bits = 1
    while (1 << bits) < K * N:
        bits += 1
    key_mask = np.uint64((1 << bits) - 1)
    # perturbed costs, the crash basis for every problem
    c = np.zeros((K, N))
    c[:, :r] = pert
    basis0, Binv0 = _crash(M, colnorm, r)
    basis = np.empty((K, p), dtype=np.int64)
    Binv = np.empty((K, p, p))
    uB = np.empty((K, p))
    for k in range(K):
        basis[k] = basis0
        Binv[k] = Binv0
        for i in range(p):
            uB[k, i] = up[basis0[i]]
    z, D = _start(M, c, basis, Binv, c, False)
    status = np.zeros(K, dtype=np.int64)
    its = np.zeros(K, dtype=np.int64)
    work = _run(M, MT, b, up, colnorm2, key_mask, z, D, Binv, basis, uB, status, its,
                max_iter, refactor_every)
    n_its = its.max() if K else 0
    _refactor(M, basis, Binv)
    c[:, :r] = Gd  # the exact costs
    mu = _duals(c, basis, Binv)
    bounds = np.empty(K)
    good = _certified(M, b, c, r, mu, z, Binv, uB, status, bounds)
    n_bad = K - int(good.sum())
    if n_bad and n_its < max_iter:  # clean-up with the exact costs
        sub = np.flatnonzero(~good)
        cs = c[sub]
        bs = basis[sub]
        Bs = Binv[sub]
        _refactor(M, bs, Bs)
        zs, Ds = _start(M, cs, bs, Bs, z[sub], True)
        us = np.empty((sub.size, p))
        for a in range(sub.size):
            for i in range(p):
                us[a, i] = up[bs[a, i]]
        ss = np.zeros(sub.size, dtype=np.int64)  # every one runs again (the numpy path too)
        its_s = np.zeros(sub.size, dtype=np.int64)
        work += _run(M, MT, b, up, colnorm2, key_mask, zs, Ds, Bs, bs, us, ss, its_s,
                     max_iter - n_its, refactor_every)
        n_its += its_s.max()
        _refactor(M, bs, Bs)
        mus = _duals(cs, bs, Bs)
        bounds_s = np.empty(sub.size)
        goods = _certified(M, b, cs, r, mus, zs, Bs, us, ss, bounds_s)
        for a in range(sub.size):
            mu[sub[a]] = mus[a]
            good[sub[a]] = goods[a]
            bounds[sub[a]] = bounds_s[a]
    return mu, good, n_its, work, bounds


def _hull_py(G, A, b, stream, max_iter, refactor_every):
    """The batched hull LPs of ``{c + G xi : A xi = b, |xi| <= 1}`` in the call: the columns
    in some constraint (``Gc``, ``Ac``), the costs ``[Gc; -Gc]`` perturbed by the factors
    ``stream`` (:func:`.dual_simplex._jitter`'s prefix, the same products as :func:`solve`),
    :func:`_solve_py` (compiled); and ``rad_free = sum_j |G_ij|`` over the other columns.
    Returns the bounds of ``max`` (rows ``0..n-1``) and of ``-min`` (rows ``n..2n-1``),
    which finished, the lock-step and summed iterations, ``rad_free``, the number of free
    columns and the coupled columns' indices."""
    n, R = G.shape
    p = A.shape[0]
    cols = np.empty(R, dtype=np.int64)
    rc = 0
    rad_free = np.zeros(n)
    for j in range(R):
        coupled = False
        for i in range(p):
            if A[i, j] != 0.0:
                coupled = True
                break
        if coupled:
            cols[rc] = j
            rc += 1
        else:
            for i in range(n):
                rad_free[i] += abs(G[i, j])
    cols = cols[:rc]
    K = 2 * n
    Ac = np.empty((p, rc))
    Gd = np.empty((K, rc))
    pert = np.empty((K, rc))
    for a in range(rc):
        j = cols[a]
        for i in range(p):
            Ac[i, a] = A[i, j]
        for i in range(n):
            Gd[i, a] = G[i, j]
            Gd[n + i, a] = -G[i, j]
    for k in range(K):
        for a in range(rc):
            pert[k, a] = Gd[k, a] * (1.0 + PERTURBATION * stream[k * rc + a])
    mu, good, its, work, bounds = _solve_jit(Ac, b, Gd, pert, max_iter, refactor_every)
    return bounds, good, its, work, rad_free, R - rc, cols


if AVAILABLE:
    _inverse, _basis_matrix, _crash, _refactor, _duals, _start, _run, _certified = (
        numba.njit(cache=True, nogil=True, error_model="numpy")(f) for f in (
            _inverse, _basis_matrix, _crash, _refactor, _duals, _start, _run, _certified))
    _solve_jit = numba.njit(cache=True, nogil=True, error_model="numpy")(_solve_py)
    _hull_jit = numba.njit(cache=True, nogil=True, error_model="numpy")(_hull_py)
else:  # pragma: no cover - depends on the installation
    _solve_jit = _hull_jit = None


@dataclass(frozen=True)
class HullResult:
    """:func:`hull`'s result: ``bounds`` (2n: the maxima of ``G_i xi``, then of ``-G_i xi``,
    over the constrained columns), which finished, the work, ``rad_free`` (n), the number of
    free columns and the constrained ones (``cols``)."""

    bounds: np.ndarray
    converged: np.ndarray
    iterations: int
    problem_iterations: int
    rad_free: np.ndarray
    free: int
    cols: np.ndarray


def hull(G: np.ndarray, A: np.ndarray, b: np.ndarray, max_iter: int | None = None,
         seed: int = 0, refactor_every: int | None = None) -> HullResult:
    """The 2n batched hull LPs of ``{c + G xi : A xi = b, |xi| <= 1}`` (``p >= 1``
    constraints, at least one column in a constraint), split into constrained and free
    columns, solved by :func:`solve`'s method and bounded by weak duality, in one compiled
    call: the numbers of ``solve(A[:, cols], b, [Gc; -Gc])`` and its ``bounds``.  Requires
    numba (:data:`AVAILABLE`)."""
    if _hull_jit is None:
        raise RuntimeError("the compiled batched hull needs numba")
    G = np.ascontiguousarray(G, dtype=np.float64)
    A = np.ascontiguousarray(A, dtype=np.float64)
    b = np.ascontiguousarray(b, dtype=np.float64)
    (n, R), p = G.shape, A.shape[0]
    if max_iter is None:
        max_iter = dual_simplex.max_iterations(p)
    if refactor_every is None:
        refactor_every = dual_simplex.REFACTOR_EVERY
    if 2 * n * (R + p) > 1 << 32:
        raise ValueError(f"too many LPs or columns for one batch ({2 * n} x {R + p})")
    stream = _jitter((2 * n, R), seed).reshape(-1)  # a prefix long enough for any split
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        bounds, good, its, work, rad_free, free, cols = _hull_jit(
            G, A, b, stream, int(max_iter), int(refactor_every))
    return HullResult(bounds, good, int(its), int(work), rad_free, int(free), cols)


def solve(A: np.ndarray, b: np.ndarray, Gd: np.ndarray, max_iter: int | None = None,
          seed: int = 0, refactor_every: int | None = None) -> DualSimplexResult:
    """Dual points of ``max Gd[k]' xi  s.t.  A xi = b, |xi| <= 1`` for every row ``k``, as
    :func:`.dual_simplex.solve` (same method, same perturbation for ``seed``, the same
    iteration budget and the bases refactorised every ``refactor_every`` updates, by default
    :data:`.dual_simplex.REFACTOR_EVERY`) in one compiled call; ``seconds`` holds the whole
    call as ``"solve"``.  Requires numba (:data:`AVAILABLE`)."""
    if _solve_jit is None:
        raise RuntimeError("the compiled batched solve needs numba")
    from time import perf_counter

    A = np.ascontiguousarray(A, dtype=np.float64)
    b = np.ascontiguousarray(b, dtype=np.float64)
    Gd = np.ascontiguousarray(np.atleast_2d(np.asarray(Gd, dtype=np.float64)))
    p, K = A.shape[0], Gd.shape[0]
    if max_iter is None:
        max_iter = dual_simplex.max_iterations(p)
    if refactor_every is None:
        refactor_every = dual_simplex.REFACTOR_EVERY
    if p == 0:
        return DualSimplexResult(np.zeros((K, 0)), np.ones(K, bool), 0, 0)
    if K * (A.shape[1] + p) > 1 << 32:
        raise ValueError(f"too many LPs or columns for one batch ({K} x {A.shape[1] + p})")
    t0 = perf_counter()
    pert = Gd * (1.0 + PERTURBATION * _jitter(Gd.shape, seed))
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        mu, good, its, work, bounds = _solve_jit(A, b, Gd, pert, int(max_iter),
                                                 int(refactor_every))
    return DualSimplexResult(mu, good, int(its), int(work), {"solve": perf_counter() - t0},
                             bounds)
