"""Offline Luenberger gains ``L`` (error dynamics ``e+ = (A - L C) e + w - L v``) for the
"ready for control" observers of Althoff & Rath (Automatica 2021, Secs. 3.2-3.3):

* :func:`prad_e_design` - P-radius gain of Wang, Zhou, Puig et al. (CCC 2017), PRad-E;
* :func:`nom_g_design` - nominal gain with decay rate ``mu`` (Wang et al., Automatica 2018), Nom-G;
* :func:`hinf_g_design` - H-infinity gain of Tang et al. (TAC 2019, eq. 16), Hinf-G.

Each design solves its LMI with cvxpy + Clarabel (PRad-E also in closed form, through a
Riccati equation), then re-checks the LMI on the returned numbers with numpy eigenvalues
(:mod:`observers.lmi`) and returns a verified :class:`GainDesign`; an infeasible or failed
design raises :class:`~observers.errors.DesignFailed`.

Notation: ``E`` and ``F`` are the generator matrices of the disturbance set ``W`` (state
space) and of the noise set ``V`` (output space), ``Y = P L``.  Nom-G and Hinf-G are
feasibility problems as CORA states them, so their gains depend on the solver there; the
objectives chosen here make every gain the unique (or central) solution of a stated problem.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import numpy as np

from . import lmi
from .errors import DesignFailed

#: tolerances of the PRad-E SDP: its optimum is unique, so it is solved to high accuracy
TIGHT = {"tol_gap_abs": 1e-10, "tol_gap_rel": 1e-10, "tol_feas": 1e-10}
#: strictness margin of the strict LMIs (``SM <= -eps I`` stands for ``SM < 0``)
STRICT_EPS = 1e-6


@dataclass(frozen=True)
class GainDesign:
    """A verified observer gain ``L = P^{-1} Y`` with its Lyapunov matrix and figures of merit."""

    L: np.ndarray
    P: np.ndarray
    rho: float  # spectral radius of A - L C
    info: dict = field(default_factory=dict)


# -- helpers ----------------------------------------------------------------------------------
def range_factor(G: np.ndarray, rtol: float = 1e-12) -> np.ndarray:
    """``U_r S_r`` from the thin SVD of ``G``: a full-column-rank factor with the same ``G G'``.

    LMIs in which ``G`` enters only through ``G' G`` and ``G' X`` keep their feasible set in
    the other variables when ``G`` is replaced by this factor (congruence with ``V_r'``).
    """
    G = np.asarray(G, dtype=float)
    if G.size == 0:
        return np.zeros((G.shape[0], 0))
    U, s, _ = np.linalg.svd(G, full_matrices=False)
    r = int(np.sum(s > rtol * s[0])) if s.size and s[0] > 0 else 0
    return U[:, :r] * s[:r]


def range_basis(G: np.ndarray, rtol: float = 1e-12) -> np.ndarray:
    """Orthonormal basis of the range of ``G`` (n x rank)."""
    F = range_factor(G, rtol)
    return F / np.linalg.norm(F, axis=0) if F.shape[1] else F


def gain_from(P: np.ndarray, Y: np.ndarray, what: str) -> np.ndarray:
    """``L = P^{-1} Y`` after checking that ``P`` is positive definite."""
    P = lmi.sym(P)
    lam = np.linalg.eigvalsh(P)
    if not np.all(np.isfinite(lam)) or lam[0] <= 1e-12 * max(1.0, lam[-1]):
        raise DesignFailed(f"{what}: P is not positive definite (eigenvalues "
                           f"{lam[0]:.3g} ... {lam[-1]:.3g}), so L = P^-1 Y is undefined")
    return np.linalg.solve(P, Y)


def _solve(problem, what: str, **solver_options) -> str:
    """:func:`observers.lmi.solve` without cvxpy's "inaccurate" warning: an inaccurate
    solution is accepted or rejected by the numpy verification that follows every solve."""
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message="Solution may be inaccurate")
        return lmi.solve(problem, what, **solver_options)


def _bmat(blocks: list[list]):
    """Block matrix where ``None`` is a zero block (its size read from the other blocks).

    With numpy blocks only it is a numpy array; with any cvxpy expression among them, a cvxpy
    expression (so each LMI below is written once, for the solver and for the verification).
    """
    rows = [next(b.shape[0] for b in row if b is not None) for row in blocks]
    cols = [next(row[j].shape[1] for row in blocks if row[j] is not None)
            for j in range(len(blocks[0]))]
    filled = [[np.zeros((rows[i], cols[j])) if b is None else b for j, b in enumerate(row)]
              for i, row in enumerate(blocks)]
    if all(isinstance(b, np.ndarray) for row in filled for b in row):
        return np.block(filled)
    import cvxpy as cp

    return cp.bmat(filled)


def check_modes(system, who: str, rate: float = 1.0) -> None:
    """Raise if (A, C) has an unobservable mode with ``|lambda| >= rate``.

    ``rate = 1`` is detectability (a :class:`~systems.ModelError` from the system); ``rate < 1``
    is the decay rate a design needs (a :class:`DesignFailed` naming the mode).
    """
    if hasattr(system, "require_detectable"):
        system.require_detectable(who)
    if rate < 1.0 and hasattr(system, "unobservable_modes"):
        slow = [m for m in np.atleast_1d(system.unobservable_modes()) if abs(m) >= rate]
        if slow:
            raise DesignFailed(
                f"{who}: the unobservable mode(s) {', '.join(f'{abs(m):.6g}' for m in slow)} "
                f"decay slower than the required rate {rate:.6g}; no gain can be faster")


# -- PRad-E -----------------------------------------------------------------------------------
def cora_bisection_beta(tol: float = 0.01) -> float:
    """Contraction factor at which CORA's bisection for PRad-E stops.

    CORA bisects ``beta`` on [0, 1] until the bracket is narrower than ``tol``, moving up after
    every solve that is not certified infeasible.  The PRad-E LMI as CORA states it is
    non-strict, and ``(P, Y) = (0, 0)`` satisfies it for every ``beta``, so every step moves up
    and the last (kept) solve is at ``1 - 2**-k`` (0.9921875 for ``tol = 0.01``).  This
    function replays that bracket arithmetic, which makes the 6 earlier solves unnecessary.
    """
    lo, hi, beta = 0.0, 1.0, 0.5
    while hi - lo > tol:
        beta = 0.5 * (lo + hi)
        lo = beta  # feasible, see above
    return beta


def prad_e_lmi(A, C, E, F, beta, P, Y):
    """The PRad-E matrix of Wang et al. (CCC 2017, eq. 17), to be ``<= 0``::

        [ -beta P     0      0    A'P - C'Y' ]
        [    0     -E'E      0       E'P     ]
        [    0       0    -F'F       F'Y'    ]
        [ PA - YC   PE      YF       -P      ]

    Works with numpy arrays and with cvxpy expressions (``P``, ``Y`` variables).  CORA writes
    ``F Y'`` in the third block row; that equals ``F' Y'`` for the symmetric (diagonal) ``F``
    of all benchmarks, and only ``F' Y'`` has the right shape for a non-square ``F``.
    """
    return _bmat([[-beta * P, None, None, A.T @ P - C.T @ Y.T],
                  [None, -E.T @ E, None, E.T @ P],
                  [None, None, -F.T @ F, F.T @ Y.T],
                  [P @ A - Y @ C, P @ E, Y @ F, -P]])


def prad_e_design(A, C, E, F, beta: float, solver: str = "auto") -> GainDesign:
    """PRad-E gain: ``L = P^{-1} Y`` with ``P`` of maximal trace subject to the PRad-E LMI.

    Parameters
    ----------
    A, C : arrays
        System and output matrices.
    E, F : arrays
        Generators of W and V.  The LMI depends on them only through their ranges (congruence
        with ``diag(I, T_E, T_F, I)``), so they are replaced by orthonormal range bases; this
        is the same problem, scaled for the solver.
    beta : float
        Contraction factor in (0, 1); CORA uses :func:`cora_bisection_beta` (0.9921875).
    solver : {"auto", "sdp", "riccati"}
        ``"sdp"``: maximise ``trace(P)`` with cvxpy + Clarabel.  ``"auto"``: ``"riccati"`` when
        V is full-dimensional, else ``"sdp"``.  ``"riccati"``: the same optimum in closed
        form.  With ``X = P^{-1}`` the LMI reads
        ``X >= (A - L C) X (A - L C)' / beta + Q_E + L Q_F L'`` (``Q_E``, ``Q_F``: projectors
        on the ranges of E and F), whose least solution over all ``L`` is the stabilising
        solution of the filter Riccati equation of ``(A / sqrt(beta), C)`` with weights
        ``Q_E`` and ``beta Q_F``, with ``L = A X C' (C X C' + beta Q_F)^{-1}``.  The largest
        ``P`` (in the Loewner order, hence of largest trace) is its inverse, and the gain is
        unique.  Needs a full-dimensional noise set V.  Both routes agree to solver accuracy
        (tests); the SDP takes minutes for 30 states, the Riccati equation milliseconds.

    Notes
    -----
    The returned ``(P, Y)`` is verified in numpy: the LMI (with the range bases) is negative
    semidefinite up to round-off, ``P`` is positive definite and
    ``rho(A - L C) <= sqrt(beta) < 1``.
    """
    what = "PRad-E"
    if not 0.0 < beta < 1.0:
        raise DesignFailed(f"{what}: beta must lie in (0, 1), got {beta}")
    A, C = np.asarray(A, float), np.asarray(C, float)
    QE, QF = range_basis(E), range_basis(F)
    if solver == "auto":
        solver = "riccati" if QF.shape[1] == C.shape[0] else "sdp"
    if solver == "sdp":
        P, Y = _prad_e_sdp(A, C, QE, QF, beta, what)
    elif solver == "riccati":
        P, Y = _prad_e_riccati(A, C, QE, QF, beta, what)
    else:
        raise DesignFailed(f"{what}: unknown solver {solver!r} (use 'auto', 'sdp' or 'riccati')")
    L = gain_from(P, Y, what)
    lmi.require_nsd(prad_e_lmi(A, C, QE, QF, beta, P, Y), f"{what} LMI", tol=1e-7)
    rho = lmi.spectral_radius(A - L @ C)
    if rho > np.sqrt(beta) * (1 + 1e-6):
        raise DesignFailed(f"{what}: verification failed (spectral radius of A - L C is "
                           f"{rho:.6g} > sqrt(beta) = {np.sqrt(beta):.6g})")
    return GainDesign(L, P, rho, {"beta": beta, "solver": solver, "trace_P": float(np.trace(P))})


def _prad_e_sdp(A, C, QE, QF, beta, what):
    import cvxpy as cp

    n, m = C.shape[1], C.shape[0]
    P = cp.Variable((n, n), symmetric=True)
    Y = cp.Variable((n, m))
    SM = prad_e_lmi(A, C, QE, QF, beta, P, Y)
    problem = cp.Problem(cp.Maximize(cp.trace(P)), [P >> 0, 0.5 * (SM + SM.T) << 0])
    _solve(problem, what, **TIGHT)
    return P.value, Y.value


def _prad_e_riccati(A, C, QE, QF, beta, what):
    from scipy.linalg import solve_discrete_are

    m = C.shape[0]
    if QF.shape[1] < m:
        raise DesignFailed(f"{what}: solver='riccati' needs a noise set V of full dimension "
                           f"{m} (its generators span {QF.shape[1]}); use solver='sdp'")
    Q, R = QE @ QE.T, beta * np.eye(m)
    try:
        X = solve_discrete_are(A.T / np.sqrt(beta), C.T, Q, R)
    except (np.linalg.LinAlgError, ValueError) as exc:
        raise DesignFailed(f"{what}: the Riccati equation has no stabilising solution "
                           f"({exc})") from None
    X = lmi.sym(X)
    L = A @ X @ C.T @ np.linalg.inv(C @ X @ C.T + R)
    lam = np.linalg.eigvalsh(X)
    if lam[0] <= 1e-12 * max(1.0, lam[-1]):
        raise DesignFailed(f"{what}: the Riccati solution is singular (the disturbance set W "
                           "does not excite every mode), so no P of finite trace exists")
    P = lmi.sym(np.linalg.inv(X))
    return P, P @ L


# -- Nom-G ------------------------------------------------------------------------------------
def nom_g_lmi(A, C, mu, P, Y):
    """The Nom-G matrix (Wang et al., Automatica 2018, eq. 36), to be ``> 0``:
    ``[[mu P, (P A - Y C)'], [P A - Y C, P]]``."""
    M = P @ A - Y @ C
    return _bmat([[mu * P, M.T], [M, P]])


def nom_g_design(A, C, mu: float = 1.0) -> GainDesign:
    """Nom-G gain: the analytic centre of the Nom-G LMI normalised by ``trace(P) = n``.

    The LMI ``[[mu P, *], [P A - Y C, P]] > 0`` (equivalently
    ``(A - L C)' P (A - L C) < mu P``) only asks for a decay rate ``sqrt(mu)`` of the nominal
    error; CORA passes it to the solver without an objective, so its gain is whatever point
    the solver returns.  Here the gain is the *analytic centre* of the feasible set: the
    maximiser of ``log det`` of the LMI matrix subject to ``trace(P) = n`` (the LMI is
    homogeneous in ``(P, Y)``, so a normalisation is needed).  The objective is strictly
    concave, so the point is unique and reproducible, and it lies deep inside the feasible set
    (every eigenvalue of the LMI is kept away from zero).

    Verified in numpy: the LMI is positive definite, ``P`` too, and
    ``rho(A - L C) < sqrt(mu) <= 1``.
    """
    import cvxpy as cp

    what = "Nom-G"
    if not 0.0 < mu <= 1.0:
        raise DesignFailed(f"{what}: mu must lie in (0, 1], got {mu}")
    A, C = np.asarray(A, float), np.asarray(C, float)
    n, m = C.shape[1], C.shape[0]
    P = cp.Variable((n, n), symmetric=True)
    Y = cp.Variable((n, m))
    SM = nom_g_lmi(A, C, mu, P, Y)
    problem = cp.Problem(cp.Maximize(cp.log_det(0.5 * (SM + SM.T))), [cp.trace(P) == n])
    _solve(problem, what)
    P, Y = lmi.sym(P.value), Y.value
    L = gain_from(P, Y, what)
    margin = lmi.require_pd(nom_g_lmi(A, C, mu, P, Y), f"{what} LMI")
    rho = lmi.spectral_radius(A - L @ C)
    if rho >= np.sqrt(mu):
        raise DesignFailed(f"{what}: verification failed (spectral radius of A - L C is "
                           f"{rho:.6g} >= sqrt(mu) = {np.sqrt(mu):.6g})")
    return GainDesign(L, P, rho, {"mu": mu, "lmi_margin": margin})


# -- Hinf-G -----------------------------------------------------------------------------------
def hinf_g_lmi(A, C, E, F, g, P, Y):
    """The Hinf-G matrix of Tang et al. (TAC 2019, eq. 16), to be ``< 0`` (``g = gamma^2``)::

        [ I - P      0        0     (P A - Y C)' ]
        [   0     -g I        0       (P E)'     ]
        [   0       0      -g I      (-Y F)'     ]
        [ PA - YC   PE      -Y F        -P       ]

    By the bounded-real lemma it certifies ``sum |e_k|^2 < g sum (|w~_k|^2 + |v~_k|^2) +
    e_0' P e_0`` for ``w_k = E w~_k``, ``v_k = F v~_k``.
    """
    n, nw, nv = A.shape[0], E.shape[1], F.shape[1]
    M = P @ A - Y @ C
    return _bmat([[np.eye(n) - P, None, None, M.T],
                  [None, -g * np.eye(nw), None, (P @ E).T],
                  [None, None, -g * np.eye(nv), (-Y @ F).T],
                  [M, P @ E, -Y @ F, -P]])


def hinf_g_design(A, C, E, F, gamma_slack: float = 0.1) -> GainDesign:
    """Hinf-G gain in two stages, both SDPs with cvxpy + Clarabel.

    1. ``gamma*^2 = min gamma^2`` subject to the Hinf-G LMI (the problem the paper states;
       CORA instead scans ``gamma`` on ``linspace(1, 50, 100)`` and keeps the first
       feasible point the solver returns).
    2. The minimisers of stage 1 are not unique (gains returned at different tolerances differ
       by ~10 %), so the gain is fixed by a second criterion: among the gains with
       ``gamma <= (1 + gamma_slack) gamma*``, the one minimising ``trace(P)``, i.e. the
       smallest weight on the initial error in the H-infinity bound (see
       :func:`hinf_g_lmi`).  This point is unique in practice and reproducible.

    ``E`` and ``F`` are replaced by full-rank factors with the same ``E E'`` and ``F F'``
    (an orthogonal congruence of the LMI).  Strict inequalities are imposed with a margin
    ``STRICT_EPS`` and verified in numpy (LMI negative definite, ``rho(A - L C) < 1``).
    """
    import cvxpy as cp

    what = "Hinf-G"
    if not gamma_slack > 0:
        raise DesignFailed(f"{what}: gamma_slack must be positive, got {gamma_slack}")
    A, C = np.asarray(A, float), np.asarray(C, float)
    E, F = range_factor(E), range_factor(F)
    n, m = C.shape[1], C.shape[0]
    P = cp.Variable((n, n), symmetric=True)
    Y = cp.Variable((n, m))
    g = cp.Variable(nonneg=True)

    def strict(SM):
        return 0.5 * (SM + SM.T) << -STRICT_EPS * np.eye(SM.shape[0])

    _solve(cp.Problem(cp.Minimize(g), [strict(hinf_g_lmi(A, C, E, F, g, P, Y))]),
              f"{what} (min gamma)")
    g_star = float(g.value)
    g_max = (1.0 + gamma_slack) ** 2 * g_star
    _solve(cp.Problem(cp.Minimize(cp.trace(P)),
                         [strict(hinf_g_lmi(A, C, E, F, g_max, P, Y))]),
              f"{what} (min trace P)")
    P, Y = lmi.sym(P.value), Y.value
    L = gain_from(P, Y, what)
    lmi.require_pd(-hinf_g_lmi(A, C, E, F, g_max, P, Y), f"{what} LMI")
    rho = lmi.spectral_radius(A - L @ C)
    if rho >= 1.0:
        raise DesignFailed(f"{what}: verification failed (spectral radius of A - L C is "
                           f"{rho:.6g} >= 1)")
    return GainDesign(L, P, rho, {"gamma_min": float(np.sqrt(g_star)),
                                  "gamma": float(np.sqrt(g_max))})
