"""Approximate scores of the axis exchanges of ROPO's generator-axes search, with error bounds
(compiled, numba).

The search (:func:`observers.numerics.ropo.generator_axes`) holds the tableau ``M = B^-1 G``
(n x r) and scores the exchange of axis ``i`` for generator ``k`` by the log volume after the
pivot on ``(i, k)``::

    score(k, i) = log ||M_i||_1 + sum_{l != i} log phi_li(t_kl),
    phi_li(t) = sum_j |M_lj - t M_ij|,   t_kl = M_lk / M_ik.

Scoring every pair directly costs ``K n^2 r`` (``K`` generators outside the axes).  Here
``phi_li`` is seen as a convex piecewise-linear function of ``t`` with breakpoints
``b_j = M_lj / M_ij`` and weights ``|M_ij|`` (columns with ``M_ij = 0`` add the constant
``|M_lj|``), and ``t_kl`` is itself the breakpoint of column ``k``: after one sort, prefix sums
give ``phi_li`` at every breakpoint, ``phi(t) = t (W_le - W_gt) - (S_le - S_gt) + const``
(``W``: weights, ``S``: weights times breakpoints, at or below / above ``t``), so all pairs
cost ``n^2 r log r``.  Entries of ``M_i`` at most :data:`NEGLIGIBLE` times its 1-norm count
as zero there: a column ``j`` of them adds ``|M_lj|`` instead of ``|M_lj - t M_ij|``, off by
at most ``|t| |M_ij|``, and their sum ``|t| nu_i`` (``nu_i``: the 1-norm of the neglected
entries) is added to the error bound below.  After a few exchanges the identity columns of
the tableau carry rounding entries of about 1e-17 in every row; left in, each row had a
breakpoint in almost every column (390 of 400 at 200 tanks), left out 20-30.

The values differ from the direct sums by rounding, so the caller uses them only to shortlist:
with ``e`` a bound on the error of both ways, every pair whose approximate score is more than
the band of :func:`observers.numerics.linalg.first_best` above the least possible score is
provably not chosen, and the shortlisted pairs are scored again by the direct formula. The
bound: a sum of ``m`` products in any order is within ``gamma_m`` of the sum of their
magnitudes (Higham, Sec. 3.1); the magnitudes in ``phi_li(t)`` add up to at most ``||M_l||_1 +
|t| ||M_i||_1``, so ``|phi~ - phi| <= e_l = 2 (r + 8) eps (||M_l||_1 + |t| ||M_i||_1) + |t|
nu_i (1 + gamma)``, the logarithm moves by at most ``e_l / (phi~ - e_l)``, and the sum over
``l`` of the logarithms (and their own rounding) by ``(n + 2) eps sum |log phi|``; the direct
sums are bounded the same way. Pairs without a bound (a ``phi`` within its error of zero) are
always scored directly; the band around the least known score also covers the case that the
least score is such a pair's (if ``d`` is below the least lower bound ``L <= U``, then
``TIE_RTOL (|d| - max(|U|, |L|)) <= L - d <= U - d``). Without numba :data:`exchange_scores` is
``None`` and the caller scores every pair directly.
"""

from __future__ import annotations

import math

import numpy as np

from .switch import njit

#: entries of the pivot row at most this times its 1-norm (the unit roundoff of the row's
#: largest entries) are left out of the breakpoints: their term ``|M_lj - t M_ij|`` counts as
#: ``|M_lj|``, off by at most ``|t M_ij|``, which the error bound adds (a subnormal entry
#: would also put a breakpoint at infinity)
NEGLIGIBLE = 2.0**-52


def _exchange_scores_py(M, out, ok):
    """``(approx, err)`` (``K x n``): approximate scores of the exchanges ``(out[kk], i)``
    with ``ok[kk, i]`` and a bound on the distance of both the approximate and the direct
    score from the exact one (``inf`` and ``0`` for the other pairs; ``nan`` where a value of
    ``phi`` is within its error bound of zero, so that no bound holds: score it directly)."""
    n, r = M.shape
    K = out.shape[0]
    eps = 2.220446049250313e-16
    gamma = 2.0 * (r + 8) * eps
    tiny = 1e-300
    approx = np.full((K, n), np.inf)
    err = np.zeros((K, n))
    rowabs = np.zeros(n)
    for p in range(n):
        acc = 0.0
        for j in range(r):
            acc += abs(M[p, j])
        rowabs[p] = acc
    pos = np.full(r, -1, dtype=np.int64)
    for kk in range(K):
        pos[out[kk]] = kk
    b = np.empty(r)
    w = np.empty(r)
    cols = np.empty(r, dtype=np.int64)
    logs = np.zeros((K, n))  # sum of |log phi| per pair, for the bound of the log sum
    for i in range(n):
        any_ok = False
        for kk in range(K):
            if ok[kk, i]:
                any_ok = True
                approx[kk, i] = math.log(rowabs[i])
                logs[kk, i] = abs(approx[kk, i])
                if not abs(M[i, out[kk]]) > NEGLIGIBLE * rowabs[i]:
                    approx[kk, i] = np.nan  # its own breakpoint is left out: no bound
        if not any_ok:
            continue
        small = NEGLIGIBLE * rowabs[i]
        nu = 0.0  # 1-norm of the neglected entries of row i
        for j in range(r):
            if not abs(M[i, j]) > small:
                nu += abs(M[i, j])
        nu *= 1.0 + gamma
        for l in range(n):
            if l == i:
                continue
            m = 0
            const = 0.0
            for j in range(r):
                a = M[i, j]
                if abs(a) > small:
                    b[m] = M[l, j] / a
                    w[m] = abs(a)
                    cols[m] = j
                    m += 1
                else:
                    const += abs(M[l, j])
            order = np.argsort(b[:m])
            w_tot = 0.0
            s_tot = 0.0
            for q in range(m):
                w_tot += w[q]
                s_tot += w[q] * b[q]
            w_le = 0.0
            s_le = 0.0
            for q in range(m):
                jj = order[q]
                t = b[jj]
                w_le += w[jj]
                s_le += w[jj] * b[jj]
                kk = pos[cols[jj]]
                if kk < 0 or not ok[kk, i]:
                    continue
                phi = t * (w_le - (w_tot - w_le)) - (s_le - (s_tot - s_le)) + const
                e = gamma * (rowabs[l] + abs(t) * rowabs[i]) + abs(t) * nu
                low = phi - e
                if low > tiny:
                    lg = math.log(phi)
                    approx[kk, i] += lg
                    logs[kk, i] += abs(lg)
                    err[kk, i] += 2.0 * e / low
                else:  # too close to zero to bound: no shortcut for this pair
                    approx[kk, i] = np.nan
    for kk in range(K):
        for i in range(n):
            if ok[kk, i]:
                # the log sum's rounding; the row sum of row i (relative gamma) and the direct
                # score's log |M_ik| + log(||M_i||_1 / |M_ik|), which the approximation folds
                pivot = abs(math.log(abs(M[i, out[kk]])))
                err[kk, i] += (2.0 * (n + 2) * eps * logs[kk, i] + 4.0 * gamma
                               + 64.0 * eps * (1.0 + pivot))
    return approx, err


#: the compiled scores (``None`` without numba)
exchange_scores = njit(_exchange_scores_py, error_model="numpy")
