"""Error raised by the set classes for malformed input (shape, non-finite values, empty sets)."""


class SetError(ValueError):
    """A set was built or used with invalid data (wrong shape, NaN/inf, empty, mismatched dims)."""


class EmptySet(SetError):
    """An operation found the set empty (e.g. infeasible constraints of a constrained
    zonotope): for an estimate this means the measurements contradict the model."""
