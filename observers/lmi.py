"""Helpers for offline LMI/SDP designs: solve with cvxpy + Clarabel, then verify in numpy.

A design is accepted only if the matrix inequalities hold for the *returned numbers*,
checked with ``numpy.linalg.eigvalsh``; a solver's "optimal" status is not enough.
"""

from __future__ import annotations

import numpy as np

from .errors import DesignFailed

ACCEPTED = ("optimal", "optimal_inaccurate")


def solve(problem, what: str, **solver_options) -> str:
    """Solve a cvxpy problem with Clarabel; returns the status or raises :class:`DesignFailed`."""
    import cvxpy as cp

    try:
        problem.solve(solver=cp.CLARABEL, **solver_options)
    except cp.error.SolverError as exc:
        raise DesignFailed(f"{what}: solver failed ({exc})") from None
    status = problem.status
    if status not in ACCEPTED:
        raise DesignFailed(f"{what}: the SDP is {status}")
    return status


def sym(M: np.ndarray) -> np.ndarray:
    """Symmetric part ``(M + M') / 2``."""
    M = np.asarray(M, dtype=float)
    return 0.5 * (M + M.T)


def min_eig(M: np.ndarray) -> float:
    """Smallest eigenvalue of the symmetric part of ``M``."""
    return float(np.linalg.eigvalsh(sym(M))[0])


def require_psd(M: np.ndarray, what: str, tol: float = 1e-8) -> float:
    """Check ``M >= -tol * scale`` (scale = max(1, |M|_max)); returns the smallest eigenvalue."""
    lam = min_eig(M)
    scale = max(1.0, float(np.abs(M).max()))
    if not np.isfinite(lam) or lam < -tol * scale:
        raise DesignFailed(f"{what}: verification failed (smallest eigenvalue {lam:.3g})")
    return lam


def require_pd(M: np.ndarray, what: str, margin: float = 0.0) -> float:
    """Check ``M > margin`` strictly; returns the smallest eigenvalue."""
    lam = min_eig(M)
    if not np.isfinite(lam) or lam <= margin:
        raise DesignFailed(f"{what}: verification failed (smallest eigenvalue {lam:.3g})")
    return lam


def require_nsd(M: np.ndarray, what: str, tol: float = 1e-8) -> float:
    """Check ``M <= tol * scale``; returns the largest eigenvalue."""
    return -require_psd(-np.asarray(M, float), what, tol)


def spectral_radius(M: np.ndarray) -> float:
    """Largest absolute eigenvalue."""
    return float(np.max(np.abs(np.linalg.eigvals(M)))) if np.size(M) else 0.0
