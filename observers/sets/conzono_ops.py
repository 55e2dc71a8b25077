"""Array kernels of constrained-zonotope operations (pure functions on ``(c, G, A, b)``).

A constrained zonotope is ``{c + G xi : A xi = b, ||xi||_inf <= 1}`` (Scott et al., Automatica
69, 2016).  These functions work on plain arrays so that observer loops avoid the validation of
the :class:`~observers.sets.ConZonotope` constructor; the class methods are thin wrappers.

Operations
----------
* :func:`intersect` -- generalised intersection ``{x in Z : R x in Y}`` (exact; Scott et al.,
  Prop. 1), with CORA's block layout (``conIntersect``).
* :func:`intersect_measurement` -- ``{x in Z : y - C x in V}`` for a noise zonotope ``V``, in
  the parametrisation of a gain ``L`` (Alanwar et al.); :func:`intersect_strips` for
  box-shaped ``V`` (measurement strips; CORA ``intersectStrip``).
* :func:`lifted_reduce` -- order reduction of the lifted zonotope ``([c; -b], [G; A])``
  (Scott et al., Sec. 4.3; CORA ``conZonotope/reduce``), after dropping all-zero constraints
  and generators; the order counts either per state dimension (CORA: ``order n + nc``
  generators) or per lifted dimension (``order (n + nc)``, the data-driven observers).
* :func:`normalize_constraints` -- rows of ``A xi = b`` scaled to unit largest entry (exact;
  puts constraint rows on one scale before a lifted reduction).
* :func:`implied_bounds` / :func:`rescale` -- interval constraint propagation and the exact
  rescaling of the generator box to the bounds implied by the constraints (Scott et al.,
  Sec. 4.2).
* constraint elimination, bounding the number of constraints by dropping the oldest ones
  (the first rows) into an enclosure, as named strategies (:data:`CONSTRAINT_ELIMINATIONS`):

  - ``"fold"`` (:func:`fold_constraints`): rescale, then a least-squares shear of the whole
    lifted zonotope (generators *and* kept constraints) along the dropped rows;
  - ``"frobenius"`` (:func:`eliminate_constraints`): the enclosure ``<c + L b_S, G - L A_S>``
    with the Frobenius-optimal gain ``L = G A_S' (A_S A_S')^+`` (Scott et al. 2016, Raghuraman
    & Koeln 2022); kept constraints unchanged.

  Both are sound for any gain (every feasible ``xi`` has ``A_S xi = b_S``); ``"fold"`` keeps
  more of what the dropped rows implied (box rescaling, kept rows sheared consistently).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ..kernels import propagation, switch
from .reduction import Reduction, lifted_reduction

_EPS = np.finfo(float).eps
_TINY = np.finfo(float).tiny

Arrays = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]


def intersect(Z: Arrays, Y: Arrays, R: np.ndarray) -> Arrays:
    """Exact ``{x in Z : R x in Y}`` for constrained zonotopes ``Z = (c, G, A, b)`` and
    ``Y = (cy, Gy, Ay, by)``.

    Layout (as CORA's ``conIntersect``): ``xi = [xi_z; xi_y]``, generators ``[G, 0]``,
    constraints ``[A 0; 0 Ay; R G, -Gy] xi = [b; by; cy - R c]``.
    """
    c, G, A, b = Z
    cy, Gy, Ay, by = Y
    nc, r = A.shape
    ncy, ry = Ay.shape
    G_new = np.hstack([G, np.zeros((G.shape[0], ry))])
    A_new = np.vstack([
        np.hstack([A, np.zeros((nc, ry))]),
        np.hstack([np.zeros((ncy, r)), Ay]),
        np.hstack([R @ G, -Gy]),
    ])
    b_new = np.concatenate([b, by, cy - R @ c])
    return c, G_new, A_new, b_new


def intersect_measurement(
    Z: Arrays, C: np.ndarray, y: np.ndarray, V: tuple[np.ndarray, np.ndarray], L: np.ndarray,
) -> Arrays:
    """Exact ``{x in Z : y - C x in V}`` for ``Z = (c, G, A, b)`` and the noise zonotope
    ``V = (cv, Gv)`` (m x nv), parametrised by a gain ``L`` (n x m).

    Centre ``c + L (y - C c - cv)``, generators ``[(I - L C) G, -L Gv]`` and the new
    constraints ``C G xi + Gv xi_v = y - C c - cv`` (old constraints padded with ``nv`` zero
    columns): every point ``c + G xi`` of ``Z`` with ``y - C(c + G xi) = cv + Gv xi_v`` is
    ``c + G xi + L (y - C c - cv - C G xi - Gv xi_v)``.  For any ``L`` this is the same set
    (Alanwar et al. 2022, Prop. 3; ``L = 0`` is Scott et al.'s generalised intersection); the
    gain only changes the parametrisation, hence later order reductions.
    """
    c, G, A, b = Z
    cv, Gv = V
    nc = A.shape[0]
    nv = Gv.shape[1]
    CG = C @ G
    resid = y - C @ c - cv
    G_new = np.hstack([G - L @ CG, -(L @ Gv)])
    A_new = np.vstack([
        np.hstack([A, np.zeros((nc, nv))]),
        np.hstack([CG, Gv]),
    ])
    return c + L @ resid, G_new, A_new, np.concatenate([b, resid])


def intersect_strips(
    Z: Arrays, C: np.ndarray, y: np.ndarray, sigma: np.ndarray, Lam: np.ndarray,
) -> Arrays:
    """Exact ``Z`` intersected with the strips ``|C x - y| <= sigma``, parametrised by a gain
    (CORA ``conZonotope/intersectStrip``): :func:`intersect_measurement` with
    ``V = <0, -diag(sigma)>``, i.e. centre ``c + Lam (y - C c)``, generators
    ``[(I - Lam C) G, Lam diag(sigma)]``, new constraints ``C G xi - diag(sigma) xi_new =
    y - C c``."""
    return intersect_measurement(Z, C, y, (np.zeros(C.shape[0]), -np.diag(sigma)), Lam)


def compact_zeros(c, G, A, b, tol: float = _EPS) -> Arrays:
    """Drop constraints whose row of ``[A b]`` is zero and generators zero in both ``G`` and ``A``
    (entries with ``|.| <= tol`` count as zero; CORA ``compact_(cZ, 'zeros', eps)``)."""
    if A.shape[0]:
        rows = np.any(np.abs(A) > tol, axis=1) | (np.abs(b) > tol)
        if not rows.all():
            A, b = A[rows], b[rows]
    cols = np.any(np.abs(G) > tol, axis=0)
    if A.shape[0]:
        cols |= np.any(np.abs(A) > tol, axis=0)
    if not cols.all():
        G, A = G[:, cols], A[:, cols]
    return c, G, A, b


#: meanings of the order of :func:`lifted_reduce`
ORDER_BASES = ("state", "lifted")


def lifted_reduce(
    c: np.ndarray, G: np.ndarray, A: np.ndarray, b: np.ndarray, order: float,
    strategy: Reduction, per: str = "state",
) -> Arrays:
    """Order reduction of a constrained zonotope (Scott et al. 2016, Sec. 4.3).

    After :func:`compact_zeros`, the lifted zonotope ``([c; -b], [G; A])`` in ``R^(n+nc)`` is
    reduced with the zonotope strategy ``strategy`` in its variant for lifted zonotopes
    (:func:`.reduction.lifted_reduction`: :meth:`.reduction.PCA.lifted` clusters singular
    values more widely; a strategy without a variant as it is) and split back.
    ``per="state"`` (CORA's ``conZonotope/reduce``): lifted order ``max(1, (order n + nc) /
    (n + nc))``, at most ``order * n + nc`` generators remain;
    ``per="lifted"``: lifted order ``order``, at most ``order * (n + nc)`` generators.  The
    constraints are kept (their number is unchanged).
    """
    c, G, A, b = compact_zeros(c, G, A, b)
    n, nc = G.shape[0], A.shape[0]
    if per == "state":
        order = max(1.0, (order * n + nc) / (n + nc))
    G_up = lifted_reduction(strategy).reduce(np.vstack([G, A]), order)
    return c, G_up[:n], G_up[n:], b


def normalize_constraints(c, G, A, b) -> Arrays:
    """The same set with every constraint row of ``[A b]`` divided by the largest ``|A_ij|``
    of the row (zero rows unchanged)."""
    if A.shape[0] == 0:
        return c, G, A, b
    s = np.abs(A).max(axis=1)
    s = np.where(s > 0, 1.0 / np.where(s > 0, s, 1.0), 1.0)
    return c, G, A * s[:, None], b * s


def implied_bounds(
    A: np.ndarray, b: np.ndarray, lo: np.ndarray | None = None, hi: np.ndarray | None = None,
    sweeps: int = 3,
) -> tuple[np.ndarray, np.ndarray]:
    """Bounds on ``xi`` implied by ``A xi = b`` and ``lo <= xi <= hi`` (default the unit box),
    by interval constraint propagation (each row solved for each of its variables).

    The bounds are outward-rounded and never tighter than the true projection of the feasible
    set, so they are safe to use as the new box (:func:`rescale`): each candidate is widened
    by :func:`observers.kernels.propagation.slack_factor` (``(r + 8) eps``) times the
    magnitudes in its row, a bound on the rounding of sums of ``r`` products in any order.
    An empty feasible set can show up as ``lo > hi`` somewhere; callers must check.

    With numba the sweeps run compiled (:mod:`observers.kernels.propagation`: loops, no
    ``nc x r`` temporaries, sums in a fixed order); the numpy path below gives the same
    bounds up to rounding.
    """
    nc, r = A.shape
    lo = -np.ones(r) if lo is None else np.array(lo, dtype=float)
    hi = np.ones(r) if hi is None else np.array(hi, dtype=float)
    if nc == 0 or r == 0:
        return lo, hi
    gamma = propagation.slack_factor(r)
    if switch.use_compiled():
        propagation.implied_bounds_loop(np.ascontiguousarray(A, dtype=float),
                                        np.asarray(b, dtype=float), lo, hi, int(sweeps),
                                        _TINY, gamma)
        return lo, hi
    absA = np.abs(A)
    # a subnormal coefficient would overflow 1 / a (and inf - inf poison the bounds with
    # NaN): such a row says nothing useful about that variable, so it is not solved for it
    nz = absA >= _TINY
    inv = np.where(nz, 1.0 / np.where(nz, A, 1.0), 0.0)
    for _ in range(sweeps):
        mid, rad = 0.5 * (hi + lo), 0.5 * (hi - lo)
        s_mid = A @ mid                      # sum_k a_ik mid_k
        s_rad = absA @ rad                   # sum_k |a_ik| rad_k
        # for variable j of row i: a_ij xi_j = b_i - sum_{k != j} a_ik xi_k
        cen = (b - s_mid)[:, None] + A * mid          # b_i - sum_{k != j} a_ik mid_k
        wid = s_rad[:, None] - absA * rad             # sum_{k != j} |a_ik| rad_k
        slack = gamma * (np.abs(b)[:, None] + (absA @ np.abs(mid))[:, None] + s_rad[:, None]
                         + absA * (np.abs(mid) + rad))
        wid = wid + slack
        with np.errstate(over="ignore", invalid="ignore"):
            x_c = cen * inv
            x_r = wid * np.abs(inv)
            cand_lo, cand_hi = x_c - x_r, x_c + x_r
        # an overflowed (infinite or NaN) candidate bounds nothing
        new_lo = np.where(nz & np.isfinite(cand_lo), cand_lo, -np.inf).max(axis=0)
        new_hi = np.where(nz & np.isfinite(cand_hi), cand_hi, np.inf).min(axis=0)
        new_lo = np.maximum(lo, new_lo)
        new_hi = np.minimum(hi, new_hi)
        if np.array_equal(new_lo, lo) and np.array_equal(new_hi, hi):
            break
        lo, hi = new_lo, new_hi
    return lo, hi


def rescale(c, G, A, b, min_gain: float = 1e-6, sweeps: int = 3) -> Arrays:
    """The same set with the generator box shrunk to the bounds implied by the constraints.

    With ``xi_j in [l_j, u_j]`` implied (:func:`implied_bounds`), substitute
    ``xi_j = m_j + r_j xi'_j`` (``m = (u+l)/2``, ``r = (u-l)/2``): ``c += G m``,
    ``b -= A m``, ``G, A`` columns scaled by ``r``.  Exact: the set does not change, but the
    box now carries what the constraints implied, so a later elimination loses less.
    Columns whose bounds shrink by less than ``min_gain`` are left as they are; fixed
    variables (``r = 0``) become part of the centre and their columns zero (columns are
    never removed here, so that callers can keep track of them).
    """
    if A.shape[0] == 0:
        return c, G, A, b
    lo, hi = implied_bounds(A, b, sweeps=sweeps)
    if np.any(lo > hi):
        return c, G, A, b  # empty (or numerically empty): leave it to the LP to report
    rad = 0.5 * (hi - lo)
    mid = 0.5 * (hi + lo)
    change = (rad < 1.0 - min_gain) | (np.abs(mid) > min_gain)
    if not change.any():
        return c, G, A, b
    rad = np.where(change, rad, 1.0)
    mid = np.where(change, mid, 0.0)
    return c + G @ mid, G * rad, A * rad, b - A @ mid


def eliminate_constraints(c, G, A, b, max_constraints: int) -> Arrays:
    """Outer approximation keeping the ``max_constraints`` newest (last) constraints: the
    older rows ``A_S xi = b_S`` are eliminated by ``<c + L b_S, G - L A_S>`` with the
    Frobenius-optimal gain ``L = G A_S' (A_S A_S')^+`` (minimises ``||G - L A_S||_F``); the
    kept constraints are unchanged.  Sound for any ``L``: feasible ``xi`` have
    ``A_S xi = b_S``, so ``c + G xi = c + L b_S + (G - L A_S) xi``."""
    k = A.shape[0] - max_constraints
    if k <= 0:
        return c, G, A, b
    AS, bS = A[:k], b[:k]
    L = regress(G, AS)
    return c + L @ bS, G - L @ AS, A[k:], b[k:]


def fold_constraints(c, G, A, b, max_constraints: int) -> Arrays:
    """Outer approximation keeping at most ``max_constraints`` constraints (the newest ones,
    i.e. the last rows: the observers append the constraints of each new measurement).

    Method: :func:`rescale` (exact), then the ``k`` oldest constraints ``A_S xi = b_S`` are
    folded into the centre, the generators and the kept constraints ``A_R xi = b_R`` and
    dropped:

    ``{c + Lam b_S + (G - Lam A_S) xi : (A_R - N A_S) xi = b_R - N b_S, |xi| <= 1}``

    contains the set for all ``Lam`` (n x k) and ``N`` ((nc-k) x k), since both rewrites add
    ``Lam (b_S - A_S xi) = 0`` and ``N (b_S - A_S xi) = 0`` on the set.  In the lifted
    zonotope ``([c; -b], [G; A])`` this is a shear followed by the projection that drops the
    folded coordinates; ``[Lam; N] = [G; A_R] A_S' (A_S A_S')^+`` (least squares, i.e. the
    F-radius-minimising choice) regresses the other coordinates on the dropped ones, so that
    little of the lifted generators points along the dropped directions.  For a single
    measurement row ``[C_i G_z, F_i]`` of CZN-A, ``Lam`` is the F-radius strip gain of Alamo
    et al. applied with today's generators to a measurement ``k`` steps old, and ``N`` keeps
    the newer measurement rows consistent with the shifted centre.  The newest constraints
    stay exact up to this shear.  Rescaling first matters: the shrunk box keeps what the
    folded constraints implied about each generator variable (on the linear 6-tank it
    lowers the RMS radii by up to 15 %; on the vehicle it makes no difference).
    """
    nc = A.shape[0]
    if nc <= max_constraints:
        return c, G, A, b
    c, G, A, b = rescale(c, G, A, b)
    k = nc - max_constraints
    AS, bS = A[:k], b[:k]
    AR, bR = A[k:], b[k:]
    n = G.shape[0]
    gain = regress(np.vstack([G, AR]), AS)
    Lam, N = gain[:n], gain[n:]
    return c + Lam @ bS, G - Lam @ AS, AR - N @ AS, bR - N @ bS


#: constraint-elimination strategies by name (``ConZonotope.reduce_constraints(k, method)``)
CONSTRAINT_ELIMINATIONS: dict[str, Callable[..., Arrays]] = {
    "fold": fold_constraints,
    "frobenius": eliminate_constraints,
}


def regress(Y: np.ndarray, X: np.ndarray) -> np.ndarray:
    """Least-squares ``K`` minimising ``||Y - K X||_F``, i.e. ``Y X' (X X')^+`` (minimum norm
    where ``X`` has dependent rows; any ``K`` keeps the constraint eliminations sound).

    Solved as the least-squares problem ``X' K' = Y'`` (SVD of the r x k matrix ``X'``), not
    through the Gram matrix ``X X'``, whose condition number is the square of ``X``'s: with
    the nearly dependent rows of old measurement constraints the Gram route's ``K`` moved
    with the BLAS kernel by ``cond(X)^2 eps`` and the constrained zonotopes that keep
    eliminating rows amplified it (DD-CZ-A1 on the 6-tank: 1e-5 of an RMS radius)."""
    return np.linalg.lstsq(X.T, Y.T, rcond=None)[0].T
