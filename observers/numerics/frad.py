"""F-radius gains of the zonotopic observers FRad-A, FRad-B, FRad-C (and CZN-B), pure functions.

Notation: a zonotope is ``(c, G)``; the measurement set of ``y`` is the strip (or the
intersection of strips) ``|C x - y| <= sigma``; ``E`` and ``F`` are the generator matrices of
the disturbance set ``W`` and the noise set ``V``.
"""

from __future__ import annotations

import numpy as np

from ..sets.zonotope import strip_generators
from .linalg import psd_solve


def alamo_frad_gain(G: np.ndarray, c_row: np.ndarray, sigma: float) -> np.ndarray:
    r"""F-radius-minimising gain of one strip (Alamo et al. 2005, Sec. 6):
    ``lambda = G G' c' / (c G G' c' + sigma^2)``; zero where the denominator is zero (the set
    is flat along ``c`` and the strip exact: it cannot shrink the set, and any gain gives the
    same set).

    The gain of the strip :math:`|c\,x - y| \le \sigma` (:math:`c` a row of :math:`C`) that
    minimises the F-radius :math:`\|[(I - \lambda c)G,\ \lambda\sigma]\|_F` of the
    enclosure of intersection method I (Sec. 3.1 of Althoff & Rath 2021, FRad-A of its
    Table 2): setting the gradient of
    :math:`\operatorname{trace}\bigl((I - \lambda c)GG^T(I - \lambda c)^T\bigr) +
    \sigma^2\lambda^T\lambda` to zero gives

    .. math::

        \lambda^\ast = \frac{GG^Tc^T}{c\,GG^Tc^T + \sigma^2}.
    """
    Gc = G.T @ c_row
    den = Gc @ Gc + sigma**2
    return (G @ Gc) / den if den > 0 else np.zeros(G.shape[0])


def wang_frad_gain(
    P: np.ndarray, A: np.ndarray | None, C: np.ndarray, E: np.ndarray, F: np.ndarray
) -> np.ndarray:
    r"""F-radius gain for all strips at once (Wang, Puig, Cembrano, Automatica 2018):
    ``Lam = R C' (C R C' + F F')^{-1}`` with ``R = A P A' + E E'``.

    The gain :math:`\Lambda` of intersection method II (FRad-B of Table 2 of Althoff &
    Rath 2021) that minimises the F-radius of the corrected set, in the form of a Kalman
    gain with the generator "covariance" :math:`GG^T` in place of a covariance:

    .. math::

        R = APA^T + EE^T, \qquad \Lambda = RC^T\left(CRC^T + FF^T\right)^{-1},

    with :math:`P = GG^T` (:math:`R = P` when ``A`` is ``None``).

    ``P`` is ``G G'`` of the set the gain is computed from.  With ``A=None`` the prior
    covariance ``R = P`` is used unchanged (for callers passing the predicted set's ``G G'``).
    """
    R = P if A is None else A @ P @ A.T + E @ E.T
    S = C @ R @ C.T + F @ F.T
    return psd_solve(S, C @ R).T  # = R C' S^{-1}, S symmetric


def combastel_gain(P: np.ndarray, A: np.ndarray, C: np.ndarray, F: np.ndarray) -> np.ndarray:
    r"""F-radius-minimising gain of the set-propagation observer (Combastel, Automatica 2015,
    Sec. 4.3): ``L = A P C' (C P C' + F F')^{-1}`` with ``P = G G'`` of the current set.

    The gain of FRad-C (Sec. 3.2 of Althoff & Rath 2021, citing Combastel's Sec. 4.3), the
    one that minimises the F-radius of :math:`\mathcal{S}_{k+1}` in eq. 8 for the current
    set :math:`\mathcal{S}_k = c \oplus G\mathcal{B}^r`:

    .. math::

        L_k = AGG^TC^T\left(CGG^TC^T + FF^T\right)^{-1}.
    """
    S = C @ P @ C.T + F @ F.T
    return A @ psd_solve(S, C @ P).T


def alamo_sequential_gain(
    P: np.ndarray, C: np.ndarray, sigma: np.ndarray,
    c: np.ndarray | None = None, y: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray | None]:
    r"""The n x m gain ``L`` of the strips ``|C x - y| <= sigma`` applied one after the other,
    strip ``i`` with Alamo's F-radius gain (:func:`alamo_frad_gain`) on the current
    ``P = G G'``; with a centre ``c`` (and the measurement ``y``), also the centre after the
    strips.

    Strip ``i`` with row :math:`c_i`:

    .. math::

        p = Pc_i^T, \quad s = c_ip + \sigma_i^2, \quad \lambda_i = p / s, \quad
        P \leftarrow P - p\lambda_i^T, \quad L \leftarrow [(I - \lambda_ic_i)L,\ \lambda_i],

    so that :math:`\prod_i (I - \lambda_i c_i) = I - LC` and the added generators are
    :math:`L\operatorname{diag}(\sigma)` (the column of each earlier strip is multiplied by
    the later factors); the centre takes :math:`c \leftarrow c + \lambda_i(y_i - c_ic)` strip
    by strip.  A strip with :math:`s = 0` (the set flat along :math:`c_i`, the strip exact)
    gets the zero gain.  The one formula of FRad-A (:func:`alamo_frad_strips`) and of the
    bundle member ``"alamo"`` (:func:`observers.numerics.bundle.member_gain`); ``P`` is not
    modified.

    Returns
    -------
    L : numpy.ndarray
        n x m gain.
    c : numpy.ndarray or None
        The centre after the strips (``None`` without ``c``).
    """
    n, m = P.shape[0], C.shape[0]
    P = P.copy()
    L = np.empty((n, m))
    for i in range(m):
        ci = C[i]
        p = P @ ci
        s = ci @ p + sigma[i] ** 2
        lam = p / s if s > 0 else np.zeros(n)
        if c is not None:
            c = c + lam * (y[i] - ci @ c)
        if i:  # (I - lam ci') applied to the columns of the earlier strips
            L[:, :i] -= np.outer(lam, ci @ L[:, :i])
        L[:, i] = lam
        P -= np.outer(p, lam)
    return L, c


def alamo_frad_strips(
    c: np.ndarray, G: np.ndarray, C: np.ndarray, y: np.ndarray, sigma: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    r"""All strips of ``|C x - y| <= sigma``, one after the other, each with the F-radius gain
    of :func:`alamo_frad_gain` (FRad-A), computed on ``P = G G'`` instead of ``G``.

    For strip :math:`i` with row :math:`c_i`:

    .. math::

        p = Pc_i^T, \quad s = c_ip + \sigma_i^2, \quad \lambda_i = p / s, \quad
        c \leftarrow c + \lambda_i(y_i - c_ic),

        P \leftarrow P - pp^T / s, \quad L \leftarrow [(I - \lambda_ic_i)L,\ \lambda_i],

    and the generators of the result are
    :math:`[(I - LC)G,\ L\operatorname{diag}(\sigma)]`.

    Strip ``i`` with row ``c_i``, ``p = P c_i`` and ``s = c_i' p + sigma_i^2`` has the gain
    ``lambda_i = p / s``; the update ``G <- [(I - lambda_i c_i') G, sigma_i lambda_i]`` of
    :func:`observers.families.strip_update` changes ``P`` into ``P - p p' / s``.  The product
    of the factors is ``prod_i (I - lambda_i c_i') = I - L C`` with the n x m matrix ``L``
    whose column ``i`` is ``lambda_i`` multiplied by the later factors (``L <- [(I - lambda_i
    c_i') L, lambda_i]``), and the added generators are ``L diag(sigma)``.  So the loop runs on
    n x n and n x m matrices and touches the n x r generators once: ``[(I - L C) G,
    L diag(sigma)]`` (as ``G - L (C G)`` when m < n / 2: fewer flops).  Mathematically the
    same set as applying :func:`alamo_frad_gain` and the strip update strip by strip (equal up
    to rounding).  A strip with ``s = 0`` (the set is flat along ``c_i`` and the strip exact)
    gets the zero gain, as in :func:`alamo_frad_gain`.
    """
    L, c = alamo_sequential_gain(G @ G.T, C, sigma, c, y)
    return c, strip_generators(G, L, C, sigma)
