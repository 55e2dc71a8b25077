"""Shared online loops of the zonotopic observer families.

* :class:`StripBasedObserver`: prediction ``A S + B u + W``, intersection with the
  measurement strips (method I: strip by strip, :class:`PerStripObserver`; method II: all
  strips at once, :class:`AllStripsObserver`), order reduction.
* :class:`PropagationObserver`: ``S+ = (A - L C) S + B u + L y + (-L) V + W`` with a constant
  or adaptive gain, then order reduction.

Concrete observers only supply the gain (or the intersection) and, if any, an offline design.
"""

from __future__ import annotations

from abc import abstractmethod

import numpy as np

from .base import Observer
from .errors import ObserverError, OptionError
from .sets import Interval, SetError, Zonotope, get_reduction
from .sets.reduction import check_order
from .strip import propagate, strip_update


def as_zonotope(S, what: str) -> Zonotope:
    """Zonotope view of a system set (zonotopes and intervals are accepted)."""
    if isinstance(S, Zonotope):
        return S
    if isinstance(S, Interval):
        return Zonotope.from_interval(S)
    raise ObserverError(f"{what} must be a Zonotope or an Interval, got {type(S).__name__}")


class LinearModelObserver(Observer):
    """Observers that read the linear model: ``design`` collects ``A, B, C`` and the sets
    ``X0, W, V`` as zonotopes (subclasses extend it with ``super().design()``)."""

    def design(self) -> None:
        s = self.system
        self.A = np.asarray(s.A, dtype=float)
        self.B = np.asarray(s.B, dtype=float)
        self.C = np.asarray(s.C, dtype=float)
        self.X0 = as_zonotope(s.X0, "X0")
        self.W = as_zonotope(s.W, "W")
        self.V = as_zonotope(s.V, "V")


class ZonotopeObserver(LinearModelObserver):
    """Common options and system data of the zonotopic observers."""

    OPTIONS = {"order": 100, "reduction": "girard"}

    def validate_options(self) -> None:
        try:
            check_order(self.options["order"])
            get_reduction(self.options["reduction"])
        except SetError as exc:
            raise OptionError(f"{self.name}: {exc}") from None

    def design(self) -> None:
        """Collect the system data used online (subclasses extend with ``super().design()``)."""
        super().design()
        self.E = self.W.G
        self.F = self.V.G
        Vi = self.V.interval()
        self.sigma = np.maximum(np.abs(Vi.lo), np.abs(Vi.hi))  # strip half-widths
        self.order = float(self.options["order"])
        self._reduce = get_reduction(self.options["reduction"]).reduce


class StripBasedObserver(ZonotopeObserver):
    """Predict, intersect with the measurement strips of ``y[k]``, reduce."""

    def reset(self) -> None:
        super().reset()
        self._c: np.ndarray | None = None
        self._G: np.ndarray | None = None

    @abstractmethod
    def intersect(self, c: np.ndarray, G: np.ndarray, y: np.ndarray):
        """Enclose ``(c, G)`` intersected with the measurement set of ``y``."""

    def step(self, u_prev, y) -> Zonotope:
        y = self._measurement(y)
        if self._c is None:  # first set: X0 intersected with y[0], not reduced (as CORA)
            c, G = self.intersect(self.X0.c, self.X0.G, y)
        else:
            u = self._input(u_prev)
            c = self.A @ self._c + self.B @ u + self.W.c
            G = np.hstack([self.A @ self._G, self.E])
            c, G = self.intersect(c, G, y)
            G = self._reduce(G, self.order)
        self._c, self._G = c, G
        self.k += 1
        return Zonotope._trusted(c, G)


class PerStripObserver(StripBasedObserver):
    """Intersection method I: one strip after the other, each with its own gain."""

    @abstractmethod
    def strip_gain(self, G: np.ndarray, i: int) -> np.ndarray:
        """Gain vector (n,) for strip ``i`` given the current generators ``G``."""

    def intersect(self, c, G, y):
        for i in range(self.C.shape[0]):
            lam = self.strip_gain(G, i).reshape(-1, 1)
            c, G = strip_update(c, G, lam, self.C[i : i + 1], y[i : i + 1], self.sigma[i : i + 1])
        return c, G


class AllStripsObserver(StripBasedObserver):
    """Intersection method II: all strips at once with one gain matrix."""

    @abstractmethod
    def gain(self, G: np.ndarray) -> np.ndarray:
        """Gain matrix (n x m) given the generators ``G`` of the predicted set."""

    def intersect(self, c, G, y):
        return strip_update(c, G, self.gain(G), self.C, y, self.sigma)


class PropagationObserver(ZonotopeObserver):
    """Luenberger-type set propagation; the estimate of step k+1 needs only ``y[k]``."""

    def reset(self) -> None:
        super().reset()
        self._c: np.ndarray | None = None
        self._G: np.ndarray | None = None
        self._y_prev: np.ndarray | None = None

    @abstractmethod
    def gain(self, c: np.ndarray, G: np.ndarray) -> np.ndarray:
        """Observer gain L (n x m) for the current set ``(c, G)``."""

    def step(self, u_prev, y) -> Zonotope:
        y = self._measurement(y)
        if self._c is None:  # first set: X0 itself (as CORA)
            c, G = self.X0.c, self.X0.G
        else:
            u = self._input(u_prev)
            L = self.gain(self._c, self._G)
            c, G = propagate(
                self._c, self._G, self.A, self.B, self.C, L, u, self._y_prev,
                (self.V.c, self.F), (self.W.c, self.E),
            )
            G = self._reduce(G, self.order)
        self._c, self._G, self._y_prev = c, G, y
        self.k += 1
        return Zonotope._trusted(c, G)


class ConstantGainPropagationObserver(PropagationObserver):
    """Set propagation with an offline gain ``self.L`` (set by ``design``)."""

    L: np.ndarray

    def gain(self, c, G) -> np.ndarray:
        return self.L
