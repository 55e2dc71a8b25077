"""INT-CP: the interval observer of nonlinear (and linear) systems, by inclusion functions and
contractors (mathematics in :mod:`observers.numerics.interval`)."""

from __future__ import annotations

from time import perf_counter

import numpy as np

from ..base import Observer
from ..enclosures import NotDerivable, Smooth, first_order, mean_value
from ..errors import Diverged, Unsupported
from ..families import as_zonotope
from ..numerics.interval import (
    ForwardBackward,
    contract_linear,
    down,
    intersect,
    linear_box,
    mean_value_box,
    midpoint_radius,
    shrank,
    up,
)
from ..numerics.relaxation import Factorable
from ..options import Choice, Integer, Number
from ..registry import register
from ..sets import EmptySet, Interval, SetError
from ..sets.interval_arith import Ival

INCLUSIONS = ("intersect", "natural", "mean-value")


def _hull(S) -> tuple[np.ndarray, np.ndarray]:
    """Interval hull of a zonotope rounded outward (``c +- sum |G|`` in floating point)."""
    Z = as_zonotope(S, "set")
    r = np.abs(Z.G).sum(axis=1)
    r = up(r + 2 * (Z.G.shape[1] + 2) * np.finfo(float).eps * r)
    return down(Z.c - r), up(Z.c + r)


@register(
    "INT-CP", family="interval", set_type="interval", ready_for_control=False,
    floor="filtered",
    reference="Kieffer, Jaulin, Walter, Int. J. Adapt. Control Signal Process. 16(3), 2002; "
              "Benhamou, Goualard, Granvilliers, Puget, ICLP 1999 (HC4 contractor)",
)
class IntervalContractor(Observer):
    r"""Box observer: inclusion function of f, forward-backward contraction with y (online).

    Prediction: the intersection of the natural interval extension of ``f`` and its
    mean-value form over the box (exact box image for a linear system), plus the box of W.
    Correction: contraction of the box with ``h(x) in y - V`` (row-wise linear contractor for
    ``y = C x + v``; forward-backward propagation on the expression of ``h`` and the linear
    contractor of its mean-value enclosure for a nonlinear output), repeated while the box
    shrinks.  See :mod:`observers.numerics.interval`.

    Not one of the observers of Althoff & Rath 2021 (it has no equation number there); in the
    notation of Kieffer, Jaulin and Walter (2002), with :math:`p` and :math:`r` the midpoint
    and radius of the box :math:`[x]_{k-1}`, :math:`[f]` the natural interval extension and
    :math:`J([x])` the interval Jacobian:

    .. math::

        [x]^p_k = \Bigl([f]([x]_{k-1}, u_{k-1}) \cap \bigl(f(p, u_{k-1}) +
        J([x]_{k-1})\,([x]_{k-1} - p)\bigr)\Bigr) + \operatorname{BOX}(\mathcal{W})

        [x]_k = \mathcal{C}\bigl([x]^p_k\bigr), \qquad
        \mathcal{C}: \text{contract } [x] \text{ with }
        h(x) \in y_k - \operatorname{BOX}(\mathcal{V})

    (for a linear system the prediction is the exact box :math:`Ap + Bu_{k-1} \pm |A|\,r`
    plus the box of :math:`\mathcal{W}`); the contraction is repeated while it narrows the
    box.

    Options
    -------
    inclusion : {"intersect", "natural", "mean-value"}
        Inclusion function of a nonlinear ``f``: both intersected (default) or one of them.
    sweeps : int
        Most contraction sweeps per measurement.
    shrink : float
        Another sweep runs only if the last one narrowed some component by more than this
        fraction of its width.
    """

    REQUIRES = ("W", "V", "X0")
    OPTIONS = {"inclusion": Choice("intersect", INCLUSIONS),
               "sweeps": Integer(10, low=1),
               "shrink": Number(1e-3, low=0, high=1)}

    def design(self) -> None:
        s = self.system
        self.linear = bool(getattr(s, "is_linear", True))
        who = self.name
        if self.linear:
            if not (hasattr(s, "A") and hasattr(s, "B")):
                raise Unsupported(f"{who} needs A and B of a linear system")
            self.A, self.B = np.asarray(s.A, float), np.asarray(s.B, float)
        else:
            try:
                s.derived  # noqa: B018 - the interval evaluation of f
            except ValueError as exc:  # systems.ModelError: f cannot be traced
                raise Unsupported(f"{who} evaluates f in interval arithmetic: {exc}") from None
            self._f = Smooth(s, "f")
        C = None
        if getattr(s, "output_is_linear", True):
            C = s.C
        else:
            C = getattr(s, "output_matrix", None)
        self.C = None if C is None else np.asarray(C, float)
        self._hc4 = None
        if self.C is None:
            self._h = Smooth(s, "h")
            try:
                d = s.derived_h
                self._hc4 = ForwardBackward(Factorable(d.expressions, d.symbols[0], (), "h"),
                                            s.n)
            except (ValueError, Unsupported):  # no tree: the mean-value contractor only
                self._hc4 = None
        self.X0 = _hull(s.X0)
        self.W = _hull(s.W)
        self.V = _hull(s.V)
        self.inclusion = self.options["inclusion"]
        self.sweeps = int(self.options["sweeps"])
        self.rel = float(self.options["shrink"])

    def reset(self) -> None:
        super().reset()
        self._box: tuple[np.ndarray, np.ndarray] | None = None
        #: accumulated seconds per phase since the last reset
        self.phase_times = {"prediction": 0.0, "update": 0.0}

    # -- prediction ------------------------------------------------------------------------
    def predict(self, lo: np.ndarray, hi: np.ndarray, u: np.ndarray):
        """A box containing ``f(x, u) + w`` for every ``x`` in ``[lo, hi]``, ``w`` in W."""
        if self.linear:
            Bu = linear_box(self.B, u, u, np.zeros(self.B.shape[0]))
            flo, fhi = linear_box(self.A, lo, hi, np.zeros(lo.size))
            flo, fhi = down(flo + Bu[0]), up(fhi + Bu[1])
        else:
            flo, fhi = self._nonlinear_image(lo, hi, u)
        return down(flo + self.W[0]), up(fhi + self.W[1])

    def _nonlinear_image(self, lo, hi, u):
        s, k = self.system, self.k
        try:
            s.check_domain(lo, hi)
        except Diverged as exc:
            raise type(exc)(str(exc), step=k) if exc.step is None else exc from None
        boxes = []
        derived = s.derived
        if self.inclusion in ("intersect", "natural"):
            try:
                v = derived.value_bounds(lo, hi, u)
                boxes.append((np.asarray(v.lo, float), np.asarray(v.hi, float)))
            except SetError:  # an operation left its domain over the wide box
                pass
        if self.inclusion in ("intersect", "mean-value"):
            p, r = midpoint_radius(lo, hi)
            try:
                fp = derived.value_bounds(p, p, u)
                Jlo, Jhi = s.jacobian_bounds(lo, hi, u)
                boxes.append(mean_value_box(Ival(fp.lo, fp.hi), Jlo, Jhi, r))
            except SetError:
                pass
        if not boxes:
            raise Diverged("no inclusion function of f could be evaluated over the box",
                           step=k)
        flo, fhi = boxes[0]
        for b in boxes[1:]:
            flo, fhi = intersect(flo, fhi, *b, "the inclusion functions of f")
        if not (np.all(np.isfinite(flo)) and np.all(np.isfinite(fhi))):
            raise Diverged("non-finite enclosure of f", step=k)
        return flo, fhi

    # -- correction ------------------------------------------------------------------------
    def contract(self, lo: np.ndarray, hi: np.ndarray, y: np.ndarray):
        """The box ``[lo, hi]`` contracted with ``h(x) in y - V`` (sweeps while it shrinks)."""
        ylo, yhi = down(y - self.V[1]), up(y - self.V[0])
        for _ in range(self.sweeps):
            lo2, hi2 = lo, hi
            if self.C is not None:
                lo2, hi2 = contract_linear(lo2, hi2, self.C, ylo, yhi)
            else:
                lo2, hi2 = self._contract_nonlinear(lo2, hi2, ylo, yhi)
            more = shrank(lo, hi, lo2, hi2, self.rel)
            lo, hi = lo2, hi2
            if not more:
                break
        return lo, hi

    def _contract_nonlinear(self, lo, hi, ylo, yhi):
        if self._hc4 is not None:
            try:
                lo, hi = self._hc4.contract(lo, hi, ylo, yhi)
            except EmptySet:
                raise
            except SetError:  # h cannot be evaluated over the box (sqrt reaching 0): skip
                pass
        try:
            H, d, rad = mean_value(self._h, lo, hi, np.zeros(0), self.k)
        except NotDerivable:  # h given with hand-written derivatives only
            H, d, rad = first_order(self._h, lo, hi, np.zeros(0), self.k)
        return contract_linear(lo, hi, H, down(ylo - d - rad, 2), up(yhi - d + rad, 2))

    def step(self, u_prev, y) -> Interval:
        y = self._measurement(y)
        t0 = perf_counter()
        if self._box is None:
            lo, hi = self.X0
        else:
            lo, hi = self.predict(*self._box, self._input(u_prev))
        t1 = perf_counter()
        lo, hi = self.contract(lo, hi, y)
        self.phase_times["prediction"] += t1 - t0
        self.phase_times["update"] += perf_counter() - t1
        self._box = (lo, hi)
        self.k += 1
        return Interval(lo, hi)
