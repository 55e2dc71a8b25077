"""Error for malformed benchmark configurations."""


class ConfigError(ValueError):
    """A benchmark configuration is malformed (one-line message naming the problem)."""
