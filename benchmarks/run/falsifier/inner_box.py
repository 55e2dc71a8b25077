"""Nonlinear falsifier: verified consistent trajectories that push each state to its extremes.

For a record ``(u, y)`` of ``x_{j+1} = f(x_j, u_j) + w_j``, ``y_j = h(x_j) + v_j`` with
``x_0 in X0``, ``w_j in W``, ``v_j in V`` (zonotopes ``c + G xi``, ``|xi|_inf <= 1``), the
*consistent* states of step ``k`` are the ``x_k`` of the trajectories that reproduce
``y_0 .. y_k`` exactly (``y_0 .. y_{k-1}`` for the *predicted* floor, the set before ``y_k``).
For a nonlinear model that set has no exact polytope description, so its interval hull is
not computable; this module bounds it from *inside*: for chosen steps and every state it
searches, in both directions, for a consistent trajectory making the state as small or as
large as possible, and keeps only trajectories that pass :func:`verify` (forward simulation
in the model with every noise factor checked against its bound).  The extremes found form an
*inner box* of the exact hull.  Any observer is sound only if its sets contain every
consistent state, so

* a verified consistent state outside an observer's interval hull (by more than a stated
  tolerance) is a *certified violation* (:class:`Violation`), and
* the observer's RMS radius divided by the inner box's is an *upper bound* of its gap to the
  exact hull (``gap <= ...``), since the inner box lies inside the exact hull.

The search (a trust-region SLP over the whole horizon, and why) is in
:mod:`benchmarks.run.falsifier_slp`; :func:`falsify` drives it over the chosen steps and
checks hulls, :meth:`FalsifierResult.check` checks more hulls against a result, and
``python -m benchmarks.run.falsifier SCENARIO`` measures it (observers run, violations,
``gap <=`` per state, cost).

Verification and tolerances
---------------------------
:func:`verify` re-simulates ``x_0 = c_0 + G_0 xi_0``, ``x_{j+1} = f(x_j, u_j) + c_W + G_W
omega_j`` in floating point, requires ``|xi_0|_inf <= 1`` and ``|omega_j|_inf <= 1`` exactly
(they are the trajectory's own numbers) and recomputes the measurement factors ``nu_j`` of
``y_j - h(x_j) - c_V`` (``G_V^+`` applied to the residual of the trajectory's own ``nu_j``,
so for a non-square ``G_V`` a trajectory is judged by the factors it carries, corrected),
requiring ``|nu_j|_inf <= 1 + 1e-9``: the measurements and the simulated outputs carry
rounding, and a record with noise on the vertices of V (the audit's adversarial kinds) has
``|v_j| = r_V`` exactly.  The search keeps the factors of ``X0`` and ``W`` inside ``1 - 1e-9``
and those of ``V`` inside ``1 - 1e-7`` (the LP's tolerance, accumulated along the dynamics,
and the linearisation error of the last step), so that its points verify with room to spare;
where the anchor itself lies in those margins (noise on the vertices of the sets, whose
consistent set has no interior) the margins are dropped and a candidate that misses by a
hair is polished by a least-norm Gauss-Newton step on the measurement factors at or beyond
their bound (:meth:`Search.polish`).  The simulated states carry the rounding of ``k``
floating-point steps (~1e-14 relative), so a state is called a violation only when it lies
outside a hull by more than ``rel_tol * max(1, |x|)`` (``rel_tol = 1e-9``) plus the hull's
own tolerance.  On a record without interior the extremes are ill-conditioned: a reference
LP's own tolerance moves them by up to ~1 % of the thinnest radii (see the tests).

>>> import systems
>>> sc = systems.scenario("vanderpol-sim", steps=30)
>>> res = falsify(sc.system, sc, steps=[10, 29], starts=1)
>>> bool(np.all(res.inner_lo <= res.inner_hi))
True
"""

from __future__ import annotations

import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from benchmarks.run.falsifier_slp import (
    FACTOR_MARGIN,
    MAX_ITER,
    NOISE_MARGIN,
    VERIFY_TOL,
    Model,
    Search,
    Stats,
    Trajectory,
    Verification,
    find_anchor,
)
from systems.errors import ModelError

__all__ = ["FACTOR_MARGIN", "NOISE_MARGIN", "REL_TOL", "VERIFY_TOL", "FalsifierResult",
           "Trajectory", "Verification", "Violation", "falsify", "spread_steps", "verify"]

#: relative part of the tolerance of a violation (rounding of the forward simulation)
REL_TOL = 1e-9
#: window="auto": the whole horizon while it has at most this many state variables
AUTO_STATES = 3000
FLOORS = ("filtered", "predicted")


def verify(system: Any, u, y, traj: Trajectory) -> Verification:
    """Whether ``traj`` is a trajectory consistent with the record ``(u, y)``.

    Forward simulation ``x_0 = c_0 + G_0 xi0``, ``x_{j+1} = f(x_j, u_j) + c_W + G_W omega_j``;
    the factors of ``X0`` and ``W`` must satisfy ``|.|_inf <= 1`` exactly and the measurement
    factors ``nu_j`` of ``y_j - h(x_j) - c_V`` too, for the ``traj.measured`` measurements.

    Parameters
    ----------
    system : LinearSystem or NonlinearSystem
    u, y : array_like
        The record (``u[j]`` drives ``x_{j+1}``, ``y[j]`` measures ``x_j``).
    traj : Trajectory
    """
    return Model(system, u, y).check(traj)


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
        (re-check with :func:`verify`; empty lists with ``keep_trajectories=False``).
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
        ``slp_iterations``, ``unconverged`` (runs that hit the iteration limit), ``verified``.
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


def falsify(system: Any, record: Any, steps: int | Sequence[int] = 10,
            hulls: Mapping[str, Any] | None = None, *, starts: int = 1, seed: int = 0,
            floor: str = "filtered", window: int | str | None = "auto",
            hull_tol: float | Mapping[str, float] = 0.0, max_iter: int = MAX_ITER,
            keep_trajectories: bool = True) -> FalsifierResult:
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
    starts : int
        SLP runs per objective (>= 1), see the module docstring.
    seed : int
        Seed of the random directions of the extra starts.
    floor : {"filtered", "predicted"}
        Reproduce ``y_0 .. y_k`` (the set after ``y_k``, against which every observer is
        held) or ``y_0 .. y_{k-1}`` (before ``y_k``: only for observers whose estimate of
        step ``k`` does not use ``y_k``; a larger set, so a larger inner box).
    window : int, "auto" or None
        Disturbances free over the last ``window`` steps before ``k`` (earlier ones stay at
        the anchor's; ``x_0`` is always free); None: the whole horizon; "auto": the whole
        horizon while ``(k + 1) n <= AUTO_STATES``.
    hull_tol : float or mapping
        The hulls' own absolute tolerance (per observer in a mapping).
    max_iter : int
        SLP iterations per run.
    keep_trajectories : bool
        Keep the verified extreme trajectories in the result.

    Returns
    -------
    FalsifierResult
    """
    if floor not in FLOORS:
        raise ModelError(f"falsifier: floor must be one of {', '.join(FLOORS)}, got {floor!r}")
    if isinstance(starts, bool) or not isinstance(starts, (int, np.integer)) or starts < 1:
        raise ModelError(f"falsifier: starts must be an integer >= 1, got {starts!r}")
    if not (window is None or window == "auto" or (
            isinstance(window, (int, np.integer)) and not isinstance(window, bool)
            and window >= 1)):
        raise ModelError(f"falsifier: window must be an integer >= 1, 'auto' or None, "
                         f"got {window!r}")
    t0 = time.perf_counter()
    u, y, x_true = _record(record)
    M = Model(system, u, y)
    if isinstance(steps, (int, np.integer)) and not isinstance(steps, bool):
        steps = spread_steps(M.N, int(steps))
    steps = np.unique(np.asarray(steps, dtype=int).reshape(-1))
    if steps.size == 0 or steps.min() < 0 or steps.max() >= M.N:
        raise ModelError(f"falsifier: steps must lie in 0 .. {M.N - 1}, got {steps.tolist()}")
    n = M.n
    scale = np.maximum(np.abs(M.G0).sum(axis=1), 1e-12)  # radii of X0's hull
    stats = Stats()
    anchor = find_anchor(M, x_true, stats, 5 * max_iter)
    rng = np.random.default_rng(seed)
    S = steps.size
    lo, hi = np.full((S, n), np.nan), np.full((S, n), np.nan)
    lo_tr: list = [[None] * n for _ in range(S)]
    hi_tr: list = [[None] * n for _ in range(S)]
    for s, k in enumerate(steps.tolist()):
        m = k + 1 if floor == "filtered" else k
        search = Search(M, k, m, _window_start(k, n, window), stats, max_iter)
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
            finals[i, sgn] = search.run(start, c)
        if starts > 1:
            for _ in range(starts - 1):
                d = rng.standard_normal(n)
                search.run(start, d / np.linalg.norm(d) / scale)
            for i, sgn in objectives:
                tried = {id(start), id(finals[i, sgn])}
                ranked = sorted(search.pool, key=lambda p, i=i, sgn=sgn: -sgn * p.X[k][i])
                c = np.zeros(n)
                c[i] = sgn / scale[i]
                for p in [p for p in ranked if id(p) not in tried][:starts - 1]:
                    search.run(p, c)
        verified = np.isfinite(search.lo)
        lo[s, verified], hi[s, verified] = search.lo[verified], search.hi[verified]
        if keep_trajectories:
            lo_tr[s], hi_tr[s] = search.lo_traj, search.hi_traj
    result = FalsifierResult(
        steps=steps, inner_lo=lo, inner_hi=hi,
        lo_trajectories=lo_tr if keep_trajectories else [],
        hi_trajectories=hi_tr if keep_trajectories else [],
        floor=floor, anchor=anchor.z,
        stats={"seconds": time.perf_counter() - t0, **vars(stats)})
    if hulls:
        result.add_hulls(hulls, hull_tol)
    return result


# -- command line: measurements -------------------------------------------------------------
def _main(argv: Sequence[str] | None = None) -> int:
    """``python -m benchmarks.run.falsifier SCENARIO``: run observers on a scenario, falsify
    their hulls at steps spread over the record, print the inner box's RMS radii, the
    violations, the gap upper bounds and the cost (a measurement tool; the harness calls
    :func:`falsify`)."""
    import argparse

    import observers
    import systems

    ap = argparse.ArgumentParser(prog="python -m benchmarks.run.falsifier",
                                 description=_main.__doc__.split(":", 1)[1].strip())
    ap.add_argument("scenario")
    ap.add_argument("--observers", default="all",
                    help="comma-separated names, or 'all' (the guaranteed observers that "
                         "accept the system)")
    ap.add_argument("--steps", type=int, default=10, help="steps searched (default 10)")
    ap.add_argument("--first", type=float, default=0.2,
                    help="first searched step as a fraction of the record (default 0.2)")
    ap.add_argument("--floor", choices=FLOORS, default="filtered")
    ap.add_argument("--window", default="auto", help="an integer, 'auto' or 'none'")
    ap.add_argument("--starts", type=int, default=1)
    args = ap.parse_args(argv)
    window = None if args.window == "none" else (
        "auto" if args.window == "auto" else int(args.window))
    sc = systems.scenario(args.scenario)
    names = ([i.name for i in observers.available() if i.guaranteed]
             if args.observers == "all" else args.observers.split(","))
    hulls = {}
    for name in names:
        info = observers.get(name)
        allowed = info.option_defaults() if info.scenario_options is None else (
            info.scenario_options)
        try:
            obs = observers.create(name, sc.system,
                                   **{k: v for k, v in sc.options.items() if k in allowed})
        except (observers.Unsupported, observers.DesignFailed, observers.OptionError):
            continue
        hulls[name] = observers.run(obs, sc.u, sc.y, keep_sets=False, on_error="status")
    steps = spread_steps(sc.N, args.steps, int(args.first * sc.N))
    res = falsify(sc.system, sc, steps=steps, hulls=hulls, starts=args.starts,
                  floor=args.floor, window=window)
    st = res.stats
    print(f"{sc.name}: steps {steps.tolist()}, floor {res.floor}, window {args.window}, "
          f"starts {args.starts}: {st['seconds']:.2f} s, {st['lps']} LPs, {st['loads']} "
          f"models, {st['corrections']} corrections, {st['runs']} runs")
    rms = np.sqrt(np.mean(res.inner_radius ** 2, axis=0))
    print("inner box RMS radii: " + " ".join(f"{r:.4g}" for r in rms))
    for name, gap in res.gap_upper.items():
        bad = sum(v.observer == name for v in res.violations)
        print(f"{name:>12}: gap <= {np.mean(gap):.3g} (states: "
              + " ".join(f"{g:.3g}" for g in gap) + f"); violations: {bad}")
    for v in res.violations[:20]:
        print(f"  {v.observer} step {v.step} x{v.state + 1} {v.side}: consistent {v.value:.9g} "
              f"outside {v.bound:.9g} by {v.excess:.3g}")
    return 0


if __name__ == "__main__":
    raise SystemExit(_main())
