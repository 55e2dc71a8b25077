"""Interval observer of Tang, Wang, Wang, Raissi and Shen (TAC 2019, Alg. 1; Alg. 1 of
Althoff & Rath, Automatica 2021): a Luenberger point estimate plus an interval bound of its
error.

With ``M = A - L C`` and ``D = W + (-L) V``, the error ``e_k = x_k - x^_k`` of the point
estimate ``x^_{k+1} = A x^_k + B u_k + L (y_k - C x^_k)`` lies in
``M^k (X0 - c0) + sum_{j<k} M^j D``; Alg. 1 bounds it by
``BOX(M^k (X0 - c0)) + sum_{j<k} BOX(M^j D)``, boxing each term before summing so that no
wrapping accumulates.  That bound is exactly the interval hull of the *unreduced*
set-propagation estimate with the same gain, obtained in interval arithmetic: the state of the
loop is two generator matrices of fixed size (``M^k G_X0`` and ``M^k [G_W, -L G_V]``) and two
vectors (the centre and radius of the summed boxes), so a step costs one matrix product.
CORA instead sums the boxes into a zonotope whose generator count grows by n every step.

Conventions (``step(u_prev, y)`` receives ``u[k-1]`` and ``y[k]``):

* ``"aligned"`` (default): step k returns the bound of ``x_k`` (Alg. 1, line 5, at k); it
  needs ``y[k-1]`` only, so it is ready before ``y[k]`` arrives.  Step 0 returns ``X0``.
* ``"cora-lagged"``: CORA's ``priv_observe_interval`` stores the bound of step k-1 as its
  set of step k (``R{i+1}`` is computed before ``x^`` is updated), so its sets need not contain
  ``x_k``.  Offered only to reproduce CORA's numbers.

Deviation from CORA in both conventions: the error set starts from ``X0 - c0`` (CORA uses
``X0`` itself, which counts a non-zero centre twice; all benchmark ``X0`` are centred at 0).
"""

from __future__ import annotations

import numpy as np

from .errors import OptionError
from .families import LinearModelObserver
from .sets import Interval

CONVENTIONS = ("aligned", "cora-lagged")


def box_radius(G: np.ndarray) -> np.ndarray:
    """Radius of the interval hull of a zonotope with generators ``G``: ``sum |G|`` by rows."""
    return np.abs(G).sum(axis=1)


def luenberger_step(x: np.ndarray, A, B, C, L, u: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Point estimate update ``A x + B u + L (y - C x)`` (Alg. 1, line 6)."""
    return A @ x + B @ u + L @ (y - C @ x)


def interval_bound(x: np.ndarray, G_x: np.ndarray, c_wv: np.ndarray, r_wv: np.ndarray):
    """Bounds ``x^ + BOX(S_x) + S_wv`` (Alg. 1, lines 4-5) as ``(lo, hi)``.

    ``G_x`` are the generators of the centred initial-error term ``M^k (X0 - c0)``;
    ``(c_wv, r_wv)`` are the centre and radius of ``S_wv``, the summed disturbance boxes.
    """
    c = x + c_wv
    r = box_radius(G_x) + r_wv
    return c - r, c + r


class IntervalObserver(LinearModelObserver):
    """Alg. 1 with the constant gain ``self.L`` (set by ``design``); returns intervals.

    Subclasses provide ``L`` (n x ny), e.g. through :class:`~observers.offline.OfflineGain`.
    """

    OPTIONS = {"convention": "aligned"}
    L: np.ndarray

    def validate_options(self) -> None:
        if self.options["convention"] not in CONVENTIONS:
            raise OptionError(f"{self.name}: convention must be one of "
                              f"{', '.join(map(repr, CONVENTIONS))}, "
                              f"got {self.options['convention']!r}")

    def design(self) -> None:
        """Collect the system data used online (subclasses extend with ``super().design()``)."""
        super().design()
        self.lagged = self.options["convention"] == "cora-lagged"

    def reset(self) -> None:
        super().reset()
        L = np.asarray(self.L, dtype=float)
        self._M = self.A - L @ self.C
        self._x = self.X0.c.copy()  # x^_0 = centre of X0
        # generators propagated by M: [initial error | D = W + (-L) V], one product per step
        self._G = np.hstack([self.X0.G, self.W.G, -L @ self.V.G])
        self._r0 = self.X0.G.shape[1]
        self._cD = self.W.c - L @ self.V.c  # centre of M^k D
        self._c_wv = np.zeros(self.A.shape[0])  # S_wv: centre and radius of the summed boxes
        self._r_wv = np.zeros(self.A.shape[0])
        self._y_prev: np.ndarray | None = None
        self._pending: Interval | None = None  # last bound (cora-lagged returns it one step late)

    def _bound(self) -> Interval:
        return Interval(*interval_bound(self._x, self._G[:, : self._r0], self._c_wv,
                                        self._r_wv))

    def _advance(self, u: np.ndarray) -> None:
        """From step k-1 to k (Alg. 1, lines 6-9)."""
        self._x = luenberger_step(self._x, self.A, self.B, self.C, self.L, u, self._y_prev)
        self._c_wv = self._c_wv + self._cD
        self._r_wv = self._r_wv + box_radius(self._G[:, self._r0 :])
        self._cD = self._M @ self._cD
        self._G = self._M @ self._G

    def step(self, u_prev, y):
        y = self._measurement(y)
        if self._y_prev is None:  # step 0: X0 itself (as CORA)
            out = self.X0
            if self.lagged:
                self._pending = self._bound()
        else:
            self._advance(self._input(u_prev))
            bound = self._bound()
            if self.lagged:
                out, self._pending = self._pending, bound
            else:
                out = bound
        self._y_prev = y
        self.k += 1
        return out
