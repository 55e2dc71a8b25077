"""Compiled (numba) one-step formulas of the zonotopic observer families: one kernel call per
step instead of about 30-80 numpy calls.

On the 6-state vehicle (a 6 x ~600 generator matrix) a step of a zonotope observer costs a few
tens of thousands of flops, and the numpy path spends most of its time in per-call overhead
(about 1 us per call).  The kernels run the formulas of :mod:`observers.families` and
:mod:`observers.numerics.frad` in the same order of operations, then the order reduction of
:func:`reduce` (below), so the sets are those of the numpy path up to rounding:

* :func:`strip_step`: prediction ``(A c + d + c_W, [A G, E])``, intersection with the
  strips ``|C x - y| <= sigma`` (:func:`observers.families.strip_update`) with the gain chosen
  by ``mode``, reduction;
* :func:`propagate_step`: ``S+ = (A - L C) S + d + L y + (-L) V + W``
  (:func:`observers.families.propagate`) with a given gain or Combastel's, reduction;
* :func:`bravo_step`: prediction, Bravo's choice of the least ``det(T T')`` candidate strip by
  strip (VolMin-B, :mod:`observers.numerics.volmin`), reduction.

Gain modes of :func:`strip_step`: :data:`GIVEN` (``L``, all strips at once: PRad-B/C/D),
:data:`PER_STRIP` (column ``i`` of ``L`` for strip ``i``, one strip after the other: PRad-A),
:data:`ALAMO` (FRad-A, :func:`observers.numerics.frad.alamo_frad_strips`), :data:`WANG`
(FRad-B, :func:`observers.numerics.frad.wang_frad_gain`, with ``A`` applied once more when
``wang_cora`` is true).  :func:`propagate_step` takes :data:`GIVEN` (Nom-G, PRad-E) or
:data:`COMBASTEL` (FRad-C, :func:`observers.numerics.frad.combastel_gain`).

A kernel returns ``ok = False`` when it cannot vouch for the numpy path's result (a
non-finite entry, a singular matrix in a gain): the caller then runs the numpy path for that
step, which knows the fallbacks (pseudo-inverse, zero gain).

Order reductions (:func:`reduce`, also used alone by :class:`.reduction.Girard` and
:class:`.reduction.PCA`): as one kernel call each.

On the 6-state vehicle (order 100: a 6 x ~610 generator matrix) the numpy reductions cost
about 70 numpy calls of a microsecond or more each (zero-column scan, metric, partition,
gathers, the QR and SVD, the cluster bases of :func:`.reduction.principal_axes`), most of the
step of every zonotope observer.  :func:`reduce` runs the same definition in machine code:

1. all-zero columns dropped;
2. nothing else if at most ``n * order`` columns remain;
3. else the ``r - floor(n (order - 1))`` columns with the smallest ``||g||_1 - ||g||_inf``
   (stable sort: ties by column index) are reduced, the others kept in their order;
4. ``[G_kept, box]``: the diagonal box of the reduced columns (Girard) or the box aligned with
   their principal axes, computed as in :func:`.reduction.principal_axes` (SVD of the
   triangular factor of a QR of ``G_red'`` when there are more columns than rows, clusters of
   repeated singular values, the pivoted-Cholesky basis of each cluster's projector).

The result is the same set as the numpy path up to rounding (numba's LAPACK is SciPy's
OpenBLAS, numpy's its own: summation orders differ in the last bits).  A matrix with a
non-finite entry is left to the numpy path (status ``False``), whose stable sort decides
where NaNs go.

The reduction and step kernels share this module on purpose: numba's on-disk cache is keyed by
the source file of the cached function only, and a step kernel links the reduction into its
machine code, so a reduction kept in another file could change without invalidating the
cached step kernels.
"""

from __future__ import annotations

import math

import numpy as np

from ._jit import AVAILABLE, njit

GIVEN, PER_STRIP, ALAMO, WANG, COMBASTEL, BRAVO = 0, 1, 2, 3, 4, 5
#: CORA's threshold below which ``c g_j`` counts as zero in Bravo's choice (candidate j = the
#: unchanged zonotope); :data:`observers.numerics.volmin.ZERO_PROJECTION` is this value
BRAVO_ZERO_PROJECTION = 1e10 * np.finfo(float).eps
#: reduction methods of :func:`reduce`
GIRARD, PCA = 0, 1


def _cluster_basis_into(P, out, col0, m, pivot_rtol):
    """Pivoted-Cholesky basis of the projector ``P`` (n x n, rank ``m``) into
    ``out[:, col0:col0 + m]`` (:func:`.reduction._cluster_basis`; ``P`` is overwritten)."""
    n = P.shape[0]
    for i in range(m):
        dmax = -np.inf
        for a in range(n):
            if P[a, a] > dmax:
                dmax = P[a, a]
        thr = (1.0 - pivot_rtol) * dmax
        j = 0
        for a in range(n):
            if P[a, a] >= thr:
                j = a
                break
        s = math.sqrt(P[j, j])
        for a in range(n):
            out[a, col0 + i] = P[a, j] / s
        for a in range(n):
            va = out[a, col0 + i]
            for b in range(n):
                P[a, b] -= va * out[b, col0 + i]


def _pairwise_block(a, start, m):
    """``a[start:start + m].sum()`` for ``m <= 128`` in numpy's order of operations (eight
    accumulators)."""
    if m < 8:
        res = 0.0
        for i in range(m):
            res += a[start + i]
        return res
    r0 = a[start]
    r1 = a[start + 1]
    r2 = a[start + 2]
    r3 = a[start + 3]
    r4 = a[start + 4]
    r5 = a[start + 5]
    r6 = a[start + 6]
    r7 = a[start + 7]
    i = 8
    while i < m - (m % 8):
        r0 += a[start + i]
        r1 += a[start + i + 1]
        r2 += a[start + i + 2]
        r3 += a[start + i + 3]
        r4 += a[start + i + 4]
        r5 += a[start + i + 5]
        r6 += a[start + i + 6]
        r7 += a[start + i + 7]
        i += 8
    res = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
    while i < m:
        res += a[start + i]
        i += 1
    return res


def _pairwise_sum(a, m):
    """``a[:m].sum()`` of a contiguous ``a`` in numpy's order of operations (pairwise
    summation: halves rounded down to a multiple of 8 above 128 entries, :func:`_pairwise_block`
    below), so that the Girard box of a one-row matrix equals numpy's bit for bit.  Iterative
    (an explicit stack): numba's on-disk cache mishandles recursive functions."""
    if m <= 128:
        return _pairwise_block(a, 0, m)
    st_start = np.empty(64, dtype=np.int64)
    st_m = np.empty(64, dtype=np.int64)
    st_phase = np.zeros(64, dtype=np.int64)
    st_left = np.empty(64)
    sp = 1
    st_start[0], st_m[0], st_phase[0] = 0, m, 0
    result = 0.0
    while sp > 0:
        top = sp - 1
        s, mm = st_start[top], st_m[top]
        half = mm // 2
        half -= half % 8
        if mm <= 128 or st_phase[top] == 2:
            if mm <= 128:
                val = _pairwise_block(a, s, mm)
            else:
                val = st_left[top]
            sp -= 1
            if sp == 0:
                result = val
            elif st_phase[sp - 1] == 1:
                st_left[sp - 1] = val
            else:  # the right half of the parent: its sum is left + right
                st_left[sp - 1] = st_left[sp - 1] + val
        elif st_phase[top] == 0:
            st_phase[top] = 1
            st_start[sp], st_m[sp], st_phase[sp] = s, half, 0
            sp += 1
        else:
            st_phase[top] = 2
            st_start[sp], st_m[sp], st_phase[sp] = s + half, mm - half, 0
            sp += 1
    return result


def _smallest(h, r, k):
    """Indices of the ``k`` smallest of ``h[:r]`` in the order of a stable sort (ties by
    index), then the others: ``argsort(h[:r], kind="stable")`` with the first ``k`` found by
    insertion into a sorted buffer (``k`` is usually a few percent of ``r``)."""
    if 4 * k >= r:
        return np.argsort(h[:r], kind="mergesort")
    buf = np.empty(k, dtype=np.int64)
    m = 0
    for j in range(r):
        v = h[j]
        if m == k:
            if not (v < h[buf[k - 1]]):  # later index: equal values lose
                continue
            m -= 1
        q = m
        while q > 0 and v < h[buf[q - 1]]:
            buf[q] = buf[q - 1]
            q -= 1
        buf[q] = j
        m += 1
    out = np.empty(r, dtype=np.int64)
    out[:k] = buf
    return out


#: in the step kernels, up to this dimension the principal axes come from :func:`_jacobi_left`
#: (no LAPACK call: the QR and SVD of numba's LAPACK wrappers cost about 15 us of copies and
#: workspace queries on a 6 x 14 matrix); above it from LAPACK as in the numpy path.  The
#: reductions called alone (:class:`.reduction.PCA`, e.g. the lifted reductions of the CZN
#: observers, whose hulls amplify a 1e-13 change of the axes to 1e-3 of an RMS radius on the
#: 6-tank record) keep LAPACK's QR and SVD, as the numpy path
JACOBI_MAX_DIM = 12


def _jacobi_left(red):
    """Left singular vectors ``U`` (n x n, orthonormal) and singular values ``s`` (descending)
    of ``red`` (n x k) by one-sided Jacobi (Hestenes) on the rows of ``red``: plane rotations
    ``J'`` make the rows of ``J' red`` orthogonal, so ``red' J = W`` with orthogonal columns,
    ``U = J`` and ``s`` the row norms (accurate to rounding relative to ``||red||``, like the
    SVD).  ``J`` stays orthogonal for any rank, so zero singular values get a basis too."""
    n, k = red.shape
    Y = red.copy()
    J = np.eye(n)
    for _ in range(80):
        rotated = False
        for p in range(n - 1):
            for q in range(p + 1, n):
                alpha = 0.0
                beta = 0.0
                gamma = 0.0
                for i in range(k):
                    alpha += Y[p, i] * Y[p, i]
                    beta += Y[q, i] * Y[q, i]
                    gamma += Y[p, i] * Y[q, i]
                if gamma == 0.0 or abs(gamma) <= 1e-15 * math.sqrt(alpha * beta):
                    continue
                rotated = True
                zeta = (beta - alpha) / (2.0 * gamma)
                t = 1.0 / (abs(zeta) + math.sqrt(1.0 + zeta * zeta))
                if zeta < 0.0:
                    t = -t
                cs = 1.0 / math.sqrt(1.0 + t * t)
                sn = cs * t
                for i in range(k):
                    yp = Y[p, i]
                    yq = Y[q, i]
                    Y[p, i] = cs * yp - sn * yq
                    Y[q, i] = sn * yp + cs * yq
                for i in range(n):
                    jp = J[i, p]
                    jq = J[i, q]
                    J[i, p] = cs * jp - sn * jq
                    J[i, q] = sn * jp + cs * jq
        if not rotated:
            break
    s = np.empty(n)
    for p in range(n):
        acc = 0.0
        for i in range(k):
            acc += Y[p, i] * Y[p, i]
        s[p] = math.sqrt(acc)
    order = np.argsort(-s, kind="mergesort")
    U = np.empty((n, n))
    s_sorted = np.empty(n)
    for j in range(n):
        s_sorted[j] = s[order[j]]
        for i in range(n):
            U[i, j] = J[i, order[j]]
    return U, s_sorted


def _principal_axes(red, cluster_rtol, pivot_rtol, jacobi_dim):
    """:func:`.reduction.principal_axes` (n x n orthonormal axes of the columns ``red``), by
    :func:`_jacobi_left` if ``n <= jacobi_dim``."""
    n, k = red.shape
    if n <= jacobi_dim:
        U, s = _jacobi_left(red)
    else:
        if k > n:
            _, R = np.linalg.qr(np.ascontiguousarray(red.T))
            U, s0, _ = np.linalg.svd(np.ascontiguousarray(R.T))
        else:
            U, s0, _ = np.linalg.svd(red)
        s = np.zeros(n)
        s[: s0.size] = s0
    tol = cluster_rtol * s[0]
    out = np.empty((n, n))
    P = np.empty((n, n))
    a = 0
    while a < n:
        b = a + 1
        while b < n and not (s[b - 1] - s[b] > tol):
            b += 1
        for i in range(n):  # P = V V' with V = U[:, a:b]
            for j in range(n):
                acc = 0.0
                for q in range(a, b):
                    acc += U[i, q] * U[j, q]
                P[i, j] = acc
        _cluster_basis_into(P, out, a, b - a, pivot_rtol)
        a = b
    return out


def _reduce_py(G, order, method, cluster_rtol, pivot_rtol, jacobi_dim):
    """The reduced generators and ``True``, or an empty matrix and ``False`` when ``G`` has a
    non-finite entry (left to the numpy path).  ``order`` is checked by the caller."""
    n, r0 = G.shape
    norm1 = np.empty(r0)
    h = np.empty(r0)
    nz = np.empty(r0, dtype=np.int64)
    r = 0
    for j in range(r0):
        s1 = 0.0
        mx = 0.0
        for i in range(n):
            v = abs(G[i, j])
            s1 += v
            if v > mx:
                mx = v
        if not math.isfinite(s1):
            return np.empty((n, 0)), False
        norm1[j] = s1
        if s1 != 0.0:
            nz[r] = j
            h[r] = s1 - mx
            r += 1
    if r <= n * order:
        if r == r0:
            return G.copy(), True
        out = np.empty((n, r))
        for i in range(n):
            for q in range(r):
                out[i, q] = G[i, nz[q]]
        return out, True
    n_keep = int(math.floor(n * (order - 1)))
    n_red = r - n_keep
    ranked = _smallest(h, r, n_red)
    is_red = np.zeros(r, dtype=np.bool_)
    for q in range(n_red):
        is_red[ranked[q]] = True
    out = np.zeros((n, n_keep + n))
    kept = np.empty(n_keep, dtype=np.int64)
    q = 0
    for p in range(r):
        if not is_red[p]:
            kept[q] = nz[p]
            q += 1
    for i in range(n):  # row by row: contiguous reads and writes
        for q in range(n_keep):
            out[i, q] = G[i, kept[q]]
    if method == GIRARD:
        # numpy sums |G_red| (a column gather: Fortran-ordered) column after column, except
        # for a single row (then also C-contiguous: pairwise summation); the same order here
        if n == 1:
            row = np.empty(n_red)
            for q in range(n_red):
                row[q] = abs(G[0, nz[ranked[q]]])
            out[0, n_keep] = _pairwise_sum(row, n_red)
        else:
            for q in range(n_red):
                j = nz[ranked[q]]
                for i in range(n):
                    out[i, n_keep + i] += abs(G[i, j])
        return out, True
    red = np.empty((n, n_red))
    for q in range(n_red):
        j = nz[ranked[q]]
        for i in range(n):
            red[i, q] = G[i, j]
    U = _principal_axes(red, cluster_rtol, pivot_rtol, jacobi_dim)
    proj = np.dot(np.ascontiguousarray(U.T), red)
    for a in range(n):
        box = 0.0
        for q in range(n_red):
            box += abs(proj[a, q])
        for i in range(n):
            out[i, n_keep + a] = U[i, a] * box
    return out, True


def _finite(a):
    for v in a.flat:
        if not np.isfinite(v):
            return False
    return True


#: up to this size the kernels factor matrices with the small loops below (LU with partial
#: pivoting, Cholesky) instead of numba's LAPACK wrappers, whose copies and checks cost a few
#: microseconds per call; the same factorisations, equal up to rounding
SMALL_DIM = 12


def _lu_small(M):
    """LU factorisation with partial pivoting (the first largest pivot, as LAPACK's getrf):
    ``(LU, perm, sign, singular)`` with ``M[perm] = L U``."""
    n = M.shape[0]
    LU = M.copy()
    perm = np.arange(n)
    sign = 1.0
    singular = False
    for k in range(n):
        p = k
        best = abs(LU[k, k])
        for i in range(k + 1, n):
            if abs(LU[i, k]) > best:
                best = abs(LU[i, k])
                p = i
        if best == 0.0:
            singular = True
            continue
        if p != k:
            for j in range(n):
                tmp = LU[k, j]
                LU[k, j] = LU[p, j]
                LU[p, j] = tmp
            tp = perm[k]
            perm[k] = perm[p]
            perm[p] = tp
            sign = -sign
        for i in range(k + 1, n):
            LU[i, k] /= LU[k, k]
            f = LU[i, k]
            for j in range(k + 1, n):
                LU[i, j] -= f * LU[k, j]
    return LU, perm, sign, singular


def _det(M):
    """``det M`` (``np.linalg.det``: the product of the LU pivots with the permutation's
    sign)."""
    if M.shape[0] > SMALL_DIM:
        return np.linalg.det(M)
    LU, _, sign, _ = _lu_small(M)
    det = sign
    for i in range(M.shape[0]):
        det *= LU[i, i]
    return det


def _solve(S, B):
    """``(S^{-1} B, ok)``; ``ok`` is false for a singular ``S`` (``np.linalg.solve`` raises
    there) or a non-finite solution."""
    n = S.shape[0]
    if n > SMALL_DIM:
        try:
            X = np.linalg.solve(S, B)
        except Exception:  # noqa: BLE001 - numba catches no specific class
            return np.zeros(B.shape), False
        return X, _finite(X)
    LU, perm, _, singular = _lu_small(S)
    X = np.empty(B.shape)
    if singular:
        return X, False
    for col in range(B.shape[1]):
        for i in range(n):  # forward substitution, unit lower triangle
            acc = B[perm[i], col]
            for j in range(i):
                acc -= LU[i, j] * X[j, col]
            X[i, col] = acc
        for i in range(n - 1, -1, -1):  # back substitution
            acc = X[i, col]
            for j in range(i + 1, n):
                acc -= LU[i, j] * X[j, col]
            X[i, col] = acc / LU[i, i]
    return X, _finite(X)


def _cholesky(S):
    """``(L, ok)`` with ``S = L L'`` (``np.linalg.cholesky``); ``ok`` false where ``S`` is not
    positive definite (numpy raises there)."""
    k = S.shape[0]
    if k > SMALL_DIM:
        try:
            return np.linalg.cholesky(S), True
        except Exception:  # noqa: BLE001 - numba catches no specific class
            return np.zeros((k, k)), False
    Lc = np.zeros((k, k))
    for j in range(k):
        acc = S[j, j]
        for q in range(j):
            acc -= Lc[j, q] * Lc[j, q]
        if not acc > 0.0:
            return Lc, False
        Lc[j, j] = math.sqrt(acc)
        for i in range(j + 1, k):
            acc = S[i, j]
            for q in range(j):
                acc -= Lc[i, q] * Lc[j, q]
            Lc[i, j] = acc / Lc[j, j]
    return Lc, True


def _solve_t(S, B):
    """``(S^{-1} B)'`` for a symmetric ``S`` (LU solve), and whether it exists and is finite
    (else the caller falls back to the numpy path)."""
    X, ok = _solve(S, B)
    return np.ascontiguousarray(X.T), ok


def _strip_step_py(c, G, A, d, cW, E, C, y, sigma, L, F, mode, wang_cora, order, method,
                   cluster_rtol, pivot_rtol):
    n, r = G.shape
    m = C.shape[0]
    re = E.shape[1]
    cp = np.dot(A, c) + d + cW
    Gp = np.empty((n, r + re))
    Gp[:, :r] = np.dot(A, G)
    Gp[:, r:] = E
    rp = r + re
    if mode == GIVEN or mode == WANG:
        if mode == WANG:
            P = np.dot(Gp, np.ascontiguousarray(Gp.T))
            if wang_cora:
                R = np.dot(np.dot(A, P), np.ascontiguousarray(A.T)) + np.dot(
                    E, np.ascontiguousarray(E.T))
            else:
                R = P
            CT = np.ascontiguousarray(C.T)
            S = np.dot(np.dot(C, R), CT) + np.dot(F, np.ascontiguousarray(F.T))
            if not _finite(S):
                return cp, Gp, False
            Lam, ok = _solve_t(S, np.dot(C, R))
            if not ok:
                return cp, Gp, False
        else:
            Lam = L
        cn = cp + np.dot(Lam, y - np.dot(C, cp))
        Gn = np.empty((n, rp + m))
        Gn[:, :rp] = Gp - np.dot(Lam, np.dot(C, Gp))
        for i in range(n):
            for j in range(m):
                Gn[i, rp + j] = Lam[i, j] * sigma[j]
    elif mode == PER_STRIP:
        cn = cp
        Gn = Gp
        for i in range(m):
            lam = L[:, i].copy()
            ci = C[i]
            cn = cn + lam * (y[i] - np.dot(ci, cn))
            k = Gn.shape[1]
            G2 = np.empty((n, k + 1))
            cg = np.dot(ci, Gn)
            for a in range(n):
                for b in range(k):
                    G2[a, b] = Gn[a, b] - lam[a] * cg[b]
                G2[a, k] = lam[a] * sigma[i]
            Gn = G2
    else:  # ALAMO
        P = np.dot(Gp, np.ascontiguousarray(Gp.T))
        Lm = np.empty((n, m))
        cn = cp.copy()
        for i in range(m):
            ci = C[i].copy()
            p = np.dot(P, ci)
            s = np.dot(ci, p) + sigma[i] ** 2
            if s > 0:
                lam = p / s
            else:
                lam = np.zeros(n)
            cn = cn + lam * (y[i] - np.dot(ci, cn))
            if i:
                for b in range(i):
                    wb = 0.0
                    for a in range(n):
                        wb += ci[a] * Lm[a, b]
                    for a in range(n):
                        Lm[a, b] -= lam[a] * wb
            Lm[:, i] = lam
            for a in range(n):
                for b in range(n):
                    P[a, b] -= p[a] * lam[b]
        Gn = np.empty((n, rp + m))
        if 2 * m < n:
            Gn[:, :rp] = Gp - np.dot(Lm, np.dot(C, Gp))
        else:
            T = -np.dot(Lm, C)
            for a in range(n):
                T[a, a] += 1.0
            Gn[:, :rp] = np.dot(T, Gp)
        for a in range(n):
            for j in range(m):
                Gn[a, rp + j] = Lm[a, j] * sigma[j]
    out, ok = reduce(Gn, order, method, cluster_rtol, pivot_rtol, JACOBI_MAX_DIM)
    return cn, out, ok


def _propagate_step_py(c, G, A, d, C, L, F, y, cV, cW, E, mode, order, method, cluster_rtol,
                       pivot_rtol):
    n, r = G.shape
    rv, rw = F.shape[1], E.shape[1]
    if mode == COMBASTEL:
        P = np.dot(G, np.ascontiguousarray(G.T))
        S = np.dot(np.dot(C, P), np.ascontiguousarray(C.T)) + np.dot(
            F, np.ascontiguousarray(F.T))
        if not _finite(S):
            return c, G, False
        X, ok = _solve_t(S, np.dot(C, P))
        if not ok:
            return c, G, False
        Lg = np.dot(A, X)
    else:
        Lg = L
    M = A - np.dot(Lg, C)
    cn = np.dot(M, c) + d + np.dot(Lg, y - cV) + cW
    Gn = np.empty((n, r + rv + rw))
    Gn[:, :r] = np.dot(M, G)
    Gn[:, r:r + rv] = np.dot(-Lg, F)
    Gn[:, r + rv:] = E
    out, ok = reduce(Gn, order, method, cluster_rtol, pivot_rtol, JACOBI_MAX_DIM)
    return cn, out, ok


def _adjugate_psd(S):
    """``(det S, adj S)`` of a symmetric positive semidefinite ``S``
    (:func:`observers.numerics.volmin._adjugate_psd`: Cholesky and ``det * inv`` when well
    conditioned, else the eigendecomposition without divisions)."""
    k = S.shape[0]
    if k == 0:
        return 1.0, np.zeros((0, 0))
    Lc, chol_ok = _cholesky(S)
    if chol_ok:
        dmin = np.inf
        dmax = -np.inf
        for i in range(k):
            dmin = min(dmin, Lc[i, i])
            dmax = max(dmax, Lc[i, i])
        if dmin > 1e-6 * dmax:
            det = 1.0
            for i in range(k):
                det *= Lc[i, i]
            det = det**2
            inv, _ = _solve(S, np.eye(k))
            return det, det * inv
    mu, U = np.linalg.eigh(S)
    cof = np.empty(k)
    for i in range(k):
        p = 1.0
        for j in range(k):
            p *= 1.0 if i == j else mu[j]
        cof[i] = p
    det = 1.0
    for j in range(k):
        det *= mu[j]
    return det, np.dot(np.ascontiguousarray(U * cof), np.ascontiguousarray(U.T))


def _bravo_choice(G, c_row, sigma, B, zero_projection):
    """:func:`observers.numerics.volmin.bravo_choice`: the index of the candidate of least
    ``det(T T')`` (0: unchanged zonotope; ties: the first)."""
    n, r = G.shape
    scores = np.empty(r + 1)
    scores[0] = _det(np.dot(G, np.ascontiguousarray(G.T)))
    a = np.dot(c_row, G)
    q = np.dot(a, a)
    nvalid = 0
    for j in range(r):
        scores[j + 1] = scores[0]
        if abs(a[j]) > zero_projection:
            nvalid += 1
    if q == 0.0 or nvalid == 0:
        return int(np.argmin(scores))
    BG = np.dot(np.ascontiguousarray(B.T), G)
    Ga = np.dot(BG, a)
    Gt = np.empty_like(BG)
    for i in range(BG.shape[0]):
        for j in range(r):
            Gt[i, j] = BG[i, j] - Ga[i] * (a[j] / q)
    det_S0, adj = _adjugate_psd(np.dot(Gt, np.ascontiguousarray(Gt.T)))
    AG = np.dot(adj, Gt)
    scale = sigma**2 / np.dot(c_row, c_row)
    for j in range(r):
        if abs(a[j]) > zero_projection:
            quad = 0.0
            for i in range(Gt.shape[0]):
                quad += Gt[i, j] * AG[i, j]
            scores[j + 1] = scale * (det_S0 + (q / a[j] ** 2) * quad)
    return int(np.argmin(scores))


def _bravo_step_py(c, G, A, d, cW, E, C, y, sigma, bases, zero_projection, order, method,
                   cluster_rtol, pivot_rtol):
    """Prediction, Bravo's strip-by-strip intersection (VolMin-B,
    :func:`observers.numerics.volmin.bravo_update`), reduction."""
    n, r = G.shape
    re = E.shape[1]
    cn = np.dot(A, c) + d + cW
    Gn = np.empty((n, r + re))
    Gn[:, :r] = np.dot(A, G)
    Gn[:, r:] = E
    for i in range(C.shape[0]):
        ci = C[i].copy()
        j = _bravo_choice(Gn, ci, sigma[i], bases[i], zero_projection)
        if j == 0:
            continue
        a = np.dot(ci, Gn)
        lam = Gn[:, j - 1] / a[j - 1]
        cn = cn + lam * (y[i] - np.dot(ci, cn))
        G2 = np.empty_like(Gn)
        for p in range(n):
            for k in range(Gn.shape[1]):
                G2[p, k] = Gn[p, k] - lam[p] * a[k]
            G2[p, j - 1] = sigma[i] * lam[p]
        Gn = G2
    out, ok = reduce(Gn, order, method, cluster_rtol, pivot_rtol, JACOBI_MAX_DIM)
    return cn, out, ok


if AVAILABLE:  # helpers, resolved by the kernels when they compile (at their first call)
    (_pairwise_block, _pairwise_sum, _smallest, _cluster_basis_into, _jacobi_left,
     _principal_axes, _lu_small, _det, _solve, _cholesky, _adjugate_psd, _finite,
     _solve_t) = (njit(f) for f in (
         _pairwise_block, _pairwise_sum, _smallest, _cluster_basis_into, _jacobi_left,
         _principal_axes, _lu_small, _det, _solve, _cholesky, _adjugate_psd, _finite,
         _solve_t))
    _bravo_choice = njit(_bravo_choice, error_model="numpy")
#: the compiled :func:`_reduce_py` (``None`` without numba)
reduce = njit(_reduce_py, error_model="numpy")
#: the compiled :func:`_strip_step_py` and :func:`_propagate_step_py` (``None`` without numba)
strip_step = njit(_strip_step_py, error_model="numpy")
propagate_step = njit(_propagate_step_py, error_model="numpy")
#: the compiled :func:`_bravo_step_py` (``None`` without numba)
bravo_step = njit(_bravo_step_py, error_model="numpy")
