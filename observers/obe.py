"""Numeric kernels of the ellipsoidal strip-based observers ESO-A and ESO-B (pure functions).

Notation (optimal bounding ellipsoids, Dasgupta & Huang 1987): the estimate is the ellipsoid
``{x : (x - q)' P^-1 (x - q) <= s2}``, i.e. centre ``q`` and shape matrix ``s2 P``; the level
``s2`` ("sigma^2") is carried besides ``P``.  The measurement set of ``y`` is
``{x : ||y - C x||^2 <= rho}`` after whitening (``C``, ``y`` premultiplied by a factor ``T``
of the inverse noise shape matrix, ``T'T = V^-1``, which gives ``rho = 1``), or a Euclidean
ball of radius ``gamma`` around ``y`` (``rho = gamma^2``, Gollamudi et al.).

The ``*_cora`` kernels reproduce CORA's ``@ellipsoid/intersectStrip.m`` (methods
``'Gollamudi1996'`` and ``'Liu2016'``) including its deviations from the papers; they exist
only to reproduce CORA's stored results.
"""

from __future__ import annotations

import numpy as np

from .sets.ellipsoid import obe_weight, outer_sum, quadratic_update

#: CORA's cap of the Gollamudi weight (``alpha`` in ``@ellipsoid/intersectStrip.m``)
CORA_ALPHA = 1e-4
#: CORA's initial level ``sigma^2`` of ESO-A and ESO-B
CORA_SIGMA2_0 = 0.3


def liu_prediction(
    q: np.ndarray, P: np.ndarray, s2: float, A: np.ndarray, shift: np.ndarray, QW: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Prediction of Liu, Zhao & Wu (2016, eq. (21)): the minimal-trace outer ellipsoid of
    ``A E(q, s2 P) + shift + E(0, QW)``, returned as ``(q, P)`` at the unchanged level ``s2``:
    ``P = A P A' / (1 - p) + QW / (s2 p)``."""
    APA = A @ P @ A.T
    return A @ q + shift, outer_sum(s2 * APA, QW, "min-trace") / s2


def obe_update(
    q: np.ndarray, P: np.ndarray, s2: float, Ct: np.ndarray, yt: np.ndarray, rho: float,
    alpha: float = 1.0,
) -> tuple[np.ndarray, np.ndarray, float, float]:
    """Selective OBE measurement update (Gollamudi et al. 1996; Liu et al. 2016).

    The set is updated only if that can decrease the level, ``s2 + ||delta||^2 > rho``
    (``delta = yt - Ct q``); the weight is ``lam = min(alpha, nu)`` with ``nu`` from
    :func:`~observers.sets.ellipsoid.obe_weight` and ``g = lambda_max(Ct P Ct')``.
    Returns ``(q, P, s2, lam)``, ``lam = 0`` when nothing was updated.
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
    """CORA's Gollamudi update (ALGORITHMS.md, ESO-A).

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
    """CORA's Liu update (ALGORITHMS.md, ESO-B), ``T`` the upper Cholesky factor of
    ``V^-1``.

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
