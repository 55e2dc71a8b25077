"""Compiled (numba) order reductions: :class:`.reduction.Girard` and :class:`.reduction.PCA`
as one kernel call each.

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

numba is optional: :data:`AVAILABLE` is false when it is not installed or when the
environment variable ``SETOBS_NUMBA=0`` disables it (see :mod:`._dual_simplex_jit`).
"""

from __future__ import annotations

import math

import numpy as np

from ._jit import AVAILABLE, numba

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


def _principal_axes(red, cluster_rtol, pivot_rtol):
    """:func:`.reduction.principal_axes` (n x n orthonormal axes of the columns ``red``)."""
    n, k = red.shape
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


def _reduce_py(G, order, method, cluster_rtol, pivot_rtol):
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
        out = np.empty((n, r))
        for q in range(r):
            for i in range(n):
                out[i, q] = G[i, nz[q]]
        return out, True
    n_keep = int(math.floor(n * (order - 1)))
    n_red = r - n_keep
    ranked = _smallest(h, r, n_red)
    is_red = np.zeros(r, dtype=np.bool_)
    for q in range(n_red):
        is_red[ranked[q]] = True
    out = np.zeros((n, n_keep + n))
    q = 0
    for p in range(r):
        if not is_red[p]:
            j = nz[p]
            for i in range(n):
                out[i, q] = G[i, j]
            q += 1
    if method == GIRARD:
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
    U = _principal_axes(red, cluster_rtol, pivot_rtol)
    proj = np.dot(np.ascontiguousarray(U.T), red)
    for a in range(n):
        box = 0.0
        for q in range(n_red):
            box += abs(proj[a, q])
        for i in range(n):
            out[i, n_keep + a] = U[i, a] * box
    return out, True


if AVAILABLE:
    _smallest = numba.njit(cache=True, nogil=True)(_smallest)
    _cluster_basis_into = numba.njit(cache=True, nogil=True)(_cluster_basis_into)
    _principal_axes = numba.njit(cache=True, nogil=True)(_principal_axes)
    reduce = numba.njit(cache=True, nogil=True, error_model="numpy")(_reduce_py)
else:  # pragma: no cover - depends on the installation
    reduce = None
