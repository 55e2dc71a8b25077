"""Guaranteed state estimators behind one step interface.

>>> import observers, systems
>>> sc = systems.scenario("vehicle2d-cora")
>>> obs = observers.create("FRad-A", sc.system, order=100, reduction="pca")
>>> res = observers.run(obs, sc.u, sc.y)
>>> res.lo.shape
(100, 2)

``observers.available()`` lists the registered observers; outside packages add their own
through the entry-point group ``setobs_bench.observers`` (see the plugin guide of the
documentation, ``docs/guide/plugins.rst``).  Importing this package does not import the
plugins; they are loaded on the first registry query.
"""

from .base import Observer, RunResult, run
from .errors import (
    DesignFailed,
    Diverged,
    MeasurementError,
    ObserverError,
    OptionError,
    UnknownObserver,
    Unsupported,
)
from .registry import ObserverInfo, available, create, get, names, register, unregister

__all__ = [
    "DesignFailed",
    "Diverged",
    "MeasurementError",
    "Observer",
    "ObserverError",
    "ObserverInfo",
    "OptionError",
    "RunResult",
    "UnknownObserver",
    "Unsupported",
    "available",
    "create",
    "get",
    "names",
    "register",
    "run",
    "unregister",
]
