"""Independent formulations of the exact consistent set, solved from scratch (the checks of
:mod:`observers.numerics.exact`), and the membership LP of :class:`~.exact.ExactSet`.

Two formulations, neither sharing code with the incremental solver (no warm start, no
axis-aligned split, no column bounds derived from earlier hulls):

* **dense** (:func:`dense_hulls`): the states are eliminated.  With
  ``z = (xi, omega_0, .., omega_{k-1}, nu_0, .., nu_k)`` in the unit box (the generator
  factors of ``X0``, of every ``w_j`` and of every ``v_j``), ``x_j = a_j + P_j z`` with
  ``a_0 = c0``, ``P_0 = [G0, 0]``, ``a_{j+1} = A a_j + B u_j + cW``,
  ``P_{j+1} = A P_j + [0 .. E (at omega_j) .. 0]``; the measurements are the equalities
  ``C (a_j + P_j z) + cV + F nu_j = y_j``.  The hull is ``a_k +- max/min (P_k z)_i``, each LP
  solved by ``scipy.optimize.linprog`` (HiGHS) from scratch and evaluated from its dual point
  (weak duality ``b'y - ||c - A'y||_1``, valid for any dual point, not outward rounded), so it
  does not depend on the feasibility tolerance of the primal point.  Its cost per step grows
  with the square of the record length (the "naive" re-solve).
* **explicit** (:func:`explicit_hulls`): states and all noise factors as variables,
  ``x_0 - G0 xi = c0``, ``x_{j+1} - A x_j - E omega_j = B u_j + cW``,
  ``C x_j + F nu_j = y_j - cV``, sparse, each LP solved from scratch by linprog; its values
  are the primal optima at the solver's tolerance (the states are free, so there is no
  simple dual bound).  Cheap enough to check whole records at every step.

The values are checks at solver tolerance (1e-10), not guarantees.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.optimize import linprog

#: primal and dual feasibility tolerances of the check LPs (HiGHS's smallest accepted value)
CHECK_TOLERANCE = 1e-10
_OPTIONS = {"primal_feasibility_tolerance": CHECK_TOLERANCE,
            "dual_feasibility_tolerance": CHECK_TOLERANCE}


def _model(model):
    A, B, C, X0, W, V = model
    A, C = np.asarray(A, float), np.asarray(C, float)
    n = A.shape[0]
    B = np.asarray(B, float).reshape(n, -1)
    sets = tuple((np.asarray(c, float).reshape(-1), np.asarray(G, float)) for c, G in
                 (X0, W, V))
    return A, B, C, sets


def _record(B, u, y):
    y = np.atleast_2d(np.asarray(y, float))
    N = y.shape[0]
    u = (np.asarray(u, float).reshape(-1, B.shape[1]) if B.shape[1]
         else np.zeros((N, 0)))
    return u, y


# -- dense formulation (states eliminated) -------------------------------------------------
def _dense_min(c: np.ndarray, A_eq: np.ndarray, b_eq: np.ndarray) -> float:
    """Weak-duality lower bound of ``min c'z  s.t.  A_eq z = b_eq, -1 <= z <= 1`` from the
    dual point of linprog's solution."""
    if A_eq.shape[0] == 0:
        return -float(np.abs(c).sum())
    res = linprog(c, A_eq=A_eq, b_eq=b_eq, bounds=(-1.0, 1.0), method="highs-ds",
                  options=_OPTIONS)
    if res.status == 2:
        raise ValueError("the check LP is infeasible (record inconsistent with the model)")
    if res.status != 0:
        raise RuntimeError(f"the check LP failed: {res.message}")
    y = np.asarray(res.eqlin.marginals, float)
    return float(b_eq @ y - np.abs(c - A_eq.T @ y).sum())


def _dense_hull(a, P, A_eq, b_eq):
    n = a.shape[0]
    lo, hi = np.empty(n), np.empty(n)
    for i in range(n):
        hi[i] = a[i] - _dense_min(-P[i], A_eq, b_eq)
        lo[i] = a[i] + _dense_min(P[i], A_eq, b_eq)
    return lo, hi


def dense_hulls(model: tuple, u, y, steps=None) -> dict[int, tuple[np.ndarray, ...]]:
    """Predicted and filtered hulls by the dense LP over the noise factors.

    Parameters
    ----------
    model : tuple
        ``(A, B, C, X0, W, V)``: the linear model and the ``(centre, generators)`` of the
        initial, disturbance and noise zonotopes (as for
        :class:`~observers.numerics.exact.ExactHullLP`).
    u, y : array_like
        The record (``u[j]`` drives ``x_{j+1}``, ``y[j]`` measures ``x_j``).
    steps : iterable of int, optional
        Steps at which to solve (default: every step of ``y``).

    Returns
    -------
    dict
        ``step -> (pred_lo, pred_hi, filt_lo, filt_hi)``.
    """
    A, B, C, ((c0, G0), (cW, E), (cV, F)) = _model(model)
    u, y = _record(B, u, y)
    n = A.shape[0]
    want = set(range(y.shape[0])) if steps is None else {int(k) for k in steps}
    last = max(want)
    r0, rw, rv = G0.shape[1], E.shape[1], F.shape[1]
    nvar = r0 + last * rw + (last + 1) * rv
    iw, iv = r0, r0 + last * rw  # first omega and nu columns
    a = c0.copy()
    P = np.zeros((n, nvar))
    P[:, :r0] = G0
    rows: list[np.ndarray] = []
    rhs: list[float] = []
    out = {}
    for k in range(last + 1):
        if k > 0:
            a = A @ a + B @ u[k - 1] + cW
            P = A @ P
            P[:, iw + (k - 1) * rw : iw + k * rw] += E
        if k in want:  # predicted: the measurements of the steps before k
            pred = _dense_hull(a, P, np.array(rows).reshape(-1, nvar), np.array(rhs))
        Mk = C @ P
        Mk[:, iv + k * rv : iv + (k + 1) * rv] += F
        rows.extend(Mk)
        rhs.extend(y[k] - cV - C @ a)
        if k in want:
            filt = _dense_hull(a, P, np.array(rows).reshape(-1, nvar), np.array(rhs))
            out[k] = (*pred, *filt)
    return out


# -- explicit formulation (states and factors as variables) ---------------------------------
def explicit_lp(model: tuple, u, y, k: int, measured: int | None = None):
    """The LP ``A_eq z = b_eq`` with bounds of the trajectories ``x_0..x_k`` of ``model``
    (``(A, B, C, X0, W, V)`` as for :func:`dense_hulls`) consistent with ``u[0..k-1]`` and
    ``y[0..measured-1]`` (default ``measured = k + 1``: the filtered set; ``k``: the
    predicted one).

    Returns
    -------
    A_eq : scipy.sparse.csr_matrix
    b_eq : ndarray
    bounds : list of (low, high)
        ``(None, None)`` for the states, ``(-1, 1)`` for the factors.
    xk : ndarray of int
        The columns of ``x_k``.
    """
    A, B, C, ((c0, G0), (cW, E), (cV, F)) = _model(model)
    u, y = _record(B, u, y)
    n, m = A.shape[0], C.shape[0]
    measured = k + 1 if measured is None else measured
    r0, rw, rv = G0.shape[1], E.shape[1], F.shape[1]
    i0 = n * (k + 1)  # x_j at n j; xi at i0
    iw = i0 + r0  # omega_j at iw + rw j
    iv = iw + rw * k  # nu_j at iv + rv j
    nvar = iv + rv * measured
    ri, ci, vals, rhs = [], [], [], []
    row = 0

    def put(first_col: int, M: np.ndarray) -> None:
        r, c = np.nonzero(M)
        ri.append(r + row)
        ci.append(c + first_col)
        vals.append(M[r, c])

    put(0, np.eye(n))
    put(i0, -G0)
    rhs.append(c0)
    row += n
    for j in range(k):
        put(n * (j + 1), np.eye(n))
        put(n * j, -A)
        put(iw + rw * j, -E)
        rhs.append(B @ u[j] + cW)
        row += n
    for j in range(measured):
        put(n * j, C)
        put(iv + rv * j, F)
        rhs.append(y[j] - cV)
        row += m
    A_eq = sp.csr_matrix((np.concatenate(vals), (np.concatenate(ri), np.concatenate(ci))),
                         shape=(row, nvar))
    bounds = [(None, None)] * (n * (k + 1)) + [(-1.0, 1.0)] * (nvar - n * (k + 1))
    return A_eq, np.concatenate(rhs), bounds, np.arange(n) + n * k


#: linprog settings tried in turn: HiGHS's dual simplex can stop without a verdict ("Not
#: Set") on the larger explicit LPs; then without presolve, then the interior-point method
_RETRIES = (("highs-ds", {}), ("highs-ds", {"presolve": False}), ("highs-ipm", {}))


def _explicit_opt(c, A_eq, b_eq, bounds) -> float:
    for method, extra in _RETRIES:
        res = linprog(c, A_eq=A_eq, b_eq=b_eq, bounds=bounds, method=method,
                      options={**_OPTIONS, **extra})
        if res.status in (0, 2):
            break
    if res.status == 2:
        raise ValueError("the check LP is infeasible (record inconsistent with the model)")
    if res.status != 0:
        raise RuntimeError(f"the check LP failed: {res.message}")
    return float(res.fun)


def explicit_hulls(model: tuple, u, y, steps=None) -> dict[int, tuple[np.ndarray, ...]]:
    """Predicted and filtered hulls by the explicit sparse LP, from scratch at every step
    (arguments and result as :func:`dense_hulls`)."""
    y = np.atleast_2d(np.asarray(y, float))
    n = np.asarray(model[0]).shape[0]
    out = {}
    for k in (range(y.shape[0]) if steps is None else steps):
        hull = []
        for measured in (k, k + 1):
            A_eq, b_eq, bounds, xk = explicit_lp(model, u, y, k, measured)
            lo, hi = np.empty(n), np.empty(n)
            for i in range(n):
                c = np.zeros(A_eq.shape[1])
                c[xk[i]] = 1.0
                lo[i] = _explicit_opt(c, A_eq, b_eq, bounds)
                hi[i] = -_explicit_opt(-c, A_eq, b_eq, bounds)
            hull += [lo, hi]
        out[int(k)] = tuple(hull)
    return out


def consistent(model: tuple, u, y, x, tol: float = 0.0) -> bool:
    """Whether a trajectory of ``model`` (``(A, B, C, X0, W, V)`` as for :func:`dense_hulls`)
    consistent with ``u[0..k-1]``, ``y[0..k]`` (``k = len(y) - 1``) ends within ``tol`` of
    ``x`` (infinity norm): a feasibility LP at HiGHS's tolerance."""
    y = np.atleast_2d(np.asarray(y, float))
    k = y.shape[0] - 1
    A_eq, b_eq, bounds, xk = explicit_lp(model, u, y, k)
    bounds = list(bounds)
    for i, col in enumerate(xk):
        bounds[col] = (float(x[i]) - tol, float(x[i]) + tol)
    res = linprog(np.zeros(A_eq.shape[1]), A_eq=A_eq, b_eq=b_eq, bounds=bounds,
                  method="highs")
    return res.status == 0
