"""Numeric kernels of the ellipsoidal observers: the strip-based ESO-A and ESO-B (optimal
bounding ellipsoids) and the invariant-set observers ESO-C and ESO-D.

ESO-A and ESO-B
---------------

Notation (optimal bounding ellipsoids, Dasgupta & Huang 1987): the estimate is the ellipsoid
``{x : (x - q)' P^-1 (x - q) <= s2}``, i.e. centre ``q`` and shape matrix ``s2 P``; the level
``s2`` ("sigma^2") is carried besides ``P``.  The measurement set of ``y`` is
``{x : ||y - C x||^2 <= rho}`` after whitening (``C``, ``y`` premultiplied by a factor ``T``
of the inverse noise shape matrix, ``T'T = V^-1``, which gives ``rho = 1``), or a Euclidean
ball of radius ``gamma`` around ``y`` (``rho = gamma^2``, Gollamudi et al.).

The ``*_cora`` kernels reproduce CORA's ``@ellipsoid/intersectStrip.m`` (methods
``'Gollamudi1996'`` and ``'Liu2016'``) including its deviations from the papers; they exist
only to reproduce CORA's stored results.

ESO-C and ESO-D
---------------
Offline designs and online recursion of the ellipsoidal invariant-set observers ESO-C and
ESO-D (Loukkas, Martinez & Meslem 2017; Martinez, Loukkas & Meslem 2020).

Model: ``x+ = A x + B u + E xi_w + c_W``, ``y = C x + F xi_v + c_V`` with every component of
``wbar = [xi_w; xi_v]`` in ``[-1, 1]`` (``E``, ``F`` are the generator matrices of the
disturbance and noise zonotopes), hence ``||wbar||^2 <= p`` (``p`` columns of ``[E, F]``).
The Luenberger observer ``xh+ = A xh + B u + L (y - c_V - C xh) + c_W`` has the error
``e+ = Ao e + D wbar`` with ``Ao = A - L C``, ``D = [E, -L F]``.

If ``V(e) = e'Pe`` satisfies the H-infinity inequality
``V(e+) - V(e) + e'Qe - gamma^2 ||wbar||^2 <= 0``, i.e. the LMI::

    [ Ao'P Ao - P + Q    Ao'P D            ]
    [ D'P Ao             D'P D - gamma^2 I ]  <=  0,

and ``Q >= lam P`` (``0 < lam <= 1``), then ``V(e+) <= (1 - lam) V(e) + gamma^2 p`` and the
level ``l_k`` with ``l_0 >= V(e_0)``, ``l+ = (1 - lam) l + gamma^2 p`` bounds ``V(e_k)``: the
true state lies in the ellipsoid ``xh_k + {e : e'Pe <= l_k}`` (the paper's
``mu_k = l_k / cbar``, ``cbar = gamma^2 ||wbar||^2 / lam``).

Soundness does not depend on how ``Q`` was chosen: :func:`certify` recomputes, in numpy, the
largest admissible ``Q`` for the solver's ``P``, ``L``, ``gamma`` (a Schur complement), backs
off by a small margin, verifies the LMI by eigenvalues and derives ``lam`` from it.  The
gains are a uniquely defined point of the LMI: up to 30 states its central-path point at 1 %
above the least ``gamma^2`` (:func:`hinf_central`), above 30 states the H-infinity filter
Riccati equation (:func:`hinf_gain`, :func:`hinf_riccati`), certified the same way.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np
from scipy.linalg import eigh, solve_discrete_lyapunov
from scipy.stats import chi2

from ..errors import DesignFailed
from ..sets.ellipsoid import min_trace_weight, obe_weight, outer_sum, quadratic_update
from .lmi import (
    LinearDesignProblem,
    gain_from,
    require_nsd,
    require_pd,
    require_psd,
    solve,
    spectral_radius,
    sym,
    unit_noise,
)

#: CORA's cap of the Gollamudi weight (``alpha`` in ``@ellipsoid/intersectStrip.m``)
CORA_ALPHA = 1e-4
#: CORA's initial level ``sigma^2`` of ESO-A and ESO-B
CORA_SIGMA2_0 = 0.3


def liu_prediction(
    q: np.ndarray, P: np.ndarray, s2: float, A: np.ndarray, shift: np.ndarray, QW: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    r"""Prediction of Liu, Zhao & Wu (2016, eq. (21)): the minimal-trace outer ellipsoid of
    ``A E(q, s2 P) + shift + E(0, QW)``, returned as ``(q, P)`` at the unchanged level ``s2``:
    ``P = A P A' / (1 - p) + QW / (s2 p)``.

    Notes
    -----
    The estimate is :math:`\{x \mid (x - q)^\top P^{-1} (x - q) \le \sigma^2\}` (level
    :math:`\sigma^2` = ``s2``).  The prediction of Althoff & Rath (2021, Sec. 2.4, step 1),
    :math:`A \mathcal{S}_{k-1} \oplus B u_{k-1} \oplus \mathcal{W}`, is enclosed by the
    member of least trace of the family of outer ellipsoids of a Minkowski sum
    (``shift`` :math:`= B u_{k-1} + c_W`, :math:`\mathcal{W} = \mathcal{E}(c_W, Q_W)`):

    .. math::

        q^p = A q + B u_{k-1} + c_W, \qquad
        P^p = \frac{A P A^\top}{1 - p} + \frac{Q_W}{\sigma^2 p}, \qquad
        p = \frac{\sqrt{\operatorname{tr} Q_W}}
                 {\sqrt{\operatorname{tr}(\sigma^2 A P A^\top)} + \sqrt{\operatorname{tr} Q_W}} .
    """
    APA = A @ P @ A.T
    return A @ q + shift, outer_sum(s2 * APA, QW, "min-trace") / s2


def obe_update(
    q: np.ndarray, P: np.ndarray, s2: float, Ct: np.ndarray, yt: np.ndarray, rho: float,
    alpha: float = 1.0,
) -> tuple[np.ndarray, np.ndarray, float, float]:
    r"""Selective OBE measurement update (Gollamudi et al. 1996; Liu et al. 2016).

    The set is updated only if that can decrease the level, ``s2 + ||delta||^2 > rho``
    (``delta = yt - Ct q``); the weight is ``lam = min(alpha, nu)`` with ``nu`` from
    :func:`~observers.sets.ellipsoid.obe_weight` and ``g = lambda_max(Ct P Ct')``.
    Returns ``(q, P, s2, lam)``, ``lam = 0`` when nothing was updated.

    Notes
    -----
    The measurement set is :math:`\{x \mid \|\tilde y - \tilde C x\|^2 \le \rho\}`
    (ESO-A: :math:`\tilde C = C`, :math:`\tilde y = y_k - c_V`,
    :math:`\rho = \gamma^2 = \lambda_{\max}(Q_V)`; ESO-B: :math:`\tilde C = T C`,
    :math:`\tilde y = T (y_k - c_V)`, :math:`T^\top T = Q_V^{-1}`, :math:`\rho = 1`).  Every
    point of its intersection with the estimate satisfies, for :math:`0 < \lambda < 1`,
    the convex combination
    :math:`(1 - \lambda)(x - q)^\top P^{-1} (x - q) + \lambda \|\tilde y - \tilde C x\|^2
    \le (1 - \lambda)\sigma^2 + \lambda \rho`, an ellipsoid (the correction of eq. (6) of
    Althoff & Rath 2021 as an outer ellipsoid).  With the innovation
    :math:`\delta = \tilde y - \tilde C q`:

    .. math::

        K &= P \tilde C^\top \Bigl(\tilde C P \tilde C^\top
             + \tfrac{1 - \lambda}{\lambda} I\Bigr)^{-1}, \qquad
        q^+ = q + K \delta, \qquad
        P^+ = \frac{(I - K \tilde C) P}{1 - \lambda}, \\
        \sigma^{2+} &= (1 - \lambda) \sigma^2 + \lambda \rho
             - \delta^\top \Bigl(\frac{\tilde C P \tilde C^\top}{1 - \lambda}
             + \frac{I}{\lambda}\Bigr)^{-1} \delta .

    The update is made only if :math:`\sigma^2 + \|\delta\|^2 > \rho`, with the weight
    minimising the bound of :math:`\sigma^{2+}` (Gollamudi et al. 1996), capped at
    :math:`\alpha`:

    .. math::

        \lambda = \min(\alpha, \nu), \qquad
        \nu = \frac{1 - \sqrt{g / (1 + \beta (g - 1))}}{1 - g}, \qquad
        g = \lambda_{\max}(\tilde C P \tilde C^\top), \qquad
        \beta = \frac{\rho - \sigma^2}{\|\delta\|^2}

    (:math:`\nu = (1 - \beta)/2` for :math:`g = 1`).  The returned set is
    :math:`\mathcal{E}(q^+, \sigma^{2+} P^+)`.
    """
    delta = yt - Ct @ q
    e = float(delta @ delta)
    if s2 + e <= rho:
        return q, P, s2, 0.0
    g = float(np.linalg.eigvalsh(Ct @ P @ Ct.T)[-1])
    lam = min(alpha, obe_weight(g, (rho - s2) / e))
    if not 0.0 < lam < 1.0:
        return q, P, s2, lam  # the caller decides (no valid weight)
    q, P, s2 = quadratic_update(q, P, s2, Ct, rho, yt, lam)
    return q, P, s2, lam


def _within_tol(a, b, tol: float = 1e-8) -> bool:
    """CORA's ``withinTol``: absolute or relative tolerance, for all entries."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    d = np.abs(a - b)
    return bool(np.all((d <= tol) | (d <= tol * np.minimum(np.abs(a), np.abs(b)))))


def gollamudi_update_cora(
    q: np.ndarray, P: np.ndarray, s2_prev: float, C: np.ndarray, y: np.ndarray, phi: float,
    alpha: float = CORA_ALPHA,
) -> tuple[np.ndarray, np.ndarray, float]:
    """CORA's Gollamudi update of ESO-A (``@ellipsoid/intersectStrip.m``).

    Deviations from the paper reproduced here: the test and ``beta`` compare against ``phi``
    instead of ``phi^2``; the weight is capped at ``alpha`` (1e-4); the new level is computed
    from a prior level 1 (not ``s2_prev``); the centre moves by ``lam P C' delta`` with the
    *prior* ``P``; the stored shape is ``P+ / s2+`` instead of ``s2+ P+``.
    """
    delta = y - C @ q
    e = float(delta @ delta)
    if s2_prev + e <= phi:
        return q, P, s2_prev
    g = float(np.linalg.svd(C @ P @ C.T, compute_uv=False)[0])
    if _within_tol(delta, 0.0):
        nu = alpha
    else:
        beta = (phi - s2_prev) / e
        if _within_tol(g, 1.0):
            nu = 0.5 * (1.0 - beta)
        else:
            omega = 1.0 + beta * (g - 1.0)
            nu = (1.0 - np.sqrt(g / omega)) / (1.0 - g) if omega > 0 else alpha
    lam = min(alpha, nu)
    q_new = q + lam * (P @ (C.T @ delta))
    _, P_new, s2 = quadratic_update(q, P, 1.0, C, phi**2, y, lam)
    return q_new, P_new / s2, s2


def liu_update_cora(
    q: np.ndarray, P: np.ndarray, s2_prev: float, C: np.ndarray, y: np.ndarray, T: np.ndarray
) -> tuple[np.ndarray, np.ndarray, float]:
    """CORA's Liu update of ESO-B (``@ellipsoid/intersectStrip.m``), ``T`` the upper Cholesky
    factor of ``V^-1``.

    Deviations from the paper reproduced here: the test and ``beta`` use the raw innovation
    ``delta`` instead of the whitened one, and the new shape is ``(1-lam) (I - K C) P``
    instead of ``(I - K C) P / (1-lam)``.  No cap: the weight may leave ``(0, 1)`` (CORA then
    computes with complex numbers); the caller must check it.
    """
    delta = y - C @ q
    e = float(delta @ delta)
    if s2_prev + e <= 1.0:
        return q, P, s2_prev
    Ct = T @ C
    g = float(np.linalg.eigvalsh(Ct @ P @ Ct.T)[-1])
    beta = (1.0 - s2_prev) / e
    if _within_tol(g, 1.0):
        lam = 0.5 * (1.0 - beta)
    else:
        omega = 1.0 + beta * (g - 1.0)
        lam = (1.0 - np.sqrt(g / omega)) / (1.0 - g) if omega > 0 else np.nan
    if not 0.0 < lam < 1.0:
        return q, P, np.nan
    q_new, P_new, s2 = quadratic_update(q, P, s2_prev, Ct, 1.0, T @ y, lam)
    return q_new, (1.0 - lam) ** 2 * P_new, s2


__all__ = [
    "CORA_ALPHA",
    "CORA_SIGMA2_0",
    "gollamudi_update_cora",
    "liu_prediction",
    "liu_update_cora",
    "obe_update",
]


# -- ESO-C and ESO-D: invariant sets --------------------------------------------------------
#: relative safety margin applied to gamma^2 and Q before the final verification
MARGIN = 1e-9


def _hinf_matrix(P, Y, g, plant: LinearDesignProblem, Qn):
    """The matrix ``M(P, Y, g)`` of the H-infinity LMI ``M <= 0`` of :func:`hinf_lmi` for the
    matrices ``plant`` and the weight ``Qn``: a cvxpy expression for cvxpy variables ``P``,
    ``Y``, ``g``, a numpy array for numbers."""
    A, C, E, F = plant
    n, p = A.shape[0], E.shape[1] + F.shape[1]
    PAo = P @ A - Y @ C
    if isinstance(P, np.ndarray) and isinstance(Y, np.ndarray):
        hstack, block = np.hstack, np.block
    else:
        import cvxpy as cp

        hstack, block = cp.hstack, cp.bmat
    PD = hstack([P @ E, -Y @ F])
    return block([
        [-P + Qn, np.zeros((n, p)), PAo.T],
        [np.zeros((p, n)), -g * np.eye(p), PD.T],
        [PAo, PD, -P],
    ])


def hinf_lmi(
    plant: LinearDesignProblem, Q: np.ndarray, what: str
) -> tuple[np.ndarray, np.ndarray, float]:
    """Observer gain of the H-infinity LMI for the matrices ``plant``
    (:class:`~observers.numerics.lmi.LinearDesignProblem`) and a given weight ``Q`` (Loukkas
    et al. 2017, eq. (26); Martinez et al. 2020, Theorem 1), minimising ``gamma^2``.

    Variables ``P = P'``, ``Y = P L`` and ``g = gamma^2``::

        [ -P + Q    0      A'P - C'Y' ]
        [  0       -g I    D_P'       ]  <=  0,   D_P = [P E, -Y F]
        [ P A - Y C  D_P   -P         ]

    ``Q`` is scaled to unit norm for the solver (the LMI is homogeneous in ``(P, Y, g, Q)``).
    Returns ``(P, L, gamma^2)``; raises :class:`DesignFailed` if Clarabel finds no solution.
    """
    import cvxpy as cp

    C = plant.C
    n, m = C.shape[1], C.shape[0]
    scale = float(np.linalg.eigvalsh(sym(Q))[-1])
    if not scale > 0:
        raise DesignFailed(f"{what}: the weight Q must be positive definite")
    Qn = sym(Q) / scale
    P = cp.Variable((n, n), symmetric=True)
    Y = cp.Variable((n, m))
    g = cp.Variable()
    M = _hinf_matrix(P, Y, g, plant, Qn)
    solve(cp.Problem(cp.Minimize(g), [0.5 * (M + M.T) << 0]), what)
    if P.value is None or Y.value is None or g.value is None:
        raise DesignFailed(f"{what}: the solver returned no point")
    Pv = sym(P.value)
    require_pd(Pv, f"{what} (P > 0)")
    L = gain_from(Pv, Y.value, what)
    return Pv * scale, L, float(g.value) * scale


#: :func:`hinf_gain` solves the H-infinity LMI by :func:`hinf_riccati` above this many states
#: (the published rows, up to 30 states, take :func:`hinf_central`)
HINF_RICCATI_ABOVE = 30
#: relative slack of ``gamma^2`` over its least value at which :func:`hinf_riccati` returns
#: its point
HINF_SLACK = 1e-2


#: relative excess of ``gamma^2`` over its least value allowed to the point of
#: :func:`hinf_central` (the duality-gap bound of its point of the central path)
HINF_CENTRAL_GAP = 1e-2


def _negated_hinf(plant: LinearDesignProblem, Qn):
    """``-M(P, Y, g)`` of :func:`hinf_lmi` (:func:`_hinf_matrix`) as a linear matrix function
    of ``x = [1, upper triangle of P, Y (row-major), g]``: the array of its ``N`` matrices."""
    A, C, E, F = plant
    n, m, p = C.shape[1], C.shape[0], E.shape[1] + F.shape[1]
    iu = np.triu_indices(n)
    N = 1 + iu[0].size + n * m + 1
    k = 2 * n + p
    blocks = np.zeros((N, k, k))

    def neg_m(P, Y, g, q):
        return -sym(_hinf_matrix(P, Y, g, plant, q * Qn))

    zP, zY = np.zeros((n, n)), np.zeros((n, m))
    blocks[0] = neg_m(zP, zY, 0.0, 1.0)
    for t, (i, j) in enumerate(zip(*iu, strict=True)):
        Eij = np.zeros((n, n))
        Eij[i, j] = Eij[j, i] = 1.0
        blocks[1 + t] = neg_m(Eij, zY, 0.0, 0.0)
    base = 1 + iu[0].size
    for t in range(n * m):
        Ek = np.zeros(n * m)
        Ek[t] = 1.0
        blocks[base + t] = neg_m(zP, Ek.reshape(n, m), 0.0, 0.0)
    blocks[-1] = neg_m(zP, zY, 1.0, 0.0)
    return blocks, iu


def hinf_central(plant: LinearDesignProblem, Q, what: str, gap: float = HINF_CENTRAL_GAP
                 ) -> tuple[np.ndarray, np.ndarray, float]:
    """A unique point of the LMI of :func:`hinf_lmi` (for ``plant`` and ``Q``): its point on
    the central path of ``min gamma^2`` at the duality-gap bound ``gap * gamma*^2``.

    The least ``gamma^2`` pins only ``gamma``: the optimal ``(P, Y)`` form a face on which an
    SDP solver stops anywhere (ESO-C's radii on the 6-D vehicle moved by 11 % between OpenBLAS
    kernels).  The point returned here maximises ``log det(-M(P, Y, g)) - t g`` (``t = k /
    (gap g*)``, ``k`` the order of ``M``, ``g*`` the least ``gamma^2`` as Clarabel reports it),
    a strictly concave function (the log-determinant barrier of a set bounded when ``E`` has
    full row rank: ``D' P D <= g I`` bounds ``P``, then ``Y``) whose maximiser is unique and
    has ``g - g* <= k / t = gap g*`` (Boyd & Vandenberghe, Convex Optimization, Sec. 11.6).
    It is found in numpy by damped Newton (:func:`~observers.numerics.lmi.analytic_centre`)
    from a strictly feasible point (Clarabel's ``max s: M + s I <= 0``); a relative error
    ``d`` of ``g*`` moves it by about ``d`` only (``t`` scales with it), not ``d / gap``.
    Returns ``(P, L, gamma^2)`` as :func:`hinf_lmi`.
    """
    import cvxpy as cp

    from .lmi import analytic_centre

    C, E = plant.C, plant.E
    n, m = C.shape[1], C.shape[0]
    scale = float(np.linalg.eigvalsh(sym(Q))[-1])
    if not scale > 0:
        raise DesignFailed(f"{what}: the weight Q must be positive definite")
    if np.linalg.matrix_rank(E) < n:
        return hinf_lmi(plant, Q, what)  # the barrier has no maximiser: no unique point
    Qn = sym(Q) / scale
    g_star = hinf_lmi(plant, Qn, what)[2]
    blocks, iu = _negated_hinf(plant, Qn)
    # a strictly feasible start (the barrier needs one): the most interior point with g at
    # most twice its least value
    P, Y, g, s_ = (cp.Variable((n, n), symmetric=True), cp.Variable((n, m)), cp.Variable(),
                   cp.Variable())
    M = _hinf_matrix(P, Y, g, plant, Qn)
    solve(cp.Problem(cp.Maximize(s_), [0.5 * (M + M.T) << -s_ * np.eye(blocks.shape[1]),
                                       g <= 2.0 * g_star, s_ <= 1.0]),
          f"{what} (strictly feasible start)")
    if s_.value is None or not s_.value > 0:
        raise DesignFailed(f"{what}: the H-infinity LMI has no strictly feasible point")
    x0 = np.concatenate([[1.0], P.value[iu], Y.value.ravel(), [float(g.value)]])
    a_eq = np.zeros(x0.size)
    a_eq[0] = 1.0
    linear = np.zeros(x0.size)
    linear[-1] = blocks.shape[1] / (gap * g_star)
    # stop at a squared Newton decrement of 1e-10 (the objective is ~1e3 here, so 1e-13 is
    # below its rounding): the last full Newton step then leaves an error of order 1e-10 in
    # the local norm (quadratic convergence)
    x = analytic_centre([blocks], x0, a_eq, what, tol=1e-10, linear=linear)
    Pc = np.zeros((n, n))
    Pc[iu] = x[1:1 + iu[0].size]
    Pc = sym(Pc + np.triu(Pc, 1).T)
    Yc = x[1 + iu[0].size:-1].reshape(n, m)
    require_pd(Pc, f"{what} (P > 0)")
    return Pc * scale, gain_from(Pc, Yc, what), float(x[-1]) * scale


#: CORA's grid of ``gamma`` (``linspace(1, 50, 100)``): its designs take the first feasible one
CORA_GAMMA_GRID = np.linspace(1.0, 50.0, 100)
#: least relative excess of the grid's gamma^2 over the least gamma^2 in :func:`hinf_cora`
CORA_GRID_MARGIN = 1e-3
#: relative excess of the condition bound of :func:`hinf_cora` (``"cora"``) over its least value
CORA_KAPPA_SLACK = 0.1
#: the most states :func:`hinf_cora` designs for; above, every strategy takes the
#: least-gamma point (:func:`hinf_gain`).  Its bisection on the condition number costs one SDP
#: per step, measured (ESO-D, one core): 31 s at 12 tanks, 172 s at 18, 581 s at 24, more than
#: 20 min at 30, while the points it reaches there do not reproduce ARCH 2021 Table 5 either
#: (ESO-D 77.0 at 18 tanks, 92.5 at 24, published 42.9, 60.4)
CORA_MAX_STATES = 12
#: design strategies of ESO-C and ESO-D: ``"cora"`` CORA's procedure (gamma grid) at the
#: analytic centre of the feasible set with ``cond(P)`` bounded; ``"cora-centre"`` the same
#: at the analytic centre of the whole feasible set; ``"least-gamma"`` the central-path point
#: 1 % above the least gamma^2 (:func:`hinf_gain`, units-free)
DESIGNS = ("cora", "cora-centre", "least-gamma")


def _fold_gamma(plant: LinearDesignProblem, Qn, gn: float):
    """Blocks of ``-M(P, Y, g)`` (:func:`_negated_hinf`) at a fixed ``g = gn``, as a linear
    matrix function of ``x = [1, upper triangle of P, Y]``, and the blocks of ``P``."""
    blocks, iu = _negated_hinf(plant, Qn)
    B = blocks[:-1].copy()
    B[0] = B[0] + gn * blocks[-1]
    n = plant.A.shape[0]
    PB = np.zeros((B.shape[0], n, n))
    for t, (i, j) in enumerate(zip(*iu, strict=True)):
        PB[1 + t, i, j] = PB[1 + t, j, i] = 1.0
    return B, PB, iu


def hinf_cora(plant: LinearDesignProblem, Q, what: str, point: str = "cora"
              ) -> tuple[np.ndarray, np.ndarray, float]:
    """CORA's solve of the H-infinity LMI of :func:`hinf_lmi` made a unique point.

    ``gamma``: the first of :data:`CORA_GAMMA_GRID` (absolute units, as CORA's) at least
    :data:`CORA_GRID_MARGIN` above the least ``gamma^2`` (Clarabel).  There, ``point=
    "cora-centre"``: the analytic centre of ``{P >= 0, M(P, Y) <= 0}``; ``point="cora"``: that
    of the set cut by ``s I <= P <= k s I``, ``k = (1 +`` :data:`CORA_KAPPA_SLACK` ``) k*``,
    ``k*`` the least condition number of a strictly feasible ``P`` (bisection on Clarabel's
    most interior point; strictness measured on the LMI with its noise rows scaled by
    ``1 / gamma``, a congruence). A feasibility solve stops near its well-conditioned start:
    on the 6-tank this point reproduces ARCH 2021 Table 3's ESO-D within 3 %, the plain centre
    misses it threefold.  Damped Newton in numpy (:func:`~observers.numerics.lmi.
    analytic_centre`).  Returns ``(P, L, gamma^2)``; :class:`DesignFailed` where no grid
    ``gamma`` is feasible (as CORA fails) or no condition bound is found.
    """
    import cvxpy as cp

    from .lmi import analytic_centre

    A, C, E, F = plant
    n, m = C.shape[1], C.shape[0]
    if np.linalg.matrix_rank(E) < n:
        raise DesignFailed(f"{what}: CORA's design point needs a full-dimensional W")
    scale = float(np.linalg.eigvalsh(sym(Q))[-1])
    if not scale > 0:
        raise DesignFailed(f"{what}: the weight Q must be positive definite")
    Qn = sym(Q) / scale
    g_star = hinf_lmi(plant, Qn, what)[2]
    i = int(np.searchsorted(CORA_GAMMA_GRID ** 2, g_star * scale * (1.0 + CORA_GRID_MARGIN)))
    if i >= CORA_GAMMA_GRID.size:
        raise DesignFailed(f"{what}: no gamma of CORA's grid 1..50 is feasible (least gamma "
                           f"{np.sqrt(g_star * scale):.4g})")
    g = float(CORA_GAMMA_GRID[i]) ** 2
    gn = g / scale
    B, PB, iu = _fold_gamma(plant, Qn, gn)
    k = B.shape[1]
    P, Y, s, t = (cp.Variable((n, n), symmetric=True), cp.Variable((n, m)), cp.Variable(),
                  cp.Variable())
    M = _hinf_matrix(P, Y, gn, plant, Qn)
    # the margin of the bisection below is measured on the LMI with its noise rows scaled by
    # 1 / sqrt(g) (a congruence: the same set, the same analytic centre), whose blocks are then
    # of one scale: unscaled, a small g (ESO-C's weight) caps the margin far below the
    # solver's tolerance
    T = np.diag(np.concatenate([np.ones(n), np.full(k - 2 * n, 1.0 / np.sqrt(gn)), np.ones(n)]))
    lmi = T @ (0.5 * (M + M.T)) @ T
    found: list = []

    def feasible(kap: float) -> bool:
        # strictly, by a margin relative to the scale of P: Clarabel calls a problem with a
        # sliver of a feasible set (or none, within its tolerance) solved
        cons = [lmi << -t * np.eye(k), P >> (s + t) * np.eye(n),
                P << kap * s * np.eye(n) - t * np.eye(n), t <= 1.0]
        try:
            solve(cp.Problem(cp.Maximize(t), cons), what)
        except DesignFailed:
            return False
        ok = t.value is not None and t.value > min(0.5, 1e-6 * max(1.0, float(s.value)))
        if ok:  # a start for the centre below, strictly inside for every larger bound
            found[:] = [P.value, Y.value, float(s.value)]
        return ok

    if point == "cora":
        lo, hi = 1.0, 2.0
        while not feasible(hi):
            lo, hi = hi, hi * hi
            if hi > 1e16:
                raise DesignFailed(f"{what}: no condition bound of P found")
        while hi > lo * (1.0 + 1e-5):
            mid = np.sqrt(lo * hi)
            lo, hi = (lo, mid) if feasible(mid) else (mid, hi)
        feasible(hi)
        Pv, Yv, sv = found
        kap = hi * (1.0 + CORA_KAPPA_SLACK)
        x0 = np.concatenate([[1.0], Pv[iu], Yv.ravel(), [sv]])
        B = np.concatenate([B, np.zeros((1, k, k))])
        lower = np.concatenate([PB, -np.eye(n)[None]])
        upper = np.concatenate([-PB, kap * np.eye(n)[None]])
        blocks = [B, lower, upper]
    elif point == "cora-centre":
        solve(cp.Problem(cp.Maximize(t), [lmi << -t * np.eye(k), P >> t * np.eye(n),
                                          t <= 1.0]), f"{what} (strictly feasible start)")
        if t.value is None or not t.value > 0:
            raise DesignFailed(f"{what}: the H-infinity LMI has no strictly feasible point")
        x0 = np.concatenate([[1.0], P.value[iu], Y.value.ravel()])
        blocks = [B, PB]
    else:
        raise ValueError(f"unknown CORA design point {point!r}")
    a_eq = np.zeros(x0.size)
    a_eq[0] = 1.0
    x = analytic_centre(blocks, x0, a_eq, what, tol=1e-12)
    Pc = np.zeros((n, n))
    Pc[iu] = x[1:1 + iu[0].size]
    Pc = sym(Pc + np.triu(Pc, 1).T)
    Yc = x[1 + iu[0].size:1 + iu[0].size + n * m].reshape(n, m)
    require_pd(Pc, f"{what} (P > 0)")
    return Pc * scale, gain_from(Pc, Yc, what), g


def design_gain(plant: LinearDesignProblem, Q, what: str, design: str = "cora"
                ) -> tuple[np.ndarray, np.ndarray, float]:
    """The H-infinity gain of the design strategy ``design`` (:data:`DESIGNS`):
    :func:`hinf_cora` for ``"cora"`` and ``"cora-centre"``, :func:`hinf_gain` for
    ``"least-gamma"`` (and, for every strategy, above :data:`CORA_MAX_STATES` states, with a
    degenerate ``W``, or where CORA's procedure has no point: no feasible gamma on its
    absolute grid, no condition bound: the Riccati route or the central-path point).
    Returns ``(P, L, gamma^2)``."""
    if design not in DESIGNS:
        raise ValueError(f"unknown ESO design {design!r} (known: {', '.join(DESIGNS)})")
    if (design == "least-gamma" or plant.A.shape[0] > CORA_MAX_STATES
            or hinf_route(plant) == "riccati"
            or np.linalg.matrix_rank(plant.E) < plant.A.shape[0]):
        return hinf_gain(plant, Q, what)  # (no bounded feasible set without a full W)
    try:
        return hinf_cora(plant, Q, what, design)
    except DesignFailed:
        # CORA's absolute grid has no feasible gamma, or no condition bound is found (a
        # feasible set too thin for the solver, e.g. the textbook DC motor): the units-free
        # least-gamma point, as before the strategy existed, rather than no gain
        return hinf_gain(plant, Q, what)


def hinf_route(plant: LinearDesignProblem) -> str:
    """The route :func:`hinf_gain` takes for ``plant``: ``"riccati"`` above
    :data:`HINF_RICCATI_ABOVE` states with a full-dimensional noise set (``F`` of full row
    rank), else ``"central"``.  Read at call time, so that cache keys (which must name the
    route) and the solve agree."""
    F = np.atleast_2d(np.asarray(plant.F, dtype=float))
    full = F.size > 0 and np.linalg.matrix_rank(F) == F.shape[0]
    return "riccati" if plant.A.shape[0] > HINF_RICCATI_ABOVE and full else "central"


def hinf_gain(plant: LinearDesignProblem, Q, what: str) -> tuple[np.ndarray, np.ndarray, float]:
    """:func:`hinf_central` up to :data:`HINF_RICCATI_ABOVE` states (or without a
    full-dimensional noise set), :func:`hinf_riccati` above (for ``plant`` and ``Q``), both
    given the noise at unit scale (:func:`~observers.numerics.lmi.unit_noise`: the same gain,
    ``gamma^2`` scaled back), so that the point does not depend on the units of the data."""
    route = hinf_route(plant)
    F = np.atleast_2d(np.asarray(plant.F, dtype=float))
    plant, s2 = unit_noise(LinearDesignProblem(plant.A, plant.C, plant.E, F))
    if route == "riccati":
        P, L, g = hinf_riccati(plant, Q, what)
    else:
        P, L, g = hinf_central(plant, Q, what)
    return P, L, g * s2


def hinf_riccati(
    plant: LinearDesignProblem, Q: np.ndarray, what: str, rtol: float = 1e-3,
    slack: float = HINF_SLACK,
) -> tuple[np.ndarray, np.ndarray, float]:
    """The least ``gamma^2`` of :func:`hinf_lmi` (for ``plant`` and ``Q``) and a point
    ``(P, L)`` of its LMI from the H-infinity filter Riccati equation, without an SDP.

    With ``D = [E, -L F]`` and ``P > 0`` the LMI is the bounded-real inequality
    ``[Ao, D]' P [Ao, D] <= diag(P - Q, g I)``; it forces ``P > Q``, and with ``X = P^-1``,
    ``Z = (X^-1 - Q)^-1`` it reads ``X >= (Abar - L Cbar) diag(Z, I/g) (Abar - L Cbar)'``
    (``Abar = [A, E, 0]``, ``Cbar = [C, 0, F]``).  The right side is least at
    ``L = A Z C' (C Z C' + F F'/g)^-1``, where it equals
    ``T(X) = A (X^-1 - Q + C' (F F'/g)^-1 C)^-1 A' + E E'/g``; ``T`` is monotone, so the LMI is
    feasible for ``g`` exactly when ``X = T(X)`` has a solution with ``X^-1 > Q``, the
    H-infinity filter Riccati equation (in the standard form with ``[C; I]`` and the
    indefinite weight ``diag(F F'/g, -Q^-1)``; Nagpal & Khargonekar, IEEE TAC 36(2), 1991).
    ``g`` is bisected (relative ``rtol``) on the existence of its stabilising solution
    (``scipy.linalg.solve_discrete_are``) with ``X > 0`` and ``X^-1 > Q``; at the least
    ``gamma`` the solution is at the edge of admissibility (``P`` huge along some directions),
    so the returned point is that of ``g = (1 + slack) gamma*^2`` (:data:`HINF_SLACK`).  The
    least ``gamma^2`` agrees with Clarabel's (6-state vehicle: 3.32808 against 3.32827; 12
    tanks: 0.105281 both).  The caller verifies the LMI in numpy (:func:`certify`).
    """
    from scipy.linalg import block_diag, solve_discrete_are

    A, C, E, F = plant
    n = C.shape[1]
    scale = float(np.linalg.eigvalsh(sym(Q))[-1])
    if not scale > 0:
        raise DesignFailed(f"{what}: the weight Q must be positive definite")
    Qn = sym(Q) / scale
    R0 = sym(F @ F.T)
    EE = sym(E @ E.T)
    Ct = np.vstack([C, np.eye(n)])
    Qi = sym(np.linalg.inv(Qn))

    def point(g: float):
        try:
            X = solve_discrete_are(A.T, Ct.T, EE / g, block_diag(R0 / g, -Qi))
        except (np.linalg.LinAlgError, ValueError):
            return None
        X = sym(X)
        if not np.all(np.isfinite(X)) or np.linalg.eigvalsh(X)[0] <= 0:
            return None
        Zi = sym(np.linalg.inv(X)) - Qn
        if np.linalg.eigvalsh(Zi)[0] <= 0:
            return None
        return X, Zi

    lo, hi = None, 1.0
    for _ in range(100):  # a bracket [lo, hi] by factors of 4
        if point(hi) is not None:
            break
        lo, hi = hi, 4.0 * hi
    else:
        raise DesignFailed(f"{what}: the H-infinity Riccati equation has no admissible "
                           "solution for any gamma")
    if lo is None:
        lo = hi
        while lo > 1e-300 and point(lo / 4.0) is not None:
            lo /= 4.0
        lo, hi = lo / 4.0, lo
    while hi > lo * (1.0 + rtol):
        mid = np.sqrt(lo * hi)
        if point(mid) is not None:
            hi = mid
        else:
            lo = mid
    # admissibility near the least gamma is decided by a generalised eigenvalue problem at
    # the edge of its conditioning: the slack is raised tenfold (twice) where it fails
    for factor in (1.0, 10.0, 100.0):
        g = hi * (1.0 + factor * slack)
        found = point(g)
        if found is not None:
            break
    if found is None:
        raise DesignFailed(f"{what}: the H-infinity Riccati equation has no admissible "
                           f"solution at gamma^2 = {g * scale:.6g}")
    X, Zi = found
    Z = sym(np.linalg.inv(Zi))
    L = A @ Z @ C.T @ np.linalg.inv(C @ Z @ C.T + R0 / g)
    P = sym(np.linalg.inv(X))
    return P * scale, L, g * scale


def error_system(plant: LinearDesignProblem, L) -> tuple[np.ndarray, np.ndarray]:
    r"""``Ao = A - L C`` and ``D = [E, -L F]`` of the estimation error (``A, C, E, F`` from
    ``plant``).

    Notes
    -----
    With :math:`w = c_W + E \bar w_1`, :math:`v = c_V + F \bar w_2`,
    :math:`\bar w = [\bar w_1; \bar w_2] \in [-1, 1]^p`, the error
    :math:`e_k = x_k - \hat x_k` of the Luenberger observer (Althoff & Rath 2021, eq. (7))
    evolves as

    .. math::

        e_{k+1} = A_o e_k + D \bar w_k, \qquad A_o = A - L C, \qquad
        D = \begin{bmatrix} E & -L F \end{bmatrix} .
    """
    A, C, E, F = plant
    return A - L @ C, np.hstack([E, -L @ F])


def schur_bound(Ao, D, P, gamma2) -> tuple[np.ndarray, float]:
    """Largest ``Q`` for which the LMI holds with the given ``P``, ``L``, ``gamma^2``.

    ``S = P - Ao'P Ao - Ao'P D H^-1 D'P Ao`` with ``H = gamma^2 I - D'P D``; ``gamma^2`` is
    raised if needed so that ``H`` is positive definite.  This is also the closed-form
    maximiser of ``log det Q`` subject to the LMI (Loukkas et al., Alg. 1, step 3): the LMI is
    equivalent to ``Q <= S``, and ``det`` is monotone on the PSD order.
    Returns ``(S, gamma^2)``.
    """
    DPD = sym(D.T @ P @ D)
    d_max = float(np.linalg.eigvalsh(DPD)[-1]) if DPD.size else 0.0
    gamma2 = max(gamma2, d_max * (1.0 + 1e-6), 1e-12 * float(np.abs(P).max()))
    H = gamma2 * np.eye(D.shape[1]) - DPD
    PAo = P @ Ao
    DPAo = D.T @ PAo
    S = P - Ao.T @ PAo - DPAo.T @ np.linalg.solve(H, DPAo)
    return sym(S), gamma2


def certify(Ao, D, P, gamma2, Q, what: str) -> tuple[np.ndarray, float, float]:
    """Sound ``(Q, lam, gamma^2)`` for the gain and ``P`` of a design (see module docstring).

    ``gamma^2`` and ``Q`` are backed off by ``MARGIN`` (relative to ``max(|P|, gamma^2)``) so
    that the LMI holds strictly, ``Q`` is lowered further if it exceeds the Schur bound, and
    the LMI is verified with numpy eigenvalues.  ``lam`` is the smallest generalised
    eigenvalue of ``(Q, P)``, reduced by a relative 1e-6 and capped at 1.
    """
    tau = MARGIN * max(float(np.linalg.eigvalsh(P)[-1]), gamma2)
    gamma2 = gamma2 + tau
    S, gamma2 = schur_bound(Ao, D, P, gamma2)
    excess = max(0.0, float(np.linalg.eigvalsh(sym(Q) - S)[-1]))
    Q = sym(Q) - (excess + tau) * np.eye(Q.shape[0])
    PAo, PD = P @ Ao, P @ D
    M = np.block([
        [Ao.T @ PAo - P + Q, Ao.T @ PD],
        [PD.T @ Ao, D.T @ PD - gamma2 * np.eye(D.shape[1])],
    ])
    require_nsd(M, f"{what} (H-infinity LMI)", tol=0.0)
    require_pd(Q, f"{what} (Q > 0)")
    lam = float(eigh(Q, P, eigvals_only=True)[0]) * (1.0 - 1e-6)
    if not lam > 0:
        raise DesignFailed(f"{what}: no positive decay rate (lambda = {lam:.3g})")
    lam = min(lam, 1.0)
    require_psd(Q - lam * P, f"{what} (Q >= lambda P)", tol=0.0)
    return Q, lam, gamma2


def _lyapunov_weight(Ao: np.ndarray, Sigma: np.ndarray, what: str) -> np.ndarray:
    """``Q = V^-1`` with ``Ao V Ao' - V + Sigma = 0`` (the error covariance for a disturbance
    covariance ``Sigma``); ``V`` is regularised relative 1e-9 if it is singular."""
    if spectral_radius(Ao) >= 1.0:
        raise DesignFailed(f"{what}: the first gain does not make A - L C Schur stable")
    V = sym(solve_discrete_lyapunov(Ao, sym(Sigma)))
    w = np.linalg.eigvalsh(V)
    if not w[-1] > 0:
        raise DesignFailed(f"{what}: the disturbance set W is a single point, so the error "
                           "covariance that weights the second gain is zero")
    V = V + max(0.0, 1e-9 * w[-1] - w[0]) * np.eye(V.shape[0])
    return sym(np.linalg.inv(V))


def first_gain(plant: LinearDesignProblem, what: str = "ESO-C/ESO-D", design: str = "cora"
               ) -> np.ndarray:
    """Step 1 of both designs below: the gain of the H-infinity LMI with the weight ``Q = I``
    (:func:`design_gain` of the strategy ``design``).  It depends on ``plant`` (``A, C, E,
    F``) and ``design`` only, so ESO-C and ESO-D on one system share it (their plugins cache
    it once)."""
    return design_gain(plant, np.eye(plant.A.shape[0]), f"{what} (gain with Q = I)", design)[1]


def loukkas_design(plant: LinearDesignProblem, QW, quantile: float, what: str = "ESO-C",
                   L1: np.ndarray | None = None, design: str = "cora") -> dict:
    r"""Algorithm 1 of Loukkas, Martinez & Meslem (2017) for the matrices ``plant``
    (:class:`~observers.numerics.lmi.LinearDesignProblem`).

    1. gain of the H-infinity LMI with ``Q = I`` (:func:`first_gain`; ``L1`` if given);
    2. ``Q = V^-1`` with ``V`` the error covariance of that gain for the disturbance
       covariance ``QW / chi2inv(quantile, n)`` (``QW`` the shape of an ellipsoid containing
       ``W``, read as the ``quantile`` confidence ellipsoid of a Gaussian);
    3. new gain of the LMI with this ``Q``; then ``Q`` maximising ``log det Q`` subject to the
       LMI for that gain (closed form, :func:`schur_bound`);
    4. ``lam`` from :func:`certify`.

    Notes
    -----
    The gains solve the H-infinity LMI (Loukkas et al. 2017, eq. (26)) in
    :math:`P = P^\top \succ 0`, :math:`Y = P L` and :math:`g = \gamma^2`, for a weight
    :math:`Q \succ 0`, minimising :math:`g`:

    .. math::

        \begin{bmatrix} -P + Q & 0 & A^\top P - C^\top Y^\top \\
        0 & -g I & D_P^\top \\
        P A - Y C & D_P & -P \end{bmatrix} \preceq 0, \qquad
        D_P = \begin{bmatrix} P E & -Y F \end{bmatrix}, \qquad L = P^{-1} Y .

    By a Schur complement it is
    :math:`V(e^+) - V(e) + e^\top Q e - \gamma^2 \|\bar w\|^2 \le 0` for
    :math:`V(e) = e^\top P e`.  Step 2 weights it with the inverse error covariance,
    :math:`Q = \Sigma_e^{-1}`, :math:`A_o \Sigma_e A_o^\top - \Sigma_e + Q_W / \chi^2_n(q) = 0`
    (:math:`q` = ``quantile``); step 3 replaces :math:`Q` by the largest weight the LMI
    admits for the new gain (the maximiser of :math:`\log\det Q`),

    .. math::

        Q = P - A_o^\top P A_o - A_o^\top P D \,(\gamma^2 I - D^\top P D)^{-1} D^\top P A_o,

    and :math:`\lambda` is the least generalised eigenvalue of :math:`(Q, P)`, so that
    :math:`Q \succeq \lambda P` (capped at 1).
    """
    n = plant.A.shape[0]
    L = first_gain(plant, what, design) if L1 is None else L1
    Ao, _ = error_system(plant, L)
    Q = _lyapunov_weight(Ao, QW / chi2.ppf(quantile, n), what)
    P, L, gamma2 = design_gain(plant, Q, f"{what} (gain with the covariance weight)", design)
    Ao, D = error_system(plant, L)
    S, gamma2 = schur_bound(Ao, D, P, gamma2)
    Q, lam, gamma2 = certify(Ao, D, P, gamma2, S, what)
    return {"L": L, "P": P, "Q": Q, "gamma2": np.array(gamma2), "lam": np.array(lam)}


def martinez_design(plant: LinearDesignProblem, variance: float = 1.0 / 3.0, what: str = "ESO-D",
                    L1: np.ndarray | None = None, design: str = "cora") -> dict:
    r"""Algorithm 1 of Martinez, Loukkas & Meslem (2020) for the matrices ``plant``
    (:class:`~observers.numerics.lmi.LinearDesignProblem`).

    1. gain of the H-infinity LMI with ``Q = I`` (:func:`first_gain`; ``L1`` if given);
    2. ``Q = V^-1`` with ``Ao V Ao' - V + D W D' = 0``, ``W = variance I`` (eqs. (63)-(64):
       1/3 is the variance of a uniform distribution on [-1, 1]);
    3. new gain of the LMI with this ``Q``; ``lam`` from :func:`certify`.

    Notes
    -----
    Both gains solve the H-infinity LMI of Martinez et al. (2020, Theorem 1; the LMI of
    :func:`loukkas_design`), in :math:`P \succ 0`, :math:`Y = P L`, :math:`g = \gamma^2`:

    .. math::

        \begin{bmatrix} -P + Q & 0 & A^\top P - C^\top Y^\top \\
        0 & -g I & D_P^\top \\
        P A - Y C & D_P & -P \end{bmatrix} \preceq 0, \qquad
        D_P = \begin{bmatrix} P E & -Y F \end{bmatrix},

    first with :math:`Q = I`, then with the weight of eqs. (63)-(64),

    .. math::

        Q = \Sigma_e^{-1}, \qquad
        A_o \Sigma_e A_o^\top - \Sigma_e + \tfrac{1}{3} D D^\top = 0,

    and :math:`\lambda` is the least generalised eigenvalue of :math:`(Q, P)` after the
    certification (:func:`certify`).
    """
    L = first_gain(plant, what, design) if L1 is None else L1
    Ao, D = error_system(plant, L)
    Q = _lyapunov_weight(Ao, variance * (D @ D.T), what)
    P, L, gamma2 = design_gain(plant, Q, f"{what} (gain with the covariance weight)", design)
    Ao, D = error_system(plant, L)
    Q, lam, gamma2 = certify(Ao, D, P, gamma2, Q, what)
    return {"L": L, "P": P, "Q": Q, "gamma2": np.array(gamma2), "lam": np.array(lam)}


class InvariantRecursion(NamedTuple):
    """The constant data of the online recursion of ESO-C and ESO-D (:func:`invariant_step`).

    Attributes
    ----------
    Ao : ndarray
        ``A - L C``.
    B : ndarray
        The input matrix.
    L : ndarray
        The observer gain.
    offset : ndarray
        ``c_W - L c_V``.
    lam : float
        The decay rate of the level.
    drive : float
        ``gamma^2 ||wbar||^2``, the growth of the level per step.
    """

    Ao: Any
    B: Any
    L: Any
    offset: Any
    lam: float
    drive: float


def invariant_step(
    x: np.ndarray, level: float, rec: InvariantRecursion, u: np.ndarray, y: np.ndarray,
) -> tuple[np.ndarray, float]:
    r"""One step of the observer and of its error level (Loukkas et al., eqs. (46)-(51)):
    ``xh+ = Ao xh + B u + L y + offset`` (``offset = c_W - L c_V``) and
    ``l+ = (1 - lam) l + drive`` (``drive = gamma^2 ||wbar||^2``), with the data of ``rec``.

    Notes
    -----
    The Luenberger observer of Althoff & Rath (2021, eq. (7)) and the level of its error
    bound:

    .. math::

        \hat x_{k+1} = (A - L C) \hat x_k + B u_k + L y_k + c_W - L c_V, \qquad
        \ell_{k+1} = (1 - \lambda) \ell_k + \gamma^2 p ,

    with :math:`p` the number of columns of :math:`[E, F]`
    (:math:`\|\bar w\|^2 \le p`).  From the LMI and :math:`Q \succeq \lambda P`,
    :math:`V(e_{k+1}) \le (1 - \lambda) V(e_k) + \gamma^2 p`, so
    :math:`\ell_0 \ge \max_{x \in \mathcal{X}_0} (x - \hat x_0)^\top P (x - \hat x_0)`
    keeps :math:`e_k^\top P e_k \le \ell_k` and the estimate is the ellipsoid

    .. math::

        \mathcal{S}_k = \{x \mid (x - \hat x_k)^\top P (x - \hat x_k) \le \ell_k\}
        = \mathcal{E}(\hat x_k,\ \ell_k P^{-1}) .
    """
    return rec.Ao @ x + rec.B @ u + rec.L @ y + rec.offset, (1.0 - rec.lam) * level + rec.drive


# -- ESMF: the extended set-membership filter ------------------------------------------------
def box_shape(rad: np.ndarray) -> np.ndarray:
    """Shape matrix of an ellipsoid centred at 0 containing the box ``[-rad, rad]``:
    ``diag(k rad^2)`` over the ``k`` non-zero radii (``sum x_i^2 / (k rad_i^2) <= 1`` at every
    point of the box), zero where ``rad`` is zero."""
    rad = np.asarray(rad, dtype=float)
    k = int(np.count_nonzero(rad))
    return np.diag(k * rad * rad * (1.0 + 4 * np.finfo(float).eps)) if k else np.zeros(
        (rad.size, rad.size))


def ellipsoid_box(q: np.ndarray, Q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    r"""Interval hull ``q +- sqrt(diag(Q))`` of the ellipsoid ``E(q, Q)``, widened by a
    relative 1e-12 (the square roots and the rounding of ``Q``).

    Notes
    -----
    .. math::

        \operatorname{BOX}(\mathcal{E}(q, Q)) = \bigl[q_i - \sqrt{Q_{ii}},\
        q_i + \sqrt{Q_{ii}}\bigr]_{i = 1}^{n} .
    """
    r = np.sqrt(np.maximum(np.diag(Q), 0.0)) * (1.0 + 1e-12)
    r = np.nextafter(r + 1e-300, np.inf)
    return np.nextafter(q - r, -np.inf), np.nextafter(q + r, np.inf)


def absorb(Q: np.ndarray, rad: np.ndarray) -> np.ndarray:
    """Shape of an ellipsoid containing ``E(0, Q) + [-rad, rad]``: the minimal-trace outer sum
    with :func:`box_shape` (its weight kept inside ``[1e-9, 1 - 1e-9]``, where it can round to
    0 or 1 when one of the two is negligible; every weight in ``(0, 1)`` gives an outer
    ellipsoid); ``Q`` itself when ``rad`` is zero."""
    R = box_shape(rad)
    if not np.any(R):
        return Q.copy()
    p = min(max(min_trace_weight(Q, R), 1e-9), 1.0 - 1e-9)
    return outer_sum(Q, R, p)


def esmf_prediction(estimate: tuple, enclosure: tuple, QW, cW):
    r"""Prediction of the extended set-membership filter (Scholte & Campbell 2003) of the
    ``estimate`` ``(q, P, s2)``: the dynamics enclosed as ``f(x) in J x + d + [-rad, rad]``
    (``enclosure = (J, d, rad)``) over the box of the estimate, the remainder box absorbed
    into the disturbance ellipsoid ``E(cW, QW)`` (:func:`absorb`), then the ellipsoidal
    prediction of the linear family (:func:`liu_prediction`).  Returns ``(q, P)``.

    Notes
    -----
    Over the box of the estimate :math:`\mathcal{E}(q, \sigma^2 P)`,
    :math:`f(x, u_{k-1}) \in J x + d \pm \rho` (first-order Taylor expansion with the
    Lagrange remainder; :math:`J = A`, :math:`d = B u_{k-1}`, :math:`\rho = 0` on a linear
    system).  The remainder box goes into the disturbance shape, then Liu's prediction:

    .. math::

        Q_W' = \frac{Q_W}{1 - p} + \frac{R}{p}, \quad
        R = \operatorname{diag}(\kappa \rho_i^2), \qquad
        q^p = J q + d + c_W, \qquad
        P^p = \frac{J P J^\top}{1 - p'} + \frac{Q_W'}{\sigma^2 p'},

    with :math:`\kappa` the number of non-zero :math:`\rho_i` (the ellipsoid
    :math:`\mathcal{E}(0, R)` contains the box) and :math:`p, p'` the weights of least trace.
    """
    q, P, s2 = estimate
    J, d, rad = enclosure
    return liu_prediction(q, P, s2, J, d + cW, absorb(QW, rad))


def esmf_update(estimate: tuple, H, y_eff, rad, QV, weight: str = "obe"):
    r"""Update of the extended set-membership filter of the ``estimate`` ``(q, P, s2)``: the
    output enclosed as ``h(x) in H x + d + [-rad, rad]`` (``y_eff = y - d - c_V``), the
    remainder absorbed into the noise ellipsoid, the outputs whitened with the widened noise
    shape, then the ellipsoid of :func:`~observers.sets.ellipsoid.quadratic_update` with the
    weight of ``weight``: ``"obe"`` the selective optimal-bounding-ellipsoid update of ESO-B
    (:func:`obe_update`), ``"min-trace"`` the weight minimising the trace of the updated
    shape ``s2+ P+`` (bounded scalar search; the set is kept if no weight shrinks it).
    Returns ``(q, P, s2, lam)`` as :func:`obe_update` (``lam = 0``: not updated).

    Notes
    -----
    With :math:`h(x) \in H x + d \pm \rho_h` over the box of the prediction
    (:math:`H = C`, :math:`d = 0`, :math:`\rho_h = 0` for a linear output), the noise shape
    is widened and the outputs whitened,

    .. math::

        Q_V' = \frac{Q_V}{1 - p} + \frac{R_h}{p}, \qquad
        \tilde C = T H, \qquad \tilde y = T (y_k - d - c_V), \qquad
        T^\top T = Q_V'^{-1},

    and the update is the convex combination of :func:`obe_update` with :math:`\rho = 1`
    (same :math:`K`, :math:`q^+`, :math:`P^+`, :math:`\sigma^{2+}`), with the weight

    .. math::

        \lambda = \operatorname*{arg\,min}_{0 < \lambda < 1}
        \sigma^{2+}(\lambda) \operatorname{tr} P^+(\lambda)

    for ``"min-trace"`` (kept only if it is below :math:`\sigma^2 \operatorname{tr} P`), or
    the capped weight :math:`\nu` of :func:`obe_update` for ``"obe"``.
    """
    q, P, s2 = estimate
    Qv = absorb(QV, rad)
    T = np.linalg.inv(np.linalg.cholesky(Qv))
    Ct, yt = T @ H, T @ y_eff
    if weight == "obe":
        return obe_update(q, P, s2, Ct, yt, 1.0)
    from scipy.optimize import minimize_scalar

    def size(w: float) -> float:
        _, Pw, s2w = quadratic_update(q, P, s2, Ct, 1.0, yt, w)
        return max(s2w, 0.0) * float(np.trace(Pw))

    lam = float(minimize_scalar(size, bounds=(1e-9, 1 - 1e-9), method="bounded",
                                options={"xatol": 1e-10}).x)
    if size(lam) >= s2 * float(np.trace(P)):
        return q, P, s2, 0.0
    q, P, s2 = quadratic_update(q, P, s2, Ct, 1.0, yt, lam)
    return q, P, s2, lam
