"""Mathematics of the zonotope-bundle observer ZB-A: the strip gains of its members.

Every member of the bundle is intersected with the measurement strips by the update
``c + L (y - C c)``, ``[(I - L C) G, L diag(sigma)]``
(:meth:`observers.sets.ZonotopeBundle.intersect_strips`); the members differ in their gain
and in their order reduction, so that their intersection is tighter than any one of them
(Althoff & Krogh, CDC-ECC 2011: different over-approximations of one set, intersected).

* ``"alamo"``: strip after strip, each with the F-radius gain of Alamo, Bravo, Camacho
  (Automatica 41(6), 2005, Sec. 6), composed into one n x m gain
  (:func:`sequential_frad_gain`; the same set as FRad-A's update);
* ``"box"``: strip after strip, each with the gain that minimises the interval hull of the
  updated member: row ``j`` of the new generators is ``G_j - lambda_j c'G`` plus the
  generator ``lambda_j sigma``, so ``lambda_j`` minimises the hull radius
  ``sum_k |G_jk - lambda_j g_k| + |lambda_j| sigma`` (``g = G' c``), a weighted median of the
  points ``G_jk / g_k`` (weights ``|g_k|``) and ``0`` (weight ``sigma``),
  :func:`box_gain`; a greedy per-step choice that keeps the box small where the F-radius
  gains keep the generators small, so the two members differ;
* ``"wang"``: all strips at once with the F-radius gain ``P C' (C P C' + diag(sigma^2))^-1``,
  ``P = G G'`` (Wang, Puig, Cembrano, Automatica 93, 2018, with the predicted set's
  generators; :func:`wang_strip_gain`).
"""

from __future__ import annotations

import numpy as np

from .frad import alamo_sequential_gain, wang_frad_gain

#: (reduction, gain) of the members, in order: member i uses entry i
MEMBER_STRATEGIES = (("girard", "alamo"), ("girard", "box"), ("pca", "wang"), ("pca", "box"))


def sequential_frad_gain(G: np.ndarray, C: np.ndarray, sigma: np.ndarray) -> np.ndarray:
    """The n x m gain ``L`` of the strips of ``C`` applied one after the other, each with
    Alamo's F-radius gain on the current ``P = G G'``
    (:func:`observers.numerics.frad.alamo_sequential_gain`, FRad-A's formula)."""
    return alamo_sequential_gain(G @ G.T, C, sigma)[0]


def wang_strip_gain(G: np.ndarray, C: np.ndarray, sigma: np.ndarray) -> np.ndarray:
    """The F-radius gain of all strips at once, ``P C' (C P C' + diag(sigma^2))^-1`` with
    ``P = G G'``: :func:`observers.numerics.frad.wang_frad_gain` on the member's own
    generators (``A = None``) with the noise generators ``diag(sigma)``."""
    return wang_frad_gain(G @ G.T, None, C, None, np.diag(np.asarray(sigma, float)))


def weighted_median(points: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """Per row, a minimiser of ``sum_k weights_k |lambda - points_jk|`` (a weighted median;
    ``points``: rows x K, ``weights``: K, non-negative, not all zero)."""
    order = np.argsort(points, axis=1)
    p = np.take_along_axis(points, order, axis=1)
    w = weights[order]
    cum = np.cumsum(w, axis=1)
    k = np.argmax(cum >= 0.5 * cum[:, -1:], axis=1)
    return p[np.arange(points.shape[0]), k]


def box_gain(G: np.ndarray, C: np.ndarray, sigma: np.ndarray) -> np.ndarray:
    """The n x m gain of the strips of ``C`` applied one after the other, strip ``i`` with
    the gain minimising each component of the interval hull of the updated zonotope (see the
    module docstring), composed as in :func:`sequential_frad_gain`."""
    n, m = G.shape[0], C.shape[0]
    L = np.zeros((n, m))
    Gc = G
    for i in range(m):
        ci = C[i]
        g = ci @ Gc
        keep = np.abs(g) > 0
        if not keep.any():
            lam = np.zeros(n)
        else:
            pts = np.hstack([Gc[:, keep] / g[keep], np.zeros((n, 1))])
            w = np.concatenate([np.abs(g[keep]), [sigma[i]]])
            lam = weighted_median(pts, w)
        if i:
            L[:, :i] -= np.outer(lam, ci @ L[:, :i])
        L[:, i] = lam
        Gc = np.hstack([Gc - np.outer(lam, g), (lam * sigma[i])[:, None]])
    return L


def member_gain(kind: str, G: np.ndarray, C: np.ndarray, sigma: np.ndarray) -> np.ndarray:
    r"""Gain of a member with generators ``G`` (``kind``: ``"alamo"``, ``"box"`` or
    ``"wang"``).

    Notes
    -----
    ``"wang"``: all strips at once (Wang, Puig, Cembrano 2018),
    :math:`\Lambda = P C^\top (C P C^\top + \operatorname{diag}(\sigma)^2)^{-1}`,
    :math:`P = G G^\top`.  ``"alamo"`` and ``"box"``: strip after strip, row :math:`c_i^\top`
    with a gain :math:`\lambda_i` on the current generators, composed into one
    :math:`n \times m` gain with :math:`I - \Lambda C = \prod_i (I - \lambda_i c_i^\top)`
    (the column of each earlier strip multiplied by the later factors):

    .. math::

        \lambda_i^{\text{alamo}} = \frac{P c_i}{c_i^\top P c_i + \sigma_i^2},
        \qquad
        \lambda_{i,j}^{\text{box}} = \operatorname*{arg\,min}_{\lambda}
        \sum_k |G_{jk} - \lambda g_k| + |\lambda| \sigma_i, \quad g = G^\top c_i,

    the first the F-radius gain of Alamo et al. (2005, Sec. 6), the second, per row
    :math:`j`, the weighted median that minimises the :math:`j`-th radius of the interval
    hull of the updated member.
    """
    if kind == "alamo":
        return sequential_frad_gain(G, C, sigma)
    if kind == "box":
        return box_gain(G, C, sigma)
    return wang_strip_gain(G, C, sigma)
