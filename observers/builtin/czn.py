"""Constrained-zonotope observers CZN-A (Scott et al. 2016) and CZN-B (Alanwar et al.).

Both predict ``A S + B u + W``, intersect *exactly* with the measurement set of ``y[k]``
(the constraints keep what a zonotope would lose), then reduce the order with CORA's lifted
reduction.  They differ only in the parametrisation of the intersection:

* CZN-A: generalised intersection with ``{x : y - C x in V}`` (Scott et al., Prop. 1);
* CZN-B: intersection with the strips ``|C x - y| <= sigma`` written with the F-radius gain
  of Wang et al. (Alanwar et al., arXiv 2010.11097), which shapes the generators that the
  later reductions act on.

Beyond CORA (which lets the number of constraints grow by m per step, so that the LPs of the
interval hull grow without bound), the option ``max_constraints`` bounds it (default: the
constraints of the last two measurements, ``2 m``): the prediction is reduced first, the
intersection with ``y[k]`` is exact, then the box of the generator variables is shrunk to the
bounds the constraints imply (exact), and the oldest surplus constraints are folded into the
generators and the newer constraints by a least-squares shear of the lifted zonotope and
dropped
(:func:`observers.sets.conzono_ops.fold_constraints`).  The newest measurements stay exact;
what an old measurement told is kept as far as a zonotope update with an F-radius gain keeps
it.  ``max_constraints=None`` gives CORA's behaviour (and order of operations: intersect,
then reduce), which the conformance tests use.

Interval hulls: every returned set carries the observer's :class:`~observers.sets._lp.HullLP`,
so the runner's ``S.interval()`` solves its 2n LPs together with the batched dual simplex of
:mod:`observers.sets._dual_simplex` (compiled by numba when available; HiGHS, kept alive across
steps, for an LP it does not finish and for sets with more than
:data:`~observers.sets._lp.BATCHED_MAX_ROWS` constraints); every bound is the weak-duality
bound of a dual point, hence sound whatever the solver does.
"""

from __future__ import annotations

from abc import abstractmethod

import numpy as np

from ..families import Linearised, ZonotopeObserver
from ..options import Choice, Integer, Number
from ..registry import register
from ..sets import ConZonotope, HullLP, HullLPStats
from ..sets import conzono_ops as ops
from .frad import WangGainVariant

#: default bound on the number of constraints, as a multiple of the number of outputs m
DEFAULT_CONSTRAINT_STEPS = 2


class ConZonotopeStripObserver(Linearised, ZonotopeObserver):
    """Shared loop: predict, intersect exactly, bound the constraints, lifted reduction.

    Nonlinear systems: the prediction linearises at the centre of the constrained zonotope
    and encloses the remainder over the interval hull of its zonotope ``(c, G)`` (a superset
    of the constrained zonotope, so the enclosure stays sound).

    Options
    -------
    order, reduction
        Order and zonotope strategy of the lifted reduction (as CORA).
    max_constraints : int, "auto" or None
        Bound on the number of constraints kept after each step; ``"auto"`` is ``2 m`` (the
        measurements of the last two steps), ``None`` keeps all of them (CORA: m more per
        step, with CORA's order of intersection and reduction).
    hull_solver : {"auto", "batched", "highs"}
        LP solver of the interval hulls and support values of the returned sets
        (:class:`~observers.sets.HullLP`); the bounds are sound with each of them.
    margin : float
        Relative enlargement of the noise set in the exact intersection (default 1e-7).  An
        exact intersection keeps the true state on the boundary of the estimate when the
        noise sits on the vertices of V and W (found by the adversarial soundness audit), and
        floating-point rounding (~1e-16 relative) of the constraint data can then cut it off
        or make the set empty.  With the margin the true state lies strictly inside every
        measurement set, by far more than the rounding.  ``0`` is CORA's exact behaviour.
    """

    OPTIONS = {
        "max_constraints": Integer("auto", low=0, allow_none=True, special=("auto",)),
        "hull_solver": Choice("auto", HullLP.SOLVERS),
        "margin": Number(1e-7, low=0, high=1e-3, high_open=True),
    }

    def design(self) -> None:
        super().design()
        k = self.options["max_constraints"]
        m = self.C.shape[0]
        self.max_constraints = DEFAULT_CONSTRAINT_STEPS * m if k == "auto" else k
        inflate = 1.0 + float(self.options["margin"])
        self.F_meas = self.F * inflate  # noise generators of the measurement set
        self.sigma_meas = self.sigma * inflate  # strip half-widths

    def reset(self) -> None:
        super().reset()
        self._state: tuple[np.ndarray, ...] | None = None
        self._lp = HullLP(self.options["hull_solver"])

    @property
    def hull_stats(self) -> HullLPStats:
        """Work of the interval-hull LPs of the sets returned since the last :meth:`reset`
        (a run): LPs solved, simplex iterations, LPs handed to HiGHS."""
        return self._lp.stats

    @abstractmethod
    def intersect(self, c, G, A, b, y):
        """Exact intersection of ``(c, G, A, b)`` with the measurement set of ``y``."""

    def step(self, u_prev, y) -> ConZonotope:
        y = self._measurement(y)
        if self._state is None:  # X0 intersected with y[0], not reduced (as CORA)
            G0 = self.X0.G
            c, G, A, b = self.intersect(self.X0.c, G0, np.zeros((0, G0.shape[1])),
                                        np.zeros(0), y)
        else:
            u = self._input(u_prev)
            c, G, A, b = self._state
            # the prediction strategy linearises at the centre c (for a nonlinear system its
            # remainder box is taken over the interval hull of the zonotope (c, G), which
            # encloses the constrained zonotope)
            self.A, d, R = self.prediction(c, G, u, self.k)
            c = self.A @ c + d + self.W.c
            G = np.hstack([self.A @ G, self.E, R])
            A = np.hstack([A, np.zeros((A.shape[0], self.E.shape[1] + R.shape[1]))])
            if self.max_constraints is None:  # CORA: intersect, then reduce
                c, G, A, b = self.intersect(c, G, A, b, y)
                c, G, A, b = ops.lifted_reduce(c, G, A, b, self.order, self._reduce)
            else:  # reduce the prediction, intersect exactly, fold the oldest constraints
                c, G, A, b = ops.lifted_reduce(c, G, A, b, self.order, self._reduce)
                c, G, A, b = self.intersect(c, G, A, b, y)
                c, G, A, b = ops.fold_constraints(c, G, A, b, self.max_constraints)
        self._state = (c, G, A, b)
        self.k += 1
        return ConZonotope._trusted(c, G, A, b, self._lp)


@register(
    "CZN-A", family="strip", set_type="conzonotope", ready_for_control=False,
    reference="Scott, Raimondo, Marseglia, Braatz, Automatica 69, 2016",
)
class CZNA(ConZonotopeStripObserver):
    """Constrained zonotopes, exact generalised intersection with the measurement set."""

    def design(self) -> None:
        super().design()
        self._y_shift = self.V.c  # y - C x in V  <=>  C x in (y - c_V) + (-F) xi_v

    def intersect(self, c, G, A, b, y):
        F = self.F_meas
        return ops.intersect(c, G, A, b, y - self._y_shift, -F, np.zeros((0, F.shape[1])),
                             np.zeros(0), self.C)


@register(
    "CZN-B", family="strip", set_type="conzonotope", ready_for_control=False,
    reference="Alanwar, Rath, Said, Johansson, Althoff, arXiv 2010.11097; Scott et al. 2016",
)
class CZNB(WangGainVariant, ConZonotopeStripObserver):
    """Constrained zonotopes, strip intersection parametrised by the F-radius gain.

    Options
    -------
    variant : {"cora", "textbook"}
        As for FRad-B (:class:`~observers.builtin.frad.WangGainVariant`): ``"cora"``
        (default) computes the gain from the predicted set's ``G G'`` with ``A`` applied once
        more, ``R = A G G' A' + E E'``; ``"textbook"`` uses ``R = G G'``.
    """

    def intersect(self, c, G, A, b, y):
        return ops.intersect_strips(c, G, A, b, self.C, y, self.sigma_meas, self.wang_gain(c, G))


@register(
    "CZN-MV", family="strip", set_type="conzonotope", ready_for_control=False,
    reference="Rego, Raffo, Scott, Raimondo, Automatica 111, 108614, 2020 (mean-value "
              "extension); Scott et al. 2016",
)
class CZNMV(CZNA):
    """CZN-A with the mean-value extension of Rego et al. (2020) as prediction.

    Beyond CORA.  For a nonlinear system the prediction encloses ``f(x) - f(c)`` by the
    interval Jacobian over the box of the estimate, ``J(B) (x - c)``: its midpoint is applied
    to the set and its radius adds the box ``rad J(B) |x - c|``
    (:class:`observers.prediction.MeanValuePrediction`).  It needs first derivatives only
    (no Hessian), and is tighter than the second-order remainder when the curvature is large
    relative to the set; on linear systems it is CZN-A.
    """

    LINEARISATION = "mean-value"
