"""Compiled (numba) one-step formulas of the zonotopic observer families: one kernel call per
step instead of about 30-80 numpy calls.

On the 6-state vehicle (a 6 x ~600 generator matrix) a step of a zonotope observer costs a few
tens of thousands of flops, and the numpy path spends most of its time in per-call overhead
(about 1 us per call).  The kernels run the formulas of :mod:`observers.families`,
:mod:`observers.numerics.frad` and :mod:`observers.numerics.volmin` in the same order of
operations, then the order reduction of :func:`reduce` (below), so the sets are those of the
numpy path up to rounding.

Doorway
-------
An observer declares its kernel by name (:class:`observers.kernels.StepKernel`); at the first
compiled step of a run its family calls :func:`prepare` with that name and the static arrays
of the run, and gets the kernel and one :class:`StepData`.  Every kernel is called as
``kernel(c, G, d, y, args)`` (``d = B u``, ``args = tuple(data)``: see :class:`StepData`) and
returns ``(c, G, ok)``:

* :func:`strip_step`: prediction ``(A c + d + c_W, [A G, E])``, intersection with the strips
  ``|C x - y| <= sigma`` with a given gain (:func:`strip_update`; column by column for
  ``"per-strip"``), Alamo's strip-by-strip gains (:func:`alamo_frad_strips`) or Wang's gain
  (:func:`wang_frad_gain`, with ``A`` applied once more for ``"wang-cora"``) or, for
  ``"bravo"``, Bravo's choice of the least ``det(T T')`` candidate strip by strip
  (:func:`bravo_choice_ratios` from the leverages of :func:`leverages`, kept by
  :func:`leverage_update`; :func:`bravo_choice_gram` on ``G G'`` where it is badly
  conditioned; ``G G'`` kept by :func:`gram_update`, :func:`bravo_update`; VolMin-B),
  reduction;
* :func:`propagate_step`: ``S+ = (A - L C) S + d + L y + (-L) V + W`` (:func:`propagate`)
  with a given gain or Combastel's (:func:`combastel_gain`), reduction;
* :func:`strip_first`: the measurement update alone (the first set of a strip-based observer).

On a nonlinear system the family linearises at every step (``x+ in J x + d + R``,
:mod:`observers.prediction`) and runs the same formulas on the linearisation:
:func:`predict_linearised` (``J c + d + c_W``, ``[J G, E, R]``) then :func:`strip_predicted`
(update and reduction), or :func:`propagate_linearised`, with ``J`` in place of the model's ``A``
(:func:`linearised_args`).

The kernels' names for their gain formulas (integers) do not leave this module: :func:`prepare`
maps the kernel names to them.  The compiled formulas carry the names of their numpy twins
(:func:`strip_update` and :func:`propagate` of :mod:`observers.families`;
:func:`alamo_frad_strips`, :func:`wang_frad_gain`, :func:`combastel_gain` of
:mod:`observers.numerics.frad`; :func:`bravo_choice`, :func:`bravo_update` of
:mod:`observers.numerics.volmin`), so that the tests pair them one to one.

A kernel returns ``ok = False`` when it cannot vouch for the numpy path's result (a
non-finite entry, a singular matrix in a gain): the caller then runs the numpy path for that
step, which knows the fallbacks (pseudo-inverse, zero gain).  The compiled gains return
``(gain, ok)`` for the same reason.

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
from collections.abc import Callable
from typing import Any, NamedTuple

import numpy as np

from .switch import AVAILABLE, njit

#: singular values closer than this (relative to the largest) form one cluster (repeated), in
#: the principal axes of the PCA reduction of a zonotope (:func:`.reduction.principal_axes` and
#: here): exact ties only (the boxes of ``W`` or ``X0``), so that the axes are CORA's wherever
#: CORA's are defined (FRad-A/B reproduce ARCH 2021 Table 3 to 0.05 %)
CLUSTER_RTOL = 1e-9
#: the cluster tolerance of the PCA reductions of constrained zonotopes (their lifted
#: zonotopes ``[G; A]``, :meth:`.ConZonotope.reduce`).  A singular subspace is determined by
#: the matrix to about ``eps * s_max / gap`` (Wedin's theorem), and the constrained-zonotope
#: filters, whose sets feed LP hulls and constraint eliminations back into the next step,
#: amplified that from step to step: at 1e-9 the axes of near-repeated values moved by up
#: to 1e-7 with the OpenBLAS kernel and CZN-B's 6-tank radii by 5e-5; at 1e-3 they agree to
#: 1e-14.  Closer values get the basis of their common subspace, which depends on that
#: subspace only.  Wider clusters cost accuracy where distinct axes matter (CZN-PR on Van der
#: Pol: x2 0.198 at 1e-3, 0.249 at 3e-3, 0.345 at 1e-2).
LIFTED_CLUSTER_RTOL = 1e-3
#: the data-driven constrained zonotopes (DD-CZ-A1/A2) reduce lifted zonotopes of 30 rows
#: (6 states, 24 constraints) and thousands of generators, with many nearly repeated singular
#: values: at 1e-3 DD-CZ-A2's 6-tank radii still moved by 7e-4 between kernels, at 1e-2 by
#: 3e-12 (and its radii got 0.4 % smaller)
DATA_DRIVEN_CLUSTER_RTOL = 1e-2
#: a width of the PCA box below this (relative to its widest) is set to exactly zero: the width
#: along an axis the reduced generators do not span is zero in exact arithmetic and rounding
#: noise in floating point (exactly zero on one BLAS kernel, a column later dropped, and 1e-19
#: on another, kept), which changed the generator count and so which generators every later
#: reduction picked (VolMin-A/B on Van der Pol: 3e-4 and 2e-3 between kernels).  The sliver
#: given up is at most 1e-12 of the box, far inside the 1e-9 membership tolerance of the
#: containment checks, like the rounding of every other floating-point operation.
BOX_ZERO_RTOL = 1e-12
#: a generator whose 1-norm is at most this (relative to the largest) is dropped as zero: a
#: column that is zero in exact arithmetic (a generator annihilated by VolMin-B's update) is
#: rounding noise in floating point, exactly zero on one BLAS kernel (dropped) and 1e-19 on
#: another (kept), which changed the generator count, whether a reduction ran and every later
#: choice (VolMin-B on the 4-state vehicle at order 4: 5.5e-3 between kernels, issue 37).
#: That noise is the rounding of an exact cancellation, so it scales with the terms that
#: cancelled, not with the result: measured 1e-18 to 3e-16 of the largest generator there, and
#: up to 4e-15 in VolMin-A's update on Van der Pol (a column [-2e-17, -3.5e-16] beside a
#: largest generator of 0.09, zero on another kernel: 3.5e-4 between kernels); 1e-13 leaves a
#: margin of 25.  Dropping those columns changes the generator counts of the Van der Pol
#: record, and with them its reductions, deterministically (golden files 0.6.0).  What is
#: given up is at most r x 1e-13 of the largest generator, far inside the 1e-9 membership
#: tolerance of the containment checks, as for BOX_ZERO_RTOL.  The reductions' metrics within
#: this of the largest generator's 1-norm tie too (:func:`_tie_band`): the metric of an
#: axis-aligned generator is zero, or the noise of its other entries.
ZERO_COLUMN_RTOL = 1e-13
#: pivot ties of the cluster basis: diagonal entries within this (relative) count as equal
PIVOT_RTOL = 1e-6
#: which generators a reduction picks: metrics within this (relative) of the threshold count
#: as equal and go by column index.  Generators of one box mapped by the same matrices tie in
#: exact arithmetic and differ in the last bits by the BLAS kernel; ranked by those bits, one
#: kernel reduced one of them and another kernel the other (DD-CZ-A1 on the 6-tank: 1e-5)
TIE_RTOL = 1e-9
#: smallest ratio of the least to the largest diagonal entry of the Cholesky factor of a
#: symmetric positive definite matrix for which VolMin-B inverts it (its Gram matrices:
#: :func:`observers.numerics.volmin.psd_inverse`, :func:`_psd_inverse`); below it, a
#: condition number above about 1e12, the eigendecomposition or the Gram scores serve
CHOLESKY_MIN_PIVOT = 1e-6

# the gain formulas of the step kernels and the reduction methods of :func:`reduce`, by number
# (numba branches on integers); outside this module they are named (:func:`prepare`)
_GIVEN, _PER_STRIP, _ALAMO, _WANG, _WANG_CORA, _COMBASTEL, _BRAVO = range(7)
_GIRARD, _PCA = 0, 1
#: the reduction methods of :func:`reduce` by the names of their strategies
#: (:mod:`.reduction`)
REDUCTIONS = {"girard": _GIRARD, "pca": _PCA}

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


def _smallest(h, r, k, scale):
    """Indices of the ``k`` smallest of ``h[:r]`` in the order of a stable sort (ties by
    index), then the others: ``argsort(h[:r], kind="stable")`` with the first ``k`` found by
    insertion into a sorted buffer (``k`` is usually a few percent of ``r``); then the
    choice at the threshold made independent of rounding (:func:`_tie_band`; ``scale``: the
    largest 1-norm of the generators, the floor of its band)."""
    if 4 * k >= r:
        out = np.argsort(h[:r], kind="mergesort")
        return _tie_band(h, r, k, out, scale)
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
    return _tie_band(h, r, k, out, scale)


def _tie_band(h, r, k, out, scale):
    """``out[:k]`` (the ``k`` smallest of ``h[:r]``, sorted) re-chosen so that values within
    ``TIE_RTOL`` (relative) of the ``k``-th smallest, or within ``ZERO_COLUMN_RTOL`` of
    ``scale`` (the rounding noise of the largest generator), count as equal and go by index
    (:func:`.reduction._smallest`), kept in stable-sorted order."""
    if k == 0 or k >= r:
        return out
    thr = h[out[k - 1]]
    band = max(TIE_RTOL * abs(thr), ZERO_COLUMN_RTOL * scale)
    upto = 0  # the values up to the top of the band: when they are exactly k, they are the
    for j in range(r):  # k smallest already in out[:k], in the same stable order
        if h[j] <= thr + band:
            upto += 1
    if upto == k:
        return out
    chosen = np.empty(k, dtype=np.int64)
    m = 0
    for j in range(r):
        if h[j] < thr - band:
            chosen[m] = j
            m += 1
    for j in range(r):
        if m == k:
            break
        if abs(h[j] - thr) <= band:
            chosen[m] = j
            m += 1
    for i in range(1, k):  # stable insertion sort of the chosen by value
        j = chosen[i]
        q = i
        while q > 0 and h[j] < h[chosen[q - 1]]:
            chosen[q] = chosen[q - 1]
            q -= 1
        chosen[q] = j
    out[:k] = chosen
    return out


#: where at most one of the three dimensions of a matrix product (rows, columns, inner terms)
#: exceeds this, the compiled kernels form it by the fixed-order loops below (:func:`_mm`,
#: :func:`_gram`, :func:`_mv`, :func:`_vm`, :func:`_vv`) instead of BLAS: every entry is
#: summed term by term in index order, so the bits are the same under every BLAS kernel and on
#: every machine (the loops vectorise across independent entries only, which does not reorder
#: a sum, and numba fuses no multiply-add without ``fastmath``).  OpenBLAS's kernels block and
#: order their sums by CPU (AVX-512, AVX2, AVX), and observers whose reductions sit near ties
#: amplify that last-bit difference by about 1.2 per step: FRad-A and FRad-B on ARCH 2021
#: Table 5's 30 tanks moved by 0.7 % and 1.7 % between kernels (issue 37) with the Jacobi axes
#: below already in place.  Above it (the 100- and 200-state sweeps) BLAS's speed wins.
FIXED_ORDER_MAX_DIM = 30


def _mm(A, B):
    """``A @ B`` (2-D by 2-D) summed in index order (BLAS above :data:`FIXED_ORDER_MAX_DIM`)."""
    m, k = A.shape
    q = B.shape[1]
    if m + k + q - min(m, k, q) - max(m, k, q) > FIXED_ORDER_MAX_DIM:
        return np.dot(A, B)
    out = np.zeros((m, q))
    for i in range(m):
        row = out[i]
        for s in range(k):
            a = A[i, s]
            b = B[s]
            for j in range(q):
                row[j] += a * b[j]
    return out


def _gram(G):
    """``G @ G.T`` as :func:`_mm` forms it (the same bits): rank-one updates ``g_s g_s'`` over
    the columns in index order, exactly symmetric (entries ``(i, j)`` and ``(j, i)`` sum the
    same products in the same order); BLAS above :data:`FIXED_ORDER_MAX_DIM` rows."""
    n, r = G.shape
    if n > FIXED_ORDER_MAX_DIM:
        return np.dot(G, np.ascontiguousarray(G.T))
    Gt = np.ascontiguousarray(G.T)
    out = np.zeros((n, n))
    for s in range(r):
        g = Gt[s]
        for i in range(n):
            a = g[i]
            row = out[i]
            for j in range(n):  # the whole row: it vectorises, a triangle did not
                row[j] += a * g[j]
    return out


def _mv(A, x):
    """``A @ x`` (2-D by 1-D) summed in index order (BLAS above :data:`FIXED_ORDER_MAX_DIM`)."""
    m, k = A.shape
    if min(m, k) > FIXED_ORDER_MAX_DIM:
        return np.dot(A, x)
    out = np.zeros(m)
    for i in range(m):
        acc = 0.0
        for s in range(k):
            acc += A[i, s] * x[s]
        out[i] = acc
    return out


def _vm(x, B):
    """``x @ B`` (1-D by 2-D): :func:`_mm` of the row ``x``."""
    return _mm(np.ascontiguousarray(x).reshape((1, x.shape[0])), B)[0]


def _vv(x, y):
    """``x @ y`` (1-D by 1-D) summed in index order."""
    acc = 0.0
    for i in range(x.shape[0]):
        acc += x[i] * y[i]
    return acc


#: in the step kernels, up to this dimension the principal axes come from :func:`_jacobi_left`
#: (plain loops, so the same bits under every BLAS kernel; and no LAPACK call, whose wrappers
#: cost about 15 us of copies and workspace queries on a 6 x 14 matrix); above it from LAPACK as
#: in the numpy path.  30 covers the paper tables: measured (FRad-A/B/C on ARCH Table 5,
#: SkylakeX against Haswell), the largest per-state spread at 18 tanks fell from 1.0e-3 to
#: 3.3e-7 and at 24 tanks from 3.4e-2 to 4.9e-6, at 5-10 % more time per step (30 tanks: FRad-C
#: 1.9e-2 -> 1.6e-6, FRad-A/B stay near 1e-2: rounding of the kernel reaches them elsewhere); at
#: 100-200 states the sweeps would cost more than the step.  The reductions called alone
#: (:class:`.reduction.PCA`, e.g. the lifted reductions of the CZN observers, whose hulls
#: amplify a 1e-13 change of the axes to 1e-3 of an RMS radius on the 6-tank record) keep
#: LAPACK's QR and SVD, as the numpy path
JACOBI_MAX_DIM = 30


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


def _householder_lower(red):
    """A lower-triangular ``L`` (n x n) with ``L L' = red red'`` for ``red`` (n x k, k >= n):
    ``L = R'`` of the Householder QR ``red' = Q R``, so ``red`` and ``L`` have the same left
    singular vectors and values.  Plain loops in index order (the same bits under every BLAS
    kernel), on the rows of a copy of ``red`` (the columns of ``red'``): reflection ``j`` maps
    row ``j``'s entries ``j..k-1`` onto a multiple of the first and applies to the rows below.
    Costs about ``2 k n^2`` flops once; the Jacobi sweeps then run on ``n`` columns instead of
    ``k`` (the order-one reduction of a nonlinear remainder has ``k`` near ``100 n``)."""
    n, k = red.shape
    W = red.copy()
    L = np.zeros((n, n))
    for j in range(n):
        xx = 0.0
        for i in range(j, k):
            xx += W[j, i] * W[j, i]
        norm = math.sqrt(xx)
        alpha = -norm if W[j, j] >= 0.0 else norm
        L[j, j] = alpha
        if norm == 0.0:  # nothing to reflect: the rows below keep their entry j
            for r in range(j + 1, n):
                L[r, j] = W[r, j]
            continue
        x0 = W[j, j]
        W[j, j] = x0 - alpha  # W[j, j:] is now the reflection's vector v
        vv = 2.0 * (xx - x0 * alpha)  # v'v
        for r in range(j + 1, n):
            dot = 0.0
            for i in range(j, k):
                dot += W[j, i] * W[r, i]
            f = 2.0 * dot / vv
            for i in range(j, k):
                W[r, i] -= f * W[j, i]
            L[r, j] = W[r, j]
    return L


#: :func:`_principal_axes` runs Jacobi on the Householder factor (:func:`_householder_lower`)
#: where the reduced columns number at least this many times the rows: the order-one box of a
#: nonlinear remainder (k near 100 n: 30 x 3000, 11 ms -> 1.8 ms).  Below, on the matrix
#: itself: one-sided Jacobi on ``red`` keeps the small singular directions to high relative
#: accuracy, which the unpivoted QR gives up (measured: ROPO's 30 x 60 candidate on ARCH
#: Table 5's 30 tanks moved by 1.1e-4 between OpenBLAS kernels through the factor, 3.5e-6
#: without it), and there the factor saves less than 2x
HOUSEHOLDER_MIN_RATIO = 4


def _principal_axes(red, cluster_rtol, pivot_rtol, jacobi_dim):
    """:func:`.reduction.principal_axes` (n x n orthonormal axes of the columns ``red``), by
    :func:`_jacobi_left` if ``n <= jacobi_dim`` (on :func:`_householder_lower`'s ``n x n``
    factor where ``red`` has at least :data:`HOUSEHOLDER_MIN_RATIO` times more columns than
    rows)."""
    n, k = red.shape
    # two calls in two branches, not one on a conditional expression: numba would unify the
    # contiguous factor and the strided ``red`` to one array type and run the slower strided
    # Jacobi on both (measured: FRad-A on the vehicle 36 -> 40-49 us per step)
    if n <= jacobi_dim and k >= HOUSEHOLDER_MIN_RATIO * n:
        U, s = _jacobi_left(_householder_lower(red))
    elif n <= jacobi_dim:
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
    hmax = np.empty(r0)
    h = np.empty(r0)
    nz = np.empty(r0, dtype=np.int64)
    scale = 0.0
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
        hmax[j] = mx
        if s1 > scale:
            scale = s1
    floor = ZERO_COLUMN_RTOL * scale
    r = 0
    for j in range(r0):
        if norm1[j] > floor:
            nz[r] = j
            h[r] = norm1[j] - hmax[j]
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
    ranked = _smallest(h, r, n_red, scale)
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
    if method == _GIRARD:
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
    proj = _mm(np.ascontiguousarray(U.T), red)
    box = np.zeros(n)
    for a in range(n):
        for q in range(n_red):
            box[a] += abs(proj[a, q])
    negligible = BOX_ZERO_RTOL * box.max()
    for a in range(n):
        w = box[a] if box[a] > negligible else 0.0
        for i in range(n):
            out[i, n_keep + a] = U[i, a] * w
    return out, True


def _finite(a):
    for v in a.flat:
        if not np.isfinite(v):
            return False
    return True


#: up to this size the kernels factor matrices with the small loops below (LU with partial
#: pivoting, Cholesky) instead of numba's LAPACK wrappers: the same factorisations, equal up to
#: rounding, but summed in index order, so the same bits under every BLAS kernel (LAPACK's
#: blocked factorisations call BLAS; FRad-B on ARCH Table 5's 30 tanks solves with 15 x 15
#: matrices), and without the wrappers' copies and checks (a few microseconds per call).  The
#: same bound as :data:`FIXED_ORDER_MAX_DIM` (it was 12 before issue 37)
SMALL_DIM = FIXED_ORDER_MAX_DIM


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


def _symmetrise(M):
    """``M <- (M + M') / 2`` in place (pairs averaged once, so the result is exactly
    symmetric)."""
    for p in range(M.shape[0]):
        for s in range(p):
            avg = 0.5 * (M[p, s] + M[s, p])
            M[p, s] = avg
            M[s, p] = avg


def _psd_inverse(S):
    """``(L, S^-1, ok)`` (:func:`observers.numerics.volmin.psd_inverse`): the Cholesky
    factor and the inverse ``L^-T L^-1``, symmetrised; ``ok`` false where ``S`` is not
    positive definite or badly conditioned (:data:`CHOLESKY_MIN_PIVOT`)."""
    k = S.shape[0]
    Lc, ok = _cholesky(S)
    if not ok:
        return Lc, np.zeros((k, k)), False
    dmin = np.inf
    dmax = -np.inf
    for i in range(k):
        dmin = min(dmin, Lc[i, i])
        dmax = max(dmax, Lc[i, i])
    if not dmin > CHOLESKY_MIN_PIVOT * dmax:
        return Lc, np.zeros((k, k)), False
    Li = np.zeros((k, k))  # L^-1 by forward substitution, column by column
    for col in range(k):
        Li[col, col] = 1.0 / Lc[col, col]
        for i in range(col + 1, k):
            acc = 0.0
            for q in range(col, i):
                acc -= Lc[i, q] * Li[q, col]
            Li[i, col] = acc / Lc[i, i]
    N = _mm(np.ascontiguousarray(Li.T), Li)
    _symmetrise(N)
    return Lc, N, True


def _solve_t(S, B):
    """``(S^{-1} B)'`` for a symmetric ``S`` (LU solve), and whether it exists and is finite
    (else the caller falls back to the numpy path)."""
    X, ok = _solve(S, B)
    return np.ascontiguousarray(X.T), ok


# -- the compiled one-step formulas, named like their numpy twins --------------------------------
def _predict(c, G, A, d, W_c, E):
    """Prediction ``(A c + d + c_W, [A G, E])`` (the start of every strip-based step)."""
    n, r = G.shape
    cp = _mv(A, c) + d + W_c
    Gp = np.empty((n, r + E.shape[1]))
    Gp[:, :r] = _mm(A, G)
    Gp[:, r:] = E
    return cp, Gp


def strip_update(c, G, Lam, C, y, sigma):
    """:func:`observers.families.strip_update`: ``(c, G)`` intersected with the strips
    ``|C x - y| <= sigma`` with the gain ``Lam``."""
    c_new = c + _mv(Lam, y - _mv(C, c))
    return c_new, _strip_generators(G, Lam, C, sigma)


def _strip_generators(G, Lam, C, sigma):
    """:func:`observers.sets.zonotope.strip_generators`: ``[(I - Lam C) G, Lam diag(sigma)]``
    (as ``G - Lam (C G)`` when ``2 m < n``)."""
    n, r = G.shape
    m = C.shape[0]
    G_new = np.empty((n, r + m))
    if 2 * m < n:  # G - Lam (C G): 2 m n r flops
        G_new[:, :r] = G - _mm(Lam, _mm(C, G))
    else:  # (I - Lam C) G: n^2 r flops, fewer when 2 m >= n
        T = -_mm(Lam, C)
        for a in range(n):
            T[a, a] += 1.0
        G_new[:, :r] = _mm(T, G)
    for i in range(n):
        for j in range(m):
            G_new[i, r + j] = Lam[i, j] * sigma[j]
    return G_new


def _per_strip_update(c, G, L, C, y, sigma):
    """:meth:`observers.families.PerStripObserver.intersect` with the gain ``L[:, i]`` for
    strip ``i`` (PRad-A): :func:`strip_update` strip after strip."""
    n = G.shape[0]
    for i in range(C.shape[0]):
        lam = L[:, i].copy()
        ci = C[i]
        c = c + lam * (y[i] - _vv(ci, c))
        k = G.shape[1]
        G2 = np.empty((n, k + 1))
        cg = _vm(ci, G)
        for a in range(n):
            for b in range(k):
                G2[a, b] = G[a, b] - lam[a] * cg[b]
            G2[a, k] = lam[a] * sigma[i]
        G = G2
    return c, G


def alamo_frad_strips(c, G, C, y, sigma):
    """:func:`observers.numerics.frad.alamo_frad_strips`: every strip in turn with Alamo's
    F-radius gain, computed on ``P = G G'`` and applied to ``G`` once (FRad-A)."""
    n, r = G.shape
    m = C.shape[0]
    P = _gram(G)
    Lm = np.empty((n, m))
    cn = c.copy()
    for i in range(m):
        ci = C[i].copy()
        p = _mv(P, ci)
        s = _vv(ci, p) + sigma[i] ** 2
        if s > 0:
            lam = p / s
        else:
            lam = np.zeros(n)
        cn = cn + lam * (y[i] - _vv(ci, cn))
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
    return cn, _strip_generators(G, Lm, C, sigma)


def wang_frad_gain(P, A, C, E, F):
    """:func:`observers.numerics.frad.wang_frad_gain`: ``(Lam, ok)`` with
    ``Lam = R C' (C R C' + F F')^{-1}``, ``R = A P A' + E E'`` (``R = P`` for ``A = None``);
    ``ok`` is false where the numpy path must decide (a non-finite or singular ``S``)."""
    if A is None:
        R = P
    else:
        R = _mm(_mm(A, P), np.ascontiguousarray(A.T)) + _mm(
            E, np.ascontiguousarray(E.T))
    S = _mm(_mm(C, R), np.ascontiguousarray(C.T)) + _mm(F, np.ascontiguousarray(F.T))
    if not _finite(S):
        return np.zeros((P.shape[0], C.shape[0])), False
    return _solve_t(S, _mm(C, R))


def combastel_gain(P, A, C, F):
    """:func:`observers.numerics.frad.combastel_gain`: ``(L, ok)`` with
    ``L = A P C' (C P C' + F F')^{-1}``; ``ok`` as in :func:`wang_frad_gain`."""
    S = _mm(_mm(C, P), np.ascontiguousarray(C.T)) + _mm(F, np.ascontiguousarray(F.T))
    if not _finite(S):
        return np.zeros((A.shape[0], C.shape[0])), False
    X, ok = _solve_t(S, _mm(C, P))
    if not ok:
        return X, False
    return _mm(A, X), True


def propagate(S, prediction, C, L, y, V, W):
    """:func:`observers.families.propagate` (linear: no remainder): one step
    ``S+ = (A - L C) S + d + L y + (-L) V + W`` with ``S = (c, G)``, ``prediction = (A, d)``,
    ``V = (c_V, G_V)``, ``W = (c_W, G_W)``."""
    c, G = S
    A, d = prediction
    V_c, F = V
    W_c, E = W
    n, r = G.shape
    rv, rw = F.shape[1], E.shape[1]
    M = A - _mm(L, C)
    c_new = _mv(M, c) + d + _mv(L, y - V_c) + W_c
    G_new = np.empty((n, r + rv + rw))
    G_new[:, :r] = _mm(M, G)
    G_new[:, r:r + rv] = _mm(-L, F)
    G_new[:, r + rv:] = E
    return c_new, G_new


def _adjugate_psd(S):
    """``(det S, adj S)`` of a symmetric positive semidefinite ``S``
    (:func:`observers.numerics.volmin._adjugate_psd`: Cholesky and ``det * inv`` when well
    conditioned, else the eigendecomposition without divisions)."""
    k = S.shape[0]
    if k == 0:
        return 1.0, np.zeros((0, 0))
    Lc, N, ok = _psd_inverse(S)
    if ok:
        det = 1.0
        for i in range(k):
            det *= Lc[i, i]
        det = det**2
        return det, det * N
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
    return det, _mm(np.ascontiguousarray(U * cof), np.ascontiguousarray(U.T))


def _least(scores):
    """The index of the least of ``scores``, scores within ``TIE_RTOL`` (relative) of the
    least counting as equal and going by index (the first): candidates that tie in exact
    arithmetic differ in the last bits by the BLAS kernel, and ranked by those bits the
    choice (and every later step) depended on the kernel."""
    best = scores[0]
    for j in range(1, scores.shape[0]):
        if scores[j] < best:
            best = scores[j]
    band = TIE_RTOL * abs(best)
    for j in range(scores.shape[0]):
        if scores[j] <= best + band:
            return j
    return 0


def bravo_choice(G, c_row, sigma, B, zero_projection):
    """:func:`observers.numerics.volmin.bravo_choice`: the index of the candidate of least
    ``det(T T')`` (0: unchanged zonotope; ties within ``TIE_RTOL``: the first, :func:`_least`)."""
    n, r = G.shape
    scores = np.empty(r + 1)
    scores[0] = _det(_gram(G))
    a = _vm(c_row, G)
    q = _vv(a, a)
    nvalid = 0
    for j in range(r):
        scores[j + 1] = scores[0]
        if abs(a[j]) > zero_projection:
            nvalid += 1
    if q == 0.0 or nvalid == 0:
        return _least(scores)
    BG = _mm(np.ascontiguousarray(B.T), G)
    Ga = _mv(BG, a)
    Gt = np.empty_like(BG)
    for i in range(BG.shape[0]):
        for j in range(r):
            Gt[i, j] = BG[i, j] - Ga[i] * (a[j] / q)
    det_S0, adj = _adjugate_psd(_gram(Gt))
    AG = _mm(adj, Gt)
    scale = sigma**2 / _vv(c_row, c_row)
    for j in range(r):
        if abs(a[j]) > zero_projection:
            quad = 0.0
            for i in range(Gt.shape[0]):
                quad += Gt[i, j] * AG[i, j]
            scores[j + 1] = scale * (det_S0 + (q / a[j] ** 2) * quad)
    return _least(scores)


def bravo_choice_gram(G, a, M, c_row, sigma, B, zero_projection):
    """:func:`observers.numerics.volmin.bravo_scores_gram` (``a = c G``) and the index of the
    least score (0: unchanged zonotope; ties within ``TIE_RTOL``: the first, :func:`_least`)."""
    n, r = G.shape
    u = _mv(M, c_row)
    q = _vv(c_row, u)
    nvalid = 0
    for j in range(r):
        if abs(a[j]) > zero_projection:
            nvalid += 1
    if not q > 0.0 or nvalid == 0:
        return 0
    Bt = np.ascontiguousarray(B.T)
    Bu = _mv(Bt, u)
    S0 = _mm(_mm(Bt, M), B)
    k = S0.shape[0]
    for p in range(k):
        for s in range(k):
            S0[p, s] -= Bu[p] * Bu[s] / q
    _symmetrise(S0)
    det_S0, adj = _adjugate_psd(S0)
    K = _mm(_mm(B, adj), Bt)
    KG = _mm(K, G)
    Ku = _mv(K, u)
    uKu = _vv(u, Ku)
    cc = _vv(c_row, c_row)
    scores = np.empty(r + 1)
    scores[0] = q * det_S0 / cc
    scale = sigma**2 / cc
    for j in range(r):
        scores[j + 1] = scores[0]
        if abs(a[j]) > zero_projection:
            w = 0.0
            v = 0.0
            for p in range(n):
                w += G[p, j] * KG[p, j]
                v += KG[p, j] * u[p]
            f = a[j] / q
            scores[j + 1] = scale * (det_S0 + (q / a[j] ** 2) * (w - 2.0 * f * v + f * f * uKu))
    return _least(scores)


def leverages(G, M):
    """:func:`observers.numerics.volmin.leverages`: ``(M^-1, h, ok)`` with the leverages
    ``h_j = g_j' M^-1 g_j``; ``ok`` false where ``M`` is not positive definite or badly
    conditioned (:func:`_psd_inverse`)."""
    r = G.shape[1]
    h = np.zeros(r)
    _, N, ok = _psd_inverse(M)
    if not ok:
        return N, h, False
    NG = _mm(N, G)
    for j in range(r):
        acc = 0.0
        for p in range(G.shape[0]):
            acc += G[p, j] * NG[p, j]
        h[j] = acc
    return N, h, True


def bravo_choice_ratios(a, M, h, c_row, sigma, zero_projection):
    """:func:`observers.numerics.volmin.bravo_ratios` (``a = c G``) and the index of the
    least ratio (0: unchanged zonotope; ties within ``TIE_RTOL``: the first, :func:`_least`)."""
    r = a.shape[0]
    u = _mv(M, c_row)
    q = _vv(c_row, u)
    scores = np.ones(r + 1)
    if not q > 0.0:
        return 0
    s2 = sigma**2
    for j in range(r):
        aj = a[j]
        if abs(aj) > zero_projection:
            a2 = aj * aj
            scores[j + 1] = s2 * max(h[j], a2 / q) / a2
    return _least(scores)


def leverage_update(N, h, G, c_row, sigma, j):
    """:func:`observers.numerics.volmin.leverage_update`: ``(M^-1, h, ok)`` of Bravo's
    candidate ``j`` (1-based; 0: unchanged); ``ok`` false after a strip of zero width."""
    if j == 0:
        return N, h, True
    if not sigma > 0.0:
        return N, h, False
    n, r = G.shape
    w = _mv(N, np.ascontiguousarray(G[:, j - 1]))
    hj = h[j - 1]
    v = _vm(w, G)
    h_new = np.empty(r)
    for o in range(r):
        h_new[o] = h[o] - v[o] * v[o] / hj
    h_new[j - 1] = 1.0
    s2 = sigma**2
    N_new = np.empty((n, n))
    for p in range(n):
        for s in range(n):
            N_new[p, s] = N[p, s] - w[p] * w[s] / hj + c_row[p] * c_row[s] / s2
    _symmetrise(N_new)
    return N_new, h_new, True


def gram_update(M, G, c_row, sigma, j):
    """:func:`observers.numerics.volmin.gram_update`: ``G_j G_j'`` from ``M = G G'``."""
    if j == 0:
        return M
    n = M.shape[0]
    a_j = 0.0
    for p in range(n):
        a_j += c_row[p] * G[p, j - 1]
    lam = np.empty(n)
    for p in range(n):
        lam[p] = G[p, j - 1] / a_j
    u = _mv(M, c_row)
    q = _vv(c_row, u)
    out = np.empty((n, n))
    for p in range(n):
        for s in range(n):
            out[p, s] = M[p, s] - lam[p] * u[s] - u[p] * lam[s] + (q + sigma**2) * lam[p] * lam[s]
    _symmetrise(out)
    return out


def projections_update(P, first, C, G, a, sigma, j):
    """:func:`observers.numerics.volmin.projections_update` in place on the rows ``first``
    onward of ``P = C G`` (``a = c G`` of the strip taking candidate ``j``; 0: nothing)."""
    if j == 0:
        return
    n = G.shape[0]
    lam = np.empty(n)
    for p in range(n):
        lam[p] = G[p, j - 1] / a[j - 1]
    for k in range(first, P.shape[0]):
        cl = 0.0
        for p in range(n):
            cl += C[k, p] * lam[p]
        for o in range(P.shape[1]):
            P[k, o] = P[k, o] - cl * a[o]
        P[k, j - 1] = sigma * cl


def bravo_update(c, G, a, c_row, y, sigma, j):
    """:func:`observers.numerics.volmin.bravo_update` (``a = c G``): Bravo's candidate ``j``
    (1-based generator index; 0 returns ``(c, G)`` unchanged)."""
    if j == 0:
        return c, G
    n = G.shape[0]
    lam = G[:, j - 1] / a[j - 1]
    c_new = c + lam * (y - _vv(c_row, c))
    G_new = np.empty_like(G)
    for p in range(n):
        for k in range(G.shape[1]):
            G_new[p, k] = G[p, k] - lam[p] * a[k]
        G_new[p, j - 1] = sigma * lam[p]
    return c_new, G_new


# -- the step kernels ------------------------------------------------------------------------
class StepData(NamedTuple):
    """The static data of a run of a step kernel, built once per run by :func:`prepare`.

    One type for every kernel and observer (read-only C-contiguous float arrays, empty where a
    kernel does not use them), so that numba compiles each kernel once.  A kernel takes it as
    the plain tuple ``tuple(data)`` and names it again in its first line
    (``data = StepData(*args)``, free in compiled code): numba types a named-tuple argument
    from its class and field names at every call, about 1 us per step more than a plain
    tuple.
    """

    #: the gain formula (internal number)
    mode: int
    #: the given gain (n x m; ``"strip-given"``, ``"per-strip"``, ``"propagation-given"``)
    gain: np.ndarray
    #: the null-space bases of the rows of ``C`` (m x n x n-1; ``"bravo"``)
    bases: np.ndarray
    A: np.ndarray
    #: the caller's prediction input matrix (``d = B u``, computed in numpy); unused here
    B: np.ndarray
    W_c: np.ndarray
    #: generators of ``W``
    E: np.ndarray
    C: np.ndarray
    #: strip half-widths
    sigma: np.ndarray
    #: generators of ``V``
    F: np.ndarray
    V_c: np.ndarray
    #: Bravo's threshold of ``|c g_j|`` (``"bravo"``)
    zero_projection: float
    order: float
    #: reduction method (internal number)
    method: int
    cluster_rtol: float
    pivot_rtol: float


def _strip_update(cp, Gp, y, data):
    """The measurement update of the strip-based kernels: ``(c, G, ok)`` of the predicted set
    ``(cp, Gp)`` intersected with the strips of ``y`` by the gain of ``data.mode``."""
    mode = data.mode
    if mode == _PER_STRIP:
        cn, Gn = _per_strip_update(cp, Gp, data.gain, data.C, y, data.sigma)
    elif mode == _ALAMO:
        cn, Gn = alamo_frad_strips(cp, Gp, data.C, y, data.sigma)
    elif mode == _GIVEN:
        cn, Gn = strip_update(cp, Gp, data.gain, data.C, y, data.sigma)
    else:  # _WANG, _WANG_CORA
        P = _gram(Gp)
        if mode == _WANG_CORA:
            Lam, ok = wang_frad_gain(P, data.A, data.C, data.E, data.F)
        else:
            Lam, ok = wang_frad_gain(P, None, data.C, data.E, data.F)
        if not ok:
            return cp, Gp, False
        cn, Gn = strip_update(cp, Gp, Lam, data.C, y, data.sigma)
    return cn, Gn, True


def _update(cp, Gp, y, data):
    """The measurement update of the strip-based kernels by the gain of ``data.mode``: Bravo's
    (:func:`_bravo_update`) or a strip gain (:func:`_strip_update`); ``(c, G, ok)``."""
    if data.mode == _BRAVO:
        return _bravo_update(cp, Gp, y, data)
    return _strip_update(cp, Gp, y, data)


def _reduced(Gn, data):
    """The order reduction of every step kernel: ``(G, ok)`` (:func:`reduce`)."""
    return reduce(Gn, data.order, data.method, data.cluster_rtol, data.pivot_rtol,
                  JACOBI_MAX_DIM)


def _update_reduce(cp, Gp, y, data):
    """Update of the predicted set ``(cp, Gp)`` with ``y``, then the order reduction."""
    cn, Gn, ok = _update(cp, Gp, y, data)
    if not ok:
        return cp, Gp, False
    out, ok = _reduced(Gn, data)
    return cn, out, ok


def _append_columns(G, R):
    """``[G, R]``: the remainder generators of a linearisation after the others (the order of
    :func:`observers.families.propagate` and of the strip-based numpy step)."""
    n, r = G.shape
    out = np.empty((n, r + R.shape[1]))
    out[:, :r] = G
    out[:, r:] = R
    return out


def _strip_step_py(c, G, d, y, args):
    data = StepData(*args)
    cp, Gp = _predict(c, G, data.A, d, data.W_c, data.E)
    return _update_reduce(cp, Gp, y, data)


def _strip_first_py(c, G, y, args):
    # a writable copy of the read-only G of the initial set: the update then has the argument
    # types of every later step (:func:`_strip_step_py`) and is compiled once, not twice
    return _update(c, G.copy(), y, StepData(*args))


def _predict_linearised_py(c, G, J, d, R, args):
    data = StepData(*args)
    cp, Gp = _predict(c, G, J, d, data.W_c, data.E)
    return cp, _append_columns(Gp, R)


def _strip_predicted_py(cp, Gp, y, args):
    return _update_reduce(cp, Gp, y, StepData(*args))


def _propagation(c, G, d, y, data):
    """:func:`propagate` with the gain of ``data.mode`` (Combastel's or the given one), not
    reduced: ``(c, G, ok)``."""
    if data.mode == _COMBASTEL:
        L, ok = combastel_gain(_gram(G), data.A, data.C, data.F)
        if not ok:
            return c, G, False
        cn, Gn = propagate((c, G), (data.A, d), data.C, L, y, (data.V_c, data.F),
                           (data.W_c, data.E))
    else:  # _GIVEN (two calls: the given gain is read-only, Combastel's is not)
        cn, Gn = propagate((c, G), (data.A, d), data.C, data.gain, y, (data.V_c, data.F),
                           (data.W_c, data.E))
    return cn, Gn, True


def _propagate_step_py(c, G, d, y, args):
    data = StepData(*args)
    cn, Gn, ok = _propagation(c, G, d, y, data)
    if not ok:
        return c, G, False
    out, ok = _reduced(Gn, data)
    return cn, out, ok


def _propagate_linearised_py(c, G, d, R, y, args):
    data = StepData(*args)
    cn, Gn, ok = _propagation(c, G, d, y, data)
    if not ok:
        return c, G, False
    out, ok = _reduced(_append_columns(Gn, R), data)
    return cn, out, ok


def _bravo_update(cn, Gn, y, data):
    """Bravo's measurement update, strip after strip: ``(c, G, True)``."""
    M = _gram(Gn)
    N, h, by_leverage = leverages(Gn, M)
    # the projections c G of every strip: one product, then carried strip to strip
    P = _mm(data.C, Gn)
    for i in range(data.C.shape[0]):
        ci = data.C[i].copy()
        a = P[i].copy()
        if by_leverage:
            j = bravo_choice_ratios(a, M, h, ci, data.sigma[i], data.zero_projection)
            # false after a strip of zero width (G G' singular): the Gram scores take over
            N, h, by_leverage = leverage_update(N, h, Gn, ci, data.sigma[i], j)
        else:
            j = bravo_choice_gram(Gn, a, M, ci, data.sigma[i], data.bases[i],
                                  data.zero_projection)
        M = gram_update(M, Gn, ci, data.sigma[i], j)
        projections_update(P, i + 1, data.C, Gn, a, data.sigma[i], j)
        cn, Gn = bravo_update(cn, Gn, a, ci, y[i], data.sigma[i], j)
    return cn, Gn, True


if AVAILABLE:  # helpers, resolved by the kernels when they compile (at their first call)
    _PRODUCTS = (_mm, _gram, _mv, _vm, _vv)
    _mm, _gram, _mv, _vm, _vv = (njit(f) for f in _PRODUCTS)
    _HELPERS = (_pairwise_block, _pairwise_sum, _smallest, _tie_band, _cluster_basis_into,
                _householder_lower, _jacobi_left, _principal_axes, _lu_small, _det, _solve,
                _cholesky, _symmetrise, _psd_inverse, _adjugate_psd, _finite, _solve_t, _least)
    (_pairwise_block, _pairwise_sum, _smallest, _tie_band, _cluster_basis_into,
     _householder_lower, _jacobi_left, _principal_axes, _lu_small, _det, _solve, _cholesky,
     _symmetrise, _psd_inverse, _adjugate_psd, _finite, _solve_t, _least) = (
        njit(f) for f in _HELPERS)
    # the formulas of the kernels keep the kernels' error model (a division by zero gives
    # inf or nan, as in numpy, instead of raising; no checks in the loops)
    (_predict, _strip_generators, strip_update, _per_strip_update, alamo_frad_strips,
     wang_frad_gain, combastel_gain, propagate, bravo_choice, bravo_choice_gram, gram_update,
     bravo_update, leverages, bravo_choice_ratios, leverage_update, projections_update) = (
        njit(f, error_model="numpy") for f in (
            _predict, _strip_generators, strip_update, _per_strip_update, alamo_frad_strips,
            wang_frad_gain, combastel_gain, propagate, bravo_choice, bravo_choice_gram,
            gram_update, bravo_update, leverages, bravo_choice_ratios, leverage_update,
            projections_update))
#: ``B @ u`` summed in index order (:func:`_mv`; compiled where numba is): the input term of a
#: compiled step, the same bits under every BLAS kernel as the step itself
matvec = _mv
#: the principal axes in their deterministic basis, from one-sided Jacobi up to ``jacobi_dim``
#: rows (compiled where numba is; ``observers.sets.reduction.jacobi_principal_axes``)
principal_axes = _principal_axes
#: the compiled :func:`_reduce_py` (``None`` without numba)
reduce = njit(_reduce_py, error_model="numpy")
#: the compiled step kernels ``kernel(c, G, d, y, args) -> (c, G, ok)`` with
#: ``args = tuple(data)`` of a :class:`StepData` (``None`` without numba)
if AVAILABLE:
    _strip_update, _bravo_update, _update, _reduced, _update_reduce, _append_columns, \
        _propagation = (njit(f, error_model="numpy") for f in (
            _strip_update, _bravo_update, _update, _reduced, _update_reduce, _append_columns,
            _propagation))
#: the strip-based step (every gain of the strips, Bravo's too: the mode of its data)
strip_step = njit(_strip_step_py, error_model="numpy")
propagate_step = njit(_propagate_step_py, error_model="numpy")
#: the measurement update alone ``first(c, G, y, args) -> (c, G, ok)``: the first set of a
#: strip-based observer (``X0`` intersected with ``y[0]``, not reduced), by the same compiled
#: formulas as every later step
strip_first = njit(_strip_first_py, error_model="numpy")
#: a step on a per-step linearisation ``x+ in J x + d + R`` (nonlinear systems,
#: :mod:`observers.prediction`), in two calls so that a gain may read the Jacobian at the
#: predicted centre: ``predict_linearised(c, G, J, d, R, args) -> (cp, [J G, E, R])``, then
#: ``strip_predicted(cp, Gp, y, args) -> (c, G, ok)`` (update and reduction); the
#: propagation kernels in one call, ``propagate_linearised(c, G, d, R, y, args)``, with the
#: Jacobian ``J`` as the ``A`` of ``args``
predict_linearised = njit(_predict_linearised_py, error_model="numpy")
strip_predicted = njit(_strip_predicted_py, error_model="numpy")
propagate_linearised = njit(_propagate_linearised_py, error_model="numpy")

#: the kernel names (:class:`observers.kernels.StepKernel`) -> (kernel, gain formula, first
#: set)
_KERNELS = {
    "strip-given": (strip_step, _GIVEN, strip_first),
    "per-strip": (strip_step, _PER_STRIP, strip_first),
    "alamo": (strip_step, _ALAMO, strip_first),
    "wang": (strip_step, _WANG, strip_first),
    "wang-cora": (strip_step, _WANG_CORA, strip_first),
    "bravo": (strip_step, _BRAVO, strip_first),
    "propagation-given": (propagate_step, _GIVEN, None),
    "combastel": (propagate_step, _COMBASTEL, None),
}
#: the kernel names :func:`prepare` accepts
KERNEL_NAMES = tuple(_KERNELS)
_NO_GAIN = np.zeros((0, 0))
_NO_GAIN.setflags(write=False)
_NO_BASES = np.zeros((0, 0, 0))
_NO_BASES.setflags(write=False)


def _frozen_c(a) -> np.ndarray:
    """A read-only C-contiguous float64 copy of ``a`` (one argument type per field)."""
    out = np.array(a, dtype=np.float64, order="C", copy=True)
    out.setflags(write=False)
    return out


class StepRun(NamedTuple):
    """A compiled step kernel with the static data of one run (:func:`prepare`)."""

    #: ``kernel(c, G, d, y, args) -> (c, G, ok)``
    kernel: Callable
    #: the static data by name
    data: StepData
    #: ``tuple(data)``, the kernel's last argument
    args: tuple
    #: ``first(c, G, y, args) -> (c, G, ok)``, the measurement update alone (the first set of
    #: a strip-based observer); ``None`` for the propagation kernels (their first set is X0)
    first: Callable | None = None


class StepModel(NamedTuple):
    """The linear model a step kernel runs on: ``x+ = A x + B u + w``, ``w`` in ``(W_c, E)``,
    the strips ``|C x - y| <= sigma`` of the noise ``v`` in ``(V_c, F)`` (array_like, copied
    by :func:`prepare`)."""

    A: Any
    B: Any
    W_c: Any
    E: Any
    C: Any
    sigma: Any
    F: Any
    V_c: Any


def prepare(
    kernel: str, reduction: str, order: float, model: StepModel, *,
    gain=None, bases=None, zero_projection: float = 0.0,
) -> StepRun:
    """The compiled kernel named ``kernel`` and the static data of a run (the doorway of the
    step kernels: the only place where names become the kernels' numbers).

    Parameters
    ----------
    kernel : str
        One of :data:`KERNEL_NAMES` (the value of an :class:`observers.kernels.StepKernel`).
    reduction : str
        Name of a reduction of :func:`reduce` (a key of :data:`REDUCTIONS`).
    order : float
        Zonotope order, validated by the caller (>= 1).
    model : StepModel
        The linear model, the centre and generators of ``W`` and ``V``, the strip half-widths.
    gain : array_like, optional
        The given gain of the ``*-given`` and ``"per-strip"`` kernels.
    bases : array_like, optional
        The null-space bases of the rows of ``C`` (m x n x n-1) of ``"bravo"``.
    zero_projection : float
        Bravo's threshold of ``|c g_j|`` (``"bravo"``).

    Returns
    -------
    StepRun
        ``(kernel, data, args, first)``: call ``kernel(c, G, matvec(data.B, u), y, args)``
        with writable C-contiguous float vectors ``matvec(data.B, u)`` and ``y`` and the
        ``c, G`` of the previous step (read-only, as the sets keep them); ``first(c, G, y,
        args)`` for the first set of a strip-based observer.
    """
    step, mode, first = _KERNELS[kernel]
    data = StepData(
        mode, _NO_GAIN if gain is None else _frozen_c(gain),
        _NO_BASES if bases is None else _frozen_c(bases),
        *(_frozen_c(a) for a in model),
        float(zero_projection), float(order), REDUCTIONS[reduction], CLUSTER_RTOL, PIVOT_RTOL)
    return StepRun(step, data, tuple(data), first)


def linearised_args(run: StepRun, A) -> tuple:
    """The ``args`` of ``run`` with the state matrix ``A`` of this step in place of the model's
    (a per-step linearisation: the Jacobian the propagation kernels apply and the ``"wang-cora"``
    gain reads); a read-only copy, so that every step passes the same argument types."""
    return tuple(run.data._replace(A=_frozen_c(A)))
