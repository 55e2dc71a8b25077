"""Errors of the harness, and the errors that are the user's to fix.

:class:`ConfigError` names a problem of a benchmark configuration, a command-line argument or
an input file in one line.  :data:`USER_ERRORS` are the exceptions that mean bad input wherever
they come from (the configuration, a model, an observer's options, a set): the command line
prints them as one ``error: ...`` line with exit code 2.
"""

from observers.errors import ObserverError
from observers.sets import SetError
from systems import ModelError


class ConfigError(ValueError):
    """A benchmark configuration is malformed (one-line message naming the problem)."""


#: exceptions that are bad input, shown as one line ``error: ...`` (exit code 2)
USER_ERRORS = (ConfigError, ModelError, ObserverError, SetError)
