"""Non-guaranteed baseline of Alanwar et al. (ECC 2022, Sec. IV): N4SID subspace
identification from the offline experiment, then a Kalman filter whose 3-sigma ellipsoid is
reported as the "set".  Its containment failures are counted by the runner, not treated as bugs.

Identification uses the maintained ``nfoursid`` package (MIT; its ``NFourSID`` class computes
the subspace estimate with the PO-MOESP instrumental variable and least squares for A, B, C,
D).  The identified model is in an arbitrary state basis; it is mapped to the physical one
through the known experiment sensors ``C_train`` (full column rank): ``x = C_train^+ C_id
x_id``.  The filter uses the covariances of *uniform* noise on the known sets (``G G' / 3``)
for W, V and X0, i.e. more statistical knowledge than the set-based observers need
(``tuning="paper"`` uses the published code's larger covariances instead).
"""

from __future__ import annotations

import numpy as np

from ..base import Observer
from ..errors import DesignFailed
from ..families import as_zonotope
from ..numerics.datadriven import check_training
from ..numerics.linalg import psd_solve
from ..options import Choice, Integer, Number, training_data
from ..registry import register
from ..sets import Ellipsoid


def identify_n4sid(u: np.ndarray, z: np.ndarray, C_train: np.ndarray, n: int,
                   block_rows: int) -> tuple[np.ndarray, np.ndarray]:
    """``(A, B)`` in the physical basis from inputs ``u`` (T x m) and outputs ``z``
    (T+1 x p) by ``nfoursid``; raises :class:`DesignFailed` if that is impossible."""
    import pandas as pd
    from nfoursid.nfoursid import NFourSID

    if np.linalg.matrix_rank(C_train) < n:
        raise DesignFailed("the N4SID baseline maps the identified model to the physical state "
                           "through the experiment sensors, which need full column rank")
    T, m = u.shape
    p = z.shape[1]
    cols_y = [f"y{i}" for i in range(p)]
    cols_u = [f"u{i}" for i in range(m)]
    df = pd.DataFrame(np.hstack([z[:T], u]), columns=cols_y + cols_u)
    try:
        sid = NFourSID(df, output_columns=cols_y, input_columns=cols_u,
                       num_block_rows=block_rows)
        sid.subspace_identification()
        ss, _ = sid.system_identification(rank=n)
    except (ValueError, np.linalg.LinAlgError) as exc:
        raise DesignFailed(f"N4SID identification failed: {exc}") from None
    S = np.linalg.pinv(C_train) @ ss.c
    if np.linalg.cond(S) > 1e12:
        raise DesignFailed("N4SID returned a state basis that the sensors cannot resolve")
    Sinv = np.linalg.inv(S)
    return S @ ss.a @ Sinv, S @ ss.b


@register("KF-N4SID", family="stochastic", set_type="ellipsoid", ready_for_control=False,
          guaranteed=False,
          reference="Van Overschee & De Moor 1994 (N4SID) + Kalman filter, as in Alanwar et "
                    "al., ECC 2022, Sec. IV")
class KalmanN4SID(Observer):
    r"""N4SID model + Kalman filter, ``sigma``-ellipsoid of the posterior (not guaranteed).

    The baseline of Sec. IV of Alanwar et al. 2022 (which states no formula for it), written
    here as the code runs it.  With the identified :math:`(\hat A, \hat B)`, the centres
    :math:`c_W`, :math:`c_V` of the disturbance and noise sets and their covariances
    :math:`Q`, :math:`R` (``tuning``), one step is the prediction

    .. math::

        x^-_k = \hat A\,x_{k-1} + \hat B\,u_{k-1} + c_W, \qquad
        P^-_k = \hat A\,P_{k-1}\hat A^T + Q,

    the measurement update (Joseph form)

    .. math::

        K_k = P^-_kC^T\left(CP^-_kC^T + R\right)^{-1}, \qquad
        x_k = x^-_k + K_k\,(y_k - Cx^-_k - c_V),

        P_k = (I - K_kC)\,P^-_k\,(I - K_kC)^T + K_kRK_k^T,

    and the reported set
    :math:`\{x \mid (x - x_k)^TP_k^{-1}(x - x_k) \le \sigma^2\}`; step 0 updates
    :math:`(x_0, P_0)` from the centre and covariance of :math:`\mathcal{X}_0`.

    Options
    -------
    training : object with ``u``, ``z``, ``C``, ``Gamma``
        The offline experiment used for identification.
    block_rows : int
        Block rows of the Hankel matrices of N4SID.
    sigma : float
        Ellipsoid ``{x : (x - x_hat)' P^-1 (x - x_hat) <= sigma^2}`` (3 in the paper).
    tuning : {"uniform", "paper"}
        Noise covariances: those of uniform noise on W and V (``G G' / 3``, default), or the
        published code's ``Q = 5 r_w I``, ``R = r_v I`` (``r`` the radii of W and V), which
        overstates both noises.
    """

    REQUIRES = ("C", "W", "V", "X0")
    OPTIONS = {"training": training_data(), "block_rows": Integer(4, low=1),
               "sigma": Number(3.0, low=0, low_open=True),
               "tuning": Choice("uniform", ("uniform", "paper"))}

    def design(self) -> None:
        s = self.system
        self.C = np.asarray(s.C, dtype=float)
        n, nu = self.C.shape[1], int(s.nu)
        data = check_training(self.options["training"], n, nu, self.name)
        self.A, self.B = identify_n4sid(data.u, data.z, data.C, n,
                                        int(self.options["block_rows"]))
        W, V, X0 = (as_zonotope(getattr(s, a), a) for a in ("W", "V", "X0"))
        if self.options["tuning"] == "paper":
            self.Q = np.diag(5.0 * W.interval().radius())
            self.R = np.diag(V.interval().radius())
        else:
            self.Q, self.R = W.G @ W.G.T / 3.0, V.G @ V.G.T / 3.0
        self.cw, self.cv = W.c, V.c
        self.x0, self.P0 = X0.c, X0.G @ X0.G.T / 3.0

    def reset(self) -> None:
        super().reset()
        self._x: np.ndarray | None = None
        self._P: np.ndarray | None = None

    def step(self, u_prev, y) -> Ellipsoid:
        y = self._measurement(y)
        if self._x is None:
            x, P = self.x0, self.P0
        else:
            u = self._input(u_prev)
            x = self.A @ self._x + self.B @ u + self.cw
            P = self.A @ self._P @ self.A.T + self.Q
        S = self.C @ P @ self.C.T + self.R
        K = psd_solve(S, self.C @ P).T  # R = 0 (an exact sensor) makes S singular
        x = x + K @ (y - self.C @ x - self.cv)
        IKC = np.eye(x.size) - K @ self.C
        P = IKC @ P @ IKC.T + K @ self.R @ K.T  # Joseph form
        P = 0.5 * (P + P.T)
        self._x, self._P = x, P
        self.k += 1
        return Ellipsoid(x, self.options["sigma"] ** 2 * P)
