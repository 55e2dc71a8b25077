"""F-radius gains of the zonotopic observers FRad-A, FRad-B, FRad-C (and CZN-B), pure functions.

Notation: a zonotope is ``(c, G)``; the measurement set of ``y`` is the strip (or the
intersection of strips) ``|C x - y| <= sigma``; ``E`` and ``F`` are the generator matrices of
the disturbance set ``W`` and the noise set ``V``.
"""

from __future__ import annotations

import numpy as np


def alamo_frad_gain(G: np.ndarray, c_row: np.ndarray, sigma: float) -> np.ndarray:
    """F-radius-minimising gain of one strip (Alamo et al. 2005, Sec. 6):
    ``lambda = G G' c' / (c G G' c' + sigma^2)``."""
    Gc = G.T @ c_row
    return (G @ Gc) / (Gc @ Gc + sigma**2)


def wang_frad_gain(
    P: np.ndarray, A: np.ndarray | None, C: np.ndarray, E: np.ndarray, F: np.ndarray
) -> np.ndarray:
    """F-radius gain for all strips at once (Wang, Puig, Cembrano, Automatica 2018):
    ``Lam = R C' (C R C' + F F')^{-1}`` with ``R = A P A' + E E'``.

    ``P`` is ``G G'`` of the set the gain is computed from.  With ``A=None`` the prior
    covariance ``R = P`` is used unchanged (for callers passing the predicted set's ``G G'``).
    """
    R = P if A is None else A @ P @ A.T + E @ E.T
    S = C @ R @ C.T + F @ F.T
    return np.linalg.solve(S, C @ R).T  # = R C' S^{-1}, S symmetric


def combastel_gain(P: np.ndarray, A: np.ndarray, C: np.ndarray, F: np.ndarray) -> np.ndarray:
    """F-radius-minimising gain of the set-propagation observer (Combastel, Automatica 2015,
    Sec. 4.3): ``L = A P C' (C P C' + F F')^{-1}`` with ``P = G G'`` of the current set."""
    S = C @ P @ C.T + F @ F.T
    return A @ np.linalg.solve(S, C @ P).T



def alamo_frad_strips(
    c: np.ndarray, G: np.ndarray, C: np.ndarray, y: np.ndarray, sigma: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """All strips of ``|C x - y| <= sigma``, one after the other, each with the F-radius gain
    of :func:`alamo_frad_gain` (FRad-A), computed on ``P = G G'`` instead of ``G``.

    Strip ``i`` with row ``c_i``, ``p = P c_i`` and ``s = c_i' p + sigma_i^2`` has the gain
    ``lambda = p / s``; the update ``G <- [(I - lambda c_i') G, sigma_i lambda]`` of
    :func:`observers.families.strip_update` changes ``P`` into ``P - p p' / s``.  So the loop
    runs on n x n matrices: it accumulates ``T = prod (I - lambda c_i')`` and the new columns
    ``sigma_i lambda`` (each multiplied by the later factors), and touches the n x r generator
    matrix once, ``[T G, new columns]``.  Mathematically the same set as applying
    :func:`alamo_frad_gain` and the strip update strip by strip (equal up to rounding).
    """
    n, m = G.shape[0], C.shape[0]
    P = G @ G.T
    T = np.eye(n)
    new = np.empty((n, m))
    for i in range(m):
        ci = C[i]
        p = P @ ci
        s = ci @ p + sigma[i] ** 2
        lam = p / s
        c = c + lam * (y[i] - ci @ c)
        # (I - lam ci') X = X - lam (ci' X) for X = T and the columns added so far
        T -= np.outer(lam, ci @ T)
        if i:
            new[:, :i] -= np.outer(lam, ci @ new[:, :i])
        new[:, i] = lam * sigma[i]
        P -= np.outer(p, p / s)
    out = np.empty((n, G.shape[1] + m))
    np.matmul(T, G, out=out[:, : G.shape[1]])
    out[:, G.shape[1]:] = new
    return c, out
