"""Offline Luenberger gains ``L`` (error dynamics ``e+ = (A - L C) e + w - L v``) for the
"ready for control" observers of Althoff & Rath (Automatica 2021, Secs. 3.2-3.3):

* :func:`prad_e_design` - P-radius gain of Wang, Zhou, Puig et al. (CCC 2017), PRad-E;
* :func:`nom_g_design` - nominal gain with decay rate ``mu`` (Wang et al., Automatica 2018), Nom-G;
* :func:`hinf_g_design` - H-infinity gain of Tang et al. (TAC 2019, eq. 16), Hinf-G.

Each design solves its LMI with cvxpy + Clarabel (PRad-E also in closed form, through a
Riccati equation; Nom-G by a damped Newton method in numpy), then re-checks the LMI on the
returned numbers with numpy eigenvalues (:mod:`observers.numerics.lmi`) and returns a
verified :class:`GainDesign`; an infeasible or failed design raises
:class:`~observers.errors.DesignFailed`.

Notation: ``E`` and ``F`` are the generator matrices of the disturbance set ``W`` (state
space) and of the noise set ``V`` (output space), ``Y = P L``.  Nom-G and Hinf-G are
feasibility problems as CORA states them, so their gains depend on the solver there; the
objectives chosen here make every gain the unique (or central) solution of a stated problem.
"""

from __future__ import annotations

import numpy as np

from ..errors import DesignFailed
from . import lmi
from .lmi import GainDesign, LinearDesignProblem, bmat, gain_from, range_basis, range_factor
from .prad import NEWTON_MAX_VARIABLES

#: strictness margin of the strict LMIs (``SM <= -eps I`` stands for ``SM < 0``)
STRICT_EPS = 1e-6


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
    return bmat([[-beta * P, None, None, A.T @ P - C.T @ Y.T],
                  [None, -E.T @ E, None, E.T @ P],
                  [None, None, -F.T @ F, F.T @ Y.T],
                  [P @ A - Y @ C, P @ E, Y @ F, -P]])


def prad_e_design(A, C, E, F, beta: float, solver: str = "auto") -> GainDesign:
    r"""PRad-E gain: ``L = P^{-1} Y`` with ``P`` of maximal trace subject to the PRad-E LMI.

    The design of Sec. 3.2 of Althoff & Rath 2021 (PRad-E; eq. 17 of Wang et al., CCC 2017):

    .. math::

        L = P^{-1}Y, \qquad \max_{P,\,Y}\ \operatorname{tr}P \quad \text{s.t.} \quad
        \begin{bmatrix} -\beta P & 0 & 0 & A^TP - C^TY^T \\
        0 & -E^TE & 0 & E^TP \\
        0 & 0 & -F^TF & F^TY^T \\
        PA - YC & PE & YF & -P \end{bmatrix} \preceq 0, \quad P \succ 0

    or, equivalently with :math:`X = P^{-1}` and ``solver="riccati"``, the stabilising
    solution of

    .. math::

        X = \frac{1}{\beta}(A - LC)X(A - LC)^T + Q_E + LQ_FL^T, \qquad
        L = AXC^T\left(CXC^T + \beta Q_F\right)^{-1}.

    Parameters
    ----------
    A, C : arrays
        System and output matrices.
    E, F : arrays
        Generators of W and V.  The LMI depends on them only through their ranges (congruence
        with ``diag(I, T_E, T_F, I)``), so they are replaced by orthonormal range bases; this
        is the same problem, scaled for the solver.
    beta : float
        Contraction factor in (0, 1); CORA uses
        :func:`~observers.numerics.lmi.cora_bisection_end` (0.9921875).
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
    return GainDesign(L, P, {"rho": rho, "beta": beta, "solver": solver,
                             "trace_P": float(np.trace(P))})


def _prad_e_sdp(A, C, QE, QF, beta, what):
    import cvxpy as cp

    n, m = C.shape[1], C.shape[0]
    P = cp.Variable((n, n), symmetric=True)
    Y = cp.Variable((n, m))
    SM = prad_e_lmi(A, C, QE, QF, beta, P, Y)
    problem = cp.Problem(cp.Maximize(cp.trace(P)), [P >> 0, 0.5 * (SM + SM.T) << 0])
    lmi.solve(problem, what, **lmi.TIGHT)
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
    return bmat([[mu * P, M.T], [M, P]])


def nom_g_design(A, C, mu: float = 1.0, solver: str = "newton") -> GainDesign:
    r"""Nom-G gain: the analytic centre of the Nom-G LMI normalised by ``trace(P) = n``.

    The LMI of Sec. 3.2 of Althoff & Rath 2021 (Nom-G; eq. 36 of Wang et al., Automatica
    2018), here with the analytic-centre objective:

    .. math::

        L = P^{-1}Y, \qquad
        \begin{bmatrix} \mu P & (PA - YC)^T \\ PA - YC & P \end{bmatrix} \succ 0,
        \quad P \succ 0

    .. math::

        (P, Y) = \arg\max\ \log\det\begin{bmatrix} \mu P & (PA - YC)^T \\
        PA - YC & P \end{bmatrix} \quad \text{s.t.} \quad \operatorname{tr}P = n.

    The LMI ``[[mu P, *], [P A - Y C, P]] > 0`` (equivalently
    ``(A - L C)' P (A - L C) < mu P``) only asks for a decay rate ``sqrt(mu)`` of the nominal
    error; CORA passes it to the solver without an objective, so its gain is whatever point
    the solver returns.  Here the gain is the *analytic centre* of the feasible set: the
    maximiser of ``log det`` of the LMI matrix subject to ``trace(P) = n`` (the LMI is
    homogeneous in ``(P, Y)``, so a normalisation is needed).  The objective is strictly
    concave, so the point is unique and reproducible, and it lies deep inside the feasible set
    (every eigenvalue of the LMI is kept away from zero).

    ``solver="newton"`` (default) computes the centre by the damped Newton method of
    :func:`~observers.numerics.lmi.decay_centre` (the PRad-C/D centre's method, here without
    the ``log det P`` term), started from the steady-state Kalman gain of ``(A / sqrt(mu), C)``
    and the ``P`` of its Stein equation (:func:`nom_g_start`): seconds at 30 states where
    Clarabel's log-det cone (``solver="clarabel"``, the former route) takes minutes, and
    closer to the optimum (Clarabel stops at its duality gap, 1e-8 relative).  Above
    :data:`~observers.numerics.prad.NEWTON_MAX_VARIABLES` entries of ``(P, Y)`` (about 40
    states) the gain is that starting point (``info["solver"] = "start"``: a Kalman gain,
    strictly feasible and verified, not the centre).

    Verified in numpy: the LMI is positive definite, ``P`` too, and
    ``rho(A - L C) < sqrt(mu) <= 1``.
    """
    lmi.require_independent_outputs(C, "Nom-G")
    what = "Nom-G"
    if not 0.0 < mu <= 1.0:
        raise DesignFailed(f"{what}: mu must lie in (0, 1], got {mu}")
    A, C = np.asarray(A, float), np.asarray(C, float)
    n = C.shape[1]
    if solver == "newton" and n * (n + C.shape[0]) > NEWTON_MAX_VARIABLES:
        solver = "start"  # the Hessian would not fit: the strictly feasible start
    P, Y = lmi.cone_point(lmi.DecayCone(A, C, mu), solver, lambda: nom_g_start(A, C, mu, what),
                          lambda: _nom_g_clarabel(A, C, mu, what), what)
    P = lmi.sym(P)
    L = gain_from(P, Y, what)
    margin = lmi.require_pd(nom_g_lmi(A, C, mu, P, Y), f"{what} LMI")
    rho = lmi.spectral_radius(A - L @ C)
    if rho >= np.sqrt(mu):
        raise DesignFailed(f"{what}: verification failed (spectral radius of A - L C is "
                           f"{rho:.6g} >= sqrt(mu) = {np.sqrt(mu):.6g})")
    return GainDesign(L, P, {"rho": rho, "mu": mu, "lmi_margin": margin, "solver": solver,
                             "trace_P": float(np.trace(P)) / n})


def nom_g_start(A, C, mu: float, what: str = "Nom-G") -> tuple[np.ndarray, np.ndarray]:
    """A strictly feasible point of the Nom-G LMI with ``trace(P) = n``: the steady-state
    Kalman gain ``L`` of ``(A / sqrt(mu), C)`` (unit weights), for which
    ``rho(A - L C) < sqrt(mu)``, and the solution ``P`` of the Stein equation
    ``mu P - (A - L C)' P (A - L C) = I``, scaled; ``Y = P L``."""
    import scipy.linalg as sla

    n, m = C.shape[1], C.shape[0]
    s = np.sqrt(mu)
    try:
        X = sla.solve_discrete_are(A.T / s, C.T, np.eye(n), np.eye(m))
        L = A @ X @ C.T @ np.linalg.inv(C @ X @ C.T + np.eye(m))
        Al = A - L @ C
        P = lmi.sym(sla.solve_discrete_lyapunov(Al.T / s, np.eye(n) / mu))
    except (np.linalg.LinAlgError, ValueError):
        P = None
    if P is None or not np.all(np.isfinite(P)) or np.linalg.eigvalsh(P)[0] <= 0:
        raise DesignFailed(f"{what}: no gain makes the nominal error decay at rate "
                           f"{s:.6g} (a mode the outputs cannot correct is too slow)")
    P = P * (n / np.trace(P))
    return P, P @ L


def _nom_g_clarabel(A, C, mu: float, what: str) -> tuple[np.ndarray, np.ndarray]:
    """The Nom-G centre as a cvxpy log-det problem solved by Clarabel."""
    import cvxpy as cp

    n, m = C.shape[1], C.shape[0]
    P = cp.Variable((n, n), symmetric=True)
    Y = cp.Variable((n, m))
    SM = nom_g_lmi(A, C, mu, P, Y)
    problem = cp.Problem(cp.Maximize(cp.log_det(0.5 * (SM + SM.T))), [cp.trace(P) == n])
    lmi.solve(problem, what)
    return P.value, Y.value


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
    return bmat([[np.eye(n) - P, None, None, M.T],
                  [None, -g * np.eye(nw), None, (P @ E).T],
                  [None, None, -g * np.eye(nv), (-Y @ F).T],
                  [M, P @ E, -Y @ F, -P]])


#: Hinf-G's ``method="auto"`` takes the Riccati route above this many states (the published
#: rows, up to 30 states, keep the two SDPs)
HINF_G_RICCATI_ABOVE = 30


def hinf_g_design(A, C, E, F, gamma_slack: float = 0.1, method: str = "auto") -> GainDesign:
    r"""Hinf-G gain in two stages, both SDPs with cvxpy + Clarabel (``method="sdp"``; ``"auto"``
    up to :data:`HINF_G_RICCATI_ABOVE` states), or from Riccati equations (``"riccati"``,
    ``"auto"`` above; :func:`_hinf_g_riccati`).

    Stage 1 is the problem of Sec. 3.3 of Althoff & Rath 2021 (Hinf-G; eq. 16 of Tang et al.,
    TAC 2019):

    .. math::

        L = P^{-1}Y, \qquad \min_{P,\,Y,\,\gamma}\ \gamma^2 \quad \text{s.t.} \quad
        \begin{bmatrix} I - P & 0 & 0 & (PA - YC)^T \\
        0 & -\gamma^2 I & 0 & (PE)^T \\
        0 & 0 & -\gamma^2 I & (-YF)^T \\
        PA - YC & PE & -YF & -P \end{bmatrix} \prec 0, \quad P \succ 0

    and stage 2 keeps the same inequality with :math:`\gamma^2 \le (1 + s)^2\gamma^{\ast 2}`
    (:math:`s` = ``gamma_slack``) and minimises :math:`\operatorname{tr}P`.

    1. ``gamma*^2 = min gamma^2`` subject to the Hinf-G LMI (the problem the paper states;
       CORA instead scans ``gamma`` on ``linspace(1, 50, 100)`` and keeps the first
       feasible point the solver returns).
    2. The minimisers of stage 1 are not unique (gains returned at different tolerances differ
       by ~10 %), so the gain is fixed by a second criterion: among the gains with
       ``gamma <= (1 + gamma_slack) gamma*``, the one minimising ``trace(P)``, i.e. the
       smallest weight on the initial error in the H-infinity bound (see
       :func:`hinf_g_lmi`).  This point is unique in practice and reproducible.

    ``E`` and ``F`` are replaced by full-rank factors with the same ``E E'`` and ``F F'``
    (an orthogonal congruence of the LMI), divided by their common scale
    (:func:`~observers.numerics.lmi.unit_noise`: the same ``P``, ``Y``, and ``gamma^2`` scaled
    back, so that the gain does not depend on the units of the data).  Strict inequalities
    are imposed with a margin ``STRICT_EPS`` and verified in numpy (LMI negative definite,
    ``rho(A - L C) < 1``).
    """
    import cvxpy as cp

    what = "Hinf-G"
    if not gamma_slack > 0:
        raise DesignFailed(f"{what}: gamma_slack must be positive, got {gamma_slack}")
    A, C = np.asarray(A, float), np.asarray(C, float)
    n, m = C.shape[1], C.shape[0]
    plant, s2 = lmi.unit_noise(LinearDesignProblem(A, C, range_factor(E), range_factor(F)))
    E, F = plant.E, plant.F
    if method == "auto":
        method = "riccati" if n > HINF_G_RICCATI_ABOVE and F.shape[1] == m else "sdp"
    if method == "riccati":
        return _in_units(_hinf_g_riccati(plant, gamma_slack, what), s2)
    if method != "sdp":
        raise DesignFailed(f"{what}: unknown method {method!r} (use 'auto', 'sdp' or 'riccati')")
    P = cp.Variable((n, n), symmetric=True)
    Y = cp.Variable((n, m))
    g = cp.Variable(nonneg=True)

    def strict(SM):
        return 0.5 * (SM + SM.T) << -STRICT_EPS * np.eye(SM.shape[0])

    lmi.solve(cp.Problem(cp.Minimize(g), [strict(hinf_g_lmi(A, C, E, F, g, P, Y))]),
              f"{what} (min gamma)")
    g_star = float(g.value)
    g_max = (1.0 + gamma_slack) ** 2 * g_star
    lmi.solve(cp.Problem(cp.Minimize(cp.trace(P)),
                         [strict(hinf_g_lmi(A, C, E, F, g_max, P, Y))]),
              f"{what} (min trace P)")
    P, Y = lmi.sym(P.value), Y.value
    return _in_units(_verified_hinf_g(plant, (gain_from(P, Y, what), P, Y), (g_star, g_max),
                                      "sdp", what), s2)


def _in_units(design: GainDesign, s2: float) -> GainDesign:
    """A Hinf-G design of the plant with unit noise (:func:`~observers.numerics.lmi.unit_noise`)
    in the units of the data: the same gain and ``P``, ``gamma`` times ``sqrt(s2)``."""
    info = dict(design.info)
    for key in ("gamma_min", "gamma"):
        info[key] = info[key] * float(np.sqrt(s2))
    return GainDesign(design.L, design.P, info)


def _verified_hinf_g(plant: LinearDesignProblem, point: tuple, gammas: tuple[float, float],
                     method: str, what: str) -> GainDesign:
    """The Hinf-G design ``point = (L, P, Y)`` of ``plant`` once verified in numpy (either
    route, ``method``): the LMI with ``g_max`` of ``gammas = (g_star, g_max)`` (the least
    ``gamma^2`` and its bound) holds strictly and ``A - L C`` is Schur stable; else
    :class:`DesignFailed`."""
    A, C, E, F = plant
    L, P, Y = point
    g_star, g_max = gammas
    lmi.require_pd(-hinf_g_lmi(A, C, E, F, g_max, P, Y), f"{what} LMI")
    rho = lmi.spectral_radius(A - L @ C)
    if rho >= 1.0:
        raise DesignFailed(f"{what}: verification failed (spectral radius of A - L C is "
                           f"{rho:.6g} >= 1)")
    return GainDesign(L, P, {"rho": rho, "gamma_min": float(np.sqrt(g_star)),
                             "gamma": float(np.sqrt(g_max)), "method": method})


def _hinf_g_riccati(plant: LinearDesignProblem, gamma_slack: float, what: str) -> GainDesign:
    """Hinf-G from the H-infinity filter Riccati equation (systems too large for the SDPs) for
    the matrices ``plant`` (``E``, ``F`` full-rank factors).

    The Hinf-G LMI is the H-infinity LMI of ESO-C/D with the weight ``Q = I``
    (:func:`~observers.numerics.ellipsoidal.hinf_riccati`): its least ``gamma*^2`` comes from
    a bisection on the existence of the Riccati solution, as stage 1.  Stage 2 (least
    ``trace(P)``) has no Riccati form; instead the gain is the Riccati point of the weight
    ``(1 + 1e-3) I`` at ``gamma^2`` halfway between ``gamma*^2`` and
    ``g_max = (1 + gamma_slack)^2 gamma*^2``: a gain with the same H-infinity bound ``g_max``
    as the SDP route's (not the one of least ``trace(P)``), for which the LMI with ``I`` and
    ``g_max`` holds strictly (the surplus of the weight and of ``gamma^2`` is a negative
    definite margin), verified in numpy as the SDP route's point.
    """
    from .ellipsoidal import hinf_riccati

    n = plant.A.shape[0]
    _, _, g_star = hinf_riccati(plant, np.eye(n), what, slack=0.0)
    g_max = (1.0 + gamma_slack) ** 2 * g_star
    g_mid = 0.5 * (g_star + g_max)
    P, L, g_used = hinf_riccati(plant, (1.0 + 1e-3) * np.eye(n), what,
                                slack=g_mid / g_star - 1.0)
    if g_used >= g_max:
        raise DesignFailed(f"{what}: the Riccati point needs gamma^2 = {g_used:.6g} above the "
                           f"bound {g_max:.6g}")
    P = lmi.sym(P)
    return _verified_hinf_g(plant, (L, P, P @ L), (g_star, g_max), "riccati", what)
