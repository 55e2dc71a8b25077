"""Interval constraint propagation over ``A xi = b`` in a box, compiled (numba).

The compiled twin of :func:`observers.sets.conzono_ops.implied_bounds`: the same sweeps, the
same candidate bounds and the same outward rounding, written as loops over the rows of ``A``
so that no ``p x r`` temporary is built (the numpy path builds about twenty per sweep; on the
steady 100-tank sets of CZN-A, ``160 x 10240``, that is most of the step's time).  Its sums
run in a fixed order, so its bits do not depend on the BLAS kernel.  Without numba
:data:`implied_bounds_loop` is ``None`` and the numpy path runs (same bounds up to rounding,
both outward rounded).

Rounding (both paths).  Every sum of ``r`` products is within ``gamma_r sum |terms|`` of its
exact value whatever the order of summation (``gamma_r = r u / (1 - r u)``, ``u = eps / 2``;
Higham, *Accuracy and Stability of Numerical Algorithms*, 2nd ed., Sec. 3.1), and the few
further operations of a candidate add a relative ``u`` each.  The slack
:func:`slack_factor` ``* (|b_i| + sum_k |a_ik| (|mid_k| + rad_k) + |a_ij| (|mid_j| + rad_j))``
is at least twice that bound, so every candidate is an outward rounding of the exact one.
"""

from __future__ import annotations

import numpy as np

from .switch import njit

#: candidates computed in the rounding mode of the hardware are widened by this many ``eps``
#: per term of a row's sums, plus :data:`EXTRA_TERMS` for the operations after the sums
EXTRA_TERMS = 8


def slack_factor(r: int) -> float:
    """``(r + EXTRA_TERMS) eps``: the relative slack of a candidate bound from a row of ``r``
    terms (see the module docstring)."""
    return (r + EXTRA_TERMS) * float(np.finfo(float).eps)


def _implied_bounds_py(A, b, lo, hi, sweeps, tiny, gamma):
    """Sweeps of interval constraint propagation; ``lo``, ``hi`` are updated in place.

    For every row ``i`` and variable ``j`` with ``|a_ij| >= tiny``:
    ``xi_j = (b_i - sum_{k != j} a_ik xi_k) / a_ij`` over the current box, a centre
    ``(b_i - s_i + a_ij mid_j) / a_ij`` and a radius ``(t_i - |a_ij| rad_j + slack) / |a_ij|``
    with ``s_i = sum_k a_ik mid_k`` and ``t_i = sum_k |a_ik| rad_k``; a candidate that
    overflows bounds nothing.  Stops early when a sweep changes no bound.
    """
    p, r = A.shape
    mid = np.empty(r)
    rad = np.empty(r)
    new_lo = np.empty(r)
    new_hi = np.empty(r)
    for _ in range(sweeps):
        for j in range(r):
            mid[j] = 0.5 * (hi[j] + lo[j])
            rad[j] = 0.5 * (hi[j] - lo[j])
            new_lo[j] = -np.inf
            new_hi[j] = np.inf
        for i in range(p):
            s_mid = 0.0
            s_rad = 0.0
            s_abs = 0.0
            for k in range(r):
                a = A[i, k]
                s_mid += a * mid[k]
                s_rad += abs(a) * rad[k]
                s_abs += abs(a) * abs(mid[k])
            rest = b[i] - s_mid
            base = abs(b[i]) + s_abs + s_rad
            for j in range(r):
                a = A[i, j]
                aa = abs(a)
                if not aa >= tiny:
                    continue
                inv = 1.0 / a
                cen = rest + a * mid[j]
                wid = (s_rad - aa * rad[j]) + gamma * (base + aa * (abs(mid[j]) + rad[j]))
                x_c = cen * inv
                x_r = wid * abs(inv)
                c_lo = x_c - x_r
                c_hi = x_c + x_r
                if np.isfinite(c_lo) and c_lo > new_lo[j]:
                    new_lo[j] = c_lo
                if np.isfinite(c_hi) and c_hi < new_hi[j]:
                    new_hi[j] = c_hi
        changed = False
        for j in range(r):
            if new_lo[j] > lo[j]:
                lo[j] = new_lo[j]
                changed = True
            if new_hi[j] < hi[j]:
                hi[j] = new_hi[j]
                changed = True
        if not changed:
            break


#: the compiled sweeps (``None`` without numba)
implied_bounds_loop = njit(_implied_bounds_py)
