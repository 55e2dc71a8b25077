"""Feasibility of equality constraints over the unit box, decided by HiGHS (``highspy``).

:func:`box_feasible` is the membership test of the set types (a point in a zonotope, a
constrained zonotope, a matrix zonotope).  It lives apart from the hull LPs
(:mod:`observers.lp.hull`) so that the zonotope types, and every row whose estimates are
zonotopes, depend on this test only and not on the hull's dual simplex and sifting: an edit of
the hull LPs stales only the rows whose sets have an LP hull (``setobs-bench stale``).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

try:  # highspy is a hard dependency; keep the import error readable
    import highspy
except ImportError as exc:  # pragma: no cover - exercised only on broken installs
    raise ImportError("the 'highspy' package is required for LP-based set operations") from exc

from .highs import new_highs


def box_feasible(M: np.ndarray, t: np.ndarray, tol=0.0) -> bool:
    """Whether some ``xi`` in the unit box satisfies ``M xi = t`` up to ``|M xi - t| <= tol``.

    Rows of ``M``/``t`` are the equality constraints (e.g. ``[G; A]`` and ``[x - c; b]``);
    ``tol`` is a scalar or one tolerance per row.  Slack variables bounded by ``tol`` absorb
    the tolerance; HiGHS decides feasibility (with its own feasibility tolerance of 1e-7,
    relative: each row is first divided by its largest magnitude among ``M``'s entries and
    ``t``, which leaves the set of solutions unchanged).  Unscaled, a vertex of the box of
    radius 5e-7 was called infeasible with ``tol = 1e-9`` (slack bounds far below HiGHS's
    own tolerances, on rows far below 1), and feasible with ``tol = 0``.
    """
    m, r = M.shape
    tol = np.broadcast_to(np.asarray(tol, dtype=float), (m,))
    if r == 0:
        return bool(np.all(np.abs(t) <= tol))
    M, t = np.asarray(M, float), np.asarray(t, float)
    scale = np.maximum(np.abs(M).max(axis=1), np.abs(t))
    scale = np.where(scale > 0, scale, 1.0)  # a zero row: 0 = t within tol, as it is
    M, t, tol = M / scale[:, None], t / scale, tol / scale
    h = new_highs()
    lp = highspy.HighsLp()
    lp.num_col_ = r + m
    lp.num_row_ = m
    lp.col_cost_ = np.zeros(r + m)
    lp.col_lower_ = np.concatenate([-np.ones(r), -tol])
    lp.col_upper_ = np.concatenate([np.ones(r), tol])
    lp.row_lower_ = np.asarray(t, float)
    lp.row_upper_ = np.asarray(t, float)
    csc = sp.csc_matrix(np.hstack([M, np.eye(m)]))
    lp.a_matrix_.format_ = highspy.MatrixFormat.kColwise
    lp.a_matrix_.start_ = csc.indptr
    lp.a_matrix_.index_ = csc.indices
    lp.a_matrix_.value_ = csc.data
    h.passModel(lp)
    # HiGHS's presolve + dual simplex can stop without a verdict ("Not Set") on badly scaled
    # generators (e.g. entries from 1e-39 to 3 after many steps of a contracting gain): retry
    # without presolve, then with the interior-point solver; undecided counts as not contained
    for option, value in _FEASIBILITY_RETRIES:
        if option is not None:
            h.setOptionValue(option, value)
        h.run()
        status = h.getModelStatus()
        if status in (highspy.HighsModelStatus.kOptimal, highspy.HighsModelStatus.kInfeasible):
            break
    return status == highspy.HighsModelStatus.kOptimal


_FEASIBILITY_RETRIES = ((None, None), ("presolve", "off"), ("solver", "ipm"))
