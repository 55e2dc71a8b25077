"""Batched bounded dual simplex for many box LPs sharing one feasible set.

Solves, for the rows ``g_k`` of a cost matrix ``Gd`` (K x r) at once,

    max  g_k' xi   s.t.   A xi = b,   -1 <= xi <= 1          (A: p x r, few rows, many columns),

and returns one dual point ``mu_k`` per problem.  The caller turns every ``mu_k`` into a bound
by weak duality (``b'mu + ||g - A'mu||_1``, :func:`observers.lp.hull.dual_bounds`), so this
solver decides tightness and speed only, never soundness: a wrong basis, a stalled problem or
a rounding error gives a looser bound, not a wrong one.

Method (the dual of these LPs is the least-absolute-deviations problem
``min_mu b'mu + sum_j |g_j - a_j'mu|`` in only ``p`` unknowns):

* one logical variable per row (``A xi + s = b``, ``s`` fixed at 0); every nonbasic boxed
  variable sits at the bound given by the sign of its reduced cost, so every basis is dual
  feasible and the dual simplex needs no phase 1.  It starts from a crash basis close to
  diagonal (:func:`crash_basis`, e.g. the measurement-noise generators of the newest
  constraints), the same for all problems (half the iterations of the logical basis on the
  vehicle benchmark);
* leaving row: largest primal infeasibility weighted by exact dual steepest-edge weights
  (the squared row norms of ``B^-1``, cheap for ``p x p`` bases);
* ratio test with bound flipping (Fourer's long step): the dual objective is minimised
  exactly along the edge (a weighted median of the breakpoints), passing every breakpoint at
  which the slope stays negative and flipping those variables to their other bound;
  breakpoints are ordered by integer keys (the bit patterns of non-negative floats order
  like the floats; the low bits carry the flat index of the entry), one ``np.sort`` per
  iteration (steps often pass hundreds of breakpoints, so partial orderings did not pay
  off); an entering column with a tiny pivot element (relative ``PIVOT_TOL``) stops the
  problem (HiGHS takes over);
* the K problems run in lock step as batched numpy operations (the constraint matrix is
  shared, only costs, bases and bounds differ), so the Python overhead of an iteration is
  paid once for all of them; finished problems leave the working arrays.  With numba the
  same iterations run compiled, problem by problem (:mod:`.dual_simplex_jit`, same pivots;
  ``SETOBS_NUMBA=0`` or :func:`set_compiled` selects the numpy iterations);
* the costs are perturbed (relative 1e-11, away from zero) against stalling on the highly
  degenerate LPs of constrained zonotopes.  At the end the basis is refactorised and the
  duals of the exact costs are evaluated; problems whose optimality gap (dual objective
  minus the objective of the primal basic solution) is not negligible get clean-up
  iterations with the exact costs.

A problem that is not optimal within the iteration budget, or whose dual looks unbounded (an
empty set, or numerical trouble), is reported as not converged; the caller solves it with
HiGHS (:class:`observers.lp.hull.HullLP`).
"""

from __future__ import annotations

from contextlib import contextmanager
from dataclasses import dataclass, field
from time import perf_counter

import numpy as np

from . import dual_simplex_jit

#: primal feasibility tolerance on the basic variables (xi lives in [-1, 1])
PRIMAL_TOL = 1e-9
#: reduced costs below this, relative to the magnitudes that cancel in them, count as zero
DUAL_TOL = 1e-12
#: relative pivot tolerance (``|alpha_q| >= PIVOT_TOL ||e_r' B^-1|| ||m_q||``)
PIVOT_TOL = 1e-9
#: relative size of the cost perturbation
PERTURBATION = 1e-11
#: accepted optimality gap, relative to the magnitudes in the dual objective
GAP_TOL = 1e-11
#: the basis inverse is recomputed from scratch after this many updates
REFACTOR_EVERY = 24
_INF_KEY = np.array(np.inf).view(np.uint64)[()]


@dataclass
class DualSimplexResult:
    """Dual points ``mu`` (K x p), which problems reached optimality, the work done
    (lock-step iterations, and iterations summed over the problems) and its seconds by phase
    (``setup``, ``pivots``, ``refactor``, ``certify``; see :class:`Clock`); ``bounds``: the
    weak-duality bounds of ``mu`` where the solver evaluated them
    (:func:`observers.lp.hull.dual_bounds`' formula; ``None``: the caller evaluates them)."""

    mu: np.ndarray
    converged: np.ndarray
    iterations: int
    problem_iterations: int
    seconds: dict[str, float] = field(default_factory=dict)
    bounds: np.ndarray | None = None


class Clock:
    """Seconds spent by phase, exclusive: a phase timed inside another (a refactorisation
    during the pivots) is counted in its own phase only."""

    def __init__(self) -> None:
        self.seconds: dict[str, float] = {}
        self._open: list[str] = []

    @contextmanager
    def phase(self, name: str):
        """Time the block as phase ``name``."""
        t0 = perf_counter()
        self._open.append(name)
        try:
            yield
        finally:
            self._open.pop()
            dt = perf_counter() - t0
            self.seconds[name] = self.seconds.get(name, 0.0) + dt
            if self._open:
                outer = self._open[-1]
                self.seconds[outer] = self.seconds.get(outer, 0.0) - dt


def use_compiled() -> bool:
    """Whether :func:`solve` runs the compiled iterations (numba installed and not disabled
    by ``SETOBS_NUMBA=0``; :func:`set_compiled` switches it for tests and timings)."""
    return dual_simplex_jit.AVAILABLE and _USE_COMPILED[0]


_USE_COMPILED = [True]


def set_compiled(on: bool) -> bool:
    """Use the compiled iterations (if available) or the numpy ones; returns the old setting."""
    old = _USE_COMPILED[0]
    _USE_COMPILED[0] = bool(on)
    return old


def max_iterations(p: int) -> int:
    """Default iteration budget for ``p`` rows (optimal bases need at least ``p`` pivots)."""
    return 8 * p + 40


def solve(A: np.ndarray, b: np.ndarray, Gd: np.ndarray, max_iter: int | None = None,
          seed: int = 0) -> DualSimplexResult:
    """Dual points of ``max Gd[k]' xi  s.t.  A xi = b, |xi| <= 1`` for every row ``k``.

    See the module docstring; ``seed`` fixes the cost perturbation (results are
    deterministic).
    """
    A = np.asarray(A, dtype=float)
    b = np.asarray(b, dtype=float)
    Gd = np.atleast_2d(np.asarray(Gd, dtype=float))
    p = A.shape[0]
    K = Gd.shape[0]
    if max_iter is None:
        max_iter = max_iterations(p)
    if p == 0:
        return DualSimplexResult(np.zeros((K, 0)), np.ones(K, bool), 0, 0)
    clock = Clock()
    pert = Gd * (1.0 + PERTURBATION * _jitter(Gd.shape, seed))  # away from zero: |g| grows
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        with clock.phase("setup"):
            lp = _BatchLP(A, b, pert, clock=clock)
        with clock.phase("pivots"):
            its = lp.iterate(max_iter)
        lp.refactor()
        with clock.phase("certify"):
            lp.c[:, :lp.r] = Gd
            mu = lp.duals()
            good = lp.certified(mu)
        if not good.all() and its < max_iter:  # clean-up with the exact costs
            sub = np.nonzero(~good)[0]
            with clock.phase("setup"):
                clean = _BatchLP(A, b, Gd[sub], start=lp.subset(sub), clock=clock)
            with clock.phase("pivots"):
                its += clean.iterate(max_iter - its)
            clean.refactor()
            with clock.phase("certify"):
                mu[sub] = clean.duals()
                good[sub] = clean.certified(mu[sub])
            lp.work += clean.work
    return DualSimplexResult(mu, good, its, lp.work, clock.seconds)


_STREAMS: dict[int, np.ndarray] = {}


def _jitter(shape: tuple[int, ...], seed: int) -> np.ndarray:
    """Fixed pseudo-random factors in [1, 2): ``1 + default_rng(seed).random(shape)``, taken
    as a prefix of one cached stream per seed (a generator fills arrays in order, so the
    numbers are the same; the shapes change every step, a cache per shape missed)."""
    K, r = int(shape[0]), int(shape[1])
    seed = int(seed)
    stream = _STREAMS.get(seed)
    if stream is None or stream.size < K * r:
        size = max(K * r, 2 * (0 if stream is None else stream.size), 1 << 14)
        stream = 1.0 + np.random.default_rng(seed).random(size)
        stream.setflags(write=False)
        _STREAMS[seed] = stream
    return stream[:K * r].reshape(K, r)


def crash_basis(M: np.ndarray, colnorm: np.ndarray, share: float = 0.5,
                max_cond: float = 1e6) -> tuple[np.ndarray, np.ndarray]:
    """A starting basis close to diagonal and its inverse: column indices into
    ``M = [A, I]`` (p x (r + p); ``r + i`` is the logical of row i), ``colnorm`` the column
    norms of ``M``.

    For every row the column most aligned with that row's unit vector among those whose entry
    in the row is at least ``share`` of the row's largest entry (e.g. the measurement-noise
    generators of the newest constraints); logicals where no distinct column qualifies or
    where the basis would be ill-conditioned (1-norm condition number above ``max_cond``).
    Any basis is dual feasible here (all variables are boxed), so the choice affects the
    number of iterations only.
    """
    p, N = M.shape
    r = N - p
    logical = np.arange(r, N)
    if r == 0:
        return logical, np.eye(p)
    absA = np.abs(M[:, :r])
    score = np.where(absA >= share * absA.max(axis=1, keepdims=True), absA, 0.0)
    score /= colnorm[:r] + np.finfo(float).tiny
    pick = np.argmax(score, axis=1).tolist()
    basis = logical.copy()
    seen: set[int] = set()
    for i, j in enumerate(pick):
        if score[i, j] > 0.0 and j not in seen:
            seen.add(j)
            basis[i] = j
    B = M[:, basis]
    try:
        Binv = np.linalg.inv(B)
    except np.linalg.LinAlgError:
        return logical, np.eye(p)
    if not np.abs(B).sum(axis=0).max() * np.abs(Binv).sum(axis=0).max() <= max_cond:
        return logical, np.eye(p)
    return basis, Binv


class _BatchLP:
    """State of K bounded dual simplex runs on ``M (xi; s) = b`` with ``M = [A, I]``.

    ``start`` optionally gives the bases (K x p column indices of ``M``) and nonbasic bounds
    (K x (r + p)) to start from; the default is the same :func:`crash_basis` for every
    problem.  Nonbasic bounds are taken from the signs of the reduced costs, keeping the
    given ones where a reduced cost is zero up to rounding.
    """

    def __init__(self, A: np.ndarray, b: np.ndarray, cost: np.ndarray,
                 start: tuple[np.ndarray, np.ndarray] | None = None,
                 clock: Clock | None = None):
        self.clock = Clock() if clock is None else clock
        p, r = A.shape
        K = cost.shape[0]
        N = r + p
        self.p, self.r, self.N, self.K = p, r, N, K
        self.A = A
        M = self.M = np.hstack([A, np.eye(p)])
        self.MT = np.ascontiguousarray(M.T)
        self.b = b
        # sort keys carry the flat index (row * N + column) of a breakpoint in their low bits
        # (at most 2^32 entries: the 20 high mantissa bits left order the ratios)
        bits = max(1, int(K * N - 1).bit_length())
        if bits > 32:
            raise ValueError(f"too many LPs or columns for one batch ({K} x {N})")
        self.flat = np.arange(K * N, dtype=np.int64).reshape(K, N)
        self.key_mask = np.uint64((1 << bits) - 1)
        self.colnorm = np.sqrt(np.einsum("ij,ij->j", M, M))
        self.up = np.concatenate([np.ones(r), np.zeros(p)])  # bounds -up <= (xi; s) <= up
        self.unbounded = np.zeros(K, bool)
        self.any_unbounded = False
        self.work = 0
        self.c = np.zeros((K, N))
        self.c[:, :r] = cost
        if start is None:  # one crash basis for all problems
            basis, Binv = crash_basis(M, self.colnorm)
            self.basis = np.tile(basis, (K, 1))
            self.Binv = np.tile(Binv, (K, 1, 1))
            self.updates = 0
            mu = self.c[:, basis] @ Binv
            z_old = None
        else:
            self.basis, z_old = np.array(start[0], dtype=np.intp), start[1]
            self.refactor()
            mu = self.duals()
        self.uB = self.up[self.basis]
        d = self.c - mu @ M
        # bound by the sign of the reduced cost; a reduced cost that is zero up to rounding
        # (cancellation in c_j - m_j'mu) keeps its previous bound
        z = np.copysign(1.0, d)
        if z_old is not None:
            tiny = DUAL_TOL * (np.abs(self.c) + np.abs(mu) @ np.abs(M))
            z = np.where(np.abs(d) <= tiny, np.where(z_old != 0.0, z_old, z), z)
        D = np.abs(d)
        z[:, r:] = 0.0
        D[:, r:] = 0.0
        flat = (self.basis + (np.arange(K) * N)[:, None]).ravel()
        z.ravel()[flat] = 0.0
        D.ravel()[flat] = 0.0
        self.D, self.z = D, z

    def subset(self, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Bases and nonbasic bounds of some problems (to restart them)."""
        return self.basis[rows], self.z[rows]

    def refactor(self) -> None:
        """Recompute ``B^-1`` from the basis columns (timed as the phase ``refactor``)."""
        with self.clock.phase("refactor"):
            self._refactor()

    def _refactor(self) -> None:
        B = self.M[:, self.basis].transpose(1, 0, 2)
        try:
            self.Binv = np.linalg.inv(B)
        except np.linalg.LinAlgError:
            if not hasattr(self, "Binv"):
                self.Binv = np.linalg.pinv(B)
            else:  # keep the updated inverse where the basis is (numerically) singular
                ok = np.linalg.cond(B) < 1e14
                self.Binv[ok] = np.linalg.inv(B[ok])
        self.updates = 0

    # -- iterations --------------------------------------------------------------------------
    _STATE = ("z", "D", "Binv", "basis", "uB", "unbounded")

    def iterate(self, max_iter: int) -> int:
        """Dual simplex iterations until every problem is optimal, stuck or out of budget;
        returns the number of lock-step iterations.

        State: ``z`` (nonbasic structurals at -1/+1, basic and logical variables 0), the dual
        slacks ``D = |d|`` of the reduced costs ``d`` (``d = z D`` for nonbasic structurals)
        and the upper bounds ``uB`` of the basic variables (1 structural, 0 logical; every
        lower bound is ``-uB``).  Leaving row ``rr``: ``alpha = s e_rr' B^-1 M`` with ``s``
        the negated sign of the basic value; breakpoint of column j: ``t_j = D_j / w_j`` for
        ``w_j = z_j alpha_j > 0``, sorted by keys that hold the bit pattern of ``t_j`` in the
        high bits (negative ratios, NaN and infinity sort after every candidate) and the flat
        index of the entry in the low bits.  Problems that are done are dropped from the
        working arrays once they are a third of them.

        With numba (:data:`.dual_simplex_jit.AVAILABLE`) the same iterations run compiled,
        problem by problem (:meth:`_iterate_compiled`).
        """
        if dual_simplex_jit.AVAILABLE and use_compiled():
            return self._iterate_compiled(max_iter)
        key_mask, up = self.key_mask, self.up
        M, MT, b = self.M, self.MT, self.b
        high = ~key_mask
        colnorm2 = self.colnorm * self.colnorm
        live = np.arange(self.K)
        z, D, Binv, basis, uB, unbounded = (getattr(self, a) for a in self._STATE)
        it = 0
        while it < max_iter:
            if self.updates >= REFACTOR_EVERY:
                self._store(live, z, D, Binv, basis, uB, unbounded)
                self.refactor()
                Binv = self.Binv[live]
            n = live.shape[0]
            ar = np.arange(n)
            flat, off = self.flat[:n], self.flat[:n, 0]
            # leaving row: primal infeasibility with dual steepest-edge weights
            xB = np.einsum("kij,kj->ki", Binv, b - z @ MT)
            viol = np.abs(xB) - uB
            np.maximum(viol, 0.0, out=viol)
            weight = np.einsum("kij,kij->ki", Binv, Binv)
            rr = np.argmax(viol * viol / weight, axis=1)
            delta = viol[ar, rr]
            act = delta > PRIMAL_TOL
            if self.any_unbounded:
                act &= ~unbounded
            n_act = int(np.count_nonzero(act))
            if n_act == 0:
                break
            if 3 * n_act <= 2 * n:  # compact: keep the problems still working
                self._store(live, z, D, Binv, basis, uB, unbounded)
                live = live[act]
                z, D, Binv, basis, uB, unbounded = (getattr(self, a)[live] for a in self._STATE)
                continue
            it += 1
            self.work += n_act
            sgn = np.sign(xB[ar, rr])  # +1: above the upper bound, leaves at it
            rho = Binv[ar, rr]
            # ratio test with bound flipping
            alpha = (rho * -sgn[:, None]) @ M
            w = alpha * z
            key = ((D / w).view(np.uint64) & high) | flat.view(np.uint64)
            ks = np.sort(key, axis=1)
            passed = np.cumsum(w.ravel()[(ks & key_mask).view(np.int64)], axis=1)
            hit = passed >= 0.5 * delta[:, None]  # slope lost per breakpoint: 2 w_j
            pos = np.argmax(hit, axis=1)
            kq = ks[ar, pos]
            qf = (kq & key_mask).view(np.int64)
            q = qf - off
            wq = w.ravel()[qf]  # = |alpha_q| for a candidate
            # entering found, and not a tiny pivot element (else: leave the problem to HiGHS)
            found = hit[ar, pos] & (wq * wq >= PIVOT_TOL ** 2 * weight[ar, rr] * colnorm2[q])
            ok = act & found
            if int(np.count_nonzero(ok)) < n_act:  # dual unbounded (empty set) or trouble
                unbounded |= act & ~found
                self.any_unbounded = True
                act = ok
            tq = np.where(act, D.ravel()[qf] / wq, 0.0)
            # step: dual slacks move by tq w; the passed breakpoints flip to their other bound
            D = np.abs(D - tq[:, None] * w)
            z = np.where(key < np.where(act, kq, 0)[:, None], -z, z)
            # pivot (problems not active pivot their leaving variable back in: no change)
            la = basis[ar, rr]
            q = np.where(act, q, la)
            fl, fq = off + la, off + q
            z.ravel()[fl] = sgn * uB[ar, rr]
            z.ravel()[fq] = 0.0
            D.ravel()[fl] = tq
            D.ravel()[fq] = 0.0
            basis[ar, rr] = q
            uB[ar, rr] = up[q]
            colq = np.einsum("kij,kj->ki", Binv, MT[q])
            row = rho / colq[ar, rr][:, None]
            Binv -= colq[:, :, None] * row[:, None, :]
            Binv[ar, rr] = row
            self.updates += 1
        self._store(live, z, D, Binv, basis, uB, unbounded)
        return it

    def _iterate_compiled(self, max_iter: int) -> int:
        """:meth:`iterate` by the compiled kernel :func:`.dual_simplex_jit.iterate`, pausing
        every ``REFACTOR_EVERY`` pivots for a numpy refactorisation (as the numpy path)."""
        status = np.where(self.unbounded, dual_simplex_jit.UNBOUNDED,
                          dual_simplex_jit.RUNNING).astype(np.int64)
        its = np.zeros(self.K, np.int64)
        colnorm2 = self.colnorm * self.colnorm
        while True:
            self.work += dual_simplex_jit.iterate(
                self.M, self.MT, self.b, self.up, colnorm2, self.key_mask, PRIMAL_TOL, PIVOT_TOL,
                REFACTOR_EVERY, self.z, self.D, self.Binv, self.basis, self.uB, status, its,
                self.updates, max_iter)
            if not np.any(status == dual_simplex_jit.PAUSED):
                break
            self.refactor()
        self.unbounded = status == dual_simplex_jit.UNBOUNDED
        self.any_unbounded = bool(self.unbounded.any())
        self.updates = REFACTOR_EVERY  # pivots since the last refactorisation differ per problem
        return int(its.max(initial=0))

    def _store(self, live, *arrays) -> None:
        """Write the working arrays of the problems ``live`` back into the full state."""
        for name, a in zip(self._STATE, arrays, strict=True):
            full = getattr(self, name)
            if a is not full:
                full[live] = a

    # -- results -----------------------------------------------------------------------------
    def duals(self) -> np.ndarray:
        """``mu = B^-T c_B`` of the current bases."""
        cB = np.take_along_axis(self.c, self.basis, axis=1)
        return np.einsum("kji,kj->ki", self.Binv, cB)

    def certified(self, mu: np.ndarray) -> np.ndarray:
        """Problems whose basis is primal feasible (up to ``PRIMAL_TOL``) and whose duality
        gap at ``mu`` is negligible.  With ``x`` the basic solution (nonbasic at ``z``), the
        gap ``b'mu + sum_j |d_j| - c'x`` is ``sum_j (|d_j| - d_j z_j)`` over the nonbasic
        structurals: twice the reduced costs of the wrong sign for their bound."""
        xB = np.einsum("kij,kj->ki", self.Binv, self.b - self.z @ self.MT)
        feasible = (np.abs(xB) - self.uB).max(axis=1) <= PRIMAL_TOL
        r = self.r
        g = self.c[:, :r]
        d = g - mu @ self.A
        dz = d * self.z[:, :r]
        gap = 2.0 * np.where(dz < 0.0, -dz, 0.0).sum(axis=1)
        size = np.abs(self.b) @ np.abs(mu).T + np.abs(g).sum(axis=1)
        return feasible & ~self.unbounded & (gap <= GAP_TOL * size)
