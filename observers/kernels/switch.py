"""The numba switch shared by the compiled kernels of the package.

numba is optional: :data:`AVAILABLE` is false when it is not installed or when the environment
variable ``SETOBS_NUMBA=0`` (also ``off``, ``false``, ``no``) disables it; every kernel then
has a numpy path that computes the same numbers up to rounding.  :func:`set_compiled` switches
all kernels at run time (tests compare both paths; timings may measure both).
"""

from __future__ import annotations

import os

try:
    if os.environ.get("SETOBS_NUMBA", "1").strip().lower() in ("0", "off", "false", "no"):
        raise ImportError("disabled by SETOBS_NUMBA")
    import numba
except ImportError:  # pragma: no cover - depends on the installation
    numba = None

#: whether numba is installed and not disabled by SETOBS_NUMBA=0
AVAILABLE = numba is not None

_USE_COMPILED = [True]


def use_compiled() -> bool:
    """Whether the compiled kernels run (numba available and not switched off)."""
    return AVAILABLE and _USE_COMPILED[0]


def set_compiled(on: bool) -> bool:
    """Use the compiled kernels (if available) or the numpy paths; returns the old setting."""
    old = _USE_COMPILED[0]
    _USE_COMPILED[0] = bool(on)
    return old


def njit(func, **kw):
    """``numba.njit(cache=True, nogil=True, **kw)(func)``, or ``None`` without numba."""
    if not AVAILABLE:
        return None
    return numba.njit(cache=True, nogil=True, **kw)(func)
