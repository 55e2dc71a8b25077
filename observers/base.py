"""The observer interface (offline ``design`` in the constructor, then ``step`` per time step)
and :func:`run`, the loop that drives an observer over a measurement record.

Time-index convention (CORA's, and the papers'): ``y[k] = C x_k + v_k`` and
``x_{k+1} = A x_k + B u[k] + w_k``.  The k-th call ``step(u_prev, y)`` receives
``u_prev = u[k-1]`` (``None`` for k = 0) and ``y = y[k]`` and returns a set that contains
``x_k``.  The first estimate is ``X0`` intersected with ``y[0]`` for strip-based observers and
``X0`` itself for propagation and interval observers.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass, field
from time import perf_counter
from typing import Any, ClassVar

import numpy as np

from .errors import DesignFailed, Diverged, EmptySet, MeasurementError, OptionError, Unsupported
from .options import OptionSpec, as_spec
from .sets import doubles


@dataclass(frozen=True)
class ObserverInfo:
    """What the registry knows about an observer class (:func:`observers.registry.register`
    sets it as the class attribute ``info``).

    ``floor`` is the exact set its sets are held against (the two floors of ``Exact``):
    ``"filtered"`` (states consistent with the record up to ``y[k]``) or ``"predicted"`` (up
    to ``y[k-1]``); see :func:`observers.registry.register`.
    """

    name: str
    cls: type
    family: str
    set_type: str
    ready_for_control: bool
    guaranteed: bool = True
    reference: str = ""
    floor: str = "filtered"

    @property
    def timing(self) -> str:
        """``"ready for control"`` (estimate available before y_k) or ``"in time"``."""
        return "ready for control" if self.ready_for_control else "in time"

    def option_defaults(self) -> dict[str, Any]:
        """Accepted options with their defaults (``{}`` for a plain class without
        ``option_defaults``, which then takes no options)."""
        defaults = getattr(self.cls, "option_defaults", None)
        return dict(defaults()) if callable(defaults) else {}

    @property
    def scenario_options(self) -> tuple[str, ...] | None:
        """Options a scenario may set by default (``SCENARIO_OPTIONS``; None = all)."""
        return getattr(self.cls, "SCENARIO_OPTIONS", None)

    @property
    def summary(self) -> str:
        """First line of the class docstring."""
        doc = (self.cls.__doc__ or "").strip()
        return doc.splitlines()[0] if doc else ""



class Observer(ABC):
    """Base class of every observer plugin.

    Subclasses declare their options in ``OPTIONS`` (merged along the class hierarchy) as
    typed specs of :mod:`observers.options` (``{"order": Number(100, low=1)}``; a plain value
    is an untyped default), do their offline work in :meth:`design` (timed into
    ``design_time``), keep their online state in :meth:`reset` and implement :meth:`step`.
    The constructor checks every option with its spec before :meth:`validate_options` and
    the design.
    """

    name: ClassVar[str] = ""
    info: ClassVar[ObserverInfo | None] = None
    #: accepted options: name -> spec (:mod:`observers.options`) or plain default value
    OPTIONS: ClassVar[dict[str, OptionSpec | Any]] = {}
    #: options a benchmark scenario may set by default (e.g. its zonotope order); None = all
    #: accepted options.  Observers whose papers fix their own settings use a subset.
    SCENARIO_OPTIONS: ClassVar[tuple[str, ...] | None] = None
    #: system attributes this observer reads (data-driven observers do not read A and B)
    REQUIRES: ClassVar[tuple[str, ...]] = ("A", "B", "C", "W", "V", "X0")
    #: the kinds of model this observer estimates ("linear", "nonlinear"; a system says which
    #: it is by ``is_linear``); another kind is refused at construction (``Unsupported``),
    #: ``MODEL_NOTE`` ending the message with the reason
    MODELS: ClassVar[tuple[str, ...]] = ("linear", "nonlinear")
    MODEL_NOTE: ClassVar[str] = ""
    #: relative tolerance of the CI regression gate (``python -m benchmarks check``) on this
    #: observer's RMS radii: 1e-6 for deterministic online computations; observers whose
    #: numbers depend on an offline solver's output override it (see ``OfflineGain``)
    REGRESSION_RTOL: ClassVar[float] = 1e-6

    def __init__(self, system: Any, **options: Any):
        missing = [a for a in self.REQUIRES if not hasattr(system, a)]
        if missing:
            raise Unsupported(
                f"{self.name or type(self).__name__} needs a system with attributes "
                f"{', '.join(self.REQUIRES)}; missing: {', '.join(missing)}"
            )
        kind = "linear" if getattr(system, "is_linear", True) else "nonlinear"
        if kind not in self.MODELS:
            raise Unsupported(f"{self.name or type(self).__name__} needs a "
                              f"{' or '.join(self.MODELS)} system{self.MODEL_NOTE}")
        self.system = system
        specs = self.option_specs()  # merged along the MRO once per construction
        self.options = self._resolve_options(options, specs)
        self._check_options(specs)
        self.validate_options()
        t0 = perf_counter()
        try:
            self.design()
        except DesignFailed as exc:  # name a zero-width noise set, the likely cause
            note = zero_width_note(system)
            if not note:
                raise
            who = self.name or type(self).__name__
            msg = str(exc) if str(exc).startswith(who) else f"{who}: {exc}"
            raise DesignFailed(f"{msg} (zero-width noise: {note})") from None
        self.design_time = perf_counter() - t0
        self.reset()

    # -- options ------------------------------------------------------------------------------
    @classmethod
    def option_specs(cls) -> dict[str, OptionSpec]:
        """All accepted options with their specs, merged along the MRO (a subclass overrides
        its bases); plain values in ``OPTIONS`` become :class:`~observers.options.Untyped`.

        Returns
        -------
        dict
            Option name -> :class:`~observers.options.OptionSpec`.
        """
        out: dict[str, OptionSpec] = {}
        for klass in reversed(cls.__mro__):
            for key, entry in vars(klass).get("OPTIONS", {}).items():
                out[key] = as_spec(entry)
        return out

    @classmethod
    def option_defaults(cls) -> dict[str, Any]:
        """All accepted options with their defaults.

        Returns
        -------
        dict
            Option name -> default value.
        """
        return {key: spec.default for key, spec in cls.option_specs().items()}

    def _resolve_options(self, options: dict[str, Any], specs: dict[str, OptionSpec]
                         ) -> dict[str, Any]:
        """The given options over the defaults of ``specs`` (:meth:`option_specs`)."""
        unknown = sorted(set(options) - set(specs))
        if unknown:
            accepted = ", ".join(sorted(specs)) or "none"
            raise OptionError(
                f"{self.name}: unknown option(s) {', '.join(unknown)} (accepted: {accepted})"
            )
        return {**{key: spec.default for key, spec in specs.items()}, **options}

    def _check_options(self, specs: dict[str, OptionSpec]) -> None:
        """Check every option against its spec (one :class:`OptionError` for the first bad
        one); values are kept as given.  The only check of a single option: the online code
        trusts them."""
        who = self.name or type(self).__name__
        for key, spec in specs.items():
            spec.check(who, key, self.options[key])

    def validate_options(self) -> None:  # noqa: B027 - optional hook
        """Hook: raise :class:`OptionError` for invalid combinations of options.

        Runs after every option passed its own spec; checks of a single option's type or
        range belong in its spec.
        """

    # -- lifecycle -------------------------------------------------------------------------------
    def design(self) -> None:  # noqa: B027 - optional hook
        """Offline design (gains, LMIs); runs once in the constructor."""

    def reset(self) -> None:
        """Forget the online state so that the next ``step`` is the first one.

        ``self.k`` counts the steps taken (subclasses increment it at the end of ``step``); it
        is used in error messages.
        """
        self.k = 0

    @abstractmethod
    def step(self, u_prev: np.ndarray | None, y: np.ndarray):
        """Consume ``u[k-1]`` and ``y[k]`` and return a set containing ``x_k``."""

    # -- input checks used by subclasses -------------------------------------------------------
    def _measurement(self, y) -> np.ndarray:
        y = _numeric(y, f"{self.name}: measurement at step {self.k}").reshape(-1)
        ny = _output_dim(self.system)
        if y.shape[0] != ny:
            raise MeasurementError(
                f"{self.name}: measurement has {y.shape[0]} entries, expected {ny}")
        if not np.isfinite(y).all():
            raise MeasurementError(f"{self.name}: non-finite measurement at step {self.k}")
        return y

    def _input(self, u) -> np.ndarray:
        nu = self.system.nu
        if u is None:
            if nu:  # only the first step has no previous input
                raise MeasurementError(
                    f"{self.name}: u_prev is None at step {self.k}; only the first step after "
                    "reset() has no previous input")
            return np.zeros(0)
        u = _numeric(u, f"{self.name}: input at step {self.k}").reshape(-1)
        if u.shape[0] != nu:
            raise MeasurementError(f"{self.name}: input has {u.shape[0]} entries, expected {nu}")
        if not np.isfinite(u).all():
            raise MeasurementError(f"{self.name}: non-finite input at step {self.k}")
        return u


def _output_dim(system: Any) -> int:
    """Number of outputs of ``system`` (``ny``, or the rows of ``C``)."""
    ny = getattr(system, "ny", None)
    return int(ny) if ny is not None else system.C.shape[0]


def zero_width_note(system: Any) -> str:
    """Which noise sets of ``system`` have zero width (``W = {0}``: no process noise; a zero
    component of ``V``: an exact sensor), e.g. ``"W is a single point"``; ``""`` if none."""
    notes = []
    for key in ("W", "V"):
        S = getattr(system, key, None)
        if S is None or not hasattr(S, "interval"):
            continue
        I = S.interval()
        r = 0.5 * (np.asarray(I.hi, float) - np.asarray(I.lo, float))
        if not np.any(r > 0):
            notes.append(f"{key} is a single point")
        elif np.any(r == 0):
            zero = ", ".join(str(i + 1) for i in np.flatnonzero(r == 0))
            notes.append(f"{key} has zero width in component {zero}")
    return "; ".join(notes)


@dataclass
class RunResult:
    """Interval hulls, sets and timings of one observer over one record."""

    observer: str
    lo: np.ndarray
    hi: np.ndarray
    sets: list = field(repr=False)
    step_times: np.ndarray = field(repr=False)
    hull_times: np.ndarray = field(repr=False)
    design_time: float = 0.0
    status: str = "ok"
    message: str = ""
    failed_step: int | None = None
    error: BaseException | None = field(default=None, repr=False)  # of status "error"
    #: the floating-point values each step's set holds (:func:`observers.sets.doubles`; NaN
    #: where no set was produced or its type is unknown)
    doubles: np.ndarray | None = field(default=None, repr=False)

    @property
    def radius(self) -> np.ndarray:
        """Interval radii (N x n)."""
        return 0.5 * (self.hi - self.lo)

    @property
    def center(self) -> np.ndarray:
        """Interval centres (N x n)."""
        return 0.5 * (self.hi + self.lo)


def _numeric(a, what: str) -> np.ndarray:
    """``a`` as a float array; a :class:`MeasurementError` naming ``what`` if it is not
    numeric (instead of numpy's bare ``ValueError``)."""
    try:
        return np.asarray(a, dtype=float)
    except (TypeError, ValueError) as exc:
        raise MeasurementError(f"{what} is not numeric ({exc})") from None


def as_record(u, y, nu: int | None, ny: int | None) -> tuple[np.ndarray, np.ndarray]:
    """Validate an input/measurement record: ``y`` is N x ny with N >= 1, ``u`` is N x nu
    (or N-1 x nu); ``None`` for ``nu`` or ``ny`` takes the width of the given array."""
    y = _numeric(y, "measurements y")
    if y.ndim == 1 and ny == 1:
        y = y.reshape(-1, 1)
    if y.ndim != 2 or (ny is not None and y.shape[1] != ny):
        raise MeasurementError(f"measurements y must have shape (N, {ny or 'ny'}), "
                               f"got {y.shape}")
    if y.shape[0] == 0:
        raise MeasurementError("measurements y are empty (0 steps)")
    ny = y.shape[1]
    bad = np.argwhere(~np.isfinite(y))
    if bad.size:
        k, j = bad[0]
        raise MeasurementError(f"measurement y[{k}, {j}] is not finite ({y[k, j]})")
    N = y.shape[0]
    if u is None:
        u = np.zeros((N, nu or 0))
    u = _numeric(u, "inputs u")
    if u.ndim == 1 and nu == 1:
        u = u.reshape(-1, 1)
    if u.ndim != 2 or (nu is not None and u.shape[1] != nu) or u.shape[0] not in (N, N - 1):
        raise MeasurementError(f"inputs u must have shape ({N}, {nu or 'nu'}), got {u.shape}")
    bad = np.argwhere(~np.isfinite(u))
    if bad.size:
        k, j = bad[0]
        raise MeasurementError(f"input u[{k}, {j}] is not finite ({u[k, j]})")
    return u, y


def run(
    obs: Any,
    u,
    y,
    *,
    keep_sets: bool = True,
    divergence_bound: float = 1e12,
    on_error: str = "raise",
    budget: float | None = None,
) -> RunResult:
    """Drive ``obs`` over the record and collect interval hulls and timings.

    ``obs`` is an :class:`Observer` or any object with ``step(u_prev, y)`` returning a set
    with ``interval()`` (an object with ``lo`` and ``hi``); its ``reset()``, ``name``,
    ``design_time`` and ``system`` (for the shapes of ``u`` and ``y``) are used where present.

    ``step()`` and the interval hull are timed separately (``step_times``, ``hull_times``).
    A :class:`~observers.errors.Diverged` raised by the observer, a non-finite hull, a hull
    beyond ``divergence_bound`` or one that grew beyond :data:`GROWTH_BOUND` times the initial
    scale (the largest radius of ``X0`` or of the first hull) ends the run with status
    ``"diverged"``; an empty estimate
    (:class:`~observers.sets.EmptySet`: the measurements contradict the model and noise
    bounds, or a numerical failure) with status ``"empty"``; the remaining rows are NaN.
    Any other exception of ``step`` or ``interval`` propagates (``on_error="raise"``) or ends
    the run with status ``"error"`` and the failing step (``on_error="status"``, the
    exception in ``RunResult.error``).

    ``budget`` (seconds, optional) stops a run early that cannot finish within it: after each
    step from the :data:`BUDGET_WINDOW`-th on, the time spent so far plus the steps left at
    the median cost (step + hull) of the last :data:`BUDGET_WINDOW` steps is the projected
    time of the record; once it exceeds the budget the run ends with status ``"timeout"``
    (``failed_step``: the first step not run; the message gives the steps run, their time
    and the projection).  A set-based observer's sets grow to their order over the first
    steps, so its steps get no cheaper as the record goes on: the projection is then an
    under-estimate and a stopped run would not have finished (the median keeps a single slow
    first step, e.g. loading a compiled kernel, from stopping a run).

    Raises
    ------
    MeasurementError
        If ``u`` or ``y`` is empty, not numeric, not finite or of the wrong shape.
    """
    if on_error not in ("raise", "status"):
        raise ValueError(f"on_error must be 'raise' or 'status', got {on_error!r}")
    u, y, n = _record_of(obs, u, y)
    N = y.shape[0]
    lo = np.full((N, n or 0), np.nan)
    hi = np.full((N, n or 0), np.nan)
    step_times = np.full(N, np.nan)
    hull_times = np.full(N, np.nan)
    sets: list = []
    if callable(getattr(obs, "reset", None)):
        obs.reset()
    name = getattr(obs, "name", "") or type(obs).__name__
    result = RunResult(name, lo, hi, sets, step_times, hull_times,
                       float(getattr(obs, "design_time", np.nan)), doubles=np.full(N, np.nan))
    if budget is not None and not (isinstance(budget, (int, float)) and budget > 0):
        raise ValueError(f"budget must be a positive number of seconds, got {budget!r}")
    start = perf_counter()
    # the scale of the growth test: the largest radius of X0 (where the system gives it) or,
    # if larger, of the first hull with a positive radius
    first_radius, first_hull_seen = _initial_radius(obs), False
    for k in range(N):
        u_prev = u[k - 1] if k > 0 else None
        try:
            t0 = perf_counter()
            S = obs.step(u_prev, y[k])
            t1 = perf_counter()
            I = S.interval()
            t2 = perf_counter()
            if n is None:  # an observer without a system: its sets give the dimension
                n = np.size(I.lo)
                result.lo = lo = np.full((N, n), np.nan)
                result.hi = hi = np.full((N, n), np.nan)
            _check_hull(I, k, n)
        except Exception as exc:
            _stop(result, k, exc, on_error)
            break
        step_times[k], hull_times[k] = t1 - t0, t2 - t1
        why = _divergence(I, divergence_bound, first_radius)
        if why:
            result.status, result.failed_step = "diverged", k
            result.message = f"step {k}: {why}"
            break
        if not first_hull_seen and np.max(I.hi - I.lo, initial=0.0) > 0:
            first_hull_seen = True
            first_radius = max(first_radius, float(np.max(I.hi - I.lo)) / 2)
        lo[k], hi[k] = I.lo, I.hi
        result.doubles[k] = doubles(S)
        if keep_sets:
            sets.append(S)
        if (budget is not None and BUDGET_WINDOW <= k + 1 < N
                and _over_budget(result, k, N, start, budget)):
            break
    return result


def _stop(result: RunResult, k: int, exc: Exception, on_error: str) -> None:
    """The status of a run whose step ``k`` raised ``exc``: ``diverged`` (a
    :class:`Diverged`), ``empty`` (an :class:`EmptySet`: no state is consistent with the
    record, a failed estimate), else ``error`` (``on_error="status"``) or ``exc`` again."""
    if isinstance(exc, Diverged):
        result.status, result.message = "diverged", str(exc)
        result.failed_step = k if exc.step is None else exc.step
    elif isinstance(exc, EmptySet):
        result.status, result.failed_step = "empty", k
        result.message = f"step {k}: the estimate is empty ({exc})"
    elif on_error == "raise":
        raise exc
    else:
        result.status, result.failed_step, result.error = "error", k, exc
        result.message = f"step {k}: {type(exc).__name__}: {exc}"


#: a hull whose largest radius exceeds this multiple of the initial scale (the largest radius
#: of X0, or of the first hull if that is larger: a first estimate pinned by an exact-looking
#: measurement, 1e-13 wide on a vertex realisation, is no scale) has diverged: its
#: generators are then so large that rounding, not the measurements, decides its thin
#: directions (an exploding estimate loses the true state in the last bits long before it
#: leaves +-1e12: measured on the bus suspension, a data-driven estimate growing 1.4x per step
#: missed the true state once its radius passed 1e10 times its first).  Measured on the
#: regression subset: every estimate that does not explode stays within 100 times its first
#: radius; the exploding ones (PRad-A on the vehicle, the A1 data-driven observers on the
#: 6-tank) pass 8e7
GROWTH_BOUND = 1e7


def _initial_radius(obs: Any) -> float:
    """The largest radius of the interval hull of the system's initial set ``X0`` (0 where
    the observer has no system with one)."""
    X0 = getattr(getattr(obs, "system", None), "X0", None)
    try:
        I = X0.interval()
        return float(np.max(I.hi - I.lo, initial=0.0)) / 2
    except (AttributeError, TypeError, ValueError):
        return 0.0


def _divergence(I: Any, bound: float, first_radius: float) -> str:
    """Why the hull ``I`` means the run diverged (empty string: it did not): a non-finite
    bound, a bound beyond ``+-bound``, or a largest radius beyond :data:`GROWTH_BOUND` times
    ``first_radius`` (the initial scale: X0's largest radius or the first hull's; 0: none)."""
    if not (np.all(np.isfinite(I.lo)) and np.all(np.isfinite(I.hi))):
        return "interval hull not finite"
    if max(np.abs(I.lo).max(initial=0.0), np.abs(I.hi).max(initial=0.0)) > bound:
        return f"interval hull left +-{bound:g}"
    radius = float(np.max(I.hi - I.lo, initial=0.0)) / 2
    if first_radius and radius > GROWTH_BOUND * first_radius:
        return (f"interval hull grew to {radius:.3g}, more than {GROWTH_BOUND:g} times the "
                f"initial {first_radius:.3g} (X0 or the first estimate)")
    return ""


def _record_of(obs: Any, u, y) -> tuple[np.ndarray, np.ndarray, int | None]:
    """``(u, y)`` checked by :func:`as_record` against the shapes of ``obs.system`` (where
    present) and the state dimension ``n`` (None if the system does not give it)."""
    system = getattr(obs, "system", None)
    C = getattr(system, "C", None)  # None also for a nonlinear output (no C)
    ny = getattr(system, "ny", None) if C is None else C.shape[0]
    u, y = as_record(u, y, getattr(system, "nu", None), ny)
    n = getattr(system, "n", None) if C is None else C.shape[1]
    return u, y, n


def _check_hull(I: Any, k: int, n: int) -> None:
    """Raise :class:`ValueError` unless the interval hull ``I`` of step ``k`` has the
    dimension ``n`` and ``lo <= hi`` (to a relative 1e-9): such a hull is never scored."""
    if np.shape(I.lo) != (n,) or np.shape(I.hi) != (n,):
        raise ValueError(f"the interval hull of step {k} has shape {np.shape(I.lo)}, "
                         f"expected ({n},)")
    crossed = np.asarray(I.lo) - np.asarray(I.hi) > 1e-9 * np.maximum(
        1.0, np.maximum(np.abs(I.lo), np.abs(I.hi)))
    if np.any(crossed):  # not an interval: never scored
        i = int(np.argmax(crossed))
        raise ValueError(f"the interval hull of step {k} has lo > hi in state {i + 1} "
                         f"({float(I.lo[i]):.6g} > {float(I.hi[i]):.6g})")


#: steps whose median cost projects the rest of a budgeted run (:func:`run`)
BUDGET_WINDOW = 3


def _over_budget(result: RunResult, k: int, N: int, start: float, budget: float) -> bool:
    """After step ``k``: whether the steps run and the ``N - k - 1`` left at the recent
    median cost exceed ``budget``; if so, the run's status becomes ``"timeout"``."""
    spent = perf_counter() - start
    recent = result.step_times[max(0, k + 1 - BUDGET_WINDOW):k + 1] + \
        result.hull_times[max(0, k + 1 - BUDGET_WINDOW):k + 1]
    projected = spent + (N - k - 1) * float(np.median(recent))
    if projected <= budget:
        return False
    result.status, result.failed_step = "timeout", k + 1
    result.message = (f"stopped after step {k} of {N} (steps 0-{k}: {spent:.3g} s, the last "
                      f"at {1e3 * float(np.median(recent)):.3g} ms per step): the record "
                      f"would take about {projected:.3g} s, over the budget of {budget:g} s")
    return True
