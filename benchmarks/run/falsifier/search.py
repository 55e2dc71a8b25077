"""The search of the falsifier (:mod:`benchmarks.run.falsifier`): consistent trajectories of a
record that push one state of one step to an extreme, verified by forward simulation
(:mod:`.verification`).

Method (and why)
----------------
Each extreme is a local solution of ``max +-x_k[i]`` over the factors of ``x_0`` and of the
disturbances, subject to the dynamics and to every measurement, by a trust-region
*sequential linear programming* (SLP) method with *second-order corrections* (Fletcher,
*Practical Methods of Optimization*, 2nd ed., 1987, secs. 12.4 and 14.4; Nocedal & Wright,
*Numerical Optimization*, 2nd ed., 2006, secs. 15.6 and 18.5):

* The LP (:class:`StepLP`) is the problem linearised along a consistent trajectory ``A``
  in *multiple-shooting* form: the state deviations ``d_j = x_j - x^A_j`` are columns linked
  by the rows ``d_{j+1} = J_j d_j + G_W (omega_j - omega^A_j)``, the measurement rows are
  ``H_j d_j + G_V nu_j = y_j - h(x^A_j) - c_V``, and every factor is bounded.  The LP is
  sparse and well conditioned over hundreds of steps (a condensed, single-shooting LP would
  have dense rows of products of Jacobians); HiGHS re-solves it from the previous basis, so
  the ``2 n`` objectives of a step share one model and mostly only change its cost.
* A step: the LP's factors are simulated forward (the dynamics then hold exactly); if the
  measurement factors leave their bound (the linearisation error), the same LP is re-solved
  with its right-hand sides moved by the remainder observed at the candidate (a second-order
  correction: no new matrix, a few dual simplex pivots), until the candidate verifies.  It is
  accepted if it realises a tenth of the predicted gain, else the trust region on the factors
  shrinks; the model is re-linearised at the accepted point unless the step realised its
  predicted gain to ``STOP_RTOL`` (1e-3) of the run's total gain.  On a linear system the
  first LP is the exact problem, so its optimum is global (the tests compare it with an
  independent dense LP to 1e-3 of the radius; measured: 1e-6).
* Horizon.  The suggested shortcut, the truth fixed up to ``k - L`` and only the last ``L``
  disturbances free, fails on the tank records: the disturbance is tiny (``|w| <= 1e-3``)
  while ``X0`` has radius 4 and the tanks forget slowly (eigenvalues ~0.996), so the exact
  hull at ``k`` is shaped by the uncertain initial state and every measurement since.
  ``x_0`` is therefore always free; the disturbances are free over the whole horizon by
  default (``window="auto"``: while ``(k + 1) n <= 3000`` state columns) or over the last
  ``window`` steps (the earlier ones stay at the anchor's; the early measurements then are
  rows in ``xi0`` alone, through ``dx_j/dxi0``).  Measured on tank30-nonlinear at k = 262,
  a 99-step window (auto) gives 0.10 where the whole horizon gives 0.26 for the unmeasured
  tanks 3, 9 and 15 (disturbances accumulate there), and equal radii elsewhere, in 17 s
  instead of 75 s.
* Why SLP rather than SLSQP or IPOPT: the problem is an LP with mildly curved equality rows
  (Euler steps of smooth dynamics), so its local optima are vertices of the linearisation or
  near them, where SLP converges in one to three LPs; SLSQP's dense quasi-Newton matrices
  over ``(k + 1) n`` variables would be far slower (thousands of variables on a tank record),
  and IPOPT would add a compiled dependency for no gain on these near-linear problems.  The
  method is local: the inner box may miss the true extremes of a nonconvex problem, never
  overstate them (every point of it is a verified trajectory).
* Anchor and starts: every run starts from the *anchor*, a consistent trajectory of the
  whole record: the true one where the record has it (its factors recovered), else one found
  by a phase-1 SLP on an elastic model (excesses of the measurement factors penalised) from
  the centre of ``X0`` without disturbances.  With ``starts > 1``, ``starts - 1`` random
  directions ``c'x_k`` are maximised too (seeded by the search's seed and the step: the same
  directions whichever other steps are searched), and every objective is re-run from the
  ``starts - 1`` best other verified trajectories of the step (ranked by that objective; each
  trajectory once, neither the anchor nor the objective's own optimum).
  Measured: on tank6-nonlinear three starts moved no radius by more than 1e-4 (relative); on
  vanderpol-sim two starts widened one radius by 5 %, at 1.5-3 times the cost.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import highspy
import numpy as np
from scipy import sparse
from scipy.optimize import linprog

from observers.lp import new_highs
from systems.errors import ModelError

from .verification import EQ_TOL, VERIFY_TOL, Model, Trajectory

#: factors of X0 and W are kept within 1 - FACTOR_MARGIN during the search
FACTOR_MARGIN = 1e-9
#: factors of V are kept within 1 - NOISE_MARGIN (LP tolerance + linearisation error)
NOISE_MARGIN = 1e-7
#: measurement factors this close to 1 are held by :meth:`Search.polish`, which runs on
#: candidates beyond 1 by at most POLISH_EXCESS, with at most POLISH_SIZE gradient entries
ACTIVE = 1e-6
POLISH_EXCESS = 1e-6
POLISH_SIZE = 4_000_000
#: HiGHS primal and dual feasibility tolerance
LP_TOL = 1e-10
#: SLP iterations per run; second-order corrections per step
MAX_ITER = 20
SOC_STEPS = 8
#: a run stops when the LP predicts less than PRED_TOL (objective scaled by X0's radius), or
#: when the accepted step realised its predicted gain to STOP_RTOL of the run's total gain
PRED_TOL = 1e-9
STOP_RTOL = 1e-3
#: initial trust-region radius on the factors (2 = the whole box)
DELTA0 = 2.0
#: simplex iterations of one LP at most (HiGHS's ``simplex_iteration_limit``): a typical LP
#: takes tens to a few thousand; on degenerate records (vertex noise held at the bounds) a
#: single LP was measured running for minutes; one that stops at the limit counts as failed
LP_ITERATION_LIMIT = 50_000


# -- the SLP ------------------------------------------------------------------------------
class BudgetSpent(Exception):
    """The search's budget of simplex iterations (:attr:`Stats.budget`) is spent."""


@dataclass
class Stats:
    """Work counters of a search, and its budget of simplex iterations (None: none)."""

    lps: int = 0
    simplex_iterations: int = 0
    loads: int = 0
    corrections: int = 0
    runs: int = 0
    unconverged: int = 0
    verified: int = 0
    budget: int | None = None

    def spend(self) -> None:
        """Raise :class:`BudgetSpent` once :attr:`budget` iterations are used."""
        if self.budget is not None and self.simplex_iterations >= self.budget:
            raise BudgetSpent

    def iteration_limit(self) -> int:
        """The simplex iterations the next LP may take: :data:`LP_ITERATION_LIMIT`, or what
        is left of the budget if less."""
        if self.budget is None:
            return LP_ITERATION_LIMIT
        return max(1, min(LP_ITERATION_LIMIT, self.budget - self.simplex_iterations))


@dataclass
class Point:
    """A trajectory with its simulation: states, measurement factors, verdict."""

    z: Trajectory
    X: np.ndarray
    nu: np.ndarray
    excess: float  # sum of max(0, |nu| - (1 - margin of V in the search))
    consistent: bool
    _jac: np.ndarray | None = None

    def jacobians(self, M: Model, upto: int) -> np.ndarray:
        """``df/dx`` at ``x_0 .. x_{upto-1}`` (computed once per point)."""
        if self._jac is None or self._jac.shape[0] < upto:
            self._jac = np.array([M.jacobian(self.X[j], j) for j in range(upto)]
                                 ).reshape(upto, M.n, M.n)
        return self._jac[:upto]


class StepLP:
    """The problem of step ``k`` linearised at a trajectory ``A`` (one HiGHS model).

    Columns: the factors ``xi0`` of X0, the factors ``omega_s .. omega_{k-1}`` of the
    window's disturbances (``omega_j`` of ``j < s`` stay at ``A``'s values), the state
    deviations ``d_s .. d_k`` from ``A``, the measurement factors ``nu_0 .. nu_{m-1}`` and, in
    the elastic (phase-1) model, penalised excesses ``e+, e-`` of ``nu``.  Rows, all
    equalities: ``d_s - S_s xi0`` (``S_s = dx_s/dxi0`` at ``A``), ``d_{j+1} - J_j d_j -
    G_W omega_j`` (``s <= j < k``), and ``H_j S_j xi0 + G_V nu_j`` (``j < s``) or
    ``H_j d_j + G_V nu_j`` (``j >= s``).  The right-hand sides are the rows' values at a point
    whose forward simulation satisfies the model exactly: ``A`` itself (the linearisation),
    or, for a second-order correction, the last (inconsistent) candidate ``P`` (Fletcher's
    SOC: the linear model plus the remainder observed at ``P``).
    """

    def __init__(self, model: Model, k: int, m: int, s: int, elastic: bool, stats: Stats):
        self.M, self.k, self.m, self.s, self.elastic, self.stats = model, k, m, s, elastic, stats
        n, p0, pW, pV = model.n, model.p0, model.pW, model.pV
        L = k - s
        self.iOM = p0
        self.iD = p0 + L * pW
        self.iNU = self.iD + (L + 1) * n
        self.iE = self.iNU + m * pV
        self.ncol = self.iE + (2 * m * pV if elastic else 0)
        self.nf = self.iD  # factor columns (xi0 and the window's omega)
        self.rD = n
        self.rM = n + L * n
        self.nrow = self.rM + m * model.ny
        self._h = new_highs()
        for key, val in (("presolve", "off"), ("primal_feasibility_tolerance", LP_TOL),
                         ("dual_feasibility_tolerance", LP_TOL)):
            self._h.setOptionValue(key, val)
        self._basis = None
        self.margin = NOISE_MARGIN  # of the factors of V
        self.factor_margin = FACTOR_MARGIN  # of those of X0 and W
        self.A: Point | None = None
        self._delta: float | None = None
        self._all_rows = np.arange(self.nrow, dtype=np.int32)
        self._all_cols = np.arange(self.ncol, dtype=np.int32)

    def factors(self, P: Point) -> np.ndarray:
        """The factor columns of ``P`` (``xi0`` and the window's ``omega``)."""
        return np.concatenate([P.z.xi0, P.z.omega[self.s:].ravel()])

    def load(self, A: Point, delta: float) -> None:
        """Linearise at ``A`` with trust region ``delta`` on the factors."""
        M, k, m, s, n = self.M, self.k, self.m, self.s, self.M.n
        self.stats.loads += 1
        J = A.jacobians(M, k)
        rows: list = []
        cols: list = []
        vals: list = []

        def block(r0: int, c0: int, B: np.ndarray) -> None:
            r, c = np.nonzero(B)
            rows.append(r0 + r)
            cols.append(c0 + c)
            vals.append(B[r, c])

        S = M.G0  # dx_j/dxi0 along A with the early disturbances fixed
        Sj = []
        for j in range(s + 1):
            Sj.append(S)
            if j < s:
                S = J[j] @ S
        block(0, self.iD, np.eye(n))
        block(0, 0, -Sj[s])
        for j in range(s, k):
            r0 = self.rD + (j - s) * n
            block(r0, self.iD + (j + 1 - s) * n, np.eye(n))
            block(r0, self.iD + (j - s) * n, -J[j])
            block(r0, self.iOM + (j - s) * M.pW, -M.GW)
        for j in range(m):
            r0 = self.rM + j * M.ny
            H = M.H(A.X[j])
            if j < s:
                block(r0, 0, H @ Sj[j])
            else:
                block(r0, self.iD + (j - s) * n, H)
            block(r0, self.iNU + j * M.pV, M.GV)
            if self.elastic:
                block(r0, self.iE + j * M.pV, M.GV)
                block(r0, self.iE + (m + j) * M.pV, -M.GV)
        self.mat = sparse.csc_matrix((np.concatenate(vals), (np.concatenate(rows),
                                                             np.concatenate(cols))),
                                     shape=(self.nrow, self.ncol))
        self.A = A
        inf = highspy.kHighsInf
        bv = 1.0 - self.margin
        nuA = A.nu[:m].ravel()
        if self.elastic:
            nlo, nhi = np.full(m * M.pV, -bv), np.full(m * M.pV, bv)
        else:  # the linearisation point stays feasible
            nlo, nhi = np.minimum(-bv, nuA), np.maximum(bv, nuA)
        self.col_lo = np.concatenate([np.zeros(self.nf), np.full((k - s + 1) * n, -inf), nlo,
                                      np.zeros(self.ncol - self.iE)])
        self.col_hi = np.concatenate([np.zeros(self.nf), np.full((k - s + 1) * n, inf), nhi,
                                      np.full(self.ncol - self.iE, inf)])
        rhs = self.activity(A)
        lp = highspy.HighsLp()
        lp.num_col_, lp.num_row_ = self.ncol, self.nrow
        lp.col_cost_ = np.zeros(self.ncol)
        lp.col_lower_, lp.col_upper_ = self.col_lo, self.col_hi
        lp.row_lower_, lp.row_upper_ = rhs, rhs
        lp.a_matrix_.format_ = highspy.MatrixFormat.kColwise
        lp.a_matrix_.start_ = self.mat.indptr.astype(np.int32)
        lp.a_matrix_.index_ = self.mat.indices.astype(np.int32)
        lp.a_matrix_.value_ = self.mat.data
        self._h.passModel(lp)
        self._rhs = rhs
        self._delta = None
        self.trust(delta)
        if self._basis is not None:
            self._h.setBasis(self._basis)

    def trust(self, delta: float) -> None:
        """Bound the factor columns to ``delta`` around ``A`` and inside the margin (but
        never so as to exclude ``A``)."""
        if delta == self._delta:
            return
        b = 1.0 - self.factor_margin
        zA = self.factors(self.A)
        self.col_lo[:self.nf] = np.minimum(zA, np.maximum(-b, zA - delta))
        self.col_hi[:self.nf] = np.maximum(zA, np.minimum(b, zA + delta))
        idx = np.arange(self.nf, dtype=np.int32)
        self._h.changeColsBounds(self.nf, idx, self.col_lo[:self.nf], self.col_hi[:self.nf])
        self._delta = delta

    def activity(self, P: Point) -> np.ndarray:
        """Row values at the columns of ``P`` (deviations from ``A``), which satisfies the
        model exactly: the right-hand sides of the linear model plus ``P``'s remainder."""
        s, k = self.s, self.k
        col = np.zeros(self.ncol)
        col[:self.nf] = self.factors(P)
        col[self.iD:self.iNU] = (P.X[s:k + 1] - self.A.X[s:k + 1]).ravel()
        col[self.iNU:self.iE] = P.nu[:self.m].ravel()
        return self.mat @ col

    def set_rhs(self, rhs: np.ndarray) -> None:
        self._h.changeRowsBounds(self.nrow, self._all_rows, rhs, rhs)
        self._rhs = rhs

    def solve(self, cost: np.ndarray) -> np.ndarray | None:
        """Column values of ``min cost'col`` (None if HiGHS found no optimum)."""
        h = self._h
        h.changeColsCost(self.ncol, self._all_cols, cost)
        h.setOptionValue("simplex_iteration_limit", self.stats.iteration_limit())
        h.run()
        self.stats.lps += 1
        self.stats.simplex_iterations += int(h.getInfo().simplex_iteration_count)
        self.stats.spend()
        if h.getModelStatus() != highspy.HighsModelStatus.kOptimal:
            self._basis = None
            return None
        self._basis = h.getBasis()
        return np.asarray(h.getSolution().col_value, dtype=float)


def same_trajectory(p: Point, q: Point) -> bool:
    """Whether two points are the same trajectory (the same factors of ``x_0`` and of the
    disturbances, which determine the states)."""
    return p is q or (np.array_equal(p.z.xi0, q.z.xi0)
                      and np.array_equal(p.z.omega, q.z.omega))


class Search:
    """SLP runs for one step ``k`` (``m`` measurements, window from ``s``), collecting the
    verified extremes."""

    def __init__(self, model: Model, k: int, m: int, s: int, stats: Stats,
                 max_iter: int, elastic: bool = False):
        self.M, self.k, self.m, self.s, self.stats = model, k, m, s, stats
        self.lp = StepLP(model, k, m, s, elastic, stats)
        self.max_iter = max_iter
        n = model.n
        self.lo = np.full(n, np.inf)
        self.hi = np.full(n, -np.inf)
        self.lo_traj: list[Trajectory | None] = [None] * n
        self.hi_traj: list[Trajectory | None] = [None] * n
        self.pool: list[Point] = []

    def evaluate(self, z: Trajectory) -> Point:
        """Simulate and verify ``z``; a consistent point widens the inner box."""
        M = self.M
        X = M.simulate(z.xi0, z.omega)
        if not np.all(np.isfinite(X)):
            return Point(z, X, z.nu, math.inf, False)
        nu, res = M.noise_factors(X, z.nu)
        excess = float(np.maximum(np.abs(nu) - (1.0 - self.lp.margin), 0.0).sum())
        ok = bool(np.abs(nu).max(initial=0.0) <= 1.0 + VERIFY_TOL) and (
            M.square_V or res <= EQ_TOL * max(1.0, float(np.abs(M.y).max())))
        # xi0 and omega lie inside their bounds by construction (clipped)
        p = Point(Trajectory(z.xi0, z.omega, nu), X, nu, excess, ok)
        if ok:
            self.offer(p)
        return p

    def offer(self, p: Point) -> None:
        """Record a verified point: its ``x_k`` widens the inner box."""
        self.stats.verified += 1
        xk = p.X[self.k]
        for i in np.flatnonzero(xk < self.lo):
            self.lo[i], self.lo_traj[i] = xk[i], p.z
        for i in np.flatnonzero(xk > self.hi):
            self.hi[i], self.hi_traj[i] = xk[i], p.z

    def candidate(self, col: np.ndarray) -> Point:
        """The trajectory of the LP's factors (clipped into their bounds), simulated."""
        M, lp, s = self.M, self.lp, self.s
        zc = np.clip(col[:lp.nf], -1.0, 1.0)  # within the LP's tolerance of its bounds
        omega = lp.A.z.omega.copy()
        omega[s:] = zc[M.p0:].reshape(self.k - s, M.pW)
        nu = col[lp.iNU:lp.iE].reshape(self.m, M.pV)
        return self.evaluate(Trajectory(zc[:M.p0], omega, nu))

    def polish(self, P: Point) -> Point:
        """Least-norm (Gauss-Newton) change of the free factors of X0 and W that brings the
        measurement factors beyond 1 back to 1 and keeps those within ``ACTIVE`` of it: the
        last ~1e-9 of an LP solution on a record whose consistent set has no interior (where
        the rows' tolerance, accumulated along the dynamics, is all the room there is).
        Gradients by an adjoint sweep through the Jacobians; skipped above POLISH_SIZE."""
        M, k = self.M, self.k
        for _ in range(3):
            jj, ll = np.nonzero(np.abs(P.nu) > 1.0 - ACTIVE)
            z = np.concatenate([P.z.xi0, P.z.omega.ravel()])
            free = np.abs(z) < 1.0 - FACTOR_MARGIN / 2  # factors at a bound stay there
            if jj.size == 0 or jj.size * free.sum() > POLISH_SIZE:
                return P
            target = 1.0 - 1e-12
            e = P.nu[jj, ll] - np.clip(P.nu[jj, ll], -target, target)
            A = np.array([-(M.GV_pinv[l] @ M.H(P.X[j])) for j, l in zip(jj, ll, strict=True)])
            Gz = np.zeros((jj.size, z.size))
            Lam = np.zeros((M.n, jj.size))
            for t in range(int(jj.max()), -1, -1):
                sel = jj == t
                Lam[:, sel] = A[sel].T
                if t > 0:
                    Gz[:, M.p0 + (t - 1) * M.pW: M.p0 + t * M.pW] = (M.GW.T @ Lam).T
                    Lam = M.jacobian(P.X[t - 1], t - 1).T @ Lam
                else:
                    Gz[:, :M.p0] = (M.G0.T @ Lam).T
            Gf = Gz[:, free]
            try:
                dz = -Gf.T @ np.linalg.lstsq(Gf @ Gf.T, e, rcond=1e-13)[0]
            except np.linalg.LinAlgError:
                return P
            z[free] = np.clip(z[free] + dz, -1.0, 1.0)
            Q = self.evaluate(Trajectory(z[:M.p0], z[M.p0:].reshape(k, M.pW), P.nu))
            if Q.consistent or not Q.excess < P.excess:
                return Q if Q.consistent else P
            P = Q
        return P

    def corrected(self, P: Point, cost: np.ndarray) -> Point:
        """Second-order corrections of an inconsistent candidate (same model and basis,
        right-hand sides moved by the remainder at the last candidate), and a final
        :meth:`polish` when it misses by a hair."""
        lp = self.lp
        for _ in range(SOC_STEPS):
            if P.consistent or not np.all(np.isfinite(P.X)):
                break
            if np.abs(P.nu).max() <= 1.0 + POLISH_EXCESS:
                Q = self.polish(P)
                if Q.consistent:
                    return Q
            self.stats.corrections += 1
            lp.set_rhs(lp.activity(P))
            col = lp.solve(cost)
            if col is None:
                break
            Q = self.candidate(col)
            if not Q.excess < P.excess:
                P = Q if Q.consistent else P
                break
            P = Q
        return P

    def run(self, start: Point, c: np.ndarray) -> Point:
        """Maximise ``c'x_k`` from the consistent ``start``; returns the last accepted point.

        Trust-region SLP: each LP step is made consistent by second-order corrections, and
        accepted when it realises at least a tenth of the predicted gain; the model is
        re-linearised at the accepted point unless it predicted the gain to ``STOP_RTOL``.
        """
        M, lp, k = self.M, self.lp, self.k
        self.stats.runs += 1
        cost = np.zeros(lp.ncol)
        cost[lp.iD + (k - self.s) * M.n: lp.iNU] = -c
        cur, delta, gained = start, DELTA0, 0.0
        if lp.A is not cur:
            lp.load(cur, delta)
        for _ in range(self.max_iter):
            lp.trust(delta)
            lp.set_rhs(lp.activity(cur))
            col = lp.solve(cost)
            if col is None:
                delta *= 0.25
                if delta < 1e-9:
                    break
                continue
            pred = float(c @ col[lp.iD + (k - self.s) * M.n: lp.iNU])
            if pred <= PRED_TOL:
                break
            P = self.corrected(self.candidate(col), cost)
            actual = float(c @ (P.X[k] - cur.X[k])) if P.consistent else -math.inf
            if actual < 0.1 * pred:
                step = float(np.abs(np.clip(col[:lp.nf], -1, 1) - lp.factors(cur)).max())
                delta = 0.25 * min(delta, step)
                if delta < 1e-9:
                    break
                continue
            gained += actual
            cur = P
            if pred - actual <= STOP_RTOL * gained:
                break
            if actual >= 0.75 * pred:
                delta = min(DELTA0, 2.0 * delta)
            lp.load(cur, delta)
        else:
            self.stats.unconverged += 1
        if cur.consistent and not any(same_trajectory(p, cur) for p in self.pool):
            self.pool.append(cur)  # once per trajectory: runs often end at the same one
        return cur

    def feasible(self, start: Point) -> Point:
        """Phase 1 (elastic model, zero objective): a consistent trajectory near ``start``;
        with the margins first, then without them (a record whose consistent set has no
        point strictly inside them, e.g. with noise and x_0 on the vertices of their sets)."""
        lp, cur = self.lp, start
        cost = np.zeros(lp.ncol)
        cost[lp.iE:] = 1.0
        for margin, factor_margin in ((NOISE_MARGIN, FACTOR_MARGIN), (0.0, 0.0)):
            lp.margin, lp.factor_margin, delta = margin, factor_margin, DELTA0
            cur = self.evaluate(cur.z)  # its excess over the new margin
            lp.load(cur, delta)
            for _ in range(self.max_iter):
                if cur.consistent:
                    return cur
                lp.trust(delta)
                lp.set_rhs(lp.activity(cur))
                col = lp.solve(cost)
                P = None if col is None else self.corrected(self.candidate(col), cost)
                if P is None or not (P.consistent or P.excess < cur.excess):
                    delta *= 0.25
                    if delta < 1e-9:
                        break
                    continue
                cur = P
                lp.load(cur, delta)
        return cur


def _factors(G: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Least-norm factors of ``G xi = v`` clipped to the unit box."""
    xi = np.linalg.lstsq(G, v, rcond=None)[0]
    return np.clip(np.nan_to_num(xi), -1.0, 1.0)


def _noise_reference(M: Model, X: np.ndarray) -> np.ndarray:
    """Factors of the measurement noise of the states ``X``: for a non-square ``G_V`` the
    least-norm ones may leave the unit box where a solution inside exists, so each is the
    smallest in the infinity norm (an LP per measurement)."""
    R = M.y - M.outputs(X) - M.cV
    if M.square_V:
        return R @ M.GV_pinv.T
    p = M.pV
    cost = np.r_[np.zeros(p), 1.0]
    A_ub = np.block([[np.eye(p), -np.ones((p, 1))], [-np.eye(p), -np.ones((p, 1))]])
    out = np.empty((M.N, p))
    for j, r in enumerate(R):
        sol = linprog(cost, A_ub=A_ub, b_ub=np.zeros(2 * p),
                      A_eq=np.hstack([M.GV, np.zeros((M.ny, 1))]), b_eq=r,
                      bounds=[(None, None)] * p + [(0, None)], method="highs")
        out[j] = sol.x[:p] if sol.status == 0 else M.GV_pinv @ r
    return out


def find_anchor(M: Model, x_true: np.ndarray | None, stats: Stats, max_iter: int) -> Point:
    """A verified consistent trajectory of the whole record: the truth where given (its
    factors recovered by least squares, clipped into their bounds), repaired or found by the
    phase-1 SLP (elastic model, from the centre of X0 without disturbances) otherwise."""
    k = M.N - 1
    search = Search(M, k, M.N, 0, stats, max_iter, elastic=True)
    if x_true is not None:
        X = np.asarray(x_true, dtype=float)
        if X.shape != (M.N, M.n) or not np.all(np.isfinite(X)):
            raise ModelError(f"falsifier: x_true has shape {X.shape}, expected ({M.N}, {M.n})")
        xi0 = _factors(M.G0, X[0] - M.c0)
        with np.errstate(all="ignore"):
            D = np.array([X[j + 1] - M.f(X[j], j) - M.cW for j in range(k)]).reshape(k, M.n)
        omega = np.linalg.lstsq(M.GW, D.T, rcond=None)[0].T.reshape(k, M.pW)
        omega = np.clip(np.nan_to_num(omega), -1.0, 1.0)
        nu = _noise_reference(M, X)
    else:
        xi0, omega, nu = np.zeros(M.p0), np.zeros((k, M.pW)), np.zeros((M.N, M.pV))
    start = search.evaluate(Trajectory(xi0, omega, nu))
    if start.consistent:
        return start
    p = search.feasible(start)
    if not p.consistent:
        raise ModelError("falsifier: no consistent trajectory of the record was found (the "
                         f"measurement factors exceed their bound by {p.excess:.3g} in sum)")
    return p
