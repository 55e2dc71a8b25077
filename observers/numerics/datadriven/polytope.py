"""Refinement of a sound set of models by the linear constraints every sample imposes.

With full-state-reconstructible data (``x(k) = xh(k) + e(k)``, ``|e(k)| <= e_bar``), row i of
any consistent ``[A B] = Theta`` satisfies, for every transition k,

    ``|xh_i(k+1) - c_w,i - theta_i' dh(k)| <= e_bar_i + r_w,i + sum_j |a_ij| e_bar_j``

(``dh(k) = [xh(k); u(k)]``, ``r_w`` the interval radius of W).  Given a sound prior box
``lo <= Theta <= hi`` (from :func:`~observers.numerics.datadriven.learning.sound_model_set`), the
unknown ``|a_ij|`` is bounded by ``max(|lo_ij|, |hi_ij|)``, so each row lies in a polytope of
2T half-spaces intersected with the prior box.  Its interval hull is computed by linear
programs (HiGHS, called directly) and each bound is made sound by weak duality: for *any*
multipliers ``lam`` of the rows ``l <= F theta <= u``,

    ``max c' theta <= sum_r max(lam_r u_r, lam_r l_r) + sum_j max(s_j hi_j, s_j lo_j)``,
    ``s = c - F' lam``,

evaluated with outward rounding; the solver's primal value is never used.  Unlike the
pseudo-inverse bound, this set shrinks as the experiment grows.
"""

from __future__ import annotations

import highspy
import numpy as np
import scipy.sparse as sp

from observers.lp import new_highs

_EPS = np.finfo(float).eps


def _dual_bound(c, F, l, u, lo, hi, lam) -> float:
    s = c - F.T @ lam
    t1 = np.maximum(lam * u, lam * l).sum()
    t2 = np.maximum(s * hi, s * lo).sum()
    mag = (np.abs(lam) * np.maximum(np.abs(u), np.abs(l))).sum() + (
        np.abs(s) * np.maximum(np.abs(hi), np.abs(lo))).sum()
    return float(t1 + t2 + 16 * _EPS * (mag + 1.0) * (F.shape[0] + F.shape[1]))


class RangeLP:
    """``max c' theta  s.t.  l <= F theta <= u,  lo <= theta <= hi`` for many ``c``."""

    def __init__(self, F, l, u, lo, hi):
        self.F, self.l, self.u, self.lo, self.hi = F, l, u, lo, hi
        m, k = F.shape
        h = new_highs()
        lp = highspy.HighsLp()
        lp.num_col_, lp.num_row_ = k, m
        lp.col_cost_ = np.zeros(k)
        lp.col_lower_, lp.col_upper_ = lo.astype(float), hi.astype(float)
        lp.row_lower_, lp.row_upper_ = l.astype(float), u.astype(float)
        csc = sp.csc_matrix(F)
        lp.a_matrix_.format_ = highspy.MatrixFormat.kColwise
        lp.a_matrix_.start_ = csc.indptr
        lp.a_matrix_.index_ = csc.indices
        lp.a_matrix_.value_ = csc.data
        h.passModel(lp)
        self._h, self._k = h, k

    def maximize(self, c: np.ndarray) -> float:
        """Sound upper bound of ``max c' theta`` (the box bound if the LP fails)."""
        h = self._h
        h.changeColsCost(self._k, np.arange(self._k, dtype=np.int32), -c)
        h.run()
        sol = h.getSolution()
        if sol.dual_valid and len(sol.row_dual) == self.F.shape[0]:
            lam = -np.asarray(sol.row_dual, dtype=float)
        else:
            lam = np.zeros(self.F.shape[0])
        return _dual_bound(c, self.F, self.l, self.u, self.lo, self.hi, lam)


def refine_box(xh: np.ndarray, u: np.ndarray, e_bar: np.ndarray,
               W_hull: tuple[np.ndarray, np.ndarray], prior: tuple[np.ndarray, np.ndarray],
               rounds: int = 2):
    """Tighter sound bounds ``(lo, hi)`` of ``[A B]`` (see the module docstring).

    ``xh`` (T+1 x n) are the reconstructed states, ``u`` (T x m) the inputs, ``e_bar`` the
    reconstruction-error radii, ``W_hull = (W_c, W_r)`` centre and radius of W's interval
    hull and ``prior = (lo, hi)`` a sound prior box of ``[A B]``.
    """
    W_c, W_r = W_hull
    lo, hi = prior
    n = xh.shape[1]
    D = np.hstack([xh[:-1], u])  # T x k, row k is dh(k)'
    k = D.shape[1]
    lo, hi = lo.copy(), hi.copy()
    for _ in range(rounds):
        abar = np.maximum(np.abs(lo[:, :n]), np.abs(hi[:, :n]))
        for i in range(n):
            eps = e_bar[i] + W_r[i] + abar[i] @ e_bar
            rhs = xh[1:, i] - W_c[i]
            lp = RangeLP(D, rhs - eps, rhs + eps, lo[i].copy(), hi[i].copy())
            for j in range(k):
                c = np.zeros(k)
                c[j] = 1.0
                hi[i, j] = min(hi[i, j], lp.maximize(c))
                c[j] = -1.0
                lo[i, j] = max(lo[i, j], -lp.maximize(c))
    return lo, hi
