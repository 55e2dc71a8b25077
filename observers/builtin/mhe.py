"""MHE: moving-horizon set estimation, exact over the last L measurements.

At step k the estimate is the interval hull of the states consistent with the window of the
last ``window`` steps, started from a sound box of ``x_{k-L}``: the estimator's own hull of
that step, intersected with the hull of an ``inner`` observer run alongside if one is named.
Steps ``0 .. L`` see the whole record from ``X0`` and are exact (the ``Exact`` reference's
hulls); afterwards the estimate contains the exact consistent set and approaches it as L
grows.  The mathematics, the two formulations and the references (Shamma & Tu 1999; Rao,
Rawlings & Mayne 2003; Scott et al. 2016) are in :mod:`observers.numerics.mhe`.

Family ``moving-horizon``: not a row of the papers' tables (``observers: all`` of a
configuration leaves it out, :data:`observers.registry.OUTSIDE_ALL`); name it in a
configuration, and see the frontier study (``python -m benchmarks.studies.frontier``) for
its accuracy against its cost as L grows.  Linear systems only.
"""

from __future__ import annotations

from collections import deque

import numpy as np

from ..families import LinearModelObserver
from ..numerics import mhe as nm
from ..options import Choice, Integer
from ..registry import create, register
from ..sets import EmptySet, HullLP, Interval

#: observers that may run alongside as the ``inner`` bound of the window's first state
INNER = ("none", "FRad-A", "FRad-B", "CZN-A", "CZN-B")
#: relative enlargement of the measurement noise in the constrained-zonotope formulation (as
#: the CZN observers' ``margin``): with the noise on a vertex of V the true state lies on
#: the boundary of the exact window, where the rounding of the constraint data (relative
#: 1e-16) could cut it off; with it, strictly inside
CZN_MARGIN = 1e-7


@register(
    "MHE", family="moving-horizon", set_type="interval", ready_for_control=False,
    floor="filtered",
    reference="set-valued observer (Shamma & Tu, IEEE TAC 44(2), 1999) over a window of L "
              "steps, a set as arrival cost (Rao, Rawlings & Mayne, IEEE TAC 48(2), 2003); "
              "window as an unreduced constrained zonotope (Scott et al., Automatica 69, "
              "2016), issue 29",
)
class MHE(LinearModelObserver):
    r"""Moving-horizon set estimator: the exact hull of the last ``window`` steps' data.

    ``step`` returns the interval hull (an :class:`~observers.sets.Interval`) of the states
    consistent with ``u[k-L..k-1]``, ``y[k-L..k]`` and a sound box of ``x_{k-L}``.

    Options
    -------
    window : int
        Window length L (transitions; 1 <= L <= 1000, default 5: 1.14x the exact
        floor on the 6-tank record, 1.03x on the 6-D vehicle).
    formulation : {"czn", "lp"}
        ``"czn"`` (default): the window as a constrained zonotope, its hull by the batched
        dual simplex (cheapest for short windows; the measurement noise enlarged by
        :data:`CZN_MARGIN`, relative 1e-7, against rounding); ``"lp"``: the sparse LPs of the exact
        reference in a ring of warm-started HiGHS models (cheaper for long windows and large
        systems; every range rounded outward).
    inner : {"none", "FRad-A", "FRad-B", "CZN-A", "CZN-B"}
        An observer run alongside (its default options) whose hull of step ``k - L`` is
        intersected with the estimator's own; ``"none"`` (default) uses the own hull only.

    Notes
    -----
    With :math:`L` the window and :math:`s = \max(0, k - L)` its first step, the estimate is
    the interval hull of the consistent set of eq. (3) of Althoff & Rath (2021) restricted to
    the window and started from a sound box :math:`\mathcal{P}_s` of :math:`x_s`
    (:math:`\mathcal{P}_0 = \mathcal{X}_0`; for :math:`k > L` the estimator's own hull of
    step :math:`s`, intersected with the ``inner`` observer's):

    .. math::

        \mathcal{S}_k = \{x_k \mid x_s \in \mathcal{P}_s,\
        x_{j+1} = A x_j + B u_j + w_j,\ w_j \in \mathcal{W}\ (s \le j < k),\
        y_j - C x_j \in \mathcal{V}\ (s \le j \le k)\} .

    Formulation ``"czn"``: the exact constrained-zonotope recursion over the window, nothing
    reduced (:math:`\mathcal{P}_s = \langle c_s, G_s \rangle`,
    :math:`\mathcal{W} = \langle c_W, G_W \rangle`,
    :math:`\mathcal{V} = \langle c_V, \tilde G_V \rangle` with
    :math:`\tilde G_V = (1 + 10^{-7}) G_V`), one block of factors per step:

    .. math::

        c_{j+1} = A c_j + B u_j + c_W, \qquad
        G_{j+1} = \begin{bmatrix} A G_j & G_W \end{bmatrix}, \qquad
        C G_j \xi + \tilde G_V \nu_j = y_j - C c_j - c_V \quad (s \le j \le k),

    so that :math:`\mathcal{S}_k = \{c_k + G_k \xi \mid \text{the } (L+1) m
    \text{ constraints},\ \|(\xi, \nu)\|_\infty \le 1\}`, and its hull is :math:`2n`
    LPs, :math:`\underline{x}_{k,i} = \min e_i^\top x_k` and
    :math:`\overline{x}_{k,i} = \max e_i^\top x_k` over it, each bounded by the
    weak-duality value of a dual point.  Formulation ``"lp"``: the same LPs with the states
    as variables (the sparse form of the ``Exact`` reference).
    """

    OPTIONS = {"window": Integer(5, low=1, high=1000),
               "formulation": Choice("czn", ("czn", "lp")),
               "inner": Choice("none", INNER)}
    SCENARIO_OPTIONS = ()  # no zonotope order or reduction: nothing is reduced
    REQUIRES = ("C", "W", "V", "X0")
    MODELS = ("linear",)
    MODEL_NOTE = ": the states consistent with a nonlinear window form no polytope"

    def design(self) -> None:
        super().design()
        self.L = int(self.options["window"])
        self._sets = tuple((S.c, S.G) for S in (self.X0, self.W, self.V))
        self._V_czn = (self.V.c, self.V.G * (1.0 + CZN_MARGIN))

    def reset(self) -> None:
        super().reset()
        L = self.L
        self._record = nm.WindowRecord(L, self.B.shape[1])
        #: own hulls of steps k-L .. k-1 (at step k, before it is appended)
        self._own: deque[tuple[np.ndarray, np.ndarray]] = deque(maxlen=L)
        #: inner hulls of steps k-L .. k (appended first thing at step k)
        self._inner_hulls: deque[tuple[np.ndarray, np.ndarray] | None] = deque(maxlen=L + 1)
        self._inner = (None if self.options["inner"] == "none"
                       else create(self.options["inner"], self.system))
        self._lp = (nm.WindowHullLP((self.A, self.B, self.C, *self._sets), window=L)
                    if self.options["formulation"] == "lp" else None)
        self._solver = HullLP()

    def _inner_step(self, u, y) -> None:
        """Step the inner observer; keep its hull (None once it failed: no bound)."""
        hull = None
        if self._inner is not None and (not self._inner_hulls or
                                        self._inner_hulls[-1] is not None):
            try:
                I = self._inner.step(u, y).interval()
                if np.all(np.isfinite(I.lo)) and np.all(np.isfinite(I.hi)):
                    hull = (np.asarray(I.lo, float), np.asarray(I.hi, float))
            except Exception:  # an inner failure only loses its bound, never the estimate
                hull = None
        self._inner_hulls.append(hull)

    def _prior(self) -> tuple[np.ndarray, np.ndarray] | None:
        """The inner observer's hull of the window's first step (None: no inner bound)."""
        if self._inner is None or len(self._inner_hulls) <= self.L:
            return None
        return self._inner_hulls[0]

    def step(self, u_prev, y) -> Interval:
        y = self._measurement(y)
        k = self.k
        u = None if k == 0 else self._input(u_prev)
        self._inner_step(u, y)
        self._record.append(u, y)
        if self._lp is not None:
            h = self._lp.first(y) if k == 0 else self._lp.advance(u, y, prior=self._prior())
            lo, hi = h.filt_lo, h.filt_hi
        else:
            lo, hi = self._window_hull(k)
        self._own.append((lo, hi))
        self.k += 1
        return Interval(lo, hi)

    def _window_hull(self, k: int) -> tuple[np.ndarray, np.ndarray]:
        """The hull of the window's constrained zonotope (sound from dual points)."""
        if k <= self.L:  # the whole record from X0
            start = self._sets[0]
        else:
            lo, hi = self._own[0]
            prior = self._prior()
            if prior is not None:
                lo, hi = np.maximum(lo, prior[0]), np.minimum(hi, prior[1])
                if np.any(lo > hi):  # two sound bounds that do not meet: no state fits
                    i = int(np.argmax(lo - hi))
                    raise EmptySet(f"step {k}: the hulls of step {k - self.L} of MHE and of "
                                   f"its inner observer do not meet in x{i + 1}: the record "
                                   "is inconsistent with the model")
            start = nm.box_factors(lo, hi)
        c, G, A, b = nm.window_conzonotope(
            (self.A, self.B, self.C, start, self._sets[1], self._V_czn),
            self._record.inputs(), self._record.outputs())
        # arrays built here from finite data (the measurements and hulls are checked): the
        # hull of ConZonotope(c, G, A, b).interval(), without building the set
        return self._solver.hull(c, G, A, b)
