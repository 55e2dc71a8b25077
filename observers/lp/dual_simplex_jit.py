"""Compiled (numba) iterations of the batched bounded dual simplex (:mod:`.dual_simplex`).

:func:`iterate` runs the dual simplex iterations of :meth:`.dual_simplex._BatchLP.iterate`
in machine code instead of over numpy arrays (in lock step too, with the pivot rows of all
problems as one BLAS product, and the rest of each pivot problem by problem): the same
leaving-row rule (dual steepest edge), the same bound-flipping ratio test with the same
integer sort keys (so ties break the same way), the same pivots and the same refactorisation
points (every :data:`REFACTOR_EVERY` updates; the kernel pauses there and the caller
refactorises with numpy, as the numpy path does).  The iterates are therefore the same; only
rounding differs (summation order, and ``b - M z`` is updated with the changes of ``z`` instead
of recomputed: 10 % of the kernel's time on the vehicle), far below every tolerance.

numba is optional: :data:`AVAILABLE` is false when it is not installed or when the
environment variable ``SETOBS_NUMBA=0`` disables it, and :mod:`.dual_simplex` then runs its
numpy iterations.  Compiled functions are cached on disk (``cache=True``), so only the first
process after a change pays the compilation (a few seconds).
"""

from __future__ import annotations

import numpy as np

from ..kernels.switch import AVAILABLE, numba

#: status codes of a problem after :func:`iterate`
RUNNING, OPTIMAL, UNBOUNDED, PAUSED, BUDGET = 0, 1, 2, 3, 4


def _iterate_py(M, MT, b, up, colnorm2, key_mask, primal_tol, pivot_tol, refactor_every,
                z, D, Binv, basis, uB, status, its, updates, max_iter):
    """Iterations of every problem whose ``status`` is ``RUNNING`` or ``PAUSED`` (in place).

    A problem stops when it is primal feasible (``OPTIMAL``), when its ratio test finds no
    usable entering column (``UNBOUNDED``: empty set or a tiny pivot element, left to HiGHS),
    when ``its[k]`` reaches ``max_iter`` (``BUDGET``) or when ``updates`` reaches
    ``refactor_every`` (``PAUSED``: the caller refactorises ``Binv`` and calls again with
    ``updates = 0``).  Returns the number of pivots (summed over the problems).

    The problems pivot in lock step: at each pivot the pivot rows ``rho' M`` of all problems
    still iterating are one matrix product (BLAS reads ``M`` once for all of them instead of
    once per problem: three quarters of a problem-by-problem pivot's time went into that
    product on the 30-tank hulls); every other part of a pivot runs problem by problem.
    Each problem takes the pivots it would take alone.
    """
    p, N = M.shape
    K = z.shape[0]
    high = ~key_mask
    work = 0
    T = np.empty((K, p))  # t = b - M z of each problem, updated with every change of z
    xB = np.empty(p)
    colq = np.empty(p)
    R = np.empty((K, p))  # pivot rows e_rr' B^-1 of the problems pivoting
    act = np.empty(K, dtype=np.int64)
    rows = np.empty(K, dtype=np.int64)
    deltas = np.empty(K)
    wrrs = np.empty(K)
    sgns = np.empty(K)
    keys = np.empty(N, dtype=np.uint64)
    flips = np.empty(N, dtype=np.int64)
    ratio = np.empty(1)
    rbits = ratio.view(np.uint64)
    Mz = np.dot(z, MT)  # M z of every problem, one product
    for k in range(K):
        if status[k] != RUNNING and status[k] != PAUSED:
            continue
        status[k] = RUNNING
        for i in range(p):
            T[k, i] = b[i] - Mz[k, i]
    upd = updates
    while True:
        # every running problem: basic values xB = B^-1 t and its leaving row
        na = 0
        for k in range(K):
            if status[k] != RUNNING:
                continue
            if its[k] >= max_iter:
                status[k] = BUDGET
                continue
            if upd >= refactor_every:
                status[k] = PAUSED
                continue
            Bk, uk, t = Binv[k], uB[k], T[k]
            rr = 0
            best = -1.0
            delta = 0.0
            wrr = 0.0
            for i in range(p):
                s = 0.0
                q2 = 0.0
                for j in range(p):
                    s += Bk[i, j] * t[j]
                    q2 += Bk[i, j] * Bk[i, j]
                xB[i] = s
                v = abs(s) - uk[i]
                if v < 0.0:
                    v = 0.0
                score = v * v / q2
                if score > best:
                    best = score
                    rr = i
                    delta = v
                    wrr = q2
            if not delta > primal_tol:
                status[k] = OPTIMAL
                continue
            sgns[na] = 1.0 if xB[rr] > 0.0 else -1.0  # above the upper bound: leaves at it
            for j in range(p):
                R[na, j] = Bk[rr, j]
            act[na] = k
            rows[na] = rr
            deltas[na] = delta
            wrrs[na] = wrr
            na += 1
        if na == 0:
            break
        Wm = np.dot(R[:na], M)  # alpha = rho' M of every pivoting problem
        for a in range(na):
            k = act[a]
            rr, sgn, delta, wrr = rows[a], sgns[a], deltas[a], wrrs[a]
            zk, Dk, Bk, bk, uk, t = z[k], D[k], Binv[k], basis[k], uB[k], T[k]
            rho = R[a]
            w = Wm[a]
            # ratio test with bound flipping: candidates w_j = z_j alpha_j > 0, ordered by
            # keys holding the high bits of D_j / w_j and the column index in the low bits
            nc = 0
            for j in range(N):  # branch-free: every key is written, kept if a candidate
                wj = -sgn * w[j] * zk[j]
                w[j] = wj
                ratio[0] = Dk[j] / wj
                keys[nc] = (rbits[0] & high) | np.uint64(j)
                nc += wj > 0.0
            its[k] += 1  # counted before the ratio test decides, as in the numpy path
            work += 1
            q, npass = _pass_breakpoints(keys, nc, key_mask, w, delta, flips)
            found = q >= 0
            if found:
                wq = w[q]
                found = wq * wq >= pivot_tol * pivot_tol * wrr * colnorm2[q]
            if not found:  # dual unbounded (empty set) or trouble: HiGHS takes over
                status[k] = UNBOUNDED
                continue
            tq = Dk[q] / w[q]
            # dual step; the breakpoints passed flip to their other bound
            for j in range(N):
                Dk[j] = abs(Dk[j] - tq * w[j])
            for f in range(npass):
                j = flips[f]
                zj = zk[j]
                for i in range(p):
                    t[i] += 2.0 * MT[j, i] * zj
                zk[j] = -zj
            la = bk[rr]
            zla = sgn * uk[rr]
            zq = zk[q]
            for i in range(p):
                t[i] += MT[q, i] * zq - MT[la, i] * zla
            zk[la] = zla
            zk[q] = 0.0
            Dk[la] = tq
            Dk[q] = 0.0
            bk[rr] = q
            uk[rr] = up[q]
            # product-form update of B^-1
            for i in range(p):
                s = 0.0
                for j in range(p):
                    s += Bk[i, j] * M[j, q]
                colq[i] = s
            piv = colq[rr]
            for j in range(p):
                rho[j] = rho[j] / piv
            for i in range(p):
                if i != rr:
                    c = colq[i]
                    for j in range(p):
                        Bk[i, j] -= c * rho[j]
            for j in range(p):
                Bk[rr, j] = rho[j]
        upd += 1
    return work


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


def _heapify(h, n):
    """Make ``h[:n]`` a binary min-heap."""
    for i in range(n // 2 - 1, -1, -1):
        _sift_down(h, i, n)


def _pop_min(h, n):
    """Remove the least entry of the min-heap ``h[:n]`` and return it (the heap is then
    ``h[:n - 1]``)."""
    x = h[0]
    h[0] = h[n - 1]
    _sift_down(h, 0, n - 1)
    return x


def _pass_breakpoints(keys, nc, mask, w, delta, flips):
    """The breakpoint pass of the bound-flipping ratio test (Fourer), shared by this module's
    dual simplex and the restricted LPs of :mod:`.sifting_jit`: ``(entering, passed)``.

    ``keys[:nc]`` are the candidates ``w_j > 0``, each the high bits of its ratio
    ``D_j / w_j`` (non-negative floats order like their bit patterns) with its index ``j`` in
    the bits ``mask``; they are passed in increasing order (a binary heap: usually only a
    prefix of them is passed) while the slope, ``delta`` less ``2 w_j`` per breakpoint
    passed, stays positive.  The entering index is the breakpoint at which it no longer does
    (``-1`` if none: the dual is unbounded); the ``passed`` breakpoints before it are
    ``flips[:passed]`` (they flip to their other bound).  ``keys`` is reordered.
    """
    _heapify(keys, nc)
    total = 0.0
    npass = 0
    while nc > 0:
        j = np.int64(_pop_min(keys, nc) & mask)
        nc -= 1
        total += w[j]
        if total >= 0.5 * delta:  # slope lost per breakpoint: 2 w_j
            return j, npass
        flips[npass] = j
        npass += 1
    return np.int64(-1), npass


if AVAILABLE:
    _sift_down = numba.njit(cache=True, nogil=True)(_sift_down)
    _heapify = numba.njit(cache=True, nogil=True)(_heapify)
    _pop_min = numba.njit(cache=True, nogil=True)(_pop_min)
    _pass_breakpoints = numba.njit(cache=True, nogil=True)(_pass_breakpoints)
    iterate = numba.njit(cache=True, error_model="numpy", nogil=True)(_iterate_py)
else:  # pragma: no cover - depends on the installation
    iterate = None
