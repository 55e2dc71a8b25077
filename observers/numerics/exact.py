"""Exact interval hulls of the set of states consistent with a record (linear systems).

For ``x_{j+1} = A x_j + B u_j + w_j``, ``y_j = C x_j + v_j`` with zonotopes
``x_0 in X0 = c0 + G0 [-1, 1]^r0``, ``w_j in W = cW + E [-1, 1]^rw`` and
``v_j in V = cV + F [-1, 1]^rv``, the states ``x_k`` consistent with ``u_0..u_{k-1}`` and
``y_0..y_k`` form a polytope, the *filtered* set of step k; without ``y_k`` it is the
*predicted* set of step k (step 0: ``X0`` itself).  Its interval hull is 2n linear programs.
:class:`ExactHullLP` solves them exactly (to the LP tolerance) and soundly, step by step,
with one incremental HiGHS model per objective.

Formulation (sparse, states kept as variables)
----------------------------------------------
Each generator matrix is split into its axis-aligned columns (at most one nonzero; they add
the radius ``rho = |G_axis| 1`` to the ranges of the rows) and its general columns ``G^``
(factor variables in ``[-1, 1]``).  Variables: the states ``x_0..x_k``, ``xi`` (general
columns of X0), ``omega_j`` (of W) and ``nu_j`` (of V).  Constraints:

* ``x_0 - G0^ xi  in  [c0 - rho0, c0 + rho0]``,
* ``x_{j+1} - A x_j - E^ omega_j  in  [B u_j + cW - rhoW, B u_j + cW + rhoW]``,
* ``C x_j + F^ nu_j  in  [y_j - cV - rhoV, y_j - cV + rhoV]``.

A constraint on a single variable (a box X0; an output row of ``C`` with one nonzero and no
general noise column, as in every benchmark) is a column bound instead of a row.  Every range
computed in floating point is widened outward by a bound of its rounding error, so the
feasible set of the LP contains the exact consistent set of the model's floating-point data.

Incremental solution
--------------------
Each step appends one block of columns and rows, and the objective ``max +-x_{k,i}`` moves
from ``x_{k-1,i}`` to ``x_{k,i}``.  The constraint matrix does not depend on the record (only
the ranges do), so blocks are allocated ahead in chunks and a step only changes bounds and
two costs: HiGHS keeps its factorised basis instead of rebuilding its model (measured on the
30-tank record at step 170: a run after adding columns or rows cost 6-10 ms per model, after
changing bounds 1.5-2 ms).  The blocks
allocated ahead constrain nothing (free states, factor columns fixed at 0, dynamics rows
fixed at 0) and have their states basic and their rows nonbasic, so that a block, once
activated, is primal feasible: its states follow from those of the step before through rows
at a bound of their range.  Each of the 2n models keeps its own optimal basis from step to
step (warm start): the predicted LP of step k starts from the basis of the filtered LP of
step k-1 (a primal feasible point: the primal simplex follows the objective from
``x_{k-1,i}`` to ``x_{k,i}``), the filtered LP from that of the predicted one (an optimal
point the new measurement may cut off: the dual simplex, which restores primal feasibility;
every column is boxed, so it keeps dual feasibility by bound flips; Dantzig pricing avoids
recomputing steepest-edge weights after every change).
A warm solve that does not finish within its iteration cap (Dantzig pricing can cycle on a
degenerate LP) is solved again from scratch by the strategies of :data:`COLD_SOLVES` in turn
(steepest-edge dual, Devex dual, primal simplex, interior point), so that one solver path
failing on one LP does not loosen a floor.  Nothing is ever dropped: this is the whole
record's LP.

Cost (measured, one core, both floors, whole records)
------------------------------------------------------
6-tank (261 steps): 6.6 s; 30-tank (261 steps): 140 s (13 simplex iterations per predicted
LP and 14 per filtered LP on average; 357 s with the dual simplex for the predicted LPs, 434 s
before the blocks allocated ahead were placed); 6-state vehicle, first 200 steps: 0.23 million
iterations (0.40 million before).  A step costs 2n warm LP solves per floor; the solves grow
with the record (the LP grows by one block per step, and a new measurement cuts off more of
the exact set's many small facets), so the total grows faster than linearly with the record
length.  The naive re-solve (the dense LP from scratch) took about 80 s for one step at the
end of the 6-tank record.

Finite column bounds
--------------------
Weak duality needs finite bounds on every variable the multipliers leave a reduced cost on.
The states get bounds that every consistent trajectory satisfies, hence redundant for the
LP: while x_k is predicted, the interval prediction ``A [x_{k-1}] + B u + W`` of the bounds
of ``x_{k-1}``; while it is filtered, the predicted hull (widened by ``margin``) intersected
with the single-variable output bounds; afterwards, the filtered hull widened by ``margin``
(relative to its width) intersected with the output bounds (and X0 for x_0, which encode
constraints).  The margin keeps these bounds inactive, which saves degenerate pivots.

Soundness (weak duality, as :func:`observers.lp.hull.dual_bounds`)
--------------------------------------------------------------------
For ``max c'z  s.t.  L <= M z <= U,  l <= z <= u`` and *any* multiplier ``mu`` (zero on the
free rows), every feasible ``z`` satisfies
``c'z = mu'M z + g'z <= sum_i max(mu_i L_i, mu_i U_i) + sum_j max(g_j l_j, g_j u_j)``
with ``g = c - M'mu``.  HiGHS only proposes ``mu`` (its row duals); the bound is evaluated
here in floating point and widened by a bound of the evaluation's rounding error (the error
of ``g_j`` is at most ``(nnz_j + 3) eps (|c_j| + (|M|'|mu|)_j)``, that of a sum of ``K``
terms at most ``K eps`` times the sum of their moduli).  A primal objective value is never
used.  The LP's feasible set contains the consistent set, so the bound holds for every
consistent state; an LP that HiGHS does not solve to optimality still yields a valid (if
loose) bound, clipped by the variable's own column bounds, and is listed in
:attr:`ExactHullLP.inexact`.  Two sound bounds that cross prove the set empty; HiGHS's
infeasibility verdict is checked with a Farkas certificate (a zero objective bounded by a
negative number by the same weak duality) from its dual ray (without one, the LP is solved
again from scratch), and reported as :class:`~observers.sets.EmptySet` naming the step.

References: the consistent set is the constrained zonotope of the exact recursion without
reduction (Scott, Raimondo, Marseglia, Braatz, Automatica 69, 2016); its description by
linear constraints over the noise factors is the classical set-membership one (Schweppe,
IEEE TAC 13(1), 1968; Milanese & Vicino, Automatica 27(6), 1991).
:mod:`observers.numerics.exact_reference` solves the same hulls by an independent dense
formulation from scratch (the check).
"""

from __future__ import annotations

from dataclasses import dataclass

import highspy
import numpy as np
import scipy.sparse as sp

from ..errors import EmptySet
from ..lp import new_highs
from ..sets import Interval

_EPS = np.finfo(float).eps
_TINY = np.finfo(float).tiny
#: primal and dual feasibility tolerances of HiGHS in the exact LPs (defaults: 1e-7)
LP_TOLERANCE = 1e-9
#: relative widening of the redundant state bounds (keeps them inactive)
MARGIN = 0.1
#: steps allocated ahead at least (then an eighth of the steps done)
CHUNK = 8
#: simplex iterations a warm-started solve may take, at least and per active row: beyond it
#: the solve is taken as stalled (measured: Dantzig pricing cycles for ever on some
#: degenerate records, e.g. the audit's vertex-noise realisations of the 6-D vehicle, while a
#: cold steepest-edge solve of the same LP takes ~600 iterations); a warm solve takes tens
WARM_ITERATIONS = 3000
WARM_ITERATIONS_PER_ROW = 1
_NO_LIMIT = 2**31 - 1
#: a warm solve: dual simplex from the kept basis, Dantzig pricing, under the iteration cap
_WARM = {"solver": "simplex", "simplex_strategy": 1, "simplex_dual_edge_weight_strategy": 0}
#: a warm solve of a predicted LP: primal simplex from the kept basis.  The filtered optimum
#: of step k-1 with the new block placed by :meth:`ExactHullLP._place_basis` is a primal
#: feasible point of the predicted LP of step k; only the objective moves (from ``x_{k-1,i}``
#: to ``x_{k,i}``), which the primal simplex follows directly, while the dual simplex first
#: flips bounds to regain dual feasibility and then repairs the primal infeasibility it made.
#: Measured on the 30-tank record (261 steps, one core): 0.20 million simplex iterations and
#: 69 s for the predicted LPs against 1.10 million and 256 s with the dual simplex.  A
#: filtered LP adds bounds to an optimal point: the dual simplex's case (:data:`_WARM`)
_WARM_PREDICTED = {**_WARM, "simplex_strategy": 4}
#: the cold re-solves tried in turn after a warm solve that did not finish, each from scratch,
#: until one proves optimality or infeasibility.  Steepest-edge dual simplex first (the
#: fastest cold solve here); the others because HiGHS's steepest-edge dual simplex can stop
#: with an error at its first iteration (measured: one LP of step 243 of the 30-tank record
#: of Table 5, rebuilt from a cached prefix, where Devex pricing, the primal simplex and the
#: interior-point method all solve it to the same optimum within 4e-12) or cycle (measured:
#: the predicted LP of step 157 of the audit's 6-D vehicle realisation 4, rebuilt from a
#: cached prefix: no end after 240 s, while Devex pricing solves it in 926 iterations).
#: Every strategy but the last runs under :data:`COLD_ITERATIONS` (and per active row and
#: column); the interior-point method, last, runs without a cap
COLD_SOLVES = (
    ("steepest-edge dual simplex", {"simplex_dual_edge_weight_strategy": 2}),
    ("Devex dual simplex", {"simplex_dual_edge_weight_strategy": 1}),
    ("primal simplex", {"simplex_strategy": 4}),
    ("interior point with crossover", {"solver": "ipm"}),
)
#: simplex iterations a cold simplex solve may take, at least and per active row and column
#: (measured: cold solves take hundreds to a few thousand iterations on the records of
#: ``make bench``; the cycling solve above ran 20000 iterations in 0.33 s)
COLD_ITERATIONS = 20000
COLD_ITERATIONS_PER_SIZE = 2
_OPTIMAL = highspy.HighsModelStatus.kOptimal
#: basis statuses by their integer values (HiGHS takes lists of the enum)
_STATUS = np.array(list(highspy.HighsBasisStatus.__members__.values()), dtype=object)
_STATUS = _STATUS[np.argsort([int(s) for s in _STATUS])]
_LOWER, _BASIC = int(highspy.HighsBasisStatus.kLower), int(highspy.HighsBasisStatus.kBasic)
_INFEASIBLE = highspy.HighsModelStatus.kInfeasible


# -- small helpers ---------------------------------------------------------------------------
def widen(lo, hi, scale, terms: int) -> tuple[np.ndarray, np.ndarray]:
    """``[lo, hi]`` widened outward by ``(terms + 2) eps |scale|`` plus the smallest normal
    number: a sound enclosure of the exact range when ``lo`` and ``hi`` were computed with
    ``terms`` rounded operations whose operands sum in modulus to ``scale``."""
    pad = (terms + 2) * _EPS * np.abs(scale) + _TINY
    return np.asarray(lo, float) - pad, np.asarray(hi, float) + pad


@dataclass(frozen=True)
class SplitSet:
    """A zonotope ``c + G [-1, 1]^r`` split into its axis-aligned part (the box of radius
    ``rho`` around ``c``, ``rho`` rounded up) and its general generator columns ``G_gen``."""

    c: np.ndarray
    rho: np.ndarray
    G_gen: np.ndarray

    @classmethod
    def of(cls, c, G) -> SplitSet:
        c = np.asarray(c, float).reshape(-1)
        G = np.asarray(G, float).reshape(c.shape[0], -1)
        axis = np.count_nonzero(G, axis=0) <= 1
        Ga = np.abs(G[:, axis])
        rho = Ga.sum(axis=1)
        rho = rho + (Ga.shape[1] + 2) * _EPS * rho  # rounding of the sum, outward
        return cls(c, rho, G[:, ~axis])

    @property
    def general(self) -> int:
        """Number of general (factor) columns."""
        return self.G_gen.shape[1]

    def hull(self) -> tuple[np.ndarray, np.ndarray]:
        """Sound interval hull ``c +- (rho + |G_gen| 1)``."""
        r = self.rho + np.abs(self.G_gen).sum(axis=1)
        return widen(self.c - r, self.c + r, np.abs(self.c) + r, self.general + 2)


@dataclass(frozen=True)
class StepHulls:
    """Sound interval hulls of one step: predicted (before ``y_k``) and filtered (after)."""

    pred_lo: np.ndarray
    pred_hi: np.ndarray
    filt_lo: np.ndarray
    filt_hi: np.ndarray

    @property
    def predicted(self) -> Interval:
        """The predicted hull as an :class:`~observers.sets.Interval`."""
        return Interval(self.pred_lo, self.pred_hi)

    @property
    def filtered(self) -> Interval:
        """The filtered hull as an :class:`~observers.sets.Interval`."""
        return Interval(self.filt_lo, self.filt_hi)


@dataclass(frozen=True)
class _Layout:
    """Columns and rows of one step: first index and count of each block."""

    x: int  # states x_j (n columns)
    fac: int  # xi (step 0) or omega_{j-1} (general columns of X0 / W)
    nfac: int
    nu: int  # general columns of V used by the output rows
    nnu: int
    rows: int  # X0 rows (step 0, if X0 has general columns) or dynamics rows
    nrows: int
    meas: int  # output rows (non-simple outputs)
    nmeas: int


class ExactHullLP:
    """Incremental exact hulls: :meth:`first` (``y_0``), then :meth:`advance` per step.

    Parameters
    ----------
    A, B, C : array_like
        The linear model (``B`` may have zero columns).
    X0, W, V : tuple of array_like
        ``(centre, generators)`` of the zonotopes of the initial state, the disturbance and
        the measurement noise.
    margin : float
        Relative widening of the redundant state bounds (see the module docstring).

    Attributes
    ----------
    k : int
        Steps done (the next :meth:`advance` computes step ``k``).
    iterations, solves : int
        Simplex iterations and LPs solved so far.
    inexact : list of int
        Steps with an LP that HiGHS did not solve to optimality (their bounds are sound but
        may be loose).
    """

    def __init__(self, A, B, C, X0, W, V, margin: float = MARGIN):
        self.A = np.asarray(A, float)
        self.n = n = self.A.shape[0]
        self.B = np.asarray(B, float).reshape(n, -1)
        self.C = np.asarray(C, float).reshape(-1, n)
        self.X0, self.W, self.V = SplitSet.of(*X0), SplitSet.of(*W), SplitSet.of(*V)
        self.margin = float(margin)
        # outputs that bound one state: one nonzero in C and no general column of V
        nnz = np.count_nonzero(self.C, axis=1)
        vgen = np.any(self.V.G_gen != 0, axis=1)
        simple = (nnz == 1) & ~vgen
        self._simple = np.flatnonzero(simple)
        self._simple_col = np.argmax(self.C != 0, axis=1)[self._simple]
        self._zero = np.flatnonzero((nnz == 0) & ~vgen)
        self._meas_rows = np.flatnonzero(~simple & ((nnz > 0) | vgen))
        Fg = self.V.G_gen[self._meas_rows]
        self._nu_used = np.flatnonzero(np.any(Fg != 0, axis=0))
        self.k = 0
        self.iterations = 0
        self.solves = 0
        self.inexact: list[int] = []
        self._models = [self._new_model() for _ in range(2 * n)]
        self._layout: list[_Layout] = []
        self._ncols = self._nrows = 0
        self._cl = np.zeros(0)  # column bounds (mirror of the models)
        self._cu = np.zeros(0)
        self._rl = np.zeros(0)  # row ranges of the active rows (0 for free rows)
        self._ru = np.zeros(0)
        self._free = np.zeros(0, bool)  # rows without constraint (zero multipliers)
        self._active = 0  # rows [0, active) are active, the others free
        self._coo: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []
        self._MT: sp.csr_matrix | None = None
        self._last: StepHulls | None = None

    # -- HiGHS models ----------------------------------------------------------------------------
    @staticmethod
    def _new_model() -> highspy.Highs:
        h = new_highs()
        h.setOptionValue("presolve", "off")
        h.setOptionValue("solver", "simplex")
        h.setOptionValue("simplex_strategy", 1)  # dual simplex
        # Dantzig pricing: steepest-edge weights are recomputed after every change of the
        # model (measured: half the time of a step on the 6-tank record)
        h.setOptionValue("simplex_dual_edge_weight_strategy", 0)
        h.setOptionValue("primal_feasibility_tolerance", LP_TOLERANCE)
        h.setOptionValue("dual_feasibility_tolerance", LP_TOLERANCE)
        return h

    @property
    def num_cols(self) -> int:
        """Columns allocated (active and ahead)."""
        return self._ncols

    @property
    def num_rows(self) -> int:
        """Rows allocated (active and ahead)."""
        return self._nrows

    @property
    def num_active_rows(self) -> int:
        """Rows of the current LP."""
        return self._active

    def _block(self, lay: _Layout, first: bool, prev: int | None, outputs: bool = True
               ) -> tuple[list[np.ndarray], list[np.ndarray], list[np.ndarray]]:
        """Nonzeros (rows, columns, values) of one step's block: the X0 rows of step 0
        (``first``) or the dynamics rows linking ``x_j`` to the states at column ``prev``, and
        (``outputs``) the output rows."""
        n, W = self.n, self.W
        Cm = self.C[self._meas_rows]
        Fm = self.V.G_gen[self._meas_rows][:, self._nu_used]
        rC, cC = np.nonzero(Cm)
        rF, cF = np.nonzero(Fm)
        ri: list[np.ndarray] = []
        ci: list[np.ndarray] = []
        vals: list[np.ndarray] = []
        row, col = lay.rows, lay.x
        if first and lay.nrows:  # x_0 - G0^ xi
            r2, c2 = np.nonzero(self.X0.G_gen)
            ri += [np.arange(n) + row, r2 + row]
            ci += [np.arange(n) + col, c2 + lay.fac]
            vals += [np.ones(n), -self.X0.G_gen[r2, c2]]
        elif not first:  # x_j - A x_{j-1} - E^ omega_{j-1}
            rA, cA = np.nonzero(self.A)
            rE, cE = np.nonzero(W.G_gen)
            ri += [np.arange(n) + row, rA + row, rE + row]
            ci += [np.arange(n) + col, cA + prev, cE + lay.fac]
            vals += [np.ones(n), -self.A[rA, cA], -W.G_gen[rE, cE]]
        if outputs:  # C x_j + F^ nu_j
            ri += [rC + lay.meas, rF + lay.meas]
            ci += [cC + col, cF + lay.nu]
            vals += [Cm[rC, cC], Fm[rF, cF]]
        return ri, ci, vals

    def _allocate(self, steps: int) -> None:
        """Append the blocks of ``steps`` more steps to every model, placed so that they do
        not constrain the current LP: free states, factor columns fixed at 0, dynamics rows
        (and X0's rows) fixed at 0, output rows free; the states basic and their rows nonbasic
        (:meth:`_place_basis`), so that a block activated by :meth:`_activate_prediction`
        starts primal feasible."""
        n, W = self.n, self.W
        col, row = self._ncols, self._nrows
        ri, ci, vals = [], [], []
        new: list[_Layout] = []
        for _ in range(steps):
            j = len(self._layout)
            first = j == 0
            nfac = self.X0.general if first else W.general
            nrows = (n if self.X0.general else 0) if first else n
            lay = _Layout(x=col, fac=col + n, nfac=nfac, nu=col + n + nfac,
                          nnu=self._nu_used.size, rows=row, nrows=nrows, meas=row + nrows,
                          nmeas=self._meas_rows.size)
            r_, c_, v_ = self._block(lay, first, None if first else self._layout[j - 1].x)
            ri += r_
            ci += c_
            vals += v_
            self._layout.append(lay)
            new.append(lay)
            col = lay.nu + lay.nnu
            row = lay.meas + lay.nmeas
        free_cols = [np.arange(lay.x, lay.x + n) for lay in new if lay.nrows]
        fixed_rows = [np.arange(lay.rows, lay.rows + lay.nrows) for lay in new]
        self._append(col, row, ri, ci, vals,
                     free_cols=np.concatenate(free_cols) if free_cols else None,
                     fixed_rows=np.concatenate(fixed_rows) if fixed_rows else None)
        self._place_basis(len(self._layout) - len(new))

    def _place_basis(self, first: int) -> None:
        """Give every model the basis of the blocks from step ``first`` on: the states of a
        block with rows basic, its rows nonbasic, its factor columns nonbasic, its output rows
        basic (the earlier blocks keep a model's basis; a model without one gets this basis
        for every block).

        With this basis the states of a step about to be activated are determined by those of
        the step before through its rows, at a bound of their range: a primal feasible point
        inside the interval prediction.  HiGHS's own basis for appended blocks (slack rows
        basic, states nonbasic at 0) is primal infeasible in every dynamics row once the
        block is activated (measured on the 30-tank record, steps 0-99: 57 simplex
        iterations per predicted LP with it, 18 with this one)."""
        cols = np.full(self._ncols, _LOWER, np.int64)
        rows = np.full(self._nrows, _BASIC, np.int64)
        for lay in self._layout:
            if lay.nrows:
                cols[lay.x : lay.x + self.n] = _BASIC
                rows[lay.rows : lay.rows + lay.nrows] = _LOWER
        start = self._layout[first]
        c0, r0 = start.x, start.rows
        for h in self._models:
            basis = h.getBasis()
            if basis.valid:
                old_c = [int(s) for s in basis.col_status[:c0]]
                old_r = [int(s) for s in basis.row_status[:r0]]
                c, r = cols.copy(), rows.copy()
                c[:c0], r[:r0] = old_c, old_r
            else:
                c, r = cols, rows
            basis.col_status = _STATUS[c].tolist()
            basis.row_status = _STATUS[r].tolist()
            h.setBasis(basis)

    def _append(self, col: int, row: int, ri: list, ci: list, vals: list,
                free_cols: np.ndarray | None = None, fixed_rows: np.ndarray | None = None
                ) -> None:
        """Append columns up to ``col`` (fixed at 0, or free: ``free_cols``) and rows up to
        ``row`` (free, or fixed at 0: ``fixed_rows``) with the nonzeros ``(ri, ci, vals)`` to
        every model and to the transposed mirror.  Either way the mirror holds them as
        inactive (columns bounded by 0, rows free: zero multipliers), which they are for the
        current LP: a state bound by nothing but its own step's rows constrains nothing."""
        ri, ci, vals = (np.concatenate(a) if a else np.zeros(0) for a in (ri, ci, vals))
        ri, ci = ri.astype(np.int64), ci.astype(np.int64)
        new_cols, new_rows = col - self._ncols, row - self._nrows
        zeros = np.zeros(new_cols)
        lo_c, hi_c = zeros.copy(), zeros.copy()
        if free_cols is not None:
            lo_c[free_cols - self._ncols], hi_c[free_cols - self._ncols] = -np.inf, np.inf
        for h in self._models:
            h.addVars(new_cols, lo_c, hi_c)
        if new_rows:
            order = np.lexsort((ci, ri))
            r_, c_, v_ = ri[order] - self._nrows, ci[order], vals[order]
            starts = np.searchsorted(r_, np.arange(new_rows)).astype(np.int32)
            lo, hi = np.full(new_rows, -np.inf), np.full(new_rows, np.inf)
            if fixed_rows is not None:
                lo[fixed_rows - self._nrows] = hi[fixed_rows - self._nrows] = 0.0
            for h in self._models:
                h.addRows(new_rows, lo, hi, v_.size, starts, c_.astype(np.int32), v_)
        self._cl = np.concatenate([self._cl, zeros])
        self._cu = np.concatenate([self._cu, zeros])
        self._rl = np.concatenate([self._rl, np.zeros(new_rows)])
        self._ru = np.concatenate([self._ru, np.zeros(new_rows)])
        self._free = np.concatenate([self._free, np.ones(new_rows, bool)])
        self._coo.append((ri, ci, vals))
        self._ncols, self._nrows = col, row
        R, Cc, Vv = (np.concatenate(a) for a in zip(*self._coo, strict=True))
        self._MT = sp.csr_matrix((Vv, (Cc, R)), shape=(self._ncols, self._nrows))
        self._absMT = abs(self._MT)
        self._col_nnz = np.diff(self._MT.indptr)

    def _ensure(self, j: int) -> _Layout:
        if j >= len(self._layout):
            self._allocate(max(CHUNK, j // 8))
        return self._layout[j]

    def _lay(self, j: int) -> _Layout:
        """The columns and rows of step j (allocated)."""
        return self._layout[j]

    def _put_bounds(self, kind: str, first: int, lo: np.ndarray, hi: np.ndarray) -> None:
        """Bounds ``lo .. hi`` of the columns (``kind="Cols"``) or the row ranges
        (``"Rows"``) from ``first`` on, in the mirror and in every model."""
        lower, upper = (self._cl, self._cu) if kind == "Cols" else (self._rl, self._ru)
        lower[first : first + lo.size] = lo
        upper[first : first + lo.size] = hi
        idx = np.arange(first, first + lo.size, dtype=np.int32)
        for h in self._models:
            getattr(h, f"change{kind}Bounds")(lo.size, idx, lo, hi)

    def _set_cols(self, first: int, lo: np.ndarray, hi: np.ndarray) -> None:
        if lo.size == 0:
            return
        self._put_bounds("Cols", first, lo, hi)

    def _set_rows(self, first: int, lo: np.ndarray, hi: np.ndarray) -> None:
        if lo.size == 0:
            return
        self._put_bounds("Rows", first, lo, hi)
        self._free[first : first + lo.size] = False
        self._active = max(self._active, first + lo.size)

    def _free_rows(self, first: int, count: int) -> None:
        """Make rows ``first .. first + count - 1`` free (no constraint, zero multipliers)."""
        if count == 0:
            return
        self._rl[first : first + count] = 0.0
        self._ru[first : first + count] = 0.0
        self._free[first : first + count] = True
        idx = np.arange(first, first + count, dtype=np.int32)
        inf = np.full(count, np.inf)
        for h in self._models:
            h.changeRowsBounds(count, idx, -inf, inf)

    def _state_bounds(self, j: int) -> tuple[np.ndarray, np.ndarray]:
        x = self._lay(j).x
        return self._cl[x : x + self.n].copy(), self._cu[x : x + self.n].copy()

    def _move_objective(self, j: int) -> None:
        """Objective ``max +x_{j,i}`` in model ``2 i`` and ``max -x_{j,i}`` in ``2 i + 1``."""
        prev = self._lay(j - 1).x if j > 0 else None
        cur = self._lay(j).x
        for o, h in enumerate(self._models):
            i, minus = divmod(o, 2)
            if prev is not None:
                h.changeColCost(prev + i, 0.0)
            h.changeColCost(cur + i, 1.0 if minus else -1.0)  # HiGHS minimises

    # -- the blocks of a step --------------------------------------------------------------------
    def _output_bounds(self, y: np.ndarray, j: int) -> tuple[np.ndarray, np.ndarray]:
        """Bounds of ``x_j`` from the single-variable outputs of ``y`` (inf elsewhere)."""
        V = self.V
        t = y - V.c
        a, b = widen(t - V.rho, t + V.rho, np.abs(y) + np.abs(V.c) + V.rho, 3)
        lo, hi = np.full(self.n, -np.inf), np.full(self.n, np.inf)
        bad = self._zero[(a[self._zero] > 0.0) | (b[self._zero] < 0.0)]
        if bad.size:  # an output that measures no state: 0 = y_i - v_i
            i = int(bad[0])
            raise EmptySet(f"step {j}: output {i + 1} measures no state and y = {y[i]:g} lies "
                           "outside the noise bounds: the record is inconsistent with the model")
        s = self._simple
        if s.size:
            coef = self.C[s, self._simple_col]
            p, q = a[s] / coef, b[s] / coef
            p, q = widen(np.minimum(p, q), np.maximum(p, q),
                         np.maximum(np.abs(p), np.abs(q)), 1)
            np.maximum.at(lo, self._simple_col, p)
            np.minimum.at(hi, self._simple_col, q)
        return lo, hi

    def _activate_outputs(self, y: np.ndarray, lay: _Layout) -> None:
        """Rows ``C x_j + F^ nu_j in [y - cV - rhoV, y - cV + rhoV]`` of the other outputs."""
        rows = self._meas_rows
        if rows.size == 0:
            return
        V = self.V
        t = y[rows] - V.c[rows]
        lo, hi = widen(t - V.rho[rows], t + V.rho[rows],
                       np.abs(y[rows]) + np.abs(V.c[rows]) + V.rho[rows], 3)
        self._set_cols(lay.nu, -np.ones(lay.nnu), np.ones(lay.nnu))
        self._set_rows(lay.meas, lo, hi)

    def _activate_initial(self) -> tuple[np.ndarray, np.ndarray]:
        """Step 0's bounds: x_0 in the hull of X0, X0's general rows; returns that hull."""
        lay, X0 = self._ensure(0), self.X0
        lo, hi = X0.hull()
        self._set_cols(lay.x, lo, hi)
        self._set_cols(lay.fac, -np.ones(lay.nfac), np.ones(lay.nfac))
        if lay.nrows:
            a, b = widen(X0.c - X0.rho, X0.c + X0.rho, np.abs(X0.c) + X0.rho, 1)
            self._set_rows(lay.rows, a, b)
        return lo, hi

    def _activate_prediction(self, j: int, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Step j's prediction block: ``x_j`` bounded by the interval prediction of the bounds
        of ``x_{j-1}``, ``omega_{j-1}`` and the dynamics rows; returns the prediction."""
        n, W = self.n, self.W
        lay = self._ensure(j)
        plo, phi = self._state_bounds(j - 1)
        mid = 0.5 * (plo + phi)
        rad = 0.5 * (phi - plo) + 2 * _EPS * (np.abs(plo) + np.abs(phi))  # covers [plo, phi]
        d = self.B @ u + W.c
        d_scale = np.abs(self.B) @ np.abs(u) + np.abs(W.c)
        absA = np.abs(self.A)
        c = self.A @ mid + d
        r = absA @ rad + W.rho + np.abs(W.G_gen).sum(axis=1)
        lo, hi = widen(c - r, c + r, absA @ np.abs(mid) + d_scale + r,
                       2 * n + self.B.shape[1] + W.general + 4)
        self._set_cols(lay.x, lo, hi)
        self._set_cols(lay.fac, -np.ones(lay.nfac), np.ones(lay.nfac))
        a, b = widen(d - W.rho, d + W.rho, d_scale + W.rho, self.B.shape[1] + 3)
        self._set_rows(lay.rows, a, b)
        return lo, hi

    def _loosen(self, lo: np.ndarray, hi: np.ndarray, hard: tuple[np.ndarray, np.ndarray]
                ) -> tuple[np.ndarray, np.ndarray]:
        """Sound bounds ``[lo, hi]`` widened by the margin, within the constraint bounds."""
        pad = self.margin * (hi - lo) + 1e-9 * (np.abs(lo) + np.abs(hi))
        return np.maximum(lo - pad, hard[0]), np.minimum(hi + pad, hard[1])

    # -- solving ---------------------------------------------------------------------------------
    def _solve_all(self, j: int, stage: str) -> tuple[np.ndarray, np.ndarray]:
        """Solve the 2n LPs of ``x_j``; sound ``(lo, hi)`` from their dual points."""
        n, R = self.n, self._active
        Mu = np.zeros((2 * n, self._nrows))
        warm = _WARM_PREDICTED if stage == "predicted" else _WARM
        for o, h in enumerate(self._models):
            status = self._run(h, warm=warm)
            if status not in (_OPTIMAL, _INFEASIBLE):
                status = self._cold(h)
                if status not in (_OPTIMAL, _INFEASIBLE) and j not in self.inexact:
                    self.inexact.append(j)
            if status == _INFEASIBLE:
                certified = self._farkas(j, o)
                if not certified:  # HiGHS's verdict alone: confirm it from scratch
                    status = self._cold(h)
                if status == _INFEASIBLE:
                    how = ("proved by a Farkas certificate" if certified
                           else "HiGHS finds the LP infeasible")
                    raise EmptySet(f"step {j}: no state is consistent with the record up to "
                                   f"y[{j}] ({stage} set; {how}): the record is inconsistent "
                                   "with the model")
            sol = h.getSolution()
            if sol.dual_valid and R:
                mu = np.asarray(sol.row_dual, dtype=float)[:R]
                if np.all(np.isfinite(mu)):
                    Mu[o, :R] = -mu  # max +-x solved as min -+x: mu = -row_dual
        Mu[:, self._free] = 0.0  # free rows: zero multipliers
        col = self._lay(j).x + np.arange(n)
        bounds = self._dual_bounds(Mu, np.repeat(col, 2), np.tile([1.0, -1.0], n))
        lo, hi = -bounds[1::2], bounds[0::2]
        clo, chi = self._state_bounds(j)
        lo, hi = np.maximum(lo, clo), np.minimum(hi, chi)
        if np.any(lo > hi):
            i = int(np.argmax(lo - hi))
            raise EmptySet(f"step {j}: no state is consistent with the record up to y[{j}] "
                           f"({stage} set: its sound bounds cross in x{i + 1}, "
                           f"{lo[i]:.17g} > {hi[i]:.17g}): the record is inconsistent with "
                           "the model")
        return lo, hi

    def _dual_bounds(self, Mu: np.ndarray, cols: np.ndarray, signs: np.ndarray) -> np.ndarray:
        """Weak-duality bounds of ``max signs[o] z[cols[o]]`` for the multipliers ``Mu[o]``
        (zero on free rows), outward rounded."""
        K = Mu.shape[0]
        l, u = self._cl, self._cu
        G = -(self._MT @ Mu.T).T  # c - M'mu, without c
        G[np.arange(K), cols] += signs
        gscale = (self._absMT @ np.abs(Mu).T).T
        gscale[np.arange(K), cols] += np.abs(signs)
        gerr = (self._col_nnz + 3) * _EPS * 1.01 * gscale  # |g - fl(g)| <= gerr
        rterms = np.maximum(Mu * self._rl, Mu * self._ru)
        sterms = np.maximum(G * l, G * u)
        gpart = gerr @ np.maximum(np.abs(l), np.abs(u))
        total = rterms.sum(axis=1) + sterms.sum(axis=1) + gpart
        scale = np.abs(rterms).sum(axis=1) + np.abs(sterms).sum(axis=1) + gpart
        return total + (self._nrows + self._ncols + 4) * _EPS * 1.01 * scale + _TINY

    def _run(self, h: highspy.Highs, cold: dict | None = None,
             cap: int | None = None, warm: dict = _WARM) -> highspy.HighsModelStatus:
        """Solve ``h``: warm (the kept basis, the options ``warm``, under the warm iteration
        cap) or, with ``cold`` (options of :data:`COLD_SOLVES`), from scratch under ``cap``
        simplex iterations (None: no cap)."""
        for key, value in (_WARM if cold is not None else warm).items():
            h.setOptionValue(key, value)
        if cold is None:
            cap = max(WARM_ITERATIONS, WARM_ITERATIONS_PER_ROW * self._active)
        h.setOptionValue("simplex_iteration_limit", _NO_LIMIT if cap is None else cap)
        saved = {key: h.getOptionValue(key)[1] for key in cold or {} if key not in _WARM}
        for key, value in (cold or {}).items():
            h.setOptionValue(key, value)
        h.run()
        for key, value in saved.items():  # a cold solve's own options end with it
            h.setOptionValue(key, value)
        self.solves += 1
        self.iterations += max(h.getInfo().simplex_iteration_count, 0)
        return h.getModelStatus()

    def _cold(self, h: highspy.Highs) -> highspy.HighsModelStatus:
        """Solve ``h`` from scratch by the strategies of :data:`COLD_SOLVES` in turn, until one
        proves optimality or infeasibility (the last status otherwise); every strategy but
        the last under :data:`COLD_ITERATIONS`."""
        status = h.getModelStatus()
        cap = max(COLD_ITERATIONS,
                  COLD_ITERATIONS_PER_SIZE * (self._active + self._ncols))
        for i, (_, options) in enumerate(COLD_SOLVES):
            h.clearSolver()
            status = self._run(h, options, None if i == len(COLD_SOLVES) - 1 else cap)
            if status in (_OPTIMAL, _INFEASIBLE):
                break
        return status

    def _farkas(self, j: int, o: int) -> bool:
        """Whether the dual ray of model ``o`` (found infeasible) proves the LP infeasible:
        a multiplier whose weak-duality bound of the zero objective is negative."""
        try:
            *_, has_ray, ray = self._models[o].getDualRay()  # ([status,] has_ray, values)
        except (TypeError, ValueError, RuntimeError):  # pragma: no cover - API differences
            return False
        if not has_ray or ray is None or len(ray) != self._nrows:
            return False
        ray = np.asarray(ray, float)
        if not np.all(np.isfinite(ray)):
            return False
        ray[self._free] = 0.0  # free rows: zero multipliers
        col = np.array([self._lay(j).x])
        return any(self._dual_bounds(mu[None, :], col, np.zeros(1))[0] < 0.0
                   for mu in (ray, -ray))

    # -- public steps ----------------------------------------------------------------------------
    def first(self, y, hulls: StepHulls | None = None) -> StepHulls:
        """Step 0: predicted ``X0`` and filtered ``X0`` with ``y_0``.

        ``hulls`` (known, e.g. from a cache) skips the LPs and only sets up the model."""
        if self.k != 0:
            raise RuntimeError("first() must be the first step")
        plo, phi = self._activate_initial()
        self._move_objective(0)
        return self._filter(0, np.asarray(y, float).reshape(-1), plo, phi, plo, phi, hulls)

    def advance(self, u, y, hulls: StepHulls | None = None, predicted: bool = True
                ) -> StepHulls:
        """Step k: predict with ``u_{k-1}``, then filter with ``y_k``.

        ``predicted=False`` skips the LPs of the predicted hull: the returned predicted
        hull is then the interval prediction of the bounds of ``x_{k-1}`` (sound, looser),
        and a step costs half the LPs."""
        if self.k == 0:
            raise RuntimeError("advance() needs first() before it")
        j = self.k
        ilo, ihi = self._activate_prediction(j, np.asarray(u, float).reshape(-1))
        self._move_objective(j)
        if hulls is None and not predicted:
            plo, phi = ilo, ihi
        elif hulls is None:
            plo, phi = self._solve_all(j, "predicted")
        else:
            plo, phi = np.maximum(hulls.pred_lo, ilo), np.minimum(hulls.pred_hi, ihi)
        return self._filter(j, np.asarray(y, float).reshape(-1), plo, phi,
                            np.full(self.n, -np.inf), np.full(self.n, np.inf), hulls)

    def _filter(self, j: int, y: np.ndarray, plo: np.ndarray, phi: np.ndarray,
                hlo: np.ndarray, hhi: np.ndarray, hulls: StepHulls | None) -> StepHulls:
        """Add ``y_j`` to the predicted LP of step j (bounds ``[plo, phi]``; ``[hlo, hhi]``:
        bounds that encode constraints, X0 for step 0) and solve the filtered LPs."""
        lay = self._lay(j)
        olo, ohi = self._output_bounds(y, j)
        hard = (np.maximum(hlo, olo), np.minimum(hhi, ohi))
        lo, hi = np.maximum(plo, hard[0]), np.minimum(phi, hard[1])
        if np.any(lo > hi):
            i = int(np.argmax(lo - hi))
            raise EmptySet(f"step {j}: no state is consistent with the record up to y[{j}] "
                           f"(y[{j}] puts x{i + 1} outside its predicted bounds): the record "
                           "is inconsistent with the model")
        self._set_cols(lay.x, *self._loosen(lo, hi, hard))
        self._activate_outputs(y, lay)
        if hulls is None:  # within the predicted hull (both sound: the tighter one counts)
            flo, fhi = self._solve_all(j, "filtered")
        else:
            flo, fhi = hulls.filt_lo, hulls.filt_hi
        flo, fhi = np.maximum(flo, lo), np.minimum(fhi, hi)
        self._set_cols(lay.x, *self._loosen(flo, fhi, hard))
        self._last = StepHulls(plo, phi, flo, fhi)
        self.k = j + 1
        return self._last


class ExactSet:
    """The exact set of step k: the states consistent with the record up to ``y[k]``.

    Returned by the ``Exact`` observer; immutable.  :meth:`interval` is the exact filtered
    hull (computed by :class:`ExactHullLP`, sound), :attr:`predicted` the exact hull of the
    states consistent with the record up to ``y[k-1]`` (the predicted floor of the same step),
    :meth:`contains` decides membership by an LP over the record (the explicit formulation
    of :func:`observers.numerics.exact_reference.explicit_lp`).

    Parameters
    ----------
    model : tuple
        ``(A, B, C, X0, W, V)`` as for :class:`ExactHullLP`.
    u, y : sequence of ndarray
        The record so far (only its first ``k`` inputs and ``k + 1`` measurements are
        read; the observer appends to the same lists, never changes them).
    k : int
        The step.
    hulls : StepHulls
        The exact hulls of step k.
    """

    __slots__ = ("_model", "_u", "_y", "k", "_hulls")

    def __init__(self, model: tuple, u, y, k: int, hulls: StepHulls):
        self._model, self._u, self._y, self.k, self._hulls = model, u, y, k, hulls

    @property
    def dim(self) -> int:
        """Dimension n of the state space."""
        return self._hulls.filt_lo.shape[0]

    @property
    def doubles(self) -> int:
        """The values that define the set beside the model: the record up to step k (``k``
        inputs and ``k + 1`` measurements; :func:`observers.sets.doubles`)."""
        k = self.k
        return sum(np.size(u) for u in self._u[:k]) + sum(np.size(y) for y in self._y[:k + 1])

    def interval(self) -> Interval:
        """The exact (sound) interval hull of the filtered set."""
        return self._hulls.filtered

    @property
    def predicted(self) -> Interval:
        """The exact (sound) interval hull of the predicted set of this step."""
        return self._hulls.predicted

    @property
    def hulls(self) -> StepHulls:
        """Both hulls of this step."""
        return self._hulls

    def contains(self, x, tol: float = 0.0) -> bool:
        """Whether some trajectory consistent with the record ends within ``tol`` (infinity
        norm) of ``x`` at step k; one LP (HiGHS, at its feasibility tolerance)."""
        from .exact_reference import consistent

        x = np.asarray(x, float).reshape(-1)
        if x.shape != (self.dim,):
            raise ValueError(f"point has {x.size} entries, the set dimension {self.dim}")
        I = self._hulls.filtered
        if np.any(x < I.lo - tol) or np.any(x > I.hi + tol):
            return False
        k = self.k
        u = np.array(self._u[:k], float).reshape(k, self._model[1].shape[1])
        y = np.array(self._y[: k + 1], float)
        return consistent(self._model, u, y, x, tol)

    def __repr__(self) -> str:
        return f"ExactSet(step={self.k}, dim={self.dim})"
