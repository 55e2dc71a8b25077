"""Offline designs and online recursion of the ellipsoidal invariant-set observers ESO-C and
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
off by a small margin, verifies the LMI by eigenvalues and derives ``lam`` from it.
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import eigh, solve_discrete_lyapunov
from scipy.stats import chi2

from .errors import DesignFailed
from .lmi import require_nsd, require_pd, require_psd, solve, spectral_radius, sym

#: relative safety margin applied to gamma^2 and Q before the final verification
MARGIN = 1e-9


def hinf_lmi(
    A: np.ndarray, C: np.ndarray, E: np.ndarray, F: np.ndarray, Q: np.ndarray, what: str
) -> tuple[np.ndarray, np.ndarray, float]:
    """Observer gain of the H-infinity LMI for a given weight ``Q`` (Loukkas et al. 2017,
    eq. (26); Martinez et al. 2020, Theorem 1), minimising ``gamma^2``.

    Variables ``P = P'``, ``Y = P L`` and ``g = gamma^2``::

        [ -P + Q    0      A'P - C'Y' ]
        [  0       -g I    D_P'       ]  <=  0,   D_P = [P E, -Y F]
        [ P A - Y C  D_P   -P         ]

    ``Q`` is scaled to unit norm for the solver (the LMI is homogeneous in ``(P, Y, g, Q)``).
    Returns ``(P, L, gamma^2)``; raises :class:`DesignFailed` if Clarabel finds no solution.
    """
    import cvxpy as cp

    n, m = C.shape[1], C.shape[0]
    p = E.shape[1] + F.shape[1]
    scale = float(np.linalg.eigvalsh(sym(Q))[-1])
    if not scale > 0:
        raise DesignFailed(f"{what}: the weight Q must be positive definite")
    Qn = sym(Q) / scale
    P = cp.Variable((n, n), symmetric=True)
    Y = cp.Variable((n, m))
    g = cp.Variable()
    PAo = P @ A - Y @ C
    PD = cp.hstack([P @ E, -Y @ F])
    M = cp.bmat([
        [-P + Qn, np.zeros((n, p)), PAo.T],
        [np.zeros((p, n)), -g * np.eye(p), PD.T],
        [PAo, PD, -P],
    ])
    solve(cp.Problem(cp.Minimize(g), [0.5 * (M + M.T) << 0]), what)
    if P.value is None or Y.value is None or g.value is None:
        raise DesignFailed(f"{what}: the solver returned no point")
    Pv = sym(P.value)
    require_pd(Pv, f"{what} (P > 0)")
    L = np.linalg.solve(Pv, Y.value)
    return Pv * scale, L, float(g.value) * scale


def error_system(A, C, E, F, L) -> tuple[np.ndarray, np.ndarray]:
    """``Ao = A - L C`` and ``D = [E, -L F]`` of the estimation error."""
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
    V = V + max(0.0, 1e-9 * w[-1] - w[0]) * np.eye(V.shape[0])
    return sym(np.linalg.inv(V))


def loukkas_design(A, C, E, F, QW, quantile: float, what: str = "ESO-C") -> dict:
    """Algorithm 1 of Loukkas, Martinez & Meslem (2017).

    1. gain of the H-infinity LMI with ``Q = I``;
    2. ``Q = V^-1`` with ``V`` the error covariance of that gain for the disturbance
       covariance ``QW / chi2inv(quantile, n)`` (``QW`` the shape of an ellipsoid containing
       ``W``, read as the ``quantile`` confidence ellipsoid of a Gaussian);
    3. new gain of the LMI with this ``Q``; then ``Q`` maximising ``log det Q`` subject to the
       LMI for that gain (closed form, :func:`schur_bound`);
    4. ``lam`` from :func:`certify`.
    """
    n = A.shape[0]
    _, L, _ = hinf_lmi(A, C, E, F, np.eye(n), f"{what} (gain with Q = I)")
    Ao, _ = error_system(A, C, E, F, L)
    Q = _lyapunov_weight(Ao, QW / chi2.ppf(quantile, n), what)
    P, L, gamma2 = hinf_lmi(A, C, E, F, Q, f"{what} (gain with the covariance weight)")
    Ao, D = error_system(A, C, E, F, L)
    S, gamma2 = schur_bound(Ao, D, P, gamma2)
    Q, lam, gamma2 = certify(Ao, D, P, gamma2, S, what)
    return {"L": L, "P": P, "Q": Q, "gamma2": np.array(gamma2), "lam": np.array(lam)}


def martinez_design(A, C, E, F, variance: float = 1.0 / 3.0, what: str = "ESO-D") -> dict:
    """Algorithm 1 of Martinez, Loukkas & Meslem (2020).

    1. gain of the H-infinity LMI with ``Q = I``;
    2. ``Q = V^-1`` with ``Ao V Ao' - V + D W D' = 0``, ``W = variance I`` (eqs. (63)-(64):
       1/3 is the variance of a uniform distribution on [-1, 1]);
    3. new gain of the LMI with this ``Q``; ``lam`` from :func:`certify`.
    """
    n = A.shape[0]
    _, L, _ = hinf_lmi(A, C, E, F, np.eye(n), f"{what} (gain with Q = I)")
    Ao, D = error_system(A, C, E, F, L)
    Q = _lyapunov_weight(Ao, variance * (D @ D.T), what)
    P, L, gamma2 = hinf_lmi(A, C, E, F, Q, f"{what} (gain with the covariance weight)")
    Ao, D = error_system(A, C, E, F, L)
    Q, lam, gamma2 = certify(Ao, D, P, gamma2, Q, what)
    return {"L": L, "P": P, "Q": Q, "gamma2": np.array(gamma2), "lam": np.array(lam)}


def invariant_step(
    x: np.ndarray, level: float, Ao: np.ndarray, B: np.ndarray, L: np.ndarray, u: np.ndarray,
    y: np.ndarray, offset: np.ndarray, lam: float, drive: float,
) -> tuple[np.ndarray, float]:
    """One step of the observer and of its error level (Loukkas et al., eqs. (46)-(51)):
    ``xh+ = Ao xh + B u + L y + offset`` (``offset = c_W - L c_V``) and
    ``l+ = (1 - lam) l + drive`` (``drive = gamma^2 ||wbar||^2``)."""
    return Ao @ x + B @ u + L @ y + offset, (1.0 - lam) * level + drive
