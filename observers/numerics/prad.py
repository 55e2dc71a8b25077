"""Offline P-radius gain designs (SDPs solved with cvxpy + Clarabel, verified in numpy).

All designs share one matrix inequality.  For the strip-based update with a constant gain
``Lam`` (intersection method II; method I is the same per output), the generators of the
estimate evolve as ``H_k = [(I - Lam C) A H_{k-1}, (I - Lam C) E, Lam F]`` (``E``, ``F``: the
generator matrices of ``W`` and ``V``).  With ``Y = P Lam`` and ``M = [(P - Y C) A,
(P - Y C) E, Y F]`` the inequality

    D(P, Y) = [[diag(Wx, Ww, Wv), M'], [M, P]]  >=  0                                    (*)

says (Schur complement) that ``||H_k xi||_P^2 <= xi_x' Wx xi_x + xi_w' Ww xi_w +
xi_v' Wv xi_v`` for every stacked ``xi``.  With ``Wx = beta P`` and diagonal ``Ww``, ``Wv``
this bounds the P-radius ``R_k = max_{z in Z_k} ||z - c_k||_P^2`` by
``R_k <= beta R_{k-1} + tr(Ww) + tr(Wv)``, hence ``limsup R_k <= (tr Ww + tr Wv)/(1 - beta)``.
The designs differ in the weights, the normalisation and the objective; see the functions.
Every returned gain is checked in numpy: ``P > 0`` and (*) evaluated at ``Y = P Lam`` for the
returned ``Lam`` (smallest eigenvalue >= -1e-6 relative, :data:`VERIFY_TOL`), else
:class:`DesignFailed`.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, NamedTuple

import numpy as np

from ..errors import DesignFailed
from .lmi import (
    DecayCone,
    GainDesign,
    LinearDesignProblem,
    bmat,
    cone_point,
    cora_bisection_end,
    gain_from,
    min_eig,
    psd_constraint,
    require_independent_outputs,
    require_pd,
    require_psd,
    solve,
    solved,
    sym,
)

#: relative tolerance of the numpy check of (*): the optimum of every design lies on the
#: boundary of the LMI, where the solver's feasibility tolerance (1e-8 on its scaled problem)
#: shows up as eigenvalues of order -1e-7 relative to the largest entry of D
VERIFY_TOL = 1e-6
EPS = float(np.finfo(float).eps)


class DecayWeights(NamedTuple):
    """The weights of the P-radius inequality (*): ``D(P, Y) = [[diag(Wx, Ww, Wv), M'],
    [M, P]]``.

    Attributes
    ----------
    Wx : ndarray or cvxpy expression
        The weight of the previous generators (``beta P`` for a decay rate ``beta``).
    Ww : ndarray or cvxpy expression
        The weight of the disturbance generators.
    Wv : ndarray or cvxpy expression
        The weight of the noise generators.
    """

    Wx: Any
    Ww: Any
    Wv: Any


def decay_blocks(P, Y, plant: LinearDesignProblem, weights: DecayWeights) -> list[list]:
    """Blocks of ``D(P, Y)`` in (*) (``None``: zero), for :func:`~observers.numerics.lmi.bmat`,
    for the matrices ``plant`` and the ``weights``."""
    A, C, E, F = plant
    Wx, Ww, Wv = weights
    M1 = (P - Y @ C) @ A
    M2 = (P - Y @ C) @ E
    M3 = Y @ F
    return [
        [Wx, None, None, M1.T],
        [None, Ww, None, M2.T],
        [None, None, Wv, M3.T],
        [M1, M2, M3, P],
    ]


def decay_lmi(P, Y, plant: LinearDesignProblem, weights: DecayWeights):
    """cvxpy constraint ``D(P, Y) >= 0`` (symmetrised, as cvxpy requires)."""
    return psd_constraint(bmat(decay_blocks(P, Y, plant, weights)))


def verify_decay(
    P: np.ndarray, L: np.ndarray, plant: LinearDesignProblem, weights: DecayWeights, what: str
) -> float:
    """Check ``P > 0`` (not numerically singular: smallest eigenvalue above ``1e-9`` times the
    largest) and ``D(P, P L) >= 0`` (for ``plant`` and ``weights``) in numpy; returns the
    smallest eigenvalue of D."""
    top = float(np.linalg.eigvalsh(sym(P))[-1])
    require_pd(P, f"{what}: P > 0", margin=1e-9 * max(top, 0.0))
    if not np.all(np.isfinite(L)):
        raise DesignFailed(f"{what}: the gain is not finite")
    D = bmat(decay_blocks(P, P @ L, plant, weights))
    return require_psd(D, f"{what}: P-radius inequality", tol=VERIFY_TOL)


def line_search(
    evaluate: Callable[[float], tuple[float, Any] | None],
    s_range: tuple[float, float] = (0.1, 4.0),
    grid: int = 12,
    tol: float = 0.02,
    monotone: bool = False,
) -> tuple[float, float, Any] | None:
    """Minimise a design bound over the decay rate ``beta = 1 - 10^-s``.

    ``evaluate(beta)`` returns ``(bound, solution)`` or ``None`` (infeasible: +inf).  A grid of
    ``grid`` values of ``s`` in ``s_range`` (beta from ~0.2 to 0.9999, dense near 1 where slow
    modes put the feasible rates) brackets the minimum, then a golden-section search refines
    ``s`` to ``tol``.  Returns ``(beta, bound, solution)`` of the best evaluated point, or
    ``None`` if no grid point is feasible.  ``monotone=True`` declares that feasibility at
    ``beta`` implies feasibility at every larger ``beta``: the grid is then walked downwards
    and stops at the first infeasible value (infeasible solves are the expensive ones).
    """
    cache: dict[float, tuple[float, Any]] = {}

    def f(s: float) -> float:
        if s not in cache:
            out = evaluate(1.0 - 10.0 ** (-s))
            cache[s] = (np.inf, None) if out is None else out
        return cache[s][0]

    ss = np.linspace(*s_range, grid)
    vals = [np.inf] * grid
    for k in (reversed(range(grid)) if monotone else range(grid)):
        vals[k] = f(ss[k])
        if monotone and not np.isfinite(vals[k]):
            break
    i = int(np.argmin(vals))
    if not np.isfinite(vals[i]):
        return None
    a, b = ss[max(i - 1, 0)], ss[min(i + 1, grid - 1)]
    g = (np.sqrt(5.0) - 1.0) / 2.0
    x1, x2 = b - g * (b - a), a + g * (b - a)
    while b - a > tol:
        if f(x1) <= f(x2):
            b, x2 = x2, x1
            x1 = b - g * (b - a)
        else:
            a, x1 = x1, x2
            x2 = a + g * (b - a)
    s_best = min(cache, key=lambda s: cache[s][0])
    bound, sol = cache[s_best]
    return 1.0 - 10.0 ** (-s_best), bound, sol


def _as_arrays(plant: LinearDesignProblem) -> LinearDesignProblem:
    return LinearDesignProblem(*(np.atleast_2d(np.asarray(M, dtype=float)) for M in plant))


def _variables(n: int, m: int):
    import cvxpy as cp

    return cp.Variable((n, n), symmetric=True), cp.Variable((n, m))


# -- PRad-B (and PRad-A per output): Le et al., ISIC 2013 ----------------------------------------
#: PRad-A's per-output designs take the Riccati route above this many states when its
#: ``method`` is ``"auto"`` (at 6 states a single tank output admits no ``P > 0`` exactly,
#: so the published rows keep the SDP's point, found within the solver's tolerance); PRad-B
#: takes it at every size (``riccati_above=0``: the SDP's optimum is not unique)
RICCATI_ABOVE = 12


def le_method(n: int, F, method: str = "auto", riccati_above: int = RICCATI_ABOVE) -> str:
    """The route of :func:`le_gain` for ``method`` on a system of ``n`` states with noise
    generators ``F``: ``"auto"`` is ``"riccati"`` above ``riccati_above`` states when the
    noise set is full-dimensional (``F`` of full row rank), else ``"sdp"``."""
    if method != "auto":
        return method
    F = np.atleast_2d(np.asarray(F, dtype=float))
    full = F.size > 0 and np.linalg.matrix_rank(F) == F.shape[0]
    return "riccati" if n > riccati_above and full else "sdp"


def le_gain(plant: LinearDesignProblem, epsilon: float, beta_tol: float = 0.01,
            what: str = "PRad-B", solver: str | None = None, method: str = "sdp") -> GainDesign:
    r"""P-radius gain of Le, Stoica, Alamo, Camacho, Dumur (ISIC 2013), as implemented by CORA,
    for the matrices ``plant`` (:class:`~observers.numerics.lmi.LinearDesignProblem`).

    The shared P-radius inequality (*) of this module, with the gain recovered from
    :math:`Y = P\Lambda`:

    .. math::

        \mathcal{D}(P, Y) = \begin{bmatrix} \operatorname{diag}(W_x, W_w, W_v) & M^T \\
        M & P \end{bmatrix} \succeq 0, \qquad
        M = \begin{bmatrix} (P - YC)A & (P - YC)E & YF \end{bmatrix}, \qquad
        \Lambda = P^{-1}Y,

    which makes the P-radius :math:`R_k = \max_{z \in \mathcal{S}_k}\|z - c_k\|_P^2` of the
    estimates of intersection method II satisfy
    :math:`R_k \le \beta R_{k-1} + \operatorname{tr}W_w + \operatorname{tr}W_v` when
    :math:`W_x = \beta P`.  This design (PRad-B of Table 2 of Althoff & Rath 2021; PRad-A
    per output) solves

    .. math::

        \max_{P,\,Y,\,\tau}\ \tau \quad \text{s.t.} \quad
        \mathcal{D}(P, Y) \succeq 0 \text{ with } W_x = \beta P,\ W_w = E^TE,\
        W_v = F^TF, \quad \frac{1 - \beta}{\epsilon}P \succeq \tau I, \quad \tau \ge 0.

    Weights ``Wx = beta P``, ``Ww = E'E``, ``Wv = F'F`` (fixed, which pins the scale of P);
    maximise ``tau`` subject to (*), ``P >= 0``, ``(1 - beta) P / epsilon >= tau I`` and
    ``tau >= 0``, i.e. the smallest eigenvalue of ``(1 - beta) P / epsilon``.  ``beta`` is
    where CORA's bisection on [0, 1] with tolerance ``beta_tol`` ends
    (:func:`cora_bisection_end`: 0.9921875).  ``epsilon`` only scales ``tau``; it is kept for
    fidelity (CORA: ``norm(W) + phi'phi``).  A solution with singular P (``tau = 0``, no
    P-radius contraction possible) fails the verification.

    ``method="sdp"`` solves the SDP with cvxpy (``solver``: a strategy of
    :data:`~observers.numerics.lmi.SOLVERS`); ``method="riccati"`` returns the optimal point
    of :func:`le_riccati` (one Riccati equation: milliseconds where the SDP takes minutes),
    ``"auto"`` chooses by :func:`le_method`.  Both are optimal; where the optimum is not
    unique (it pins only the smallest eigenvalue of P) the SDP returns wherever the solver
    stops on the optimal face (Clarabel: near the limit of its central path, a point that
    moves with the solver's tolerance and with the BLAS kernel: 2.4e-2 relative in the
    6-tank radii across three OpenBLAS kernels), while the Riccati route returns the largest
    optimal ``P`` in the Loewner order, a unique point (every feasible ``X = P^-1`` lies above
    the stabilising Riccati solution, :func:`le_riccati`).  Where the optimum is unique (the
    2-D vehicle) the two agree (CORA's SDPT3 gain to 3e-7).
    """
    plant = _as_arrays(plant)
    A, C, E, F = plant
    n, m = C.shape[1], C.shape[0]
    beta = cora_bisection_end(0.0, 1.0, beta_tol)
    method = le_method(n, F, method)
    Ww, Wv = E.T @ E, F.T @ F
    if method == "riccati":
        point = le_riccati(plant, beta, what)
        verify_riccati(point, plant, beta, what)
        Pv = point.P
        tau = float(np.linalg.eigvalsh((1 - beta) * Pv)[0] / epsilon)
        return GainDesign(point.Lam, Pv, {"rate": beta, "tau": tau, "method": method})
    if method == "sdp":
        import cvxpy as cp

        P, Y = _variables(n, m)
        tau = cp.Variable()
        cons = [P >> 0, decay_lmi(P, Y, plant, DecayWeights(beta * P, Ww, Wv)),
                (1 - beta) * P / epsilon >> tau * np.eye(n), tau >= 0]
        solve(cp.Problem(cp.Maximize(tau), cons), f"{what} (beta={beta})", solver)
        Pv, Yv = sym(P.value), Y.value
    else:
        raise DesignFailed(f"{what}: unknown method {method!r} (use 'auto', 'sdp' or 'riccati')")
    L = gain_from(Pv, Yv, what)
    verify_decay(Pv, L, plant, DecayWeights(beta * Pv, Ww, Wv), what)
    tau = float(np.linalg.eigvalsh((1 - beta) * Pv)[0] / epsilon)
    return GainDesign(L, Pv, {"rate": beta, "tau": tau, "method": method})


class RiccatiPoint(NamedTuple):
    """The largest ``P`` of (*) (:func:`le_riccati`) as its inverse ``X = P^-1`` and its gain
    ``Lam`` (a Kalman filter update: defined and computed without inverting ``X``)."""

    X: np.ndarray
    Lam: np.ndarray
    #: the orthogonal projectors on the ranges of ``E`` and ``F`` (the weights of (*) in the
    #: form ``X >= ...``)
    QE: np.ndarray
    QF: np.ndarray

    @property
    def P(self) -> np.ndarray:
        """``P = X^-1``."""
        return sym(np.linalg.inv(self.X))

    @property
    def Y(self) -> np.ndarray:
        """``Y = P Lam``."""
        return self.P @ self.Lam


#: ``X = P^-1`` counts as positive definite when its smallest eigenvalue exceeds this many
#: times ``n eps`` its largest: the error bound of the computed eigenvalues of a symmetric
#: matrix (backward stable: within about ``n eps ||X||_2`` of the exact ones, Weyl), so the
#: sign of the smallest one is resolved
RESOLVED = 10.0


def le_riccati(plant: LinearDesignProblem, beta: float, what: str = "PRad-B") -> RiccatiPoint:
    """The largest ``P`` (Loewner order) satisfying (*) for ``plant`` with ``Wx = beta P``,
    ``Ww = E'E``, ``Wv = F'F``, and its gain, from one discrete Riccati equation.

    With ``Y = P Lam`` the off-diagonal block of (*) is ``P N``, ``N = [(I - Lam C) A,
    (I - Lam C) E, Lam F]``, and the Schur complement of the weights (after replacing ``E``
    and ``F`` by full-column-rank factors with the same ``E E'``, ``F F'``, an orthogonal
    congruence) turns (*) into, with ``X = P^-1``,

        X >= (I - Lam C) Xp (I - Lam C)' + Lam Q_F Lam',   Xp = A X A' / beta + Q_E,

    ``Q_E``, ``Q_F`` the orthogonal projectors on the ranges of ``E`` and ``F``.  The right
    side is smallest at ``Lam = Xp C' (C Xp C' + Q_F)^-1`` (a Kalman filter update) and is
    monotone in ``X``, so every feasible ``X`` lies above the stabilising solution ``X*`` of
    the filter Riccati equation of ``(A / sqrt(beta), C)`` with weights ``Q_E``, ``Q_F``
    (the iteration of the minimised right side from a feasible ``X`` decreases to ``X*``).
    Hence ``P* = X*^-1`` is the largest feasible ``P``: it maximises ``tau`` (the smallest
    eigenvalue of P) of :func:`le_gain`, as in the PRad-E case of
    :func:`~observers.numerics.luenberger.prad_e_design`.  The gain is returned as ``Lam``
    itself, not as ``P^-1 Y``: where a mode decays barely faster than ``sqrt(beta)`` (PRad-A's
    first output of the 6-tank: closed loop 0.99991 against 1) ``X*`` is huge along it
    (condition number 3e13), ``tau`` of order 1e-16, below any SDP solver's tolerance (the
    SDP then stops wherever it does), while ``Lam`` is a well-conditioned function of the
    moderate part of ``Xp`` (the same to 1e-10 under every OpenBLAS kernel).  Needs a
    full-dimensional noise set (``Q_F = I``); if the Riccati equation has no stabilising
    solution (a mode the outputs cannot correct decays more slowly than ``sqrt(beta)``), or
    ``X*`` is not positive definite to its rounding (:data:`RESOLVED`), there is no ``P > 0``:
    the design fails (:class:`~observers.errors.DesignFailed`), which is the table's
    ``noGain``.
    """
    from scipy.linalg import solve_discrete_are

    from .lmi import range_basis

    A, C, E, F = _as_arrays(plant)
    n, m = A.shape[0], C.shape[0]
    QE, QF = range_basis(E), range_basis(F)
    if QF.shape[1] < m:
        raise DesignFailed(f"{what}: the Riccati route needs a noise set V of full dimension "
                           f"{m} (its generators span {QF.shape[1]}); use the SDP")
    try:
        Xp = solve_discrete_are(A.T / np.sqrt(beta), C.T, QE @ QE.T, np.eye(m))
    except (np.linalg.LinAlgError, ValueError) as exc:
        raise DesignFailed(f"{what}: no P > 0 satisfies the P-radius inequality at rate "
                           f"{beta} (the Riccati equation has no stabilising solution: "
                           f"{exc})") from None
    Xp = sym(Xp)
    Lam = Xp @ C.T @ np.linalg.inv(C @ Xp @ C.T + np.eye(m))
    X = sym(Xp - Lam @ C @ Xp)
    lam = np.linalg.eigvalsh(X)
    if not np.all(np.isfinite(lam)) or lam[0] <= RESOLVED * n * EPS * max(lam[-1], 0.0):
        raise DesignFailed(f"{what}: no P > 0 satisfies the P-radius inequality at rate "
                           f"{beta} (the least solution X = P^-1 is singular)")
    return RiccatiPoint(X, Lam, QE @ QE.T, QF @ QF.T)


def verify_riccati(point: RiccatiPoint, plant: LinearDesignProblem, beta: float,
                   what: str) -> float:
    """Check (*) at a Riccati point in its form ``X >= (I - Lam C) Xp (I - Lam C)' +
    Lam Q_F Lam'`` (:func:`le_riccati`; it holds with equality there), to :data:`VERIFY_TOL`
    of ``|X|``: the form that needs no inverse of an ill-conditioned ``X``.  Returns the
    smallest eigenvalue of the difference."""
    A, C, _, _ = _as_arrays(plant)
    X, Lam = point.X, point.Lam
    if not np.all(np.isfinite(Lam)):
        raise DesignFailed(f"{what}: the gain is not finite")
    K = np.eye(A.shape[0]) - Lam @ C
    Xp = A @ X @ A.T / beta + point.QE
    lam = min_eig(X - K @ Xp @ K.T - Lam @ point.QF @ Lam.T)
    if not np.isfinite(lam) or lam < -VERIFY_TOL * max(1.0, float(np.abs(X).max())):
        raise DesignFailed(f"{what}: P-radius inequality (X form): verification failed "
                           f"(smallest eigenvalue {lam:.3g})")
    return lam


# -- PRad-C-I, PRad-C-II (Wang et al. 2018), PRad-D (Wang et al. 2019) -----------------------------
def _line_searched(evaluate, what: str, search: dict | None, monotone: bool = False):
    """Line search with rough solves (``evaluate(beta, rough)``), then an accurate solve at the
    chosen rate; returns ``(beta, solution)``."""
    found = line_search(lambda b: evaluate(b, True), monotone=monotone, **(search or {}))
    if found is None:
        raise DesignFailed(f"{what}: the P-radius LMI has no solution with P > 0 for any decay "
                           "rate in the search range (is a mode that cannot be corrected too "
                           "slow or unstable?)")
    beta, _, rough_solution = found
    final = evaluate(beta, False)
    return beta, rough_solution if final is None else final[1]


def _at_rate(evaluate, rate: float, what: str):
    """The accurate solve at the decay rate ``rate`` (``evaluate(rate, rough)``), or the rough
    one if it fails, as at the end of :func:`_line_searched`; returns ``(rate, solution)``."""
    out = evaluate(rate, False) or evaluate(rate, True)
    if out is None:
        raise DesignFailed(f"{what}: the P-radius LMI has no solution with P > 0 at the decay "
                           f"rate {rate}")
    return rate, out[1]


class _WeightedLMI:
    """(*) with ``Wx = beta P`` and free diagonal weights (CORA's PRad-C inequality): the
    variables, the parameter ``beta`` and the constraint, shared by PRad-C-I and PRad-C-II."""

    def __init__(self, plant: LinearDesignProblem):
        import cvxpy as cp

        self.data = _as_arrays(plant)
        A, C, E, F = self.data
        n, m, nw, nv = C.shape[1], C.shape[0], E.shape[1], F.shape[1]
        self.P, self.Y = _variables(n, m)
        self.gw, self.gv = cp.Variable(nw, nonneg=True), cp.Variable(nv, nonneg=True)
        self.beta = cp.Parameter(nonneg=True)
        self.lmi = decay_lmi(self.P, self.Y, self.data,
                             DecayWeights(self.beta * self.P, cp.diag(self.gw), cp.diag(self.gv)))

    def design(self, objective, constraints: list, what: str, search: dict | None,
               rate: float | None = None):
        """Line search on ``beta`` minimising ``objective/(1 - beta)`` (or ``beta = rate``),
        then verification."""
        import cvxpy as cp

        prob = cp.Problem(objective, [self.lmi, *constraints])

        def evaluate(b: float, rough: bool):
            self.beta.value = b
            if not solved(prob, rough):
                return None
            return prob.value / (1 - b), tuple(v.value for v in (self.P, self.Y, self.gw, self.gv))

        b, (Pv, Yv, gw, gv) = (_line_searched(evaluate, what, search, monotone=True)
                               if rate is None else _at_rate(evaluate, rate, what))
        gw, gv = np.maximum(gw, 0), np.maximum(gv, 0)
        Pv = sym(Pv)
        L = gain_from(Pv, Yv, what)
        verify_decay(Pv, L, self.data, DecayWeights(b * Pv, np.diag(gw), np.diag(gv)), what)
        bound = (gw.sum() + gv.sum()) / ((1 - b) * np.linalg.eigvalsh(Pv)[0])
        return GainDesign(L, Pv, {"rate": b, "radius_bound": float(np.sqrt(bound))})


def wang_c1_gain(plant: LinearDesignProblem, what: str = "PRad-C-I", search: dict | None = None,
                 rate: float | None = None) -> GainDesign:
    r"""PRad-C-I: least asymptotic radius bound with per-generator weights (Wang et al. 2018),
    for the matrices ``plant`` (:class:`~observers.numerics.lmi.LinearDesignProblem`).

    With the inequality :math:`\mathcal{D}(P, Y) \succeq 0` of :func:`le_gain` and
    :math:`\Lambda = P^{-1}Y`:

    .. math::

        \min_{P,\,Y,\,W_w,\,W_v}\ \operatorname{tr}W_w + \operatorname{tr}W_v
        \quad \text{s.t.} \quad \mathcal{D}(P, Y) \succeq 0 \text{ with } W_x = \beta P,
        \quad W_w, W_v \text{ diagonal} \succeq 0, \quad P \succeq I,

    so that :math:`\limsup_k R_k \le (\operatorname{tr}W_w + \operatorname{tr}W_v)/(1 - \beta)`.

    Weights ``Wx = beta P`` and free diagonal ``Ww = diag(gw) >= 0``, ``Wv = diag(gv) >= 0``
    (CORA's ``G``, ``O``); normalisation ``P >= I``.  For fixed ``beta`` minimise
    ``tr(Ww) + tr(Wv)``, so that ``limsup R_k <= (tr Ww + tr Wv)/(1 - beta)`` and, since
    ``P >= I``, the same number bounds the squared Euclidean radius of the estimates; ``beta``
    minimises that bound (:func:`line_search`), or is ``rate`` if given.
    """
    import cvxpy as cp

    lmi = _WeightedLMI(plant)
    n = lmi.P.shape[0]
    return lmi.design(cp.Minimize(cp.sum(lmi.gw) + cp.sum(lmi.gv)), [lmi.P >> np.eye(n)],
                      what, search, rate)


def wang_c2_gain(plant: LinearDesignProblem, what: str = "PRad-C-II",
                 search: dict | None = None) -> GainDesign:
    r"""PRad-C-II: smallest bounding ellipsoid in the trace sense (Wang, Alamo et al. 2018),
    for the matrices ``plant`` (:class:`~observers.numerics.lmi.LinearDesignProblem`).

    With the inequality :math:`\mathcal{D}(P, Y) \succeq 0` of :func:`le_gain` and
    :math:`\Lambda = P^{-1}Y`:

    .. math::

        \min_{P,\,Y,\,X,\,W_w,\,W_v}\ \operatorname{tr}X \quad \text{s.t.} \quad
        \mathcal{D}(P, Y) \succeq 0 \text{ with } W_x = \beta P, \quad
        \begin{bmatrix} X & I \\ I & P \end{bmatrix} \succeq 0, \quad
        \operatorname{tr}W_w + \operatorname{tr}W_v \le 1,

    i.e. :math:`\min \operatorname{tr}(P^{-1})`, then :math:`\beta` minimising
    :math:`\operatorname{tr}(P^{-1})/(1 - \beta)`.

    The LMI of :func:`wang_c1_gain` (CORA's PRad-C inequality) with the normalisation
    ``tr(Ww) + tr(Wv) <= 1``, so that the estimates end up in the ellipsoid
    ``{z : z' P z <= 1/(1 - beta)}``; minimise the sum of its squared semi-axes,
    ``tr(P^-1)/(1 - beta)`` (as ``tr X`` with ``[[X, I], [I, P]] >= 0``), over ``P, Y`` and
    the weights for fixed ``beta``, and over ``beta`` by :func:`line_search`.  Since the
    interval radius of state i over that ellipsoid is ``sqrt((P^-1)_ii / (1 - beta))``, the
    objective is the sum over the states of the squared bounds of their interval radii.
    """
    import cvxpy as cp

    lmi = _WeightedLMI(plant)
    n = lmi.P.shape[0]
    X = cp.Variable((n, n), symmetric=True)
    inv = cp.bmat([[X, np.eye(n)], [np.eye(n), lmi.P]])
    return lmi.design(cp.Minimize(cp.trace(X)),
                      [(inv + inv.T) / 2 >> 0, cp.sum(lmi.gw) + cp.sum(lmi.gv) <= 1],
                      what, search)


def wang_d_gain(
    plant: LinearDesignProblem, alpha: float | None = None, beta: float = 0.5,
    what: str = "PRad-D", search: dict | None = None,
) -> GainDesign:
    r"""PRad-D: largest P for fixed noise weights (Wang, Wang, Puig, Cembrano, TAC 2019), for
    the matrices ``plant`` (:class:`~observers.numerics.lmi.LinearDesignProblem`).

    With the inequality :math:`\mathcal{D}(P, Y) \succeq 0` of :func:`le_gain` and
    :math:`\Lambda = P^{-1}Y`:

    .. math::

        \max_{P,\,Y,\,t}\ t \quad \text{s.t.} \quad \mathcal{D}(P, Y) \succeq 0
        \text{ with } W_x = \alpha P,\ W_w = (1 - \alpha)\beta I,\
        W_v = (1 - \alpha)(1 - \beta) I, \quad P \succeq tI,

    which bounds the squared radius by :math:`(\beta n_w + (1 - \beta)n_v)/t`.

    Weights ``Wx = alpha P``, ``Ww = (1 - alpha) beta I``, ``Wv = (1 - alpha)(1 - beta) I``
    (CORA's ``E_new``/``F_new`` blocks reduce to these), so that ``limsup R_k <= r_inf =
    beta n_w + (1 - beta) n_v`` whatever P; the squared Euclidean radius is then bounded by
    ``r_inf / gamma^2`` if ``P >= gamma^2 I``.  For fixed ``alpha`` maximise ``t = gamma^2``
    subject to (*) and ``P >= t I`` (one SDP; it replaces the bisection on ``gamma``, since
    ``t`` enters linearly).  ``alpha=None`` chooses the decay rate ``alpha`` that minimises the
    bound by :func:`line_search`; a number fixes it (CORA and the paper use 0.5).
    """
    import cvxpy as cp

    plant = _as_arrays(plant)
    A, C, E, F = plant
    n, m, nw, nv = C.shape[1], C.shape[0], E.shape[1], F.shape[1]
    P, Y = _variables(n, m)
    t = cp.Variable()
    a = cp.Parameter(nonneg=True)
    ca = cp.Parameter(nonneg=True)  # 1 - alpha (kept a parameter so that the problem is DPP)
    prob = cp.Problem(cp.Maximize(t), [
        P >> t * np.eye(n),
        decay_lmi(P, Y, plant,
                  DecayWeights(a * P, ca * beta * np.eye(nw), ca * (1 - beta) * np.eye(nv)))])
    r_inf = beta * nw + (1 - beta) * nv

    def evaluate(al: float, rough: bool = False):
        a.value, ca.value = al, 1 - al
        # t at the level of rounding relative to P means "no P > 0" (P singular)
        if not solved(prob, rough) or t.value <= 1e-9 * float(np.abs(P.value).max()):
            return None
        return r_inf / t.value, (P.value, Y.value)

    if alpha is None:
        al, (Pv, Yv) = _line_searched(evaluate, what, search)
    else:
        out = evaluate(alpha)
        if out is None:
            raise DesignFailed(f"{what}: no P > 0 satisfies the P-radius LMI with alpha={alpha}")
        al, (Pv, Yv) = alpha, out[1]
    Pv = sym(Pv)
    L = gain_from(Pv, Yv, what)
    verify_decay(Pv, L, plant, DecayWeights(al * Pv, (1 - al) * beta * np.eye(nw),
                                            (1 - al) * (1 - beta) * np.eye(nv)), what)
    bound = r_inf / np.linalg.eigvalsh(Pv)[0]
    return GainDesign(L, Pv, {"rate": al, "radius_bound": float(np.sqrt(bound))})


# -- analytic centre of CORA's PRad-C/PRad-D cone (the published rows) ----------------------------
#: largest problem (entries of P and Y) that :func:`centre_gain` and Nom-G's design solve by
#: the numpy Newton method (30 tanks: 1530, about 2 s; 60 tanks: 6360, about a minute, over
#: the scaling study's budget); larger ones keep the Newton method's starting point (a Kalman
#: gain, strictly feasible, not the centre)
NEWTON_MAX_VARIABLES = 3_000
#: Clarabel settings tried in turn by :func:`_centre_clarabel` until one converges
CENTRE_RETRIES = ({}, {"static_regularization_enable": False},
                  {"static_regularization_enable": False, "equilibrate_enable": False},
                  {"equilibrate_enable": False})


def centre_gain(plant: LinearDesignProblem, rate: float, what: str = "PRad-C",
                solver: str = "auto") -> GainDesign:
    r"""Gain of the published PRad-C and PRad-D rows: the analytic centre of CORA's cone, for
    the matrices ``plant`` (:class:`~observers.numerics.lmi.LinearDesignProblem`).

    The cone is :math:`\mathcal{D}(P, Y) \succeq 0` of :func:`le_gain` with
    :math:`W_x = \beta P` (:math:`\beta` = ``rate``) and free diagonal weights
    :math:`W_w, W_v`; in the limit explained below the gain :math:`\Lambda = P^{-1}Y` comes
    from the analytic centre of its noise-free part, sliced by :math:`\operatorname{tr}P = 1`:

    .. math::

        \max_{P,\,Y}\ \log\det\begin{bmatrix} \beta P & ((P - YC)A)^T \\ (P - YC)A & P
        \end{bmatrix} + \log\det P \quad \text{s.t.} \quad \operatorname{tr}P = 1.

    CORA's PRad-C SDP (``Wx = beta P``, free diagonal noise weights ``Ww``, ``Wv``, objective
    ``max tr P``) is homogeneous in ``(P, Y, Ww, Wv)``: a cone, so the SDP is unbounded.  CORA
    moves its bisection on ``beta`` down only on a certified infeasible answer, so its last
    solve is at ``beta = 0.9921875`` (:func:`~observers.numerics.lmi.cora_bisection_end`),
    where SDPT3 returns a point far out along the cone.  CORA's PRad-D inequality is the same
    with weights ``alpha P``, ``(1 - alpha) beta I``, ``(1 - alpha)(1 - beta) I``; with a free
    scale of its noise weights it is the same kind of cone.

    Slicing the cone by ``tr P = 1`` and maximising ``log det D + log det P + sum(log
    weights)`` does *not* bound the problem: for a strictly feasible ``(P, Y)`` every weight
    can grow without limit (the weights appear only on the diagonal of ``D``, and ``log det D``
    grows with them), which Clarabel reports as insufficient progress on the 6-state vehicle
    and stops on with weights of 1e5-1e6 on the 6-tank system.  Along that unbounded direction
    the noise blocks drop out of the Schur complement of ``D``, and ``(P, Y)`` tend to the
    analytic centre of the noise-free decay cone sliced by ``tr P = 1``::

        max  log det [[rate P, ((P - Y C) A)'], [(P - Y C) A, P]] + log det P
        s.t. tr P = 1,

    which is what this function solves (strictly concave in ``P`` and, when ``C A`` has full
    row rank, in ``Y``: a unique optimum).  It is solved by a damped Newton method in numpy
    (:func:`~observers.numerics.lmi.decay_centre`, started from the steady-state Kalman gain
    of the system slowed down by ``sqrt(rate)``; about 15 iterations, 2 s at 30 tanks against
    minutes for Clarabel's log-det cone, and more accurate: Clarabel's point is 1e-7 below the
    optimum, 1e-4 away from it in ``L``).  Systems above :data:`NEWTON_MAX_VARIABLES` (more
    than about 40 states) keep the starting point (``solver="start"``: strictly inside the
    cone, certified in the same way, but not its centre; Clarabel's log-det cone, the route
    before, takes far beyond the scaling study's budget there; ``solver="clarabel"`` keeps
    it).  It weights each state by how much
    ``P`` can grow there, most on the measured states, so the gain trusts the measurements
    there, as the published PRad-C/PRad-D rows do; the noise weights of CORA's PRad-C and
    PRad-D both drop out in this limit, so the two rows get the same gain at the same rate.

    Certificate: the finite weights ``Ww = g I``, ``Wv = g I`` with the least ``g`` for which
    the P-radius inequality (*) holds at the returned ``(P, L)`` (the largest eigenvalue of
    ``S^-1/2 (M2 M2' + M3 M3') S^-1/2``, ``S`` the noise-free Schur complement), verified in
    numpy with the rest of (*).  The decay rate is ``rate``; if there is no ``P > 0`` for it (a
    mode that the outputs cannot correct decays more slowly than ``sqrt(rate)``) the design
    fails (:class:`~observers.errors.DesignFailed`).
    """
    plant = _as_arrays(plant)
    A, C, E, F = plant
    require_independent_outputs(C, what)
    n, m, nw, nv = C.shape[1], C.shape[0], E.shape[1], F.shape[1]
    if solver == "auto":
        solver = "newton" if n * (n + m) <= NEWTON_MAX_VARIABLES else "start"
    Pv, Yv = cone_point(_centre_cone(A, C, rate), solver, lambda: _centre_start(A, C, rate, what),
                        lambda: _centre_clarabel(A, C, rate, what), what)
    Pv = sym(Pv)
    L = gain_from(Pv, Yv, what)
    # least common noise weight g that certifies (*) at (P, L)
    Ac = (Pv - Pv @ L @ C) @ A
    S = sym(Pv - Ac @ np.linalg.solve(rate * Pv, Ac.T))
    lam, U = np.linalg.eigh(S)
    if lam[0] <= 1e-12 * max(lam[-1], 1e-300):
        raise DesignFailed(f"{what}: no strict P-radius decay at rate {rate} "
                           f"(smallest eigenvalue {lam[0]:.3g})")
    Mn = np.hstack([(Pv - Pv @ L @ C) @ E, Pv @ L @ F])
    K = (U / np.sqrt(lam)).T @ Mn
    g = float(np.linalg.eigvalsh(K @ K.T)[-1]) * (1 + 1e-6) if Mn.size else 0.0
    verify_decay(Pv, L, plant, DecayWeights(rate * Pv, g * np.eye(nw), g * np.eye(nv)), what)
    bound = g * (nw + nv) / ((1 - rate) * np.linalg.eigvalsh(Pv)[0])
    return GainDesign(L, Pv, {"rate": rate, "noise_weight": g, "solver": solver,
                              "radius_bound": float(np.sqrt(bound))})


def _centre_start(A, C, rate: float, what: str) -> tuple[np.ndarray, np.ndarray]:
    """A strictly feasible point of the centre problem: the steady-state Kalman gain of the
    system slowed down by ``sqrt(rate)`` (so that ``(I - L C) A / sqrt(rate)`` is stable, if
    any gain makes it so) and the P of the Stein equation ``rate P - A_L' P A_L = I``,
    scaled to ``tr P = 1``."""
    import scipy.linalg as sla

    n = A.shape[0]
    s = np.sqrt(rate)
    At, Ht = A / s, (C @ A) / s
    try:
        X = sla.solve_discrete_are(At.T, Ht.T, np.eye(n), np.eye(C.shape[0]))
        L = At @ X @ Ht.T @ np.linalg.inv(Ht @ X @ Ht.T + np.eye(C.shape[0]))
        Al = A - L @ C @ A
        P = sla.solve_discrete_lyapunov(Al.T / s, np.eye(n) / rate)
    except (np.linalg.LinAlgError, ValueError):
        P = None
    if P is None or not np.all(np.isfinite(P)) or np.linalg.eigvalsh(sym(P))[0] <= 0:
        raise DesignFailed(f"{what}: no P > 0 satisfies the P-radius decay at rate {rate} (a "
                           "mode that the outputs cannot correct decays more slowly than "
                           f"{s:.6g} per step)")
    P = sym(P) / np.trace(P)
    return P, P @ L


def _centre_cone(A, C, rate: float) -> DecayCone:
    """The decay cone of the centre: ``H = C A`` and the ``log det P`` term."""
    return DecayCone(A, C @ A, rate, with_logdet_P=True)


def _centre_newton(A, C, rate: float, what: str) -> tuple[np.ndarray, np.ndarray]:
    """The centre by :func:`~observers.numerics.lmi.decay_centre` (numpy Newton with the
    structured Hessian, :func:`_centre_cone`), from :func:`_centre_start`."""
    return cone_point(_centre_cone(A, C, rate), "newton", lambda: _centre_start(A, C, rate, what),
                      None, what)


def _centre_clarabel(A, C, rate: float, what: str) -> tuple[np.ndarray, np.ndarray]:
    """The centre as a cvxpy log-det problem solved by Clarabel (systems too large for the
    dense Newton method)."""
    import cvxpy as cp

    n, m = C.shape[1], C.shape[0]
    P, Y = _variables(n, m)
    M1 = (P - Y @ C) @ A
    D0 = bmat([[rate * P, M1.T], [M1, P]])
    problem = cp.Problem(cp.Maximize(cp.log_det((D0 + D0.T) / 2) + cp.log_det(P)),
                         [cp.trace(P) == 1])
    # Clarabel's default settings stall at the thin interior of the vehicle models' cone (its
    # widest slack is ~6e-5), depending on the BLAS kernels; without static regularisation,
    # then also without equilibration, the iterates converge (retries: one solve if all is well)
    for k, settings in enumerate(CENTRE_RETRIES):
        try:
            solve(problem, f"{what} (rate {rate})", **settings)
        except DesignFailed:
            if k == len(CENTRE_RETRIES) - 1:
                raise
            continue
        if problem.status == "optimal" and min_eig(D0.value) > 0:
            break
    return P.value, Y.value
