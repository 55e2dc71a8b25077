"""MHE-PR: moving-horizon set estimation for nonlinear systems, by polyhedral relaxations.

The nonlinear counterpart of ``MHE``: at step k the interval hull of an enclosure of the
states consistent with the last ``window`` steps of the record, started from a sound box of
``x_{k-L}``; the window's dynamics and measurements are relaxed over sound boxes of its states
into one constrained zonotope, and the boxes are tightened by re-bounding every state of the
window (:mod:`observers.numerics.nmhe`, where the mathematics and references are).

Family ``moving-horizon``: not a row of the papers' tables (``observers: all`` leaves it out);
the nonlinear comparison and the frontier study name it.
"""

from __future__ import annotations

from collections import deque
from functools import partial

import numpy as np

from ..base import Observer
from ..families import as_zonotope
from ..numerics import nmhe as nn
from ..numerics.mhe import WindowRecord
from ..options import Choice, Integer, Number
from ..registry import register
from ..sets import EmptySet, HullLP, Interval
from .mhe import CZN_MARGIN

#: relative enlargement of the measurement noise against the rounding of the window's
#: constraint data: ``MHE``'s (with the noise on a vertex of its set the true state lies on
#: the boundary of the window's set)
MARGIN = CZN_MARGIN


@register(
    "MHE-PR", family="moving-horizon", set_type="interval", ready_for_control=False,
    floor="filtered",
    reference="set-valued moving-horizon estimation (Shamma & Tu, IEEE TAC 44(2), 1999; Rao, "
              "Rawlings & Mayne, IEEE TAC 48(2), 2003) of a nonlinear window enclosed by lifted "
              "polyhedral relaxations (Rego, Raffo, Terra & Scott, arXiv 2504.00130, 2025) as "
              "one constrained zonotope (Scott et al., Automatica 69, 2016), boxes tightened "
              "by re-bounding (Caprara & Locatelli, Math. Program. 125, 2010), issue 40",
)
class MHEPR(Observer):
    r"""Moving-horizon set estimator for nonlinear systems (lifted polyhedral relaxations).

    ``step`` returns the interval hull (an :class:`~observers.sets.Interval`) of an enclosure
    of the states consistent with ``u[k-L..k-1]``, ``y[k-L..k]`` and a sound box of
    ``x_{k-L}`` (``X0`` while ``k <= L``).

    Options
    -------
    window : int
        Window length L (transitions; 1 <= L <= 50, default 5).
    sweeps : int
        Bound-tightening passes before the final hull (0 <= sweeps <= 10, default 1): each
        re-bounds every state of the window with the window's own LPs, intersects the boxes
        and relaxes again over them.
    tangents : {1, 3}
        Tangents of each convex or concave operation: at the midpoint (1, default) or also at
        both ends of its interval (3).
    shrink : float
        A further pass is skipped once a pass shrank the sum of the boxes' radii by less than
        this share (default 1e-3).

    Notes
    -----
    With :math:`s = \max(0, k - L)` and :math:`\mathcal{B}_j` a sound box of :math:`x_j`,
    the estimate encloses

    .. math::

        \mathcal{S}_k = \{x_k \mid x_s \in \mathcal{P}_s,\
        x_{j+1} = f(x_j, u_j) + w_j,\ w_j \in \mathcal{W},\
        y_j - h(x_j) \in \mathcal{V},\ x_j \in \mathcal{B}_j\ (s \le j \le k)\},

    each :math:`f` and :math:`h` replaced by its relaxation over :math:`\mathcal{B}_j`.  The
    boxes of the earlier states are the estimator's own smoothed hulls; that of the newest
    state, under a nonlinear output, the hull of the window before :math:`y_k`.
    """

    OPTIONS = {"window": Integer(5, low=1, high=50),
               "sweeps": Integer(1, low=0, high=10),
               "tangents": Choice(1, (1, 3)),
               "shrink": Number(1e-3, low=0.0, high=1.0)}
    SCENARIO_OPTIONS = ()  # no zonotope order or reduction: nothing is reduced
    REQUIRES = ("W", "V", "X0")
    MODELS = ("nonlinear",)
    MODEL_NOTE = " (for a linear one use MHE, which is exact over its window)"

    def design(self) -> None:
        from ..numerics.relaxation import Factorable

        s = self.system
        d = s.derived
        self._f = Factorable(d.expressions, *d.symbols, what="f")
        C = s.output_matrix
        if C is not None:
            self._h = np.asarray(C, dtype=float)
        else:
            dh = s.derived_h
            self._h = Factorable(dh.expressions, *dh.symbols, what="h")
        self.L = int(self.options["window"])
        X0, W, V = (as_zonotope(getattr(s, a), a) for a in ("X0", "W", "V"))
        self._X0 = (X0.c, X0.G)
        self._X0_box = X0.interval()
        self._W = (W.c, W.G)
        self._V = (V.c, V.G * (1.0 + MARGIN))

    def reset(self) -> None:
        super().reset()
        L = self.L
        self._record = WindowRecord(L, self.system.nu)
        #: sound boxes (lo, hi) of the states max(0, k-L) .. k-1 (smoothed by later windows)
        self._boxes: deque[tuple[np.ndarray, np.ndarray]] = deque(maxlen=L)
        self._solver = HullLP()

    def step(self, u_prev, y) -> Interval:
        y = self._measurement(y)
        k = self.k
        self._record.append(self._input(u_prev) if k else None, y)
        lo, hi = self._window(k)
        self.k += 1
        return Interval(lo, hi)

    # -- the window ---------------------------------------------------------------------------
    def _start(self, k: int) -> tuple[np.ndarray, np.ndarray]:
        """The prior of the window's first state: ``X0``, or the box of step ``k - L``."""
        if k <= self.L:
            return self._X0
        return nn.box_factors(*self._boxes[0])

    def _window(self, k: int) -> tuple[np.ndarray, np.ndarray]:
        """The hull of the window ending at step ``k``; the boxes of its earlier states are
        replaced by their smoothed ones.

        The newest state's box is read only by a nonlinear output's relaxation: it is then
        ``X0``'s at step 0, else the hull of the window before ``y_k`` (built once, the
        measurement added to it after its hull)."""
        u, y = self._record.inputs(), self._record.outputs()
        T = len(y) - 1  # transitions in the window: min(k, L)
        boxes = list(self._boxes)  # steps k - T .. k - 1
        opts = self.options
        build = partial(nn.build_window, self._f, self._h, self._start(k), u=u, W=self._W,
                        V=self._V, tangents=opts["tangents"], k=k)
        if isinstance(self._h, np.ndarray):  # a linear output: the newest box is not read
            boxes.append((np.full(self.system.n, -np.inf), np.full(self.system.n, np.inf)))
            win = build(boxes, y=y)
        elif k == 0:
            boxes.append((self._X0_box.lo, self._X0_box.hi))
            win = build(boxes, y=y)
        else:
            pred = build(boxes + [None], y=y[:-1])
            I = nn.window_hulls(pred, [T], self._solver)[0]
            boxes.append((I.lo, I.hi))
            win = nn.measure_newest(pred, self._h, boxes[T], y[-1], self._V,
                                    opts["tangents"], k)
        for sweep in range(opts["sweeps"] + 1):
            if sweep:
                win = build(boxes, y=y)
            if sweep == opts["sweeps"]:  # the final hull: the newest state only
                I = nn.window_hulls(win, [T], self._solver)[0]
                boxes[T] = _meet(boxes[T], (I.lo, I.hi), k)
                break
            hulls = nn.window_hulls(win, range(T + 1), self._solver)
            bounded = [j for j, b in enumerate(boxes) if np.isfinite(b[0]).all()]
            before = _width(boxes, bounded)
            boxes = [_meet(b, (h.lo, h.hi), k) for b, h in zip(boxes, hulls, strict=True)]
            if before - _width(boxes, bounded) <= opts["shrink"] * before:
                break  # converged: boxes[T] is final
        for j in range(T):  # smoothed boxes, as sound as the stored ones
            self._boxes[j] = boxes[j]
        self._boxes.append(boxes[T])
        return boxes[T]


def _width(boxes, js) -> float:
    """The sum of the widths of the boxes ``js``."""
    return sum(float(np.sum(boxes[j][1] - boxes[j][0])) for j in js)


def _meet(a, b, k: int) -> tuple[np.ndarray, np.ndarray]:
    """The intersection of two sound boxes of one state (both contain it: they meet)."""
    lo, hi = np.maximum(a[0], b[0]), np.minimum(a[1], b[1])
    if np.any(lo > hi):
        i = int(np.argmax(lo - hi))
        raise EmptySet(f"step {k}: two sound boxes of a state of the window do not meet in "
                       f"x{i + 1} ({lo[i]:.17g} > {hi[i]:.17g}): the record is inconsistent "
                       "with the model")
    return lo, hi
