"""The accuracy floor of a record, and every observer's distance to it.

No guaranteed observer can be tighter than the set of states consistent with the record (the
model, the noise bounds and the measurements so far); every guaranteed observer must contain
it.  This module computes that floor once per record and holds every observer's row against
it:

* **linear records**: the exact consistent set, by the reference estimator ``Exact``
  (:func:`observers.builtin.exact.exact_hulls`: sound interval hulls of the polytope of
  consistent states, cached on disk).  Two floors, because observers differ in what they have
  seen: *filtered* (after ``y[k]``) and *predicted* (before ``y[k]``); an observer is held
  against the floor of its registry entry (:attr:`observers.ObserverInfo.floor`) unless the
  configuration says otherwise (``floors: {NAME: predicted}``);
* **nonlinear records**: no exact set exists, so the falsifier
  (:mod:`benchmarks.run.falsifier`, run by :func:`.floor_inner.inner_floor`) searches verified
  consistent trajectories that make each state as large or as small as possible at
  :data:`.floor_inner.FALSIFIER_STEPS` steps spread from :data:`.floor_inner.FALSIFIER_FIRST`
  of the record on; the extremes form an *inner* box of the filtered consistent set (also
  inside the predicted one).

A run computes the floor of every scenario instance before the observers' jobs, by its
executor (:func:`.floors.compute_floors`: one :class:`.floors.FloorTask` per instance, run by
:func:`.floors.floor_task` in this process or a worker).  This module holds the exact floor and
what every row does with a floor; the falsifier's floor is :mod:`.floor_inner`, so that only
the rows of nonlinear records depend on the falsifier's code.

Per observer row (:func:`floor_columns`):

* ``gap`` per state: the RMS radius of the observer over the RMS radius of its floor, over the
  steps where both are known (every step for a linear record: the observer's ``rms_radius``
  divided by the floor's; the falsifier's steps for a nonlinear one, where the inner box makes
  it an upper bound, ``gap_kind = upper``);
* ``gap_steady`` per state: the same ratio over the steady steps only, those from
  :func:`benchmarks.metrics.steady_start` on (the first 20 % of the record, dominated by the
  initial set for every observer and the floor alike, left out): the gap in operation;
* ``covers_exact``: ``no`` if at some step the observer's interval hull misses a consistent
  state -- for a linear record, the hull does not contain the exact floor's hull up to
  :data:`COVER_RTOL` of the floor's radius, :data:`COVER_MAG_RTOL` of the bound's magnitude
  (the floor's own precision) and the scenario's containment tolerance; for a
  nonlinear record, a verified consistent state found by the falsifier lies outside the hull
  -- ``yes`` if every step of a complete run was checked against the exact floor and none
  missed (steps where the exact reference solved an LP only inexactly,
  :attr:`RecordFloor.unchecked`, have no floor: a loose floor would flag a sound observer;
  they are named in the reference's row), ``n/a`` otherwise (no floor, a nonlinear record
  without a violation: nothing proves that every consistent state is inside);
* ``uncovered_steps`` and ``first_uncovered_step``.

A record that no state fits (the exact floor is empty) contradicts its model: every observer's
row of it says so (status ``inconsistent``), whatever its sets.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

import observers
from observers.errors import ObserverError, Unsupported
from observers.sets import SetError
from systems import ModelError, Scenario

from ..metrics import steady_start
from ..verdicts import NA, NO, YES

#: an observer's hull covers the exact hull if it misses it by at most this share of the exact
#: radius (plus the scenario's containment tolerance): the agreement of the exact hulls with
#: an independent LP formulation is checked to this bound
COVER_RTOL = 1e-6
#: ... plus this share of the bound's magnitude (at least 1): the floor's bounds are sound
#: outer bounds from dual points, and on a degenerate record (the audit's vertex noise, a
#: consistent set 1e-8 thin in some states) they exceed the exact hull by up to ~1e-7 of the
#: magnitude (measured: 9.9e-7 on x1 = 13.9 of tank6-linear, audit realisation 2, step 186,
#: against an independent from-scratch LP), so a sound observer tighter than the computed
#: floor by less than this is not flagged
COVER_MAG_RTOL = 1e-6
#: the kinds of floor
EXACT, INNER = "exact", "inner"
#: ``gap_kind`` of a row: the gap itself, or an upper bound of it
GAP_EXACT, GAP_UPPER = "exact", "upper bound"


@dataclass
class RecordFloor:
    """The floor of one record.

    ``kind`` is :data:`EXACT` (``lo``/``hi`` of both floors at every step), :data:`INNER` (the
    falsifier's inner box of the filtered set at ``steps``, used for both floors), ``"empty"``
    (no state fits the record: ``message`` says where) or ``"none"`` (not computed:
    ``message`` says why).
    """

    kind: str
    lo: dict[str, np.ndarray] | None = None
    hi: dict[str, np.ndarray] | None = None
    steps: np.ndarray | None = None
    message: str = ""
    seconds: float = 0.0
    #: median seconds of a computed step of the exact reference (NaN: every step was read
    #: from its cache, or no exact floor)
    step_seconds: float = float("nan")
    #: steps without a floor because an LP of the exact reference was not solved to
    #: optimality (their hulls are sound but maybe loose; ``lo``/``hi`` are NaN there)
    unchecked: tuple[int, ...] = ()

    @property
    def usable(self) -> bool:
        return self.kind in (EXACT, INNER)

    def bounds(self, floor: str, N: int, n: int) -> tuple[np.ndarray, np.ndarray]:
        """The floor ``floor`` as N x n arrays (NaN where it is not known)."""
        lo, hi = np.full((N, n), np.nan), np.full((N, n), np.nan)
        if self.usable:
            key = floor if self.kind == EXACT else "filtered"
            rows = np.arange(N) if self.steps is None else self.steps
            lo[rows], hi[rows] = self.lo[key][: len(rows)], self.hi[key][: len(rows)]
        return lo, hi


def guarded(compute: Callable[[float], RecordFloor]) -> RecordFloor:
    """``compute(t0)`` with the failures of a record turned into floors: no state fits it
    (``kind = "empty"``), or no floor can be computed for it (``"none"``, with the reason)."""
    t0 = time.perf_counter()
    try:
        return compute(t0)
    except SetError as exc:  # EmptySet: no state fits the record
        return RecordFloor("empty", message=str(exc), seconds=time.perf_counter() - t0)
    except (Unsupported, ModelError, ObserverError) as exc:
        return RecordFloor("none", message=f"no floor: {exc}", seconds=time.perf_counter() - t0)


def exact_floor(sc: Scenario) -> RecordFloor:
    """The exact floor of a linear record (see the module docstring); never raises for a
    record it cannot handle."""
    return guarded(lambda t0: _exact(sc, t0))


def _exact(sc: Scenario, t0: float) -> RecordFloor:
    """The exact floor by the reference estimator ``Exact`` (its on-disk cache included)."""
    obs = observers.create("Exact", sc.system)
    with obs.sole_writer(sc.y):
        res = observers.run(obs, sc.u, sc.y, keep_sets=False)
    if res.status == "empty":
        raise SetError(res.message)
    if res.status != "ok":
        raise ObserverError(f"Exact: {res.status}: {res.message}")
    h = obs.hull_arrays()
    unchecked = tuple(obs.inexact_steps())
    for key in h:  # a loose floor is no floor: the steps are not checked
        h[key][list(unchecked)] = np.nan
    computed = obs.lp_stats["computed_steps"]
    step = float(np.median(res.step_times[-computed:])) if computed else float("nan")
    return RecordFloor(EXACT, {"filtered": h["filt_lo"], "predicted": h["pred_lo"]},
                       {"filtered": h["filt_hi"], "predicted": h["pred_hi"]},
                       seconds=time.perf_counter() - t0, step_seconds=step,
                       unchecked=unchecked)


def observer_floor(name: str, overrides: dict[str, str] | None = None) -> str:
    """The floor observer ``name`` is held against (the configuration's ``floors`` entry, else
    its registry entry's)."""
    if overrides and name in overrides:
        return overrides[name]
    try:
        return observers.get(name.split("[")[0]).floor
    except ObserverError:
        return "filtered"


def floor_columns(floor: RecordFloor, which: str, lo: np.ndarray, hi: np.ndarray,
                  complete: bool, tol: float) -> dict:
    """The floor columns of one observer row (see the module docstring).

    Parameters
    ----------
    floor : RecordFloor
        The record's floor.
    which : {"filtered", "predicted"}
        The observer's floor.
    lo, hi : (N, n) arrays
        The observer's interval hulls (NaN rows where it produced none).
    complete : bool
        Whether the run produced every step (status ok).
    tol : float
        The scenario's absolute containment tolerance.

    Returns
    -------
    dict
        ``floor``, ``gap`` and ``gap_steady`` (n,), ``gap_kind``, ``covers_exact``,
        ``uncovered_steps``, ``first_uncovered_step``.
    """
    N, n = lo.shape
    out = {"floor": which if floor.usable else NA, "gap": np.full(n, np.nan),
           "gap_steady": np.full(n, np.nan), "gap_kind": NA, "covers_exact": NA,
           "uncovered_steps": None, "first_uncovered_step": None}
    if not floor.usable:
        return out
    flo, fhi = floor.bounds(which, N, n)
    known = np.all(np.isfinite(flo) & np.isfinite(fhi), axis=1)
    produced = np.all(np.isfinite(lo) & np.isfinite(hi), axis=1)
    have = produced & known
    if not have.any():
        return out
    missed = misses_floor(flo, fhi, lo, hi, tol) & have
    count = int(missed.sum())
    exact = floor.kind == EXACT
    checked = produced.all() and np.array_equal(known, np.isin(np.arange(N), floor.unchecked,
                                                                invert=True))
    out["covers_exact"] = NO if count else (YES if exact and complete and checked else NA)
    out["uncovered_steps"] = count if exact or count else None
    out["first_uncovered_step"] = int(np.argmax(missed)) if count else -1
    if complete or not exact:
        steady = have & (np.arange(N) >= steady_start(N))
        out["gap"] = _rms_ratio(lo, hi, flo, fhi, have)
        out["gap_steady"] = _rms_ratio(lo, hi, flo, fhi, steady)
        out["gap_kind"] = GAP_EXACT if exact else GAP_UPPER
    return out


def misses_floor(flo: np.ndarray, fhi: np.ndarray, lo: np.ndarray, hi: np.ndarray,
                 tol: float) -> np.ndarray:
    """Per step (the last axis: the states), whether the hull ``[lo, hi]`` fails to cover the
    floor ``[flo, fhi]`` beyond the coverage slack (:data:`COVER_RTOL` of the floor's radius,
    :data:`COVER_MAG_RTOL` of the bound's magnitude, the scenario's tolerance ``tol``); a
    NaN bound never misses."""
    mag = np.maximum(1.0, np.maximum(np.abs(flo), np.abs(fhi)))
    slack = COVER_RTOL * 0.5 * (fhi - flo) + COVER_MAG_RTOL * mag + tol
    with np.errstate(invalid="ignore"):
        return ((lo > flo + slack) | (hi < fhi - slack)).any(axis=-1)


def _rms_ratio(lo, hi, flo, fhi, steps: np.ndarray) -> np.ndarray:
    """Per state, the RMS radius of ``[lo, hi]`` over that of ``[flo, fhi]`` on the rows
    ``steps`` (inf where the floor's is zero, NaN where no step is selected)."""
    n = lo.shape[1]
    if not steps.any():
        return np.full(n, np.nan)
    r_obs = np.sqrt(np.mean((0.5 * (hi - lo))[steps] ** 2, axis=0))
    r_floor = np.sqrt(np.mean((0.5 * (fhi - flo))[steps] ** 2, axis=0))
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(r_floor > 0, r_obs / np.where(r_floor > 0, r_floor, 1.0), np.inf)
