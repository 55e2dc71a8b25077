"""Is a record consistent with its linear model?  An LP feasibility check of the record.

A record ``(u, y)`` of a linear system ``x_{k+1} = A x_k + B u_k + w_k``, ``y_k = C x_k + v_k``
is consistent when some ``x_0 in X0``, ``w_k in W`` and ``v_k in V`` reproduce ``y`` exactly.
With the sets as zonotopes ``c + G xi``, ``|xi|_inf <= 1``, that is a linear feasibility
problem in the states and the noise factors; :func:`record_inflation` solves its
optimisation form::

    min s  subject to  x_0 = c0 + G0 xi_0,  x_{k+1} = A x_k + B u_k + cW + GW xi_k,
                       y_k = C x_k + cV + GV eta_k,  |xi|, |eta| <= 1 + s,  s >= 0

(sparse, the states as variables; scipy's HiGHS), whose optimum ``s`` is the factor by which
the noise and initial sets must grow for the record to fit.  ``s`` well above zero means the
data contradict the model: a set estimate that misses the true state, or an empty one, is
then the data's fault, not an observer's.  The check is a screening of the data (from the
primal optimum, with a generous threshold :data:`INCONSISTENT`), not a bound that any result
relies on; the exact consistent set will replace it.
"""

from __future__ import annotations

import numpy as np
from scipy import sparse
from scipy.optimize import linprog

#: a record whose sets must grow by more than this fraction to fit is inconsistent
INCONSISTENT = 1e-3
#: records with more LP variables than this are not checked (``None``)
MAX_VARIABLES = 200_000
#: HiGHS dual simplex: on 30 tanks x 235 steps 2 s, where the default choice took 28 s
METHOD = "highs-ds"


def record_inflation(system, u: np.ndarray, y: np.ndarray) -> float | None:
    """The smallest growth ``s >= 0`` of the initial and noise sets for which the record
    fits the model (0 for a consistent record); None if not checked (a nonlinear system, a
    record too large, or the LP solver gave no answer)."""
    if not getattr(system, "is_linear", False):
        return None
    A, B, C = system.A, system.B, system.C
    n, ny = A.shape[0], C.shape[0]
    N = y.shape[0]
    G0, GW, GV = (np.asarray(S.G, float).reshape(dim, -1) for S, dim in
                  ((system.X0, n), (system.W, n), (system.V, ny)))
    m0, mw, mv = G0.shape[1], GW.shape[1], GV.shape[1]
    nx, nw, nv = N * n, (N - 1) * mw, N * mv
    nvar = nx + m0 + nw + nv + 1
    if nvar > MAX_VARIABLES:
        return None
    ix0, iw0, iv0, i_s = nx, nx + m0, nx + m0 + nw, nvar - 1

    parts: list = []

    def block(M, r0, c0):
        M = sparse.coo_matrix(M)
        parts.append((M.row + r0, M.col + c0, M.data))

    rhs = []
    r = 0
    block(np.eye(n), r, 0)  # x_0 - G0 xi_0 = c0
    block(-G0, r, ix0)
    rhs.append(np.asarray(system.X0.c, float).reshape(n))
    r += n
    uu = np.zeros((N, 0)) if u is None or np.size(u) == 0 else np.asarray(u, float)
    for k in range(N - 1):  # x_{k+1} - A x_k - GW xi_k = B u_k + cW
        block(np.eye(n), r, (k + 1) * n)
        block(-A, r, k * n)
        block(-GW, r, iw0 + k * mw)
        bu = B @ uu[k] if B.shape[1] and k < len(uu) else np.zeros(n)
        rhs.append(bu + np.asarray(system.W.c, float).reshape(n))
        r += n
    for k in range(N):  # C x_k + GV eta_k = y_k - cV
        block(C, r, k * n)
        block(GV, r, iv0 + k * mv)
        rhs.append(np.asarray(y[k], float).reshape(ny) - np.asarray(system.V.c, float))
        r += ny
    rows = np.concatenate([p[0] for p in parts])
    cols = np.concatenate([p[1] for p in parts])
    data = np.concatenate([p[2] for p in parts])
    A_eq = sparse.csr_matrix((data, (rows, cols)), shape=(r, nvar))
    b_eq = np.concatenate(rhs)
    # |factor| <= 1 + s:  factor - s <= 1  and  -factor - s <= 1
    nf = nvar - 1 - nx
    I = sparse.identity(nf, format="csr")
    col_s = sparse.csr_matrix(-np.ones((nf, 1)))
    zeros_x = sparse.csr_matrix((nf, nx))
    A_ub = sparse.vstack([sparse.hstack([zeros_x, I, col_s]),
                          sparse.hstack([zeros_x, -I, col_s])]).tocsr()
    b_ub = np.ones(2 * nf)
    cost = np.zeros(nvar)
    cost[i_s] = 1.0
    bounds = [(None, None)] * (nvar - 1) + [(0, None)]
    try:
        res = linprog(cost, A_ub=A_ub, b_ub=b_ub, A_eq=A_eq, b_eq=b_eq, bounds=bounds,
                      method=METHOD)
    except (ValueError, MemoryError):  # pragma: no cover - solver refused the problem
        return None
    return float(res.x[i_s]) if res.status == 0 else None


def inconsistency_message(s: float) -> str:
    """The note of every observer's row of an inconsistent record."""
    return (f"the record contradicts the model: no initial state in X0 and no noise in W and "
            f"V reproduce y (the sets would have to grow by a factor {1 + s:.3g}; LP check of "
            "the data, not a fault of this observer)")
