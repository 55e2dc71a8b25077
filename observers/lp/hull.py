"""Linear programs over the unit box with equality constraints, solved by HiGHS (``highspy``).

Every bound returned here is *sound by construction*: the LP solver only proposes a dual point
``mu``; the bound itself is evaluated from weak duality,

    max { g'xi : A xi = b, -1 <= xi <= 1 }  <=  b'mu + ||g - A'mu||_1     for every mu,

with a small outward rounding of the floating-point evaluation.  A primal objective value at
solver tolerance is never used as a bound.

Interval hulls and support values of constrained zonotopes solve many such LPs with one
feasible set; :class:`HullLP` solves them together with a batched dual simplex
(:mod:`observers.lp.dual_simplex`) where the rows are few, by sifting over working sets of
columns (:mod:`observers.lp.sifting_jit`, its restricted LPs by a compiled dual simplex)
where the columns are many per row, and falls back to HiGHS for any LP that either does not
finish.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from time import perf_counter

import numpy as np

try:  # highspy is a hard dependency; keep the import error readable
    import highspy
except ImportError as exc:  # pragma: no cover - exercised only on broken installs
    raise ImportError("the 'highspy' package is required for LP-based set operations") from exc

from ..errors import EmptySet, SetError
from . import batch_solve_jit, dual_simplex, sifting, sifting_jit
from .highs import new_highs

_EPS = np.finfo(float).eps
_EMPTY = "constrained zonotope is empty (its constraints are infeasible)"
#: |b_i| above which a constraint row without variables (0 = b_i) is infeasible (HiGHS's
#: primal feasibility tolerance)
_ROW_FEASIBILITY_TOL = 1e-7


def dual_bound(g: np.ndarray, A: np.ndarray, b: np.ndarray, mu: np.ndarray) -> float:
    """Weak-duality upper bound ``b'mu + ||g - A'mu||_1`` with outward rounding.

    The slack bounds the floating-point error of the evaluation (each computed sum of ``k``
    products is within ``k eps`` times the sum of the absolute products), so the returned
    number is not below the exact value of the bound for this ``mu``.
    """
    return float(dual_bounds(np.asarray(g, float)[None, :], A, b,
                             np.asarray(mu, float)[None, :])[0])


def dual_bounds(Gd: np.ndarray, A: np.ndarray, b: np.ndarray, Mu: np.ndarray) -> np.ndarray:
    """:func:`dual_bound` for every row: ``b'mu_k + ||g_k - A'mu_k||_1`` (outward rounded)
    for cost rows ``Gd`` (K x r) and dual points ``Mu`` (K x nc)."""
    nc, r = A.shape
    t1 = Mu @ b
    t2 = np.abs(Gd - Mu @ A).sum(axis=1)
    aMu = np.abs(Mu)
    scale = (aMu @ np.abs(b) + np.abs(Gd).sum(axis=1) + aMu @ np.abs(A).sum(axis=1)
             + np.abs(t1) + t2)
    slack = (nc + r + 4) * _EPS * scale
    return t1 + t2 + slack


def split_free(G: np.ndarray, A: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(Gc, Ac, Gf)``: the generators in some constraint with their columns of ``A``, and
    the generators in none (whose factors range over ``[-1, 1]`` freely)."""
    coupled = np.any(A != 0.0, axis=0)
    if coupled.all():
        return G, A, G[:, :0]
    return G[:, coupled], A[:, coupled], G[:, ~coupled]


def _highs() -> highspy.Highs:
    h = new_highs()
    h.setOptionValue("presolve", "off")  # tiny LPs, re-solved warm: presolve only costs time
    h.setOptionValue("simplex_scale_strategy", 0)  # fewer iterations on these LPs (measured)
    return h


def _box_lp(A: np.ndarray, b: np.ndarray, cost: np.ndarray | None = None) -> highspy.HighsLp:
    """``HighsLp`` of ``A xi = b``, ``-1 <= xi <= 1`` (column-wise matrix)."""
    nc, r = A.shape
    lp = highspy.HighsLp()
    lp.num_col_ = r
    lp.num_row_ = nc
    lp.col_cost_ = np.zeros(r) if cost is None else cost
    lp.col_lower_ = -np.ones(r)
    lp.col_upper_ = np.ones(r)
    lp.row_lower_ = b
    lp.row_upper_ = b
    cols, rows = np.nonzero(A.T)  # column-wise nonzeros, sorted by column then row
    lp.a_matrix_.format_ = highspy.MatrixFormat.kColwise
    lp.a_matrix_.start_ = np.concatenate([[0], np.cumsum(np.bincount(cols, minlength=r))]
                                         ).astype(np.int32)
    lp.a_matrix_.index_ = rows.astype(np.int32)
    lp.a_matrix_.value_ = A.T[cols, rows]
    return lp


def _dual_point(h: highspy.Highs, nc: int) -> np.ndarray:
    """Dual point proposed by HiGHS for ``max g'xi`` solved as ``min -g'xi`` (any point is
    valid for :func:`dual_bound`; ``0`` if HiGHS has none)."""
    if h.getModelStatus() == highspy.HighsModelStatus.kInfeasible:
        raise EmptySet(_EMPTY)
    sol = h.getSolution()
    if sol.dual_valid and len(sol.row_dual) == nc:
        mu = -np.asarray(sol.row_dual, dtype=float)
        if np.all(np.isfinite(mu)):
            return mu
    return np.zeros(nc)


class BoxLP:
    """Reusable HiGHS model ``max g'xi  s.t.  A xi = b, -1 <= xi <= 1`` for many cost vectors.

    The constraint matrix is loaded once; successive :meth:`maximize` calls only change the
    cost, so HiGHS warm-starts from the previous basis.
    """

    def __init__(self, A: np.ndarray, b: np.ndarray):
        self.A = np.asarray(A, dtype=float)
        self.b = np.asarray(b, dtype=float)
        self._h = _highs()
        self._h.passModel(_box_lp(self.A, self.b))
        self._r = self.A.shape[1]
        self._idx = np.arange(self._r, dtype=np.int32)

    def maximize(self, g: np.ndarray) -> float:
        """Sound upper bound on ``max g'xi`` over the feasible set (raises if it is empty)."""
        g = np.asarray(g, float)
        h = self._h
        h.changeColsCost(self._r, self._idx, -g)
        h.run()
        return dual_bound(g, self.A, self.b, _dual_point(h, self.A.shape[0]))


@dataclass(frozen=True)
class HullLPStats:
    """Work counters of a :class:`HullLP` (read-only snapshot, see :attr:`HullLP.stats`).

    Attributes
    ----------
    solves : int
        LPs solved (one per direction; batched and HiGHS alike).
    iterations : int
        Simplex iterations, summed over the LPs.
    fallbacks : int
        LPs that the batched dual simplex or sifting did not finish and handed to HiGHS.
    seconds : dict
        Seconds by phase: those of the batched dual simplex (``setup``, ``pivots``,
        ``refactor``, ``certify``; :class:`observers.lp.dual_simplex.Clock`), those of
        sifting (``start``, ``models``, ``restricted``, ``pricing``;
        :class:`observers.lp.sifting.SiftResult`), ``bounds`` (the weak-duality bounds of
        their dual points) and ``highs`` (LPs solved by HiGHS).
    """

    solves: int
    iterations: int
    fallbacks: int
    seconds: dict[str, float] = field(default_factory=dict)

    @property
    def iterations_per_solve(self) -> float:
        """Mean simplex iterations per LP (NaN if no LP was solved)."""
        return self.iterations / self.solves if self.solves else float("nan")


class HullLP:
    """Sound bounds ``max g'xi  s.t.  A xi = b, -1 <= xi <= 1`` for a sequence of sets and many
    directions, in one HiGHS model kept alive.

    Observers that return a constrained zonotope per step attach one ``HullLP`` to every set
    they return (:meth:`ConZonotope.with_solver`); the runner's ``S.interval()`` then solves
    its 2n LPs here instead of building a new model per set:

    * the constraints ``(A, b)`` of a set are passed to HiGHS once (recognised by identity),
      with presolve and scaling off (both only cost time on these small LPs, measured);
    * the 2n LPs of a set differ only in their cost, so each starts from the optimal basis of
      the previous one;
    * the cost is scaled to unit infinity norm (HiGHS' tolerances are absolute).

    Starting each direction from its own optimal basis of the previous step was tried (with
    and without keeping the generators and constraints at fixed positions from step to step)
    and took *more* simplex iterations on the vehicle benchmark than the basis of the
    previous direction, so it is not done.

    Whatever basis HiGHS starts from and whatever it returns, the reported number is the
    weak-duality bound of its dual point (:func:`dual_bound`), so warm starts affect speed
    only, never soundness.

    :meth:`maximize_many` solves many directions at once: with ``solver="batched"`` by the
    batched dual simplex of :mod:`observers.lp.dual_simplex` (all 2n LPs of an interval
    hull in lock step), with HiGHS for the LPs it does not finish (and to report empty sets);
    with ``solver="sifting"`` by sifting over working sets of columns, the restricted LPs by
    the compiled dual simplex of :mod:`observers.lp.sifting_jit` (by HiGHS,
    :mod:`observers.lp.sifting`, where numba is not available; ``"sifting-highs"`` chooses
    that always), with HiGHS for the LPs it does not finish; with ``solver="highs"`` one
    HiGHS run per direction as :meth:`maximize`; ``"auto"`` (default) picks sifting where
    :func:`sifting_is_cheaper`, else the batched solver where :func:`batched_is_cheaper`,
    else HiGHS.  Either way each bound is the weak-duality bound
    of a dual point on the full problem.
    """

    #: the solver strategies (see the class docstring)
    SOLVERS = ("auto", "batched", "highs", "sifting", "sifting-highs")

    def __init__(self, solver: str = "auto"):
        if solver not in self.SOLVERS:
            raise SetError(f"unknown LP solver {solver!r} (known: {', '.join(self.SOLVERS)})")
        self.solver = solver
        self._h = _highs()
        self._loaded: tuple[np.ndarray, np.ndarray] | None = None
        self._idx = np.arange(0, dtype=np.int32)
        #: LPs solved, simplex iterations used (summed over the LPs) and LPs handed to HiGHS
        #: by the batched solver (for benchmarks)
        self.solves = 0
        self.iterations = 0
        self.fallbacks = 0
        self._seconds: dict[str, float] = {}

    @property
    def stats(self) -> HullLPStats:
        """LPs solved, simplex iterations, HiGHS fallbacks and seconds by phase so far (a
        read-only snapshot)."""
        return HullLPStats(self.solves, self.iterations, self.fallbacks, dict(self._seconds))

    def _add_seconds(self, seconds: dict[str, float]) -> None:
        for phase, s in seconds.items():
            self._seconds[phase] = self._seconds.get(phase, 0.0) + s

    def load(self, A: np.ndarray, b: np.ndarray) -> None:
        """Make ``A xi = b, -1 <= xi <= 1`` the feasible set (no-op if already loaded)."""
        if self._loaded is not None and self._loaded[0] is A and self._loaded[1] is b:
            return
        self._h.passModel(_box_lp(A, b))
        self._loaded = (A, b)
        if self._idx.shape[0] != A.shape[1]:
            self._idx = np.arange(A.shape[1], dtype=np.int32)

    def maximize(self, g: np.ndarray, A: np.ndarray, b: np.ndarray) -> float:
        """Sound upper bound on ``max g'xi  s.t.  A xi = b, -1 <= xi <= 1``."""
        if A.shape[1] == 0:  # no variables: 0 = b (HiGHS does not check rows without columns)
            if np.any(np.abs(b) > _ROW_FEASIBILITY_TOL):
                raise EmptySet(_EMPTY)
            return 0.0
        self.load(A, b)
        scale = float(np.abs(g).max(initial=0.0))
        if scale == 0.0:
            return dual_bound(g, A, b, np.zeros(A.shape[0]))
        h = self._h
        t0 = perf_counter()
        h.changeColsCost(A.shape[1], self._idx, -g / scale)
        h.run()
        self.solves += 1
        self.iterations += h.getInfo().simplex_iteration_count
        bound = dual_bound(g, A, b, _dual_point(h, A.shape[0]) * scale)
        self._add_seconds({"highs": perf_counter() - t0})
        return bound

    def maximize_many(self, Gd: np.ndarray, A: np.ndarray, b: np.ndarray) -> np.ndarray:
        """Sound upper bounds on ``max Gd[k]'xi  s.t.  A xi = b, -1 <= xi <= 1`` for every row
        ``k`` of ``Gd`` (raises :class:`SetError` if the feasible set is empty)."""
        Gd = np.atleast_2d(np.asarray(Gd, dtype=float))
        K, (p, r) = Gd.shape[0], A.shape
        if p == 0 or self.solver == "highs":
            return np.array([self.maximize(g, A, b) for g in Gd])
        if self._sifted(K, p, r):
            return self._sift(Gd, A, b)
        if not self._batched(K, p):
            return np.array([self.maximize(g, A, b) for g in Gd])
        # one compiled call where the kernels are compiled (the same method)
        res = (batch_solve_jit.solve if dual_simplex.use_compiled() else dual_simplex.solve)(
            A, b, Gd)
        t0 = perf_counter()
        bounds = dual_bounds(Gd, A, b, res.mu) if res.bounds is None else res.bounds
        self._add_seconds({**res.seconds, "bounds": perf_counter() - t0})
        self.solves += Gd.shape[0]
        self.iterations += res.problem_iterations
        self._highs_where_unfinished(bounds, res.converged, lambda: Gd, A, b)
        return bounds

    def _sifted(self, K: int, p: int, r: int) -> bool:
        """Whether ``K`` LPs with ``p`` rows and ``r`` columns are sifted (the solver chosen,
        or ``auto`` where :func:`sifting_is_cheaper`)."""
        return self.solver in ("sifting", "sifting-highs") or (
            self.solver == "auto" and sifting_is_cheaper(K, p, r))

    def _batched(self, K: int, p: int) -> bool:
        """Whether ``K`` LPs with ``p`` constraint rows go to the batched dual simplex (the
        solver chosen, or ``auto`` where :func:`batched_is_cheaper`)."""
        return self.solver == "batched" or (self.solver == "auto" and batched_is_cheaper(K, p))

    def _highs_where_unfinished(self, bounds: np.ndarray, converged: np.ndarray,
                                directions, A: np.ndarray, b: np.ndarray) -> None:
        """Tighten ``bounds[k]`` by HiGHS for each LP the batched solver did not finish
        (both bounds are valid: the smaller is kept); ``directions()`` gives the cost rows,
        built only if some LP needs them."""
        unfinished = np.nonzero(~converged)[0]
        if unfinished.size == 0:
            return
        Gd = directions()
        for k in unfinished:
            self.fallbacks += 1
            bounds[k] = min(bounds[k], self.maximize(Gd[k], A, b))

    def hull(self, c: np.ndarray, G: np.ndarray, A: np.ndarray, b: np.ndarray
             ) -> tuple[np.ndarray, np.ndarray]:
        """Sound interval hull ``(lo, hi)`` of ``{c + G xi : A xi = b, |xi| <= 1}``: the 2n
        LPs of :meth:`maximize_many` over the columns in some constraint, the other columns
        in closed form (``sum_j |G_ij|``), the sums rounded outward.  Where
        :meth:`maximize_many` would take the compiled batched dual simplex, all of it is one
        compiled call (:func:`.batch_solve_jit.hull`: the same LPs, the same bounds), HiGHS
        for the LPs it does not finish.  Raises :class:`EmptySet` where the
        set is empty."""
        n, (p, R) = G.shape[0], A.shape
        K = 2 * n
        if p == 0:  # no constraint: every column is free
            bounds, rad_free, free = np.zeros(K), np.abs(G).sum(axis=1), R
        elif (dual_simplex.use_compiled() and K * (R + p) <= 1 << 32
                and not self._sifted(K, p, R) and self._batched(K, p)):
            t0 = perf_counter()
            res = batch_solve_jit.hull(G, A, b)
            self._add_seconds({"solve": perf_counter() - t0})
            self.solves += K
            self.iterations += res.problem_iterations
            bounds, rad_free, free = res.bounds, res.rad_free, res.free
            Gc = G[:, res.cols]
            self._highs_where_unfinished(bounds, res.converged, lambda: np.vstack([Gc, -Gc]),
                                         A[:, res.cols], b)
        else:
            Gc, Ac, Gf = split_free(G, A)
            bounds = self.maximize_many(np.vstack([Gc, -Gc]), Ac, b)
            rad_free, free = np.abs(Gf).sum(axis=1), Gf.shape[1]
        hi, lo = bounds[:n], bounds[n:]
        # outward rounding of the free generators' sums and of the final sums
        slack = (free + 4) * _EPS * (np.abs(c) + np.abs(hi) + np.abs(lo) + rad_free)
        up = c + (hi + rad_free) + slack
        down = c - (lo + rad_free) - slack
        if np.any(down > up):  # both bounds are sound: they cross only for an empty set
            i = int(np.argmax(down - up))
            raise EmptySet(f"constrained zonotope is empty (its hull bounds cross in "
                           f"coordinate {i}: {down[i]:.17g} > {up[i]:.17g})")
        return down, up

    def _sift(self, Gd: np.ndarray, A: np.ndarray, b: np.ndarray) -> np.ndarray:
        """:meth:`maximize_many` by sifting (:mod:`observers.lp.sifting`) over the columns in
        some constraint; the bounds are those of the dual points on the full problem (the
        columns in no constraint count ``|g_j|``), HiGHS for the LPs sifting did not finish.
        """
        cols = sifting.constrained_columns(A)
        if cols.size == 0:  # no variable in any constraint: 0 = b
            if np.any(np.abs(b) > _ROW_FEASIBILITY_TOL):
                raise EmptySet(_EMPTY)
            return dual_bounds(Gd, A, b, np.zeros((Gd.shape[0], A.shape[0])))
        reduced = cols.size < A.shape[1]
        compiled = self.solver != "sifting-highs" and dual_simplex.use_compiled()
        try:
            res = (sifting_jit if compiled else sifting).solve(
                A[:, cols] if reduced else A, b, Gd[:, cols] if reduced else Gd)
        except sifting.NoStart:  # HiGHS gave no start vertex: every LP by HiGHS
            return np.array([self.maximize(g, A, b) for g in Gd])
        t0 = perf_counter()
        bounds = dual_bounds(Gd, A, b, res.mu)
        self._add_seconds({**res.seconds, "bounds": perf_counter() - t0})
        self.solves += Gd.shape[0]
        self.iterations += res.iterations
        for k in np.nonzero(~res.converged)[0]:  # not finished: HiGHS (both bounds are valid)
            self.fallbacks += 1
            bounds[k] = min(bounds[k], self.maximize(Gd[k], A, b))
        return bounds


#: most constraint rows for which the batched dual simplex is used (measured, see
#: :func:`batched_is_cheaper`)
BATCHED_MAX_ROWS = 70


def batched_is_cheaper(K: int, p: int) -> bool:
    """Whether the batched dual simplex is expected to beat K warm HiGHS runs on LPs with
    ``p`` rows.  Cost model from the CZN benchmarks (per LP, HiGHS: ~90 us plus ~1.2 p
    iterations of ~30 us; batched: ~2 p lock-step iterations of ~70 us plus ~8 us per LP):
    the batch pays off for many directions and few constraints (the 6-state vehicle: K = 12,
    p = 8), HiGHS for few directions and many constraints (CORA's unbounded constraints).

    Above :data:`BATCHED_MAX_ROWS` rows HiGHS wins whatever K: the dense pivots of the
    batched solver grow as p N per iteration, HiGHS's sparse ones do not.  Measured on the
    CZN hulls of the tank benchmarks (compiled kernel / HiGHS): 18 tanks, p = 22, K = 36: 3 /
    13 ms per hull; 100 tanks, p = 160, K = 200: 6.3 s / 0.2 s.  HiGHS's warm starts degrade
    on long records, so the bound was raised from 32 to 70 on whole runs of CZN-B: 30 tanks
    (p = 42, K = 60, 261 steps) 40 s against 370 s of hulls in all (55 against 57 ms per hull
    in the first steps, 0.18 against 1.9 s at the median: HiGHS's iterations per LP grow from
    ~10 to ~200); 44 tanks (p = 66, 150 steps) 81 s against 678 s.  At 60 tanks (p = 92) the
    first 40 steps took 14.8 against 12.8 s, so it stays with HiGHS.
    """
    return p <= BATCHED_MAX_ROWS and 2 * p * (70 + 8 * K) < K * (90 + 36 * p)


#: fewest columns, and fewest columns per constraint row, for which the hull LPs are sifted
#: with the compiled restricted LPs (measured, see :func:`sifting_is_cheaper`)
SIFTING_MIN_COLUMNS = 2000
SIFTING_MIN_RATIO = 12
#: the same for sifting with HiGHS's restricted LPs (without numba)
HIGHS_SIFTING_MIN_COLUMNS = 4000
HIGHS_SIFTING_MIN_RATIO = 20


def sifting_is_cheaper(K: int, p: int, r: int, compiled: bool | None = None) -> bool:
    """Whether sifting is expected to beat the other solvers on K LPs with ``p`` rows and
    ``r`` columns: for many columns, and many per row.

    With the compiled restricted LPs (:mod:`observers.lp.sifting_jit`; ``compiled``
    defaults to :func:`.dual_simplex.use_compiled`) from :data:`SIFTING_MIN_COLUMNS` columns
    and :data:`SIFTING_MIN_RATIO` per row, whatever the batched solver would do.  Measured
    on the CZN-A hulls of the tank benchmarks (fastest of two or three, per hull), the
    steady sets: 30 tanks (p = 42, r = 3063) 66 ms against 104 batched and 390 warm HiGHS;
    60 tanks (p = 92, r = 6138) 242 ms against 1324 batched and 1840 HiGHS; the growing
    sets of the first steps: 30 tanks r = 1581 28 against 24 ms batched, r = 2346 48
    against 55; 100 tanks (p = 160) r = 1260 461 against 360 ms HiGHS, r = 2340 347 against
    604, r = 3780 282 against 992; the 6-state vehicle and 6 tanks (p = 6-8, r = 100-600)
    2-6 ms against 0.3-1.7 ms batched.

    With HiGHS's restricted LPs (:mod:`observers.lp.sifting`, without numba) only where the
    batched solver is not cheaper, from :data:`HIGHS_SIFTING_MIN_COLUMNS` columns and
    :data:`HIGHS_SIFTING_MIN_RATIO` per row: each HiGHS iteration prices all ``r`` columns,
    sifting prices them once per round for a chunk of problems and iterates over a working
    set of about a thousand.  Measured on the steady CZN-A / CZN-B hulls (warm HiGHS against
    sifting, per hull): 60 tanks 2.2 against 1.5-2.0 s; 100 tanks 3.7 / 3.1 against 2.6 /
    2.3 s; 200 tanks (p = 326, r = 20489) 19.9 / 17.1 against 9.7 / 7.4 s; on the growing
    100-tank sets r = 3060: 537 ms HiGHS against 600 ms sifting, r = 4680: 937 against 693.
    """
    if K < 2:
        return False
    if dual_simplex.use_compiled() if compiled is None else compiled:
        return r >= SIFTING_MIN_COLUMNS and r >= SIFTING_MIN_RATIO * p
    return (not batched_is_cheaper(K, p) and r >= HIGHS_SIFTING_MIN_COLUMNS
            and r >= HIGHS_SIFTING_MIN_RATIO * p)
