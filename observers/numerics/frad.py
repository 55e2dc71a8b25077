"""F-radius gains of the zonotopic observers FRad-A, FRad-B, FRad-C (and CZN-B), pure functions.

Notation: a zonotope is ``(c, G)``; the measurement set of ``y`` is the strip (or the
intersection of strips) ``|C x - y| <= sigma``; ``E`` and ``F`` are the generator matrices of
the disturbance set ``W`` and the noise set ``V``.
"""

from __future__ import annotations

import numpy as np

from .linalg import psd_solve


def alamo_frad_gain(G: np.ndarray, c_row: np.ndarray, sigma: float) -> np.ndarray:
    """F-radius-minimising gain of one strip (Alamo et al. 2005, Sec. 6):
    ``lambda = G G' c' / (c G G' c' + sigma^2)``; zero where the denominator is zero (the set
    is flat along ``c`` and the strip exact: it cannot shrink the set, and any gain gives the
    same set)."""
    Gc = G.T @ c_row
    den = Gc @ Gc + sigma**2
    return (G @ Gc) / den if den > 0 else np.zeros(G.shape[0])


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
    return psd_solve(S, C @ R).T  # = R C' S^{-1}, S symmetric


def combastel_gain(P: np.ndarray, A: np.ndarray, C: np.ndarray, F: np.ndarray) -> np.ndarray:
    """F-radius-minimising gain of the set-propagation observer (Combastel, Automatica 2015,
    Sec. 4.3): ``L = A P C' (C P C' + F F')^{-1}`` with ``P = G G'`` of the current set."""
    S = C @ P @ C.T + F @ F.T
    return A @ psd_solve(S, C @ P).T

