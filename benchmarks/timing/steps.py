"""Per-step timing of observers against a plain Kalman filter step.

``python -m benchmarks time NAME... --scenario S [--repeat N] [--warmup K] [--steps M]
[--steady] [--json F]``

Each observer is designed once (the offline design is not part of the step times; its
duration is reported separately as ``design_s``), then run ``repeat`` times over the
scenario's record by :func:`observers.run`, which times every ``step()`` and every interval
hull (``RunResult.step_times``, ``RunResult.hull_times``).  The first ``warmup`` steps of each
run are dropped (default :func:`benchmarks.metrics.warmup_steps`, as in ``summary.csv``); the
statistics are over the remaining steps of all runs together.  ``--steady`` times the steady
state only: a zonotope observer's set grows by its new generators every step until the order
reduction caps it, and its steps get dearer until then; the timed steps start where the set
size (generators, and constraints of a constrained zonotope) stops changing
(:func:`steady_from`), and the table says from which step and whether it was reached.

Reference: right after the observer, in the same process and on the same record, a plain
numpy Kalman filter (:func:`kalman_step_times`) is timed the same way; ``ratio`` is the
observer's median step time divided by the Kalman filter's median step time.

Observers whose hulls solve LPs with a :class:`~observers.sets.HullLP` (the CZN observers)
expose its counters as ``hull_stats``; they are reported per run (median over the runs).

Timings on a shared machine are noisy: read them as indicative, never as test values.
"""

from __future__ import annotations

import dataclasses
import math
import sys
from dataclasses import asdict, dataclass
from time import perf_counter
from typing import Any

import numpy as np

import observers
import systems
from observers.base import as_record
from observers.sets import EmptySet
from systems import Scenario

from ..errors import ConfigError
from ..io import environment
from ..metrics import warmup_steps
from ..report.numbers import fmt, text_table
from ..run.rows import design_observer, merge_options

DEFAULT_REPEAT = 5
#: how the reference Kalman filter is built (printed with the table and stored in the JSON)
KALMAN_MODEL = ("numpy Kalman filter, covariance form (predict P = A P A' + Q, update with "
                "K = P C' (C P C' + R)^-1, P = (I - K C) P); Q = E E'/3, R = F F'/3 from the "
                "generators E of W and F of V (the covariances of uniform noise on the "
                "generator factors), means W.c and V.c, x0 = X0.c, P0 = G0 G0'/3")


@dataclass
class TimingRow:
    """Timing of one observer on one scenario (times after the warm-up of every run).

    Attributes
    ----------
    observer : str
        Observer name.
    status : str
        ``"ok"``, or why no timing is reported: a failed design (``noGain``, ``unsupported``,
        ``error``) or a failed run (``diverged``, ``empty``, ``error``).
    message : str
        Reason of a failure (``""`` if none).
    step_ms_median, step_ms_p90 : float
        Median and 90th percentile of the ``step()`` times (ms).
    hull_ms_median : float
        Median of the interval hull times (ms).
    step_hull_ms_median : float
        Median of the per-step sums of ``step()`` and interval hull times (ms).
    timed_steps : int
        Number of steps in these statistics (all runs together).
    design_s : float
        Duration of the offline design (s; a cached design loads fast).
    kalman_ms_median : float
        Median step time of the reference Kalman filter (ms; NaN if the system has no model
        for it).
    ratio : float
        ``step_ms_median / kalman_ms_median``.
    hull_lp : dict or None
        Per run (median over the runs): ``solves``, ``iterations``, ``fallbacks`` (LPs handed
        to HiGHS) and ``iterations_per_solve`` of the hull LPs; ``None`` if the observer has
        none.
    first_timed : int
        The first timed step (1-based): the warm-up plus one, or with ``steady=True`` the
        first step of the steady state (:func:`steady_from`).
    steady : bool or None
        With ``steady=True``: whether the run reached its steady state (the size of the
        estimated set constant over at least :data:`MIN_STEADY_STEPS` steps up to the end
        of the run; if not, the timed steps are the last ones, still growing); ``None``
        without.
    """

    observer: str
    status: str
    message: str = ""
    step_ms_median: float = math.nan
    step_ms_p90: float = math.nan
    hull_ms_median: float = math.nan
    step_hull_ms_median: float = math.nan
    timed_steps: int = 0
    design_s: float = math.nan
    kalman_ms_median: float = math.nan
    ratio: float = math.nan
    hull_lp: dict[str, float] | None = None
    first_timed: int = 0
    steady: bool | None = None


#: fewest steps at the final set size for a run to count as steady (:func:`steady_from`)
MIN_STEADY_STEPS = 3


def set_size(S: Any) -> tuple[int, ...]:
    """The size of an estimated set: its number of generators and, for a constrained set,
    of constraints (``()`` for a set without generators, e.g. an interval or ellipsoid)."""
    G = getattr(S, "G", None)
    if G is None or np.ndim(G) != 2:
        return ()
    A = getattr(S, "A", None)
    rows = A.shape[0] if A is not None and np.ndim(A) == 2 and A.shape[1] == G.shape[1] else 0
    return (G.shape[1], rows)


def steady_from(sizes: list[tuple[int, ...]]) -> tuple[int, bool]:
    """The first step (0-based) from which the set size stays at its final value, and
    whether the run is steady (at least :data:`MIN_STEADY_STEPS` steps at that size).

    A zonotope observer adds generators every step until its order reduction caps them (the
    step cost grows until then); a constrained zonotope also its constraints.  Timing only
    the steps from here on gives the cost of the observer in operation, not of its start."""
    if not sizes:
        return 0, False
    k = len(sizes) - 1
    while k > 0 and sizes[k - 1] == sizes[-1]:
        k -= 1
    return k, len(sizes) - k >= MIN_STEADY_STEPS


class _Sizes:
    """An observer that records the size of every set it returns (:func:`set_size`)."""

    def __init__(self, obs: Any) -> None:
        self.obs = obs
        self.sizes: list[tuple[int, ...]] = []
        for attr in ("name", "design_time", "system"):
            if hasattr(obs, attr):
                setattr(self, attr, getattr(obs, attr))

    def reset(self) -> None:
        self.sizes = []
        if callable(getattr(self.obs, "reset", None)):
            self.obs.reset()

    def step(self, u_prev: Any, y: Any) -> Any:
        S = self.obs.step(u_prev, y)
        self.sizes.append(set_size(S))
        return S


def kalman_step_times(system: Any, u: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Seconds of every predict + update step of a plain Kalman filter over one record.

    The filter is the textbook covariance form on the observer's model: at step ``k``
    (``k > 0``) predict ``x = A x + B u[k-1] + W.c``, ``P = A P A' + Q``, then update with
    ``y[k]``: ``S = C P C' + R``, ``K = P C' S^-1``, ``x = x + K (y[k] - C x - V.c)``,
    ``P = (I - K C) P`` (step 0 is the update of the prior ``x0 = X0.c``, ``P0 = G0 G0'/3``).
    The covariances are those of uniform noise on the generator factors of the bounded sets,
    ``Q = E E'/3`` and ``R = F F'/3`` for the generators ``E`` of ``W`` and ``F`` of ``V``.
    Only the step is timed (``perf_counter``), not the set-up of ``Q`` and ``R``.

    A nonlinear system (``system.is_linear`` false) gets the extended Kalman filter, the
    same equations with ``f(x, u)`` for ``A x + B u``, its Jacobian at the estimate for ``A``,
    and, for an output ``h``, ``h(x)`` for ``C x`` with ``C`` its Jacobian at the prediction
    (:func:`extended_kalman_step_times`).

    Parameters
    ----------
    system : LinearSystem or NonlinearSystem
        A system with ``A``, ``B``, ``C`` (or ``f``, ``jacobian`` and ``C`` or ``h``,
        ``h_jacobian``) and zonotopes ``W``, ``V``, ``X0``.
    u : (N, nu) or (N - 1, nu) ndarray
        Inputs; ``u[k-1]`` enters step ``k``.
    y : (N, ny) ndarray
        Measurements.

    Returns
    -------
    (N,) ndarray
        Seconds of each step.

    Raises
    ------
    numpy.linalg.LinAlgError
        If an innovation covariance ``S`` is singular.
    """
    if not getattr(system, "is_linear", True):
        return extended_kalman_step_times(system, u, y)
    A, B, C = (np.asarray(M, dtype=float) for M in (system.A, system.B, system.C))
    u, y = as_record(u, y, B.shape[1], C.shape[0])
    E, F, G0 = system.W.G, system.V.G, system.X0.G
    Q, R = E @ E.T / 3.0, F @ F.T / 3.0
    w_mean, v_mean = np.asarray(system.W.c, float), np.asarray(system.V.c, float)
    x = np.array(system.X0.c, dtype=float)
    P = G0 @ G0.T / 3.0
    eye = np.eye(A.shape[0])
    times = np.empty(y.shape[0])
    for k in range(y.shape[0]):
        t0 = perf_counter()
        if k > 0:
            x = A @ x + B @ u[k - 1] + w_mean
            P = A @ P @ A.T + Q
        PCt = P @ C.T
        S = C @ PCt + R
        K = np.linalg.solve(S, PCt.T).T  # P C' S^-1 (S is symmetric)
        x = x + K @ (y[k] - C @ x - v_mean)
        P = (eye - K @ C) @ P
        times[k] = perf_counter() - t0
    return times


def extended_kalman_step_times(system: Any, u: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Seconds of every step of the extended Kalman filter over one record of a nonlinear
    system: as :func:`kalman_step_times` with ``x = f(x, u[k-1]) + W.c``,
    ``P = J P J' + Q`` (``J = df/dx`` at the previous estimate) and, for an output ``h``, the
    innovation ``y[k] - h(x) - V.c`` with ``C = dh/dx`` at the prediction."""
    linear_output = getattr(system, "output_is_linear", True)
    C = np.asarray(system.C, dtype=float) if linear_output else None
    ny = C.shape[0] if C is not None else system.ny
    u, y = as_record(u, y, system.nu, ny)
    E, F, G0 = system.W.G, system.V.G, system.X0.G
    Q, R = E @ E.T / 3.0, F @ F.T / 3.0
    w_mean, v_mean = np.asarray(system.W.c, float), np.asarray(system.V.c, float)
    x = np.array(system.X0.c, dtype=float)
    P = G0 @ G0.T / 3.0
    eye = np.eye(x.size)
    times = np.empty(y.shape[0])
    for k in range(y.shape[0]):
        t0 = perf_counter()
        if k > 0:
            J = np.asarray(system.jacobian(x, u[k - 1])[0], dtype=float)
            x = np.asarray(system.f(x, u[k - 1]), dtype=float) + w_mean
            P = J @ P @ J.T + Q
        if linear_output:
            H, yhat = C, C @ x
        else:
            H, yhat = np.asarray(system.h_jacobian(x), dtype=float), system.h(x)
        PHt = P @ H.T
        S = H @ PHt + R
        K = np.linalg.solve(S, PHt.T).T
        x = x + K @ (y[k] - yhat - v_mean)
        P = (eye - K @ H) @ P
        times[k] = perf_counter() - t0
    return times


def _kalman_median_ms(sc: Scenario, repeat: int, warmup: int) -> float:
    """Median Kalman step (ms) over ``repeat`` runs of the record, warm-up dropped; NaN if the
    system has no model for it or the filter fails numerically."""
    try:
        t = np.concatenate([kalman_step_times(sc.system, sc.u, sc.y)[warmup:]
                            for _ in range(repeat)])
    except (AttributeError, ValueError, np.linalg.LinAlgError):
        return math.nan
    t = t[np.isfinite(t)]
    return float(np.median(t) * 1e3) if t.size else math.nan


def time_observer(name: str, sc: Scenario, options: dict, repeat: int, warmup: int,
                  steady: bool = False) -> TimingRow:
    """Design ``name`` once, run it ``repeat`` times over ``sc``'s record, then time the
    Kalman filter on the same record; failures become the row's status.

    With ``steady=True`` only the steps of the steady state are timed (:func:`steady_from`,
    at least ``warmup`` steps dropped): with ``repeat`` 1 the one run records the set sizes
    (the recording is inside the timed step, well below a microsecond: meant for the large
    systems); with ``repeat`` above 1 an untimed first run finds the steady state and the
    ``repeat`` runs that follow are timed from there.

    Parameters
    ----------
    name : str
        Registered observer name.
    sc : Scenario
        Scenario with the system and the record.
    options : dict
        Observer options (as :func:`benchmarks.run.rows.merge_options` gives them).
    repeat : int
        Runs over the record (at least 1).
    warmup : int
        Steps dropped at the start of every run.

    Returns
    -------
    TimingRow
    """
    obs, status, message = design_observer(name, sc, options)
    if obs is None:
        return TimingRow(name, status, message)
    steps, hulls, lp_runs = [], [], []
    reached: bool | None = None
    # steady state: a probe run records the set sizes (timed itself when it is the only run)
    runs = ([_Sizes(obs)] + [obs] * (repeat if repeat > 1 else 0)) if steady else [obs] * repeat
    for runner in runs:
        try:
            res = observers.run(runner, sc.u, sc.y, keep_sets=False)
        except Exception as exc:  # a plugin bug must not end the table
            print(f"warning: {name} failed on {sc.name}: {exc}", file=sys.stderr)
            return TimingRow(name, "error", f"{type(exc).__name__}: {exc}",
                             design_s=obs.design_time)
        if res.status != "ok":
            return TimingRow(name, res.status, res.message, design_s=obs.design_time)
        if isinstance(runner, _Sizes):
            k, reached = steady_from(runner.sizes)
            if reached:  # else the steps after the warm-up, all still growing
                warmup = min(max(warmup, k), sc.N - 1)
            if repeat > 1:
                continue  # the probe run is not timed
        steps.append(res.step_times[warmup:])
        hulls.append(res.hull_times[warmup:])
        stats = getattr(obs, "hull_stats", None)
        if stats is not None:
            lp_runs.append(stats)
    timed = _Timed(np.concatenate(steps), np.concatenate(hulls), warmup + 1, reached)
    return _timing_row(name, obs, timed, _kalman_median_ms(sc, repeat, warmup), lp_runs)


@dataclass(frozen=True)
class _Timed:
    """The timed steps of one observer: seconds of each step and of its hull (NaN: not
    timed), the first timed step (1-based) and whether the steady state was reached."""

    step_s: np.ndarray
    hull_s: np.ndarray
    first_timed: int
    steady: bool | None


def _timing_row(name: str, obs: Any, timed: _Timed, kalman: float, lp_runs: list
                ) -> TimingRow:
    """The ``ok`` row of the ``timed`` steps, ``kalman`` ms, and the median over ``lp_runs``
    (the observer's ``hull_stats`` after each timed run) of the hull LP counters."""
    first_timed, steady = timed.first_timed, timed.steady
    step, hull = timed.step_s * 1e3, timed.hull_s * 1e3
    step_median = float(np.median(step))
    row = TimingRow(
        name, "ok", "", step_median, float(np.percentile(step, 90)), float(np.median(hull)),
        float(np.median(step + hull)), int(step.size), obs.design_time, kalman,
        step_median / kalman if kalman > 0 else math.nan, first_timed=first_timed,
        steady=steady)
    if lp_runs:
        row.hull_lp = {key: float(np.median([getattr(s, key) for s in lp_runs]))
                       for key in ("solves", "iterations", "fallbacks", "iterations_per_solve")}
    return row


def time_observer_fast_forward(name: str, sc: Scenario, options: dict, timed: int,
                               hulls: bool = True) -> TimingRow:
    """Design ``name``, step it over ``sc``'s record *without* interval hulls until its set
    size has not changed for :data:`MIN_STEADY_STEPS` steps (the steady state; these steps
    are not timed), then time the next ``timed`` steps, each ``step()`` and its interval
    hull, as :func:`observers.run` does.

    For the large constrained zonotopes (100-200 tanks), whose steady state lies ~60-100
    steps in and whose hulls cost seconds there: the hulls of the way there would dominate
    the command's budget, and the first steps, with small sets, are not the cost of the
    observer in operation.  The row's ``steady`` says whether the size stayed constant over
    the timed steps too; a failure (``diverged``, ``empty``, an exception) is the row's
    status.  With ``hulls=False`` the timed steps run without hulls too (``step()`` only;
    the hull columns are NaN): for sets whose hull takes minutes.
    """
    obs, status, message = design_observer(name, sc, options)
    if obs is None:
        return TimingRow(name, status, message)
    u, y = sc.u, sc.y
    sizes: list[tuple[int, ...]] = []
    steps, hull_times = [], []
    k = 0
    try:
        obs.reset()
        for S in to_steady_state(obs, sc):
            sizes.append(set_size(S))
            k += 1
        first = k
        while k < min(first + timed, sc.N):
            t0 = perf_counter()
            S = obs.step(u[k - 1], y[k])
            t1 = perf_counter()
            if hulls:
                S.interval()
            t2 = perf_counter()
            steps.append(t1 - t0)
            hull_times.append(t2 - t1 if hulls else math.nan)
            sizes.append(set_size(S))
            k += 1
    except observers.Diverged as exc:
        return TimingRow(name, "diverged", f"step {k}: {exc}", design_s=obs.design_time)
    except EmptySet as exc:
        return TimingRow(name, "empty", f"step {k}: {exc}", design_s=obs.design_time)
    except Exception as exc:  # a plugin bug must not end the table
        print(f"warning: {name} failed on {sc.name}: {exc}", file=sys.stderr)
        return TimingRow(name, "error", f"{type(exc).__name__}: {exc}",
                         design_s=obs.design_time)
    if not steps:
        return TimingRow(name, "error", f"no steady state within the {sc.N} steps of "
                         f"{sc.name}", design_s=obs.design_time)
    steady = len(set(sizes[first - MIN_STEADY_STEPS:])) == 1
    stats = getattr(obs, "hull_stats", None)
    timed = _Timed(np.array(steps), np.array(hull_times), first + 1, steady)
    return _timing_row(name, obs, timed, _kalman_median_ms(sc, 1, first),
                       [] if stats is None else [stats])


def to_steady_state(obs: Any, sc: Scenario):
    """Step ``obs`` (reset) over ``sc``'s record without interval hulls, yielding each set,
    until its size (:func:`set_size`) has not changed for :data:`MIN_STEADY_STEPS` steps or
    the record ends; exceptions of ``step()`` propagate."""
    u, y = sc.u, sc.y
    sizes: list[tuple[int, ...]] = []
    k = 0
    while k < sc.N and not (len(sizes) >= MIN_STEADY_STEPS
                            and len(set(sizes[-MIN_STEADY_STEPS:])) == 1):
        S = obs.step(u[k - 1] if k else None, y[k])
        sizes.append(set_size(S))
        k += 1
        yield S


def first_steps(sc: Scenario, steps: int | None) -> Scenario:
    """``sc`` restricted to its first ``steps`` steps (``sc`` itself if ``steps`` is None).

    Raises
    ------
    ConfigError
        If ``steps`` is below 1.
    """
    if steps is None or steps >= sc.N:
        return sc
    if steps < 1:
        raise ConfigError(f"--steps must be at least 1, got {steps}")
    x_true = None if sc.x_true is None else sc.x_true[:steps]
    return dataclasses.replace(sc, u=sc.u[:steps], y=sc.y[:steps], x_true=x_true)


def resolve_warmup(sc: Scenario, warmup: int | None) -> int:
    """The steps dropped per run: ``warmup``, or :func:`warmup_steps` of the record length.

    Raises
    ------
    ConfigError
        If ``warmup`` is negative or leaves no step to time.
    """
    if warmup is None:
        return warmup_steps(sc.N)
    if warmup < 0:
        raise ConfigError(f"--warmup must be non-negative, got {warmup}")
    if warmup >= sc.N:
        raise ConfigError(f"--warmup {warmup} leaves no step to time ({sc.name} has {sc.N} "
                          "steps)")
    return warmup


@dataclass(frozen=True)
class TimingPlan:
    """How :func:`time_observers` times each observer.

    Attributes
    ----------
    repeat : int
        Runs over the record per observer.
    warmup : int or None
        Steps dropped at the start of every run (default :func:`warmup_steps`).
    steps : int or None
        Run only the first ``steps`` steps of the record (default: all of them).
    steady : bool
        Time only the steady state of every observer (see :func:`time_observer`).
    fast_forward : int
        If positive: reach the steady state without hulls, then time this many steps
        (:func:`time_observer_fast_forward`; ``repeat``, ``warmup`` and ``steady`` unused).
    hulls : bool
        With ``fast_forward``: time the interval hulls too (else ``step()`` only).
    """

    repeat: int = DEFAULT_REPEAT
    warmup: int | None = None
    steps: int | None = None
    steady: bool = False
    fast_forward: int = 0
    hulls: bool = True


def time_observers(names: list[str], scenario: str, plan: TimingPlan = TimingPlan(),
                   own: dict[str, Any] | None = None
                   ) -> tuple[Scenario, int, list[TimingRow]]:
    """Time every observer of ``names`` on ``scenario`` (see the module docstring).

    Parameters
    ----------
    names : list of str
        Observer names (each is timed once, in the given order).
    scenario : str
        Scenario name (``python -m benchmarks list scenarios``).
    plan : TimingPlan
        Runs, warm-up, steps, steady state or fast forward (default: :class:`TimingPlan`).
    own : dict, optional
        Options of every observer timed, over the scenario's defaults (e.g. ``{"window":
        5}``; see :func:`benchmarks.run.rows.merge_options`).

    Returns
    -------
    sc : Scenario
    warmup : int
        The steps dropped per run.
    rows : list of TimingRow

    Raises
    ------
    ConfigError
        Bad ``repeat``, ``warmup`` or ``steps``.
    observers.UnknownObserver, systems.ModelError
        Unknown observer or scenario (before anything runs).
    """
    if plan.repeat < 1:
        raise ConfigError(f"--repeat must be at least 1, got {plan.repeat}")
    names = list(dict.fromkeys(names))
    for name in names:
        observers.get(name)  # unknown names fail before anything runs
    sc = first_steps(systems.scenario(scenario), plan.steps)
    warmup = resolve_warmup(sc, plan.warmup)
    if plan.fast_forward > 0:
        rows = [time_observer_fast_forward(name, sc, merge_options(name, sc, own=own),
                                           plan.fast_forward, plan.hulls)
                for name in names]
    else:
        rows = [time_observer(name, sc, merge_options(name, sc, own=own), plan.repeat, warmup,
                              plan.steady)
                for name in names]
    return sc, warmup, rows


def format_table(sc: Scenario, repeat: int, warmup: int, rows: list[TimingRow]) -> str:
    """The plain-text table of ``python -m benchmarks time``."""
    head = ["observer", "status", "step med", "step p90", "hull med", "step+hull", "steps",
            "from", "design s", "KF step", "ratio"]
    body = [[r.observer, r.status, fmt(r.step_ms_median), fmt(r.step_ms_p90),
             fmt(r.hull_ms_median), fmt(r.step_hull_ms_median), str(r.timed_steps),
             str(r.first_timed) + ("" if r.steady is None else " (steady)" if r.steady
                                   else " (growing)"),
             fmt(r.design_s), fmt(r.kalman_ms_median), fmt(r.ratio)] for r in rows]
    steady = any(r.steady is not None for r in rows)
    lines = [
        f"{sc.name}: {repeat} run(s) of {sc.N} steps per observer, "
        + ("timed from the step in 'from' (the steady state; an untimed probe run first when "
           "repeat > 1)" if steady else f"the first {warmup} step(s) of each run not timed"),
        "times in ms (median, 90th percentile) over the timed steps of all runs; design in s",
        text_table(head, body, right=[False, False] + [True] * 9),
        "KF step: plain numpy Kalman filter step (covariance form; Q = E E'/3, R = F F'/3 "
        "from the",
        "generators of W and V), timed after each observer on the same record; "
        "ratio = step med / KF step",
    ]
    for r in rows:
        if r.hull_lp is not None:
            s = r.hull_lp
            lines.append(f"hull LPs of {r.observer} per run: {s['solves']:.0f} LPs, "
                         f"{s['iterations_per_solve']:.2f} simplex iterations per LP, "
                         f"{s['fallbacks']:.0f} handed to HiGHS")
    for r in rows:
        if r.status != "ok":
            lines.append(f"note: {r.observer}: {r.status}: {r.message}")
    return "\n".join(lines)


def _finite_or_none(x: Any) -> Any:
    if isinstance(x, float) and not math.isfinite(x):
        return None
    if isinstance(x, dict):
        return {k: _finite_or_none(v) for k, v in x.items()}
    return x


def to_json(sc: Scenario, repeat: int, warmup: int, rows: list[TimingRow]) -> dict[str, Any]:
    """All numbers of the table as a JSON-ready dict (NaN as ``null``).

    Keys: ``scenario``, ``steps_per_run``, ``repeat``, ``warmup``, ``kalman_model``,
    ``environment`` (:func:`benchmarks.io.environment`) and ``results``, one dict per
    observer with the fields of :class:`TimingRow`.
    """
    return {
        "scenario": sc.name,
        "steps_per_run": sc.N,
        "repeat": repeat,
        "warmup": warmup,
        "kalman_model": KALMAN_MODEL,
        "environment": environment(),
        "results": [{k: _finite_or_none(v) for k, v in asdict(r).items()} for r in rows],
    }
