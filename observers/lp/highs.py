"""HiGHS solver objects without the banner on standard output.

``highspy`` prints a two-line banner ("Running HiGHS ...") from C++ when the first ``Highs``
object of a process is constructed, before any option (``output_flag``) can be set on it, so
that the banner would land in the middle of a command's output (e.g. a CSV on stdout).
:func:`new_highs` constructs the first object of the process with file descriptor 1
redirected to ``/dev/null`` (C buffers flushed before and after, so nothing else is lost or
swallowed), then sets ``output_flag`` to ``False`` on every object.  Later constructions
print nothing, so only the first pays the two ``dup2`` calls.
"""

from __future__ import annotations

import ctypes
import os
import sys
import threading

import highspy

_lock = threading.Lock()
_banner_done = False


def _flush_c_stdout() -> None:
    try:
        ctypes.CDLL(None).fflush(None)
    except (OSError, AttributeError):  # pragma: no cover - no C library to flush
        pass


def new_highs() -> highspy.Highs:
    """A ``highspy.Highs`` with ``output_flag`` off; the first one of the process is built
    with stdout redirected so that HiGHS's construction banner is not printed."""
    global _banner_done
    with _lock:
        if _banner_done:
            h = highspy.Highs()
        else:
            sys.stdout.flush()
            _flush_c_stdout()
            saved = os.dup(1)
            try:
                with open(os.devnull, "wb") as null:
                    os.dup2(null.fileno(), 1)
                    try:
                        h = highspy.Highs()
                        _flush_c_stdout()
                    finally:
                        os.dup2(saved, 1)
            finally:
                os.close(saved)
            _banner_done = True
    h.setOptionValue("output_flag", False)
    return h
