"""Compiled (numba) one-step formulas of the zonotopic observer families: one kernel call per
step instead of about 30-80 numpy calls.

On the 6-state vehicle (a 6 x ~600 generator matrix) a step of a zonotope observer costs a few
tens of thousands of flops, and the numpy path spends most of its time in per-call overhead
(about 1 us per call).  The kernels run the formulas of :mod:`observers.families` and
:mod:`observers.numerics.frad` in the same order of operations, then the order reduction of
:mod:`._reduction_jit`, so the sets are those of the numpy path up to rounding:

* :func:`strip_step`: prediction ``(A c + d + c_W, [A G, E])``, intersection with the
  strips ``|C x - y| <= sigma`` (:func:`observers.families.strip_update`) with the gain chosen
  by ``mode``, reduction;
* :func:`propagate_step`: ``S+ = (A - L C) S + d + L y + (-L) V + W``
  (:func:`observers.families.propagate`) with a given gain or Combastel's, reduction.

Gain modes of :func:`strip_step`: :data:`GIVEN` (``L``, all strips at once: PRad-B/C/D),
:data:`PER_STRIP` (column ``i`` of ``L`` for strip ``i``, one strip after the other: PRad-A),
:data:`ALAMO` (FRad-A, :func:`observers.numerics.frad.alamo_frad_strips`), :data:`WANG`
(FRad-B, :func:`observers.numerics.frad.wang_frad_gain`, with ``A`` applied once more when
``wang_cora`` is true).  :func:`propagate_step` takes :data:`GIVEN` (Nom-G, PRad-E) or
:data:`COMBASTEL` (FRad-C, :func:`observers.numerics.frad.combastel_gain`).

A kernel returns ``ok = False`` when it cannot vouch for the numpy path's result (a
non-finite entry, a singular matrix in a gain): the caller then runs the numpy path for that
step, which knows the fallbacks (pseudo-inverse, zero gain).
"""

from __future__ import annotations

import numpy as np

from . import _reduction_jit as _red
from ._jit import njit

GIVEN, PER_STRIP, ALAMO, WANG, COMBASTEL = 0, 1, 2, 3, 4


def _finite(a):
    for v in a.flat:
        if not np.isfinite(v):
            return False
    return True


def _solve_t(S, B):
    """``(S^{-1} B)'`` for a symmetric ``S`` (LU solve), and whether it is finite (a singular
    ``S`` raises ``LinAlgError``: the caller falls back to the numpy path)."""
    X = np.linalg.solve(S, B)
    return np.ascontiguousarray(X.T), _finite(X)


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
    out, ok = _red.reduce(Gn, order, method, cluster_rtol, pivot_rtol)
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
    out, ok = _red.reduce(Gn, order, method, cluster_rtol, pivot_rtol)
    return cn, out, ok


strip_step = njit(_strip_step_py, error_model="numpy")
propagate_step = njit(_propagate_step_py, error_model="numpy")
if strip_step is not None:
    _finite = njit(_finite)
    _solve_t = njit(_solve_t)
