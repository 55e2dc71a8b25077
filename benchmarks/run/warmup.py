"""The compiled kernels loaded before timed work: :func:`warm` imports every observer plugin,
loads the compiled (numba) simplex kernels from their disk cache by one tiny hull and support
(the one-call hull and the batched solve of :mod:`observers.lp.batch_solve_jit`), and the
compiled one-step kernels (:mod:`observers.kernels.step`) by two steps of one observer per
kernel on the 2-state example and on the nonlinear 6-tank.  On a cold numba cache that compiles
them: about 3.5 min of one core on the 2-core machine, or 2.2 min with ``parallel=True``
(:data:`SHARES` in two processes) where nothing else needs the second core: the gate's
warm-up; ``make test`` builds the documentation site beside its warm-up, and with both shares
as well it took 4.5 min in CI instead of 3.5.

Called by the server process from which local workers fork (:mod:`benchmarks.run.workerinit`),
by the regression gate before its timed jobs (:mod:`benchmarks.gate.regression`) and by
``make test`` once before its workers start (``tests/conftest.py``), so that no job's time
budget and no test pays for a compilation.  Nothing here changes a result: the same modules are
imported and the same functions compiled, only earlier.
"""

from __future__ import annotations

import subprocess
import sys
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


#: :func:`load` in two shares of about equal cost on a cold cache, for :func:`warm` with
#: ``parallel=True`` (measured on the 2-core machine, each share alone: the strip kernels of
#: FRad-A and VolMin-B 136 s; the hull LPs 36 s and FRad-C's propagation kernels 66 s)
SHARES = (("FRad-A", "VolMin-B"), ("hull", "FRad-C"))

_WARMED: list[float] = []


def load(share: int | None = None) -> None:
    """Load (on a cold numba cache: compile) the kernels of one of :data:`SHARES`, or all."""
    names = SHARES[share] if share is not None else ("hull", *KERNEL_OBSERVERS)
    observers.names()
    if "hull" in names:
        Z = ConZonotope(np.zeros(2), np.array([[1.0, 0.5, 0.2], [0.0, 1.0, 0.3]]),
                        np.array([[1.0, 1.0, 1.0]]), np.array([0.5]))
        Z.interval()  # the one-call hull (batch_solve_jit.hull)
        Z.support(np.eye(2))  # the batched solve (batch_solve_jit.solve)
    for scenario in KERNEL_SCENARIOS:
        sc = systems.scenario(scenario)
        for name in KERNEL_OBSERVERS:
            if name in names:
                observers.run(observers.create(name, sc.system, **sc.options), sc.u[:2],
                              sc.y[:2])


def warm(parallel: bool = False) -> float:
    """Import every observer plugin and load the compiled kernels (compiling them on a cold
    numba cache); errors are ignored: a worker then simply pays them at its first job, as
    without the preload.  ``parallel``: the second of :data:`SHARES` is loaded by a
    subprocess meanwhile (numba's cache is shared on disk; on a cold cache the warm-up then
    takes about the larger share).  Once per process; returns the seconds the first call
    took."""
    if _WARMED:
        return _WARMED[0]
    t0 = time.perf_counter()
    other = subprocess.Popen(  # noqa: S603 - this interpreter, fixed arguments
        [sys.executable, "-c", "import benchmarks.run.warmup as w; w.load(1)"],
        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL) if parallel else None
    try:
        load(0 if parallel else None)
        if other is not None:
            other.wait()
            load()  # the other share from the cache (or compiled here if it failed there)
    except Exception:  # pragma: no cover - a broken plugin is reported by the run itself
        pass
    finally:
        if other is not None:
            other.wait()
    _WARMED.append(time.perf_counter() - t0)
    return _WARMED[0]
