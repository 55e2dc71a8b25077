"""Errors raised by observers, their designs, the registry and the set types.

The benchmark runner turns :class:`DesignFailed` into the table status ``noGain`` and
:class:`Diverged` into ``diverged`` (as the papers do) and carries on with the next observer.
"""

from __future__ import annotations


class ObserverError(ValueError):
    """Base class of all observer-related errors with a one-line, user-facing message."""


class UnknownObserver(ObserverError):
    """No observer of that name is registered (built in or via an entry point)."""


class OptionError(ObserverError):
    """An observer was created with an unknown or invalid option."""


class MeasurementError(ObserverError):
    """An input or measurement passed to ``step`` has the wrong shape or is not finite."""


class Unsupported(ObserverError):
    """The observer does not apply to this kind of system (e.g. a linear-model observer on a
    nonlinear system); tables show ``unsupported``."""

    status = "unsupported"


class DesignFailed(ObserverError):
    """The offline design found no gain (infeasible LMI, solver failure, failed verification)."""

    status = "noGain"


class Diverged(ObserverError):
    """The estimate became numerically meaningless (non-finite, exploding, failed update)."""

    status = "diverged"

    def __init__(self, message: str, step: int | None = None):
        super().__init__(message if step is None else f"step {step}: {message}")
        self.step = step


class SetError(ValueError):
    """A set was built or used with invalid data (wrong shape, NaN/inf, empty, mismatched dims).

    Raised by :mod:`observers.sets` and :mod:`observers.lp` (re-exported by
    :mod:`observers.sets`)."""


class EmptySet(SetError):
    """An operation found the set empty (e.g. infeasible constraints of a constrained
    zonotope): for an estimate this means the measurements contradict the model."""
