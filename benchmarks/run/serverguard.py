"""Preloaded first by the server process from which local workers are forked (and by no
other process): the server ends when the process that started it ends.

A worker forked from the server is killed when the server ends (``PR_SET_PDEATHSIG``,
:func:`benchmarks.run.executors._die_with_parent`), but the server itself ends only when every
holder of its "alive" pipe has closed it, and the workers hold it too: a run stopped by
``SIGTERM`` or ``SIGKILL`` left its server waiting for its workers and a worker running its job
on (an audit's exact floor held a core for 57 min).  A daemon thread here looks at the server's
parent every :data:`POLL_S` seconds and ends the server once that parent is gone (the server is
then re-parented); its workers follow.  Threads do not survive a fork, so no worker runs it.
"""

from __future__ import annotations

import os
import sys
import threading
import time

#: seconds between two looks at the server's parent
POLL_S = 0.5


def _watch(parent: int) -> None:  # pragma: no cover - in the server
    while os.getppid() == parent:
        time.sleep(POLL_S)
    os._exit(0)


def in_server() -> bool:
    """Whether this module is being imported by the forkserver's preload (a frame of
    ``multiprocessing.forkserver.main`` is on the stack): anywhere else (the docs' autodoc, a
    reader) the import starts nothing."""
    from multiprocessing import forkserver

    frame = sys._getframe()
    while frame is not None:
        if frame.f_code is forkserver.main.__code__:
            return True
        frame = frame.f_back
    return False


def guard() -> None:
    """Start the daemon thread that ends this process once its parent is gone."""
    threading.Thread(target=_watch, args=(os.getppid(),), daemon=True,
                     name="setobs-server-guard").start()


if in_server():
    guard()
