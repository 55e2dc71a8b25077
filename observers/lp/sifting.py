"""Sifting (a working set of columns) for box LPs with few rows and very many columns.

Solves, for the rows ``g_k`` of a cost matrix ``Gd`` (K x r),

    max  g_k' xi   s.t.   A xi = b,   -1 <= xi <= 1          (A: p x r, r >> p),

and returns one dual point ``mu_k`` per problem.  As for :mod:`.dual_simplex`, the caller turns
every ``mu_k`` into a bound by weak duality on the *full* problem
(:func:`observers.lp.hull.dual_bounds`), so the working sets decide tightness and speed only,
never soundness.

Method: sifting (Bixby, Gregory, Lustig, Marsten and Shanno, "Very large-scale linear
programming: a case study in combining interior point and simplex methods", Operations
Research 40(5), 1992), in a primal-feasible form for boxed columns:

* a vertex ``xi0`` of the feasible set and its basis come from one HiGHS solve of the full
  problem (:func:`start`, the first cost); it is feasible for every cost, so all K problems
  start from it;
* problem ``k`` keeps a working set ``W_k`` of columns, at first the basic columns of ``xi0``
  and the :data:`FIRST` columns that price worst against ``mu = 0``; the columns outside it
  stay fixed at their values in ``xi0`` (bounds, since ``xi0`` is a vertex), and HiGHS solves
  the restricted LP ``max g_W' xi_W  s.t.  A_W xi_W = b - A_N xi_N, |xi_W| <= 1``, which is
  feasible (``xi0`` is) and small (``p`` rows, about a thousand columns);
* the restricted duals of a chunk of :data:`CHUNK` problems are priced against every column
  at once, one matrix product ``D = G_chunk - Mu A``.  For the full point
  ``xi = (xi_W, xi_N)`` the duality gap of the pair ``(xi, mu)`` is
  ``sum_j (|d_j| - d_j xi_j) + mu'(b - A xi)``: a non-negative term per column (the second
  part is zero up to HiGHS's feasibility tolerance); a column outside ``W_k`` with a
  positive term sits at the bound its reduced cost does not want;
* a problem whose columns outside its working set add at most :data:`GAP_TOL` times
  ``||g_k||_1`` (the radius of its direction) to the gap is finished: no column left out
  can improve its bound by more (the terms of the working set are the restricted LP's own
  accuracy, HiGHS's tolerances tightened to :data:`FEASIBILITY_TOL`).  The others add up to
  :data:`ADD` columns with the largest terms to their working set (to their HiGHS model,
  which continues from its optimal basis) and re-solve; after :data:`MAX_ROUNDS` rounds, or
  if a restricted LP fails (also when retried cold with HiGHS's default tolerances), the
  problem is reported as not converged (the caller solves it in full).

Columns zero in ``A`` (generators in no constraint) contribute ``|g_j|`` in closed form
(``d_j = g_j`` for every ``mu``): they are left out of the LPs (:func:`constrained_columns`),
and the weak-duality bound of the full problem counts them.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from time import perf_counter

import highspy
import numpy as np

from ..errors import EmptySet
from .highs import new_highs

#: a problem is finished when the columns outside its working set add at most this times
#: ``||g_k||_1`` to its duality gap
GAP_TOL = 1e-9
#: most sifting rounds per problem before it is handed back unconverged
MAX_ROUNDS = 12
#: columns per problem in the first working set besides the start's basic columns (the
#: worst priced against ``mu = 0``; at least the number of rows)
FIRST = 300
#: columns added per round and problem (at most; at least the number of rows)
ADD = 160
#: problems sifted together (their HiGHS models alive at once, one pricing product)
CHUNK = 16
#: HiGHS's primal and dual feasibility tolerances in the restricted LPs (its default, 1e-7,
#: would leave dual infeasibilities that count in the bound of every column)
FEASIBILITY_TOL = 1e-10
#: the tolerances of the retry of a restricted LP that stopped without an optimum
RETRY_TOL = 1e-7
_STATUS = (highspy.HighsBasisStatus.kLower, highspy.HighsBasisStatus.kBasic,
           highspy.HighsBasisStatus.kUpper, highspy.HighsBasisStatus.kZero,
           highspy.HighsBasisStatus.kNonbasic)
_OPTIMAL = highspy.HighsModelStatus.kOptimal
_INFEASIBLE = highspy.HighsModelStatus.kInfeasible
_EMPTY = "constrained zonotope is empty (its constraints are infeasible)"


@dataclass
class SiftResult:
    """Dual points ``mu`` (K x p), which problems reached the gap tolerance, the work done
    (sifting rounds, HiGHS simplex iterations summed over the restricted LPs, mean final
    working-set size) and seconds by phase: ``start`` (the start vertex), ``models`` (the
    HiGHS models of the first working sets), ``restricted`` (the restricted LPs and the
    columns added to them), ``pricing`` (the reduced costs and gap terms of all columns)."""

    mu: np.ndarray
    converged: np.ndarray
    rounds: int
    iterations: int
    columns: float
    seconds: dict[str, float] = field(default_factory=dict)


@dataclass
class Start:
    """A vertex ``xi`` of ``{A xi = b, |xi| <= 1}`` with its HiGHS basis (column and row
    statuses as integers of ``highspy.HighsBasisStatus``) and the simplex iterations it
    took."""

    xi: np.ndarray
    col_status: np.ndarray
    row_status: np.ndarray
    iterations: int


def _highs(tol: float | None = None) -> highspy.Highs:
    """A quiet HiGHS without presolve and scaling, with primal and dual feasibility
    tolerance ``tol`` (default :data:`FEASIBILITY_TOL`)."""
    h = new_highs()
    h.setOptionValue("presolve", "off")
    h.setOptionValue("simplex_scale_strategy", 0)
    tol = FEASIBILITY_TOL if tol is None else tol
    h.setOptionValue("dual_feasibility_tolerance", tol)
    h.setOptionValue("primal_feasibility_tolerance", tol)
    return h


def load(h: highspy.Highs, A: np.ndarray, b: np.ndarray, cost: np.ndarray) -> None:
    """Make ``h``'s model ``min cost'xi``, ``A xi = b``, ``|xi| <= 1`` (the whole dense
    matrix passed column by column with ``addRows``/``addCols``: an order of magnitude
    faster than filling a ``highspy.HighsLp`` field by field; HiGHS drops the entries below
    its ``small_matrix_value`` itself)."""
    p, r = A.shape
    h.clearModel()
    none_i, none_f = np.zeros(0, dtype=np.int32), np.zeros(0)
    h.addRows(p, b, b, 0, none_i, none_i, none_f)
    values = np.ascontiguousarray(A.T).ravel()
    h.addCols(r, np.ascontiguousarray(cost, dtype=float), -np.ones(r), np.ones(r), p * r,
              np.arange(0, p * r, p, dtype=np.int32) if r else none_i,
              np.tile(np.arange(p, dtype=np.int32), r), values)


def _basis(col_status: np.ndarray, row_status: np.ndarray) -> highspy.HighsBasis:
    basis = highspy.HighsBasis()
    basis.col_status = [_STATUS[s] for s in col_status]
    basis.row_status = [_STATUS[s] for s in row_status]
    basis.valid = True
    return basis


def constrained_columns(A: np.ndarray) -> np.ndarray:
    """Indices of the columns of ``A`` with a nonzero entry (the others, generators in no
    constraint, contribute ``|g_j|`` to every bound in closed form)."""
    return np.nonzero(np.any(A != 0.0, axis=0))[0]


def start(A: np.ndarray, b: np.ndarray, g: np.ndarray) -> Start:
    """A vertex of the feasible set and its basis: HiGHS's optimum of ``max g'xi``.

    Raises
    ------
    EmptySet
        If HiGHS finds the feasible set empty.
    """
    h = _highs(RETRY_TOL)
    scale = float(np.abs(g).max(initial=0.0)) or 1.0
    load(h, A, b, -g / scale)
    h.run()
    status = h.getModelStatus()
    if status == _INFEASIBLE:
        raise EmptySet(_EMPTY)
    basis = h.getBasis()
    if status != _OPTIMAL or not basis.valid:
        raise NoStart(f"HiGHS found no optimal vertex ({h.modelStatusToString(status)})")
    xi = np.clip(np.asarray(h.getSolution().col_value, dtype=float), -1.0, 1.0)
    return Start(xi, np.array([int(s) for s in basis.col_status], dtype=np.int8),
                 np.array([int(s) for s in basis.row_status], dtype=np.int8),
                 int(h.getInfo().simplex_iteration_count))


class NoStart(RuntimeError):
    """HiGHS returned no optimal basis for the start (the caller solves in full)."""


class _Problem:
    """One problem of a chunk: its working set, point, HiGHS model (kept between rounds, so
    that each round continues from the last basis) and the right-hand side
    ``b - A_N xi_N`` of the columns fixed outside the working set."""

    def __init__(self, g: np.ndarray, A: np.ndarray, Axi: np.ndarray, b: np.ndarray,
                 st: Start, W: np.ndarray):
        self.g = g
        self.scale = float(np.abs(g).max(initial=0.0)) or 1.0
        self.xi = st.xi.copy()
        self.W = W
        self.sign = np.ones(W.size)  # model column = sign * column of A (see grow)
        self.rhs = b - Axi + A[:, W] @ self.xi[W]
        self.mu = np.zeros(A.shape[0])
        self.h = _highs()
        load(self.h, A[:, W], self.rhs, -g[W] / self.scale)
        self.h.setBasis(_basis(st.col_status[W], st.row_status))
        self.iterations = 0

    def solve(self, A: np.ndarray) -> bool:
        """Solve the restricted LP (warm); if HiGHS stops without an optimum (numerical
        trouble at the tight tolerances), once more cold with HiGHS's default tolerances;
        ``False`` if that fails too."""
        h = self.h
        h.run()
        self.iterations += int(h.getInfo().simplex_iteration_count)
        if h.getModelStatus() != _OPTIMAL:
            h = self.h = _highs(RETRY_TOL)
            load(h, A[:, self.W] * self.sign, self.rhs,
                 -self.sign * self.g[self.W] / self.scale)
            h.run()
            self.iterations += int(h.getInfo().simplex_iteration_count)
            if h.getModelStatus() != _OPTIMAL:
                return False
        sol = h.getSolution()
        if not sol.dual_valid:
            return False
        mu = -np.asarray(sol.row_dual, dtype=float) * self.scale
        if not np.all(np.isfinite(mu)):
            return False
        self.mu = mu
        self.xi[self.W] = self.sign * np.clip(np.asarray(sol.col_value, dtype=float), -1, 1)
        return True

    def grow(self, A: np.ndarray, new: np.ndarray) -> None:
        """Free the fixed columns ``new``: add them to the model and move their contribution
        out of the right-hand side.  HiGHS makes an added column nonbasic at its lower bound,
        so a column fixed at ``+1`` enters negated (``-a_j``, cost ``-g_j``): it starts where
        it was, the basis stays primal feasible and the solve continues from it."""
        p, m = A.shape[0], new.size
        self.rhs = self.rhs + A[:, new] @ self.xi[new]
        self.h.changeRowsBounds(p, np.arange(p, dtype=np.int32), self.rhs, self.rhs)
        sign = np.where(self.xi[new] > 0.0, -1.0, 1.0)
        values = np.ascontiguousarray((A[:, new] * sign).T).ravel()
        self.h.addCols(m, -sign * self.g[new] / self.scale, -np.ones(m), np.ones(m), p * m,
                       np.arange(0, p * m, p, dtype=np.int32),
                       np.tile(np.arange(p, dtype=np.int32), m), values)
        self.W = np.concatenate([self.W, new])
        self.sign = np.concatenate([self.sign, sign])

    def close(self) -> None:
        """Free the HiGHS model."""
        self.h = None


def gap_terms(D: np.ndarray, Xi: np.ndarray) -> np.ndarray:
    """Per-column terms ``|d_j| - d_j xi_j`` (non-negative for ``|xi_j| <= 1``) of the duality
    gap of the pairs ``(xi_k, mu_k)`` whose reduced costs are the rows of ``D``."""
    return np.maximum(np.abs(D) - D * Xi, 0.0)


def _top(t: np.ndarray, m: int) -> np.ndarray:
    """Indices of the (at most) ``m`` largest positive entries of ``t``."""
    m = min(m, t.shape[0])
    idx = np.argpartition(-t, m - 1)[:m] if m > 0 else np.zeros(0, dtype=np.intp)
    return idx[t[idx] > 0.0]


def _first_sets(Gd: np.ndarray, st: Start, first: int) -> list[np.ndarray]:
    """Initial working sets: the basic columns of the start and the ``first`` columns with
    the largest gap terms against ``mu = 0`` (reduced costs ``g``)."""
    basic = np.nonzero(st.col_status == 1)[0]
    T = gap_terms(Gd, st.xi[None, :])
    T[:, basic] = 0.0
    return [np.concatenate([basic, _top(T[k], first)]) for k in range(Gd.shape[0])]


def _sift_chunk(A: np.ndarray, b: np.ndarray, Gd: np.ndarray, st: Start, Axi: np.ndarray,
                opts: tuple[float, int, int, int]):
    """Sift the problems ``Gd`` (a chunk) in lock step: ``(mu, converged, rounds, iterations,
    working-set sizes, seconds)``; ``opts = (gap_tol, max_rounds, first, add)``."""
    gap_tol, max_rounds, first, add = opts
    K = Gd.shape[0]
    seconds = {"restricted": 0.0, "pricing": 0.0}
    t0 = perf_counter()
    probs = [_Problem(Gd[k], A, Axi, b, st, W) for k, W in enumerate(_first_sets(Gd, st, first))]
    seconds["models"] = perf_counter() - t0
    done, failed = np.zeros(K, bool), np.zeros(K, bool)
    radius = np.abs(Gd).sum(axis=1)
    rounds, active = 0, np.arange(K)
    while active.size and rounds < max_rounds:
        rounds += 1
        t0 = perf_counter()
        good = np.array([probs[k].solve(A) for k in active], dtype=bool)
        failed[active[~good]] = True
        active = active[good]
        t1 = perf_counter()
        seconds["restricted"] += t1 - t0
        if not active.size:
            break
        T = gap_terms(Gd[active] - np.array([probs[k].mu for k in active]) @ A,
                      np.array([probs[k].xi for k in active]))
        for i, k in enumerate(active):
            T[i, probs[k].W] = 0.0
        fin = T.sum(axis=1) <= gap_tol * radius[active]
        done[active[fin]] = True
        t2 = perf_counter()
        seconds["pricing"] += t2 - t1
        for i in np.nonzero(~fin)[0]:
            probs[active[i]].grow(A, _top(T[i], add))
        seconds["restricted"] += perf_counter() - t2
        active = active[~fin]
    for pr in probs:
        pr.close()
    return (np.array([pr.mu for pr in probs]), done & ~failed, rounds,
            sum(pr.iterations for pr in probs), [pr.W.size for pr in probs], seconds)


def solve(A: np.ndarray, b: np.ndarray, Gd: np.ndarray, st: Start | None = None,
          gap_tol: float | None = None, max_rounds: int | None = None) -> SiftResult:
    """Dual points of ``max Gd[k]' xi  s.t.  A xi = b, |xi| <= 1`` for every row ``k`` by
    sifting (see the module docstring); ``st`` is a start vertex (:func:`start` of the first
    row's cost if not given); ``gap_tol`` and ``max_rounds`` default to :data:`GAP_TOL` and
    :data:`MAX_ROUNDS`.  The problems are sifted in chunks of :data:`CHUNK` (the HiGHS
    models of a chunk live together; the pricing of a chunk is one matrix product).

    Raises
    ------
    EmptySet
        If the start solve finds the feasible set empty.
    """
    A = np.asarray(A, dtype=float)
    b = np.asarray(b, dtype=float)
    Gd = np.atleast_2d(np.asarray(Gd, dtype=float))
    K, p = Gd.shape[0], A.shape[0]
    seconds = {"start": 0.0}
    t0 = perf_counter()
    st = start(A, b, Gd[0]) if st is None else st
    Axi = A @ st.xi
    seconds["start"] = perf_counter() - t0
    mu, conv = np.zeros((K, p)), np.zeros(K, bool)
    rounds, iterations, sizes = 0, st.iterations, []
    opts = (GAP_TOL if gap_tol is None else gap_tol,
            MAX_ROUNDS if max_rounds is None else max_rounds, max(FIRST, p), max(ADD, p))
    for lo in range(0, K, CHUNK):
        sl = slice(lo, min(K, lo + CHUNK))
        mu[sl], conv[sl], r_, it, sz, sec = _sift_chunk(A, b, Gd[sl], st, Axi, opts)
        rounds, iterations = max(rounds, r_), iterations + it
        sizes += sz
        for phase, s in sec.items():
            seconds[phase] = seconds.get(phase, 0.0) + s
    return SiftResult(mu, conv, rounds, iterations, float(np.mean(sizes)) if K else 0.0,
                      seconds)
