"""The inner box of the falsifier (:mod:`benchmarks.run.falsifier`): :func:`falsify` drives
the search (:mod:`.search`) over the chosen steps, both directions of every state, and keeps
the verified extremes (:class:`FalsifierResult`: an inner box of the exact hull);
:meth:`FalsifierResult.check` holds observers' hulls to it (certified :class:`Violation`
records and upper bounds of their gap).  The package docstring has an example.
"""

from __future__ import annotations

import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from systems.errors import ModelError

from .search import (
    FACTOR_MARGIN,
    MAX_ITER,
    NOISE_MARGIN,
    BudgetSpent,
    Search,
    Stats,
    find_anchor,
    same_trajectory,
)
from .verification import Model, Trajectory

__all__ = ["REL_TOL", "FalsifierResult", "SearchOptions", "Violation", "falsify", "spread_steps"]

#: relative part of the tolerance of a violation (rounding of the forward simulation)
REL_TOL = 1e-9
#: window="auto": the whole horizon while it has at most this many state variables
AUTO_STATES = 3000
FLOORS = ("filtered", "predicted")


# -- results ------------------------------------------------------------------------------
@dataclass(frozen=True)
class Violation:
    """A verified consistent state outside an observer's interval hull.

    Attributes
    ----------
    observer : str
    step, state : int
        Time step ``k`` and state index ``i`` (0-based).
    side : {"lo", "hi"}
        Which bound of the hull the consistent value passes.
    value : float
        The consistent value of ``x_k[i]`` (of a verified trajectory).
    bound : float
        The hull's bound it passes.
    excess : float
        How far outside (``value - bound`` or ``bound - value``), larger than ``tol``.
    tol : float
        The tolerance applied.
    """

    observer: str
    step: int
    state: int
    side: str
    value: float
    bound: float
    excess: float
    tol: float


@dataclass
class FalsifierResult:
    """Inner box of the consistent set at chosen steps, the verified extremes, and the
    verdicts on observers' hulls.

    Attributes
    ----------
    steps : (S,) int array
        The steps searched.
    inner_lo, inner_hi : (S, n) arrays
        Smallest and largest verified consistent value of each state (NaN where nothing was
        verified): an inner box of the exact hull.
    lo_trajectories, hi_trajectories : list of list of Trajectory or None
        ``[s][i]``: the verified trajectory attaining ``inner_lo[s, i]`` / ``inner_hi[s, i]``
        (re-check with :func:`~.verification.verify`; empty lists with ``keep_trajectories=False``).
    floor : {"filtered", "predicted"}
        Whether ``y_k`` is part of the record reproduced at step ``k``.
    anchor : Trajectory
        The consistent trajectory of the whole record the searches start from.
    violations : list of Violation
        Certified violations of the hulls passed (see :meth:`check`).
    gap_upper : dict
        Observer -> (n,) upper bounds of its gap (RMS radius of the hull over the RMS radius
        of the inner box at the chosen steps).
    stats : dict
        Work and time: ``seconds``, ``lps``, ``simplex_iterations``, ``runs``,
        ``slp_iterations``, ``unconverged`` (runs that hit the iteration limit), ``verified``,
        ``steps_searched`` and ``budget_spent`` (the search stopped by its budget of simplex
        iterations, :class:`SearchOptions`).
    """

    steps: np.ndarray
    inner_lo: np.ndarray
    inner_hi: np.ndarray
    lo_trajectories: list
    hi_trajectories: list
    floor: str
    anchor: Trajectory
    violations: list = field(default_factory=list)
    gap_upper: dict = field(default_factory=dict)
    stats: dict = field(default_factory=dict)

    @property
    def inner_radius(self) -> np.ndarray:
        """Radii of the inner box (S x n)."""
        return 0.5 * (self.inner_hi - self.inner_lo)

    def check(self, observer: str, lo, hi, hull_tol: float = 0.0,
              rel_tol: float = REL_TOL) -> tuple[list[Violation], np.ndarray]:
        """Violations and gap upper bounds of one observer's interval hulls.

        Parameters
        ----------
        observer : str
            Name used in the :class:`Violation` records.
        lo, hi : (N, n) array_like
            The observer's hulls over the whole record (rows of the searched steps are
            used; NaN rows, e.g. after divergence, are skipped).
        hull_tol : float
            The hull's own (absolute) tolerance, added to ``rel_tol * max(1, |value|)``.

        Returns
        -------
        violations : list of Violation
        gap_upper : (n,) array
            ``rms(hull radius) / rms(inner radius)`` over the searched steps with both
            finite (inf where the inner box is a point, NaN without such steps).
        """
        lo, hi = np.asarray(lo, float), np.asarray(hi, float)
        if lo.ndim != 2 or lo.shape != hi.shape or lo.shape[0] <= self.steps.max(initial=0):
            raise ModelError(f"hulls of {observer} have shape {lo.shape}/{hi.shape}; expected "
                             f"(N, {self.inner_lo.shape[1]}) covering step "
                             f"{int(self.steps.max(initial=0))}")
        out: list[Violation] = []
        L, H = lo[self.steps], hi[self.steps]
        for s, k in enumerate(self.steps):
            for i in range(L.shape[1]):
                for side, value, bound in (("lo", self.inner_lo[s, i], L[s, i]),
                                           ("hi", self.inner_hi[s, i], H[s, i])):
                    if not (np.isfinite(value) and np.isfinite(bound)):
                        continue
                    tol = hull_tol + rel_tol * max(1.0, abs(value))
                    excess = bound - value if side == "lo" else value - bound
                    if excess > tol:
                        out.append(Violation(observer, int(k), i, side, float(value),
                                             float(bound), float(excess), float(tol)))
        ok = np.all(np.isfinite(L) & np.isfinite(H), axis=1) & np.all(
            np.isfinite(self.inner_lo) & np.isfinite(self.inner_hi), axis=1)
        if not ok.any():
            return out, np.full(L.shape[1], np.nan)
        r_obs = np.sqrt(np.mean((0.5 * (H - L))[ok] ** 2, axis=0))
        r_in = np.sqrt(np.mean(self.inner_radius[ok] ** 2, axis=0))
        with np.errstate(divide="ignore", invalid="ignore"):
            gap = np.where(r_in > 0, r_obs / np.where(r_in > 0, r_in, 1.0), np.inf)
        return out, gap

    def add_hulls(self, hulls: Mapping[str, Any],
                  hull_tol: float | Mapping[str, float] = 0.0) -> None:
        """:meth:`check` every observer of ``hulls`` (name -> object with ``lo``/``hi``,
        e.g. a :class:`~observers.RunResult`, or a pair ``(lo, hi)``); fills
        :attr:`violations` and :attr:`gap_upper`."""
        for name, hull in hulls.items():
            lo, hi = (hull.lo, hull.hi) if hasattr(hull, "lo") else hull
            tol = hull_tol.get(name, 0.0) if isinstance(hull_tol, Mapping) else hull_tol
            found, gap = self.check(name, lo, hi, float(tol))
            self.violations.extend(found)
            self.gap_upper[name] = gap


# -- driver -------------------------------------------------------------------------------
def spread_steps(N: int, count: int, first: int = 0) -> np.ndarray:
    """``count`` steps spread evenly over ``first .. N-1`` (always including ``N - 1``)."""
    if N < 1 or count < 1:
        raise ModelError(f"spread_steps: need N >= 1 and count >= 1, got {N}, {count}")
    first = min(max(int(first), 0), N - 1)
    return np.unique(np.round(np.linspace(first, N - 1, count)).astype(int))


def _record(record: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    if hasattr(record, "y"):
        return record.u, record.y, getattr(record, "x_true", None)
    if isinstance(record, (tuple, list)) and len(record) in (2, 3):
        return record[0], record[1], (record[2] if len(record) == 3 else None)
    raise ModelError("falsifier: the record must have u and y (a Scenario, a Simulation) or "
                     "be a tuple (u, y[, x_true])")


def _window_start(k: int, n: int, window: int | str | None) -> int:
    if window is None:
        return 0
    if window == "auto":
        window = max(1, AUTO_STATES // max(n, 1) - 1)
    return max(0, k - int(window))


@dataclass(frozen=True)
class SearchOptions:
    """How :func:`falsify` searches (checked when made).

    Attributes
    ----------
    starts : int
        SLP runs per objective (>= 1), see :mod:`.search`.
    seed : int
        Seed of the random directions of the extra starts (with the step: each step its
        own directions, whichever other steps are searched).
    floor : {"filtered", "predicted"}
        Reproduce ``y_0 .. y_k`` (the set after ``y_k``, against which every observer is
        held) or ``y_0 .. y_{k-1}`` (before ``y_k``: only for observers whose estimate of
        step ``k`` does not use ``y_k``; a larger set, so a larger inner box).
    window : int, "auto" or None
        Disturbances free over the last ``window`` steps before ``k`` (earlier ones stay at
        the anchor's; ``x_0`` is always free); None: the whole horizon; "auto": the whole
        horizon while ``(k + 1) n <= AUTO_STATES``.
    max_iter : int
        SLP iterations per run.
    keep_trajectories : bool
        Keep the verified extreme trajectories in the result.
    max_simplex_iterations : int or None
        A work budget for the whole search, in simplex iterations of its LPs (counted by
        HiGHS, so the same on every machine, unlike a time limit): once spent, the step
        being searched and the later ones are left out (NaN rows of the inner box; the
        result's ``stats`` say how many steps were searched).  None: no budget.
    """

    starts: int = 1
    seed: int = 0
    floor: str = "filtered"
    window: int | str | None = "auto"
    max_iter: int = MAX_ITER
    keep_trajectories: bool = True
    max_simplex_iterations: int | None = None

    def __post_init__(self):
        if self.floor not in FLOORS:
            raise ModelError(f"falsifier: floor must be one of {', '.join(FLOORS)}, "
                             f"got {self.floor!r}")
        starts, window = self.starts, self.window
        if isinstance(starts, bool) or not isinstance(starts, (int, np.integer)) or starts < 1:
            raise ModelError(f"falsifier: starts must be an integer >= 1, got {starts!r}")
        if not (window is None or window == "auto" or (
                isinstance(window, (int, np.integer)) and not isinstance(window, bool)
                and window >= 1)):
            raise ModelError(f"falsifier: window must be an integer >= 1, 'auto' or None, "
                             f"got {window!r}")
        budget = self.max_simplex_iterations
        if budget is not None and (isinstance(budget, bool) or not isinstance(
                budget, (int, np.integer)) or budget < 1):
            raise ModelError(f"falsifier: max_simplex_iterations must be an integer >= 1 or "
                             f"None, got {budget!r}")


def falsify(system: Any, record: Any, steps: int | Sequence[int] = 10,
            hulls: Mapping[str, Any] | None = None, *, options: SearchOptions | None = None,
            hull_tol: float | Mapping[str, float] = 0.0) -> FalsifierResult:
    """Search verified consistent extremes of every state at the chosen steps.

    Parameters
    ----------
    system : NonlinearSystem or LinearSystem
        ``f`` (or ``A, B``), ``C`` (or ``h``), ``W``, ``V``, ``X0``.
    record : Scenario, Simulation or tuple
        ``u``, ``y`` and, where known, ``x_true`` (the anchor of the search).
    steps : int or sequence of int
        The steps ``k`` (0-based) searched, or a count spread over the record
        (:func:`spread_steps`).
    hulls : mapping, optional
        Observer name -> its hulls (an object with ``lo``, ``hi``, e.g. a ``RunResult``, or
        a pair ``(lo, hi)``, N x n) to check (:meth:`FalsifierResult.check`).
    options : SearchOptions, optional
        How to search (default: :class:`SearchOptions` ``()``: one start, the filtered
        floor, the automatic window).
    hull_tol : float or mapping
        The hulls' own absolute tolerance (per observer in a mapping).

    Returns
    -------
    FalsifierResult
    """
    opts = SearchOptions() if options is None else options
    t0 = time.perf_counter()
    u, y, x_true = _record(record)
    M = Model(system, u, y)
    steps = _steps(steps, M.N)
    n = M.n
    stats = Stats()
    anchor = find_anchor(M, x_true, stats, 5 * opts.max_iter)
    if opts.max_simplex_iterations is not None:  # the budget of the searches after it
        stats.budget = stats.simplex_iterations + opts.max_simplex_iterations
    S = steps.size
    lo, hi = np.full((S, n), np.nan), np.full((S, n), np.nan)
    lo_tr: list = [[None] * n for _ in range(S)]
    hi_tr: list = [[None] * n for _ in range(S)]
    searched = 0
    for s, k in enumerate(steps.tolist()):
        try:
            search = _search_step(M, k, anchor, opts, stats)
        except BudgetSpent:  # this step and the later ones stay NaN
            break
        searched += 1
        verified = np.isfinite(search.lo)
        lo[s, verified], hi[s, verified] = search.lo[verified], search.hi[verified]
        if opts.keep_trajectories:
            lo_tr[s], hi_tr[s] = search.lo_traj, search.hi_traj
    result = FalsifierResult(
        steps=steps, inner_lo=lo, inner_hi=hi,
        lo_trajectories=lo_tr if opts.keep_trajectories else [],
        hi_trajectories=hi_tr if opts.keep_trajectories else [],
        floor=opts.floor, anchor=anchor.z,
        stats={"seconds": time.perf_counter() - t0, **vars(stats),
               "steps_searched": searched, "budget_spent": searched < S})
    if hulls:
        result.add_hulls(hulls, hull_tol)
    return result


def _steps(steps: int | Sequence[int], N: int) -> np.ndarray:
    """The searched steps: ``steps`` itself, or that many spread over the ``N`` steps."""
    if isinstance(steps, (int, np.integer)) and not isinstance(steps, bool):
        steps = spread_steps(N, int(steps))
    steps = np.unique(np.asarray(steps, dtype=int).reshape(-1))
    if steps.size == 0 or steps.min() < 0 or steps.max() >= N:
        raise ModelError(f"falsifier: steps must lie in 0 .. {N - 1}, got {steps.tolist()}")
    return steps


def _search_step(M: Model, k: int, anchor: Any, opts: SearchOptions, stats: Stats) -> Search:
    """The search of step ``k`` from the ``anchor`` point, run in both directions of every
    state (and from ``opts.starts - 1`` more starts: random directions seeded by
    ``(opts.seed, k)``, then each objective from the best other distinct trajectories);
    ``stats``: the run's work counters."""
    n = M.n
    scale = np.maximum(np.abs(M.G0).sum(axis=1), 1e-12)  # radii of X0's hull
    m = k + 1 if opts.floor == "filtered" else k
    search = Search(M, k, m, _window_start(k, n, opts.window), stats, opts.max_iter)
    start = search.evaluate(anchor.z.truncated(k, m))
    if not start.consistent:  # the prefix of a verified anchor: cannot happen
        raise ModelError(f"falsifier: the anchor is not consistent at step {k}")
    if (np.abs(start.nu).max(initial=0.0) > 1.0 - NOISE_MARGIN / 10
            or np.abs(search.lp.factors(start)).max(initial=0.0) > 1.0 - FACTOR_MARGIN / 10):
        # an anchor inside the margins (noise on the vertices of its sets): its consistent
        # set may have no interior, where margins would cut it; the polish does the rest
        search.lp.margin = search.lp.factor_margin = 0.0
    objectives = [(i, sgn) for sgn in (1.0, -1.0) for i in range(n)]
    finals = {}
    for i, sgn in objectives:
        c = np.zeros(n)
        c[i] = sgn / scale[i]
        stats.spend()
        finals[i, sgn] = search.run(start, c)
    if opts.starts > 1:
        rng = np.random.default_rng([opts.seed, k])  # this step's own directions
        for _ in range(opts.starts - 1):
            d = rng.standard_normal(n)
            stats.spend()
            search.run(start, d / np.linalg.norm(d) / scale)
        for i, sgn in objectives:
            tried = (start, finals[i, sgn])
            ranked = sorted(search.pool, key=lambda p, i=i, sgn=sgn: -sgn * p.X[k][i])
            c = np.zeros(n)
            c[i] = sgn / scale[i]
            others = [p for p in ranked if not any(same_trajectory(p, t) for t in tried)]
            for p in others[:opts.starts - 1]:
                stats.spend()
                search.run(p, c)
    return search
