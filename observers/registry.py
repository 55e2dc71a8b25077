"""Plugin registry: ``@register("Name", ...)`` for observer classes and discovery of outside
plugins through the entry-point group ``setobs_bench.observers`` (:data:`ENTRY_POINT_GROUP`;
the old group ``observers`` is still read, with a deprecation warning per plugin).

Built-in observers live in :mod:`observers.builtin` (one module per family) and are imported
lazily, on the first registry query, so that importing :mod:`observers.sets` (e.g. from
:mod:`systems`) never imports a plugin.
"""

from __future__ import annotations

import difflib
import importlib
import pkgutil
import warnings
from importlib.metadata import entry_points
from time import perf_counter
from typing import Any

from .base import Observer, ObserverInfo
from .errors import ObserverError, OptionError, UnknownObserver

#: entry-point group of observer plugins (``[project.entry-points."setobs_bench.observers"]``)
ENTRY_POINT_GROUP = "setobs_bench.observers"

#: the group read before 0.2.0, still read: each plugin found only there gives a
#: :class:`PluginGroupDeprecation` warning
OLD_ENTRY_POINT_GROUP = "observers"

#: row order of the papers' tables; other observers follow alphabetically.  ``Exact`` (the
#: exact reference of linear records) is the first row.
CANONICAL_ORDER = (
    "Exact",
    "VolMin-A", "VolMin-B", "FRad-A", "FRad-B", "PRad-A", "PRad-B", "PRad-C-I", "PRad-C-II",
    "PRad-D", "CZN-A", "CZN-B", "CZN-MV", "ESO-A", "ESO-B", "FRad-C", "PRad-E", "Nom-G",
    "ESO-C", "ESO-D", "Hinf-G",
)

FAMILIES = ("strip", "propagation", "interval", "data-driven", "stochastic", "reference",
            "moving-horizon", "external")

#: families that ``observers: all`` of a benchmark configuration leaves out: the stochastic
#: (non-guaranteed) baselines and the moving-horizon estimators, which are not in the papers'
#: comparisons (name them in a configuration; the frontier study shows them), and the
#: replayed results of outside tools (``setobs-bench score``, :mod:`benchmarks.exchange`)
OUTSIDE_ALL = ("stochastic", "moving-horizon", "external")

#: the two exact floors an observer's sets can be held against: the set of states consistent
#: with the record *after* ``y[k]`` (``"filtered"``) or *before* it (``"predicted"``)
FLOORS = ("filtered", "predicted")

#: floor of a family whose observers do not say: propagation and interval observers return at
#: step k a set computed from ``y[0..k-1]`` only (ready for control), the others use ``y[k]``
FAMILY_FLOORS = {"propagation": "predicted", "interval": "predicted"}


_REGISTRY: dict[str, ObserverInfo] = {}
_loaded = False


class PluginGroupDeprecation(FutureWarning):
    """A plugin announced in the old entry-point group ``observers`` (a :class:`FutureWarning`,
    so that it is shown by default to whoever runs ``setobs-bench``)."""


def register(
    name: str,
    *,
    family: str,
    set_type: str,
    ready_for_control: bool,
    guaranteed: bool = True,
    reference: str = "",
    floor: str | None = None,
):
    """Class decorator registering an :class:`~observers.base.Observer` under ``name``.

    Parameters
    ----------
    name : str
        Public name used in configs and tables (e.g. ``"FRad-A"``).
    family : str
        Observer type, one of :data:`FAMILIES`, as in the papers' classification
        (``"reference"``: the exact reference ``Exact``; ``"moving-horizon"``: ``MHE``,
        exact over a window; ``"external"``: a tool's result file replayed by
        ``setobs-bench score``).
    set_type : str
        Set representation of the estimates (``"zonotope"``, ``"ellipsoid"``, ...).
    ready_for_control : bool
        True if the estimate of step k is available before ``y_k`` arrives.
    guaranteed : bool
        False for non-guaranteed baselines (their containment failures are counted, not bugs).
    reference : str
        Literature reference shown by ``available()``.
    floor : {"filtered", "predicted"}, optional
        Which exact set the observer's sets are compared with (``Exact``'s two floors): the
        states consistent with the record up to ``y[k]`` (``"filtered"``, for observers whose
        set of step k uses ``y[k]``: strip-based, data-driven) or up to ``y[k-1]``
        (``"predicted"``, for observers whose set of step k is ready before ``y[k]``:
        propagation and interval observers).  Default: ``"predicted"`` for the families
        ``propagation`` and ``interval``, else ``"filtered"`` (:data:`FAMILY_FLOORS`).
    """
    if family not in FAMILIES:
        raise ObserverError(f"unknown observer family '{family}' (known: {', '.join(FAMILIES)})")
    floor = FAMILY_FLOORS.get(family, "filtered") if floor is None else floor
    if floor not in FLOORS:
        raise ObserverError(f"unknown floor '{floor}' of observer '{name}' (known: "
                            f"{', '.join(FLOORS)})")

    def decorate(cls):
        existing = _REGISTRY.get(name)
        if existing is not None and existing.cls.__qualname__ != cls.__qualname__:
            raise ObserverError(
                f"observer name '{name}' is already registered by {existing.cls.__module__}."
                f"{existing.cls.__qualname__}"
            )
        info = ObserverInfo(name, cls, family, set_type, ready_for_control, guaranteed, reference,
                            floor)
        cls.name = name
        cls.info = info
        _REGISTRY[name] = info
        return cls

    return decorate


def _distribution(ep) -> str:
    """Name of the distribution that announces entry point ``ep`` (``"?"`` if unknown)."""
    dist = getattr(ep, "dist", None)
    return getattr(dist, "name", None) or "?"


def _plugin_entry_points() -> list:
    """The entry points of both groups, each plugin once: those of :data:`ENTRY_POINT_GROUP`,
    then those of :data:`OLD_ENTRY_POINT_GROUP` not also in the new group (same distribution
    and target), each with a one-line :class:`PluginGroupDeprecation` warning."""
    eps = list(entry_points(group=ENTRY_POINT_GROUP))
    seen = {(_distribution(ep), ep.value) for ep in eps}
    for ep in entry_points(group=OLD_ENTRY_POINT_GROUP):
        key = (_distribution(ep), ep.value)
        if key in seen:
            continue
        seen.add(key)
        eps.append(ep)
        warnings.warn(
            f"observer plugin '{ep.name}' of distribution '{key[0]}' is announced in the "
            f"deprecated entry-point group '{OLD_ENTRY_POINT_GROUP}'; move it to "
            f"'{ENTRY_POINT_GROUP}'",
            PluginGroupDeprecation,
            stacklevel=4,
        )
    return eps


def _load_plugins() -> None:
    """Import the built-in observer modules and the entry-point plugins (once)."""
    global _loaded
    if _loaded:
        return
    _loaded = True
    from . import builtin

    for mod in pkgutil.iter_modules(builtin.__path__):
        importlib.import_module(f"{builtin.__name__}.{mod.name}")
    for ep in _plugin_entry_points():
        try:
            obj = ep.load()
        except Exception as exc:  # a broken plugin must not take the harness down
            warnings.warn(f"observer plugin '{ep.name}' failed to load: {exc}", stacklevel=2)
            continue
        if isinstance(obj, type) and getattr(obj, "info", None) is None:
            warnings.warn(
                f"observer plugin '{ep.name}' points to {obj.__qualname__}, which is not "
                "decorated with @observers.register(...)",
                stacklevel=2,
            )


def table_order(names) -> list[str]:
    """``names`` sorted in the papers' table order (:data:`CANONICAL_ORDER`), others
    alphabetically after them; the one row order of every table and listing.  A labelled
    variant ``NAME[tag]`` of a benchmark configuration follows ``NAME``."""

    def key(name: str) -> tuple[int, str]:
        try:
            return (CANONICAL_ORDER.index(name.split("[")[0]), name)
        except ValueError:
            return (len(CANONICAL_ORDER), name.lower())

    return sorted(names, key=key)


def unregister(name: str, missing_ok: bool = False) -> ObserverInfo | None:
    """Remove the observer registered under ``name`` and return its entry.

    For a process that registers observers for a while (a tool's results replayed by
    ``setobs-bench score``, a test's plugin): a later :func:`names` no longer lists it, and the
    name may be registered again by another class.  An unknown name is refused as by
    :func:`get`, unless ``missing_ok`` (then None is returned).
    """
    if missing_ok and name not in _REGISTRY:
        return None
    info = get(name)
    del _REGISTRY[info.name]
    return info


def available() -> list[ObserverInfo]:
    """All registered observers, in the papers' table order (others alphabetically)."""
    _load_plugins()
    return [_REGISTRY[n] for n in table_order(_REGISTRY)]


def names() -> list[str]:
    """Names of all registered observers."""
    return [info.name for info in available()]


def get(name: str) -> ObserverInfo:
    """Registry entry of ``name``; the error suggests close matches."""
    _load_plugins()
    try:
        return _REGISTRY[name]
    except KeyError:
        pass
    if not isinstance(name, str):
        raise UnknownObserver(f"observer name must be a string, got {name!r}")
    lower = {n.lower(): n for n in _REGISTRY}
    if name.lower() in lower:
        raise UnknownObserver(f"unknown observer '{name}'; did you mean '{lower[name.lower()]}'?")
    close = difflib.get_close_matches(name, list(_REGISTRY), n=3)
    hint = f"; did you mean {', '.join(repr(c) for c in close)}?" if close else ""
    raise UnknownObserver(
        f"unknown observer '{name}'{hint} (available: {', '.join(names())})"
    )


def create(name: str, system: Any, **options: Any) -> Observer:
    """Instantiate observer ``name`` for ``system``: this runs (and times) its offline design.

    A registered class that is not an :class:`~observers.base.Observer` (any class whose
    objects have ``step(u_prev, y)``) is called as ``cls(system, **options)``; without
    ``option_defaults`` it takes no options, and without a ``design_time`` attribute the
    construction is timed as its design.
    """
    info = get(name)
    if issubclass(info.cls, Observer):
        return info.cls(system, **options)
    unknown = sorted(set(options) - set(info.option_defaults()))
    if unknown:
        raise OptionError(f"{name}: unknown option(s) {', '.join(unknown)} "
                          f"(accepted: {', '.join(sorted(info.option_defaults())) or 'none'})")
    t0 = perf_counter()
    obs = info.cls(system, **options)
    if not hasattr(obs, "design_time"):
        try:
            obs.design_time = perf_counter() - t0
        except AttributeError:  # pragma: no cover - e.g. __slots__
            pass
    return obs
