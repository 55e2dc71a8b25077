"""Online phase kernels: measurement updates of Alanwar et al. (ECC 2022), pure functions.

* :func:`reverse_map` (Prop. 1 with Remark 1): the zonotope of states consistent with the
  measurement of one sensor;
* :func:`implicit_gain` and :func:`implicit_update` (Prop. 2): the parameterised enclosure
  of the predicted zonotope intersected with all measurement sets, with the closed-form
  minimiser of ``||G_hat||_F^2`` (the objective is quadratic in the weights).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..frad import wang_frad_gain
from .learning import output_inverse


@dataclass(frozen=True)
class Sensor:
    """One sensor ``y_i = C_i x + v_i``, ``v_i in <cv, Gv>``, with its SVD-based inverse."""

    rows: np.ndarray
    C: np.ndarray
    cv: np.ndarray
    Gv: np.ndarray
    Cinv: np.ndarray  # V1 Sigma^-1 P1'
    V2: np.ndarray  # basis of ker C_i


def split_sensors(C: np.ndarray, cv: np.ndarray, Gv: np.ndarray, sizes) -> list[Sensor]:
    """Sensors from stacked ``C`` and noise ``<cv, Gv>``: ``sizes`` lists the number of rows
    of each sensor (default: the finest split in which no noise generator couples two
    sensors).  Raises ``ValueError`` if a noise generator couples two sensors."""
    p = C.shape[0]
    if sizes is None:  # cut between rows i-1 and i unless a generator spans the cut
        nz = Gv != 0.0
        cuts = [i for i in range(1, p) if not np.any(nz[:i].any(axis=0) & nz[i:].any(axis=0))]
        sizes = np.diff([0, *cuts, p]).tolist()
    sizes = [int(s) for s in sizes]
    if sum(sizes) != p or min(sizes, default=1) < 1:
        raise ValueError(f"sensor sizes {sizes} must be positive and add up to {p} outputs")
    out, start = [], 0
    for s in sizes:
        rows = np.arange(start, start + s)
        other = np.setdiff1d(np.arange(p), rows)
        cols = np.any(Gv[rows] != 0.0, axis=0)
        if np.any(Gv[np.ix_(other, np.flatnonzero(cols))] != 0.0):
            raise ValueError(f"outputs {rows.tolist()} share noise generators with other "
                             "outputs; group them into one sensor")
        Cinv, V2 = output_inverse(C[rows])
        out.append(Sensor(rows, C[rows], cv[rows], Gv[np.ix_(rows, np.flatnonzero(cols))],
                          Cinv, V2))
        start += s
    return out


def reverse_map(sensor: Sensor, y: np.ndarray, c: np.ndarray, G: np.ndarray):
    r"""Prop. 1: centre and generators of ``Z_{x|y_i}``, with the null-space bound of Remark 1,
    ``M = ||V2' c|| + max_{x in <c, G>} ||x - c||_2`` (bounded by ``sum_j ||g_j||_2``).

    Notes
    -----
    With the SVD :math:`C_i = [P_1\ P_2] \operatorname{diag}(\Sigma, 0) [V_1\ V_2]^\top`
    (eq. (12)) and the noise :math:`\langle c_{v,i}, G_{v,i} \rangle`, eq. (16):

    .. math::

        c_{x|y^i} = V_1 \Sigma^{-1} P_1^\top (y^i(k) - c_{v,i}), \qquad
        G_{x|y^i} = \begin{bmatrix} V_1 \Sigma^{-1} P_1^\top G_{v,i} & M V_2 \end{bmatrix},

    where the null-space generators :math:`M V_2` cover the directions :math:`C_i` does not
    see, with (Remark 1, for the predicted set :math:`\langle c, G \rangle` it is
    intersected with; the radius bounded by
    :math:`\min(\sum_j \|g_j\|_2,\ \||G| \mathbf{1}\|_2)`, enlarged by a relative
    :math:`10^{-12}`)

    .. math::

        M = \|V_2^\top c\|_2 + \max_{x \in \langle c, G \rangle} \|x - c\|_2 .
    """
    ci = sensor.Cinv @ (y[sensor.rows] - sensor.cv)
    Gi = sensor.Cinv @ sensor.Gv
    if sensor.V2.shape[1]:
        rad = min(float(np.linalg.norm(G, axis=0).sum()),
                  float(np.linalg.norm(np.abs(G).sum(axis=1))))
        M = float(np.linalg.norm(sensor.V2.T @ c)) + rad
        Gi = np.hstack([Gi, M * (1 + 1e-12) * sensor.V2])
    return ci, Gi


def implicit_gain(G: np.ndarray, C: np.ndarray, Gv: np.ndarray) -> np.ndarray:
    r"""Closed-form ``argmin ||[(I - L C) G, -L Gv]||_F^2 = G G' C' (C G G' C' + Gv Gv')^-1``.

    Notes
    -----
    The objective of eq. (21) is quadratic in :math:`L`; its stationary point is

    .. math::

        L^\ast = \operatorname*{arg\,min}_{L}
        \left\| \begin{bmatrix} (I - L C) G & -L G_v \end{bmatrix} \right\|_F^2
        = G G^\top C^\top \left(C G G^\top C^\top + G_v G_v^\top\right)^{-1} .
    """
    return wang_frad_gain(G @ G.T, None, C, None, Gv)


def implicit_update(c, G, L, C, y, cv, Gv):
    r"""Prop. 2 (eqs. 18-19): ``c + L (y - C c - cv)``, ``[(I - L C) G, -L Gv]``.

    Notes
    -----
    .. math::

        \hat c = c + L (y - C c - c_v), \qquad
        \hat G = \begin{bmatrix} (I - L C) G & -L G_v \end{bmatrix} .
    """
    return c + L @ (y - C @ c - cv), np.hstack([G - L @ (C @ G), -L @ Gv])
