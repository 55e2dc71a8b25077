"""Error raised for malformed system definitions and unknown scenarios."""


class ModelError(ValueError):
    """A system, its sets or a scenario is malformed (with a one-line message naming why)."""
