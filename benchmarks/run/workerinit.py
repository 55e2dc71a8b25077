"""Preloaded by the server process from which local workers are forked
(:func:`benchmarks.run.executors._context`), so that every worker starts with what the jobs need.

Importing this module imports the harness (:mod:`benchmarks.run.runner`), every observer plugin
(with what they import: HiGHS, scipy.stats, numba, ...) and loads the compiled (numba) simplex
kernels from their disk cache by one tiny hull and support (the one-call hull and the batched
solve of :mod:`observers.lp.batch_solve_jit`), and the compiled one-step kernels
(:mod:`observers.kernels.step`) by two steps of one observer per kernel on the
2-state example.  A worker forked from that server
then pays none of it: without this, each worker spent about 2.5 s of CPU importing the
plugins and loading the kernel at its first job (measured on the 3 x 22 x 20 sweep).
Nothing here changes a result: the same modules are imported, only earlier.

:func:`warm` is also what the regression gate (:mod:`benchmarks.gate.regression`) calls before
its timed jobs, and what ``make test`` calls once before its workers start
(``tests/conftest.py``): on a cold numba cache it compiles the kernels (about 3.5 min of one
core on the 2-core machine), so that no job's time budget and no test pays for it.
"""

from __future__ import annotations

import time

import numpy as np

import benchmarks.run.runner  # noqa: F401  (the harness itself)
import observers
import systems
from observers.sets import ConZonotope

#: one observer per compiled step kernel (``strip_step`` and ``strip_first``: FRad-A, VolMin-B;
#: ``propagate_step``: FRad-C), run for two steps by :func:`warm` on a linear system and on a
#: nonlinear one (``predict_linearised``, ``strip_predicted``, ``propagate_linearised``).  Every
#: observer passes its kernel the same argument types (one ``StepData`` per run), so one call
#: loads a kernel for all of them, and none of these three has an offline SDP design, so a
#: server with a cold design cache solves no SDP before forking.
KERNEL_OBSERVERS = ("FRad-A", "FRad-C", "VolMin-B")
#: the scenarios of :func:`warm`: linear, nonlinear
KERNEL_SCENARIOS = ("alamo2d", "tank6-nonlinear")


_WARMED: list[float] = []


def warm() -> float:
    """Import every observer plugin and load the compiled kernels (compiling them on a cold
    numba cache); errors are ignored: a worker then simply pays them at its first job, as
    without the preload.  Once per process; returns the seconds the first call took."""
    if _WARMED:
        return _WARMED[0]
    t0 = time.perf_counter()
    try:
        observers.names()
        Z = ConZonotope(np.zeros(2), np.array([[1.0, 0.5, 0.2], [0.0, 1.0, 0.3]]),
                        np.array([[1.0, 1.0, 1.0]]), np.array([0.5]))
        Z.interval()  # the one-call hull (batch_solve_jit.hull)
        Z.support(np.eye(2))  # the batched solve (batch_solve_jit.solve)
        for scenario in KERNEL_SCENARIOS:
            sc = systems.scenario(scenario)
            for name in KERNEL_OBSERVERS:
                observers.run(observers.create(name, sc.system, **sc.options), sc.u[:2],
                              sc.y[:2])
    except Exception:  # pragma: no cover - a broken plugin is reported by the run itself
        pass
    _WARMED.append(time.perf_counter() - t0)
    return _WARMED[0]


warm()
