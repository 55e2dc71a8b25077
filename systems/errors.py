"""Errors raised for malformed system definitions, unknown scenarios and sets outside a
model's domain."""

from __future__ import annotations

from observers.errors import Diverged


class ModelError(ValueError):
    """A system, its sets or a scenario is malformed (with a one-line message naming why)."""


class OutputNotLinear(ModelError, AttributeError):
    """A system with a nonlinear output ``y = h(x) + v`` has no output matrix ``C``; it is
    also an :class:`AttributeError`, so ``hasattr(system, "C")`` is false and observers that
    need a linear output refuse the system by their usual check."""


class DomainError(Diverged):
    """A set of states reaches the boundary of the domain of a nonlinear model (e.g. a
    non-positive water level under a square root); observers report the run as ``diverged``
    with the step."""

    def __init__(self, message: str, state: int | None = None, step: int | None = None):
        super().__init__(message, step)
        self.state = state
