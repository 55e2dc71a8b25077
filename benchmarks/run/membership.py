"""Exact, tolerance-aware membership of a point in an estimated set, with a certified distance.

:meth:`MembershipTester.test` returns a :class:`Membership`: ``inside`` is ``True`` when the
point is *certified* to lie within ``tol`` of the set (infinity norm), ``False`` when it is
*certified* to lie farther than ``tol``, and ``None`` in the rare case that the solver's
precision does not decide (reported as "undecided", never silently counted either way).
``distance`` is a certified lower bound of the distance from the point to the set (0 inside).

Per set type, cheapest test first.  The types are told apart by what they offer (``box_form``,
``members``, ``distance``), not by importing their classes: the harness then depends on the
code of the set types the observer itself uses, so an edit of the hull LPs of constrained
zonotopes stales only the rows whose observers make them (:mod:`benchmarks.store.fingerprint`).


``Interval``
    closed form.
``ZonotopeBundle`` (an intersection of zonotopes, ``members``)
    every member as a zonotope (below): inside if inside every member, outside if outside
    one (the largest member distance bounds the distance to the intersection from below).
``Zonotope`` ``{c + G xi : |xi|_inf <= 1}`` and ``ConZonotope`` (plus ``A xi = b``): ``box_form``
    1. *hull*: a point farther than ``tol`` from the interval hull is outside; the distance
       to the hull is a lower bound of the distance to the set.
    2. *certificate*: a factor vector ``xi`` in the unit box with ``|G xi - (x - c)| <= tol``
       (and ``|A xi - b| <= tol_A``), evaluated in floating point, proves membership.  The
       least-norm solution of ``G xi = x - c`` is tried first, then a few active-set steps
       (factors beyond +-1 fixed at their sign, the others re-solved by least norm).
    3. *LP* (HiGHS, one reused ``Highs`` object): ``min t`` s.t. ``|G xi - v|_inf <= t``,
       ``A xi = b``, ``|xi|_inf <= 1``.  The clipped primal point gives an upper bound of the
       distance; the dual point gives a direction ``d`` (``|d|_1 <= 1``) and multipliers
       ``mu`` with the weak-duality lower bound ``d'v - mu'b - |G'd - A'mu|_1``, evaluated
       here with outward rounding.  Neither bound trusts a value at solver tolerance.
Anything with ``distance(x)`` (e.g. ``Ellipsoid``)
    that distance (Euclidean for ellipsoids), compared with ``tol``.
Any other set
    its own ``contains(x, tol)``; the distance is then the distance to its interval hull.
    A set without ``contains`` (a plugin's set with only ``interval()``) is undecided unless
    its hull already excludes the point.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import highspy
import numpy as np

from observers.lp import new_highs
from observers.sets import Interval

_EPS = np.finfo(float).eps
#: relative feasibility tolerance of the LP (HiGHS's default is 1e-7)
LP_TOL = 1e-10
#: active-set steps of the membership certificate tried before the LP
ACTIVE_SET_STEPS = 12
#: corrections of an undecided LP point by iterative refinement
REFINE_STEPS = 3


@dataclass(frozen=True)
class Membership:
    """Verdict of one membership test."""

    inside: bool | None  # True: certified within tol; False: certified outside; None: undecided
    distance: float  # certified lower bound of the distance to the set (0 when inside)
    method: str  # "closed-form", "hull", "certificate", "lp", "distance" or "contains"


@dataclass
class MembershipTester:
    """Reusable membership tests; counts which test decided (``counts``)."""

    counts: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        self._highs: highspy.Highs | None = None

    # -- public ---------------------------------------------------------------------------
    def test(self, S, x, tol: float, hull: tuple | None = None) -> Membership:
        """Membership of ``x`` in ``S`` up to ``tol`` (see the module docstring).

        ``hull``: the set's interval hull ``(lo, hi)`` if already known (saves its LPs for
        constrained zonotopes); it must be a sound outer bound.
        """
        x = np.asarray(x, dtype=float).reshape(-1)
        if isinstance(S, Interval):
            d = hull_distance(S.lo, S.hi, x)
            return self._count(Membership(d <= tol, d, "closed-form"))
        if hasattr(S, "box_form"):  # a zonotope or a constrained zonotope
            return self._zonotopic(S, x, tol, hull)
        if hasattr(S, "members"):  # a zonotope bundle
            return self._bundle(S, x, tol, hull)
        if hasattr(S, "distance"):
            d = float(S.distance(x))
            return self._count(Membership(d <= tol, d, "distance"))
        lo, hi = _hull(S, hull)
        d = hull_distance(lo, hi, x)
        if d > tol:
            return self._count(Membership(False, d, "hull"))
        if not hasattr(S, "contains"):  # a plugin's set with only interval(): undecided
            return self._count(Membership(None, 0.0, "hull"))
        inside = bool(S.contains(x, tol))
        return self._count(Membership(inside, 0.0 if inside else d, "contains"))

    def contains(self, S, x, tol: float, hull: tuple | None = None) -> bool:
        """Boolean verdict; an undecided case is settled by the set's own ``contains``."""
        m = self.test(S, x, tol, hull)
        return bool(S.contains(x, tol)) if m.inside is None else m.inside

    def _bundle(self, S, x: np.ndarray, tol: float, hull) -> Membership:
        """A zonotope bundle: the point must lie in every member (each tested as a zonotope);
        the largest member distance is a lower bound of the distance to the intersection."""
        if hull is not None and hull_distance(*hull, x) > tol:
            d = hull_distance(*hull, x)
            return self._count(Membership(False, d, "hull"))
        verdicts = [self._zonotopic(Z, x, tol, None) for Z in S.members]
        d = max(m.distance for m in verdicts)
        if any(m.inside is False for m in verdicts):
            return Membership(False, d, "members")
        inside = None if any(m.inside is None for m in verdicts) else True
        return Membership(inside, 0.0 if inside else d, "members")

    # -- zonotopes and constrained zonotopes ---------------------------------------------
    def _zonotopic(self, S, x: np.ndarray, tol: float, hull) -> Membership:
        lo, hi = _hull(S, hull)
        d_hull = hull_distance(lo, hi, x)
        if d_hull > tol:
            return self._count(Membership(False, d_hull, "hull"))
        c, G, A, b = (np.asarray(a, float) for a in S.box_form())
        v = x - c
        tol_a = constraint_tolerance(A, b)
        if G.shape[1] == 0:
            d = float(np.abs(v).max(initial=0.0))
            return self._count(Membership(d <= tol, d, "closed-form"))
        if box_certificate(G, v, A, b, tol, tol_a):
            return self._count(Membership(True, 0.0, "certificate"))
        lower, upper = d_hull, np.inf
        for options in (None, ROBUST_LP):  # fast settings first; HiGHS's robust ones if needed
            lower_lp, upper_lp, xi = self._distance_lp(G, v, A, b, tol_a, options)
            lower, upper = max(lower, lower_lp), min(upper, upper_lp)
            if lower <= tol < upper:  # undecided: refine the LP's point
                upper = min(upper, self._refine(G, v, A, b, tol_a, xi))
            if not lower <= tol < upper:
                break
        if upper <= tol:
            inside: bool | None = True
        elif lower > tol:
            inside = False
        else:
            inside = None
        return self._count(Membership(inside, 0.0 if inside else lower, "lp"))

    def _distance_lp(self, G, v, A, b, tol_a: float, options: dict | None = None
                     ) -> tuple[float, float, np.ndarray | None]:
        """Certified (lower, upper) bounds of ``min |G xi - v|_inf`` over the feasible box,
        and the box point of the upper bound (the LP's point if none satisfies the
        constraints to ``tol_a``; None without a primal point), to refine.

        ``options``: HiGHS options for this solve only (default :data:`FAST_LP`).
        """
        n, r = G.shape
        nc = A.shape[0]
        status, col, row_dual = self._lp(G, v, A, b, -np.ones(r), np.ones(r), options)
        if status == highspy.HighsModelStatus.kInfeasible:  # empty constrained zonotope
            return np.inf, np.inf, None
        candidates: list[np.ndarray | None] = []
        if col is not None:
            xi_lp = np.clip(col, -1.0, 1.0)
            candidates += [xi_lp, polish(G, v, A, b, xi_lp)]
        lower = 0.0
        if row_dual is not None:
            d0 = row_dual[:n] - row_dual[n:2 * n]
            mu0 = row_dual[2 * n:]
            for d, mu in ((d0, mu0), (d0, -mu0), (-d0, mu0), (-d0, -mu0)):
                lower = max(lower, dual_lower_bound(G, v, A, b, d, mu))
            candidates.append(dual_polish(G, v, A, b, d0, mu0))
        upper, best = np.inf, candidates[0] if candidates else None
        for xi in candidates:
            if xi is not None and (nc == 0 or np.abs(A @ xi - b).max() <= tol_a):
                bound = residual_bound(G, xi, v)
                if bound < upper:
                    upper, best = bound, xi
        return lower, upper, best

    def _refine(self, G, v, A, b, tol_a: float, xi: np.ndarray | None,
                steps: int = REFINE_STEPS) -> float:
        """Upper bound of the distance after iterative refinement of a box point ``xi``
        (e.g. the LP's, at solver tolerance): the residuals ``e = v - G xi`` and ``e_A = b - A xi``
        (scale ``s``) are fitted by a correction ``s delta`` with ``xi + s delta`` in the
        box, the same LP scaled by ``1 / s``, so that the solver's tolerance applies to the
        residual and not to the data (a point on the boundary that the LP's point misses by
        ~1e-7 is placed to ~1e-15).  Up to ``steps`` corrections; ``inf`` if none yields a
        point that satisfies the constraints to ``tol_a``."""
        best = np.inf
        for _ in range(steps if xi is not None else 0):
            e, e_a = v - G @ xi, b - A @ xi
            scale = max(float(np.abs(e).max(initial=0.0)), float(np.abs(e_a).max(initial=0.0)))
            if not np.isfinite(scale) or scale == 0.0:
                break
            _, col, _ = self._lp(G, e / scale, A, e_a / scale, (-1.0 - xi) / scale,
                                 (1.0 - xi) / scale, ROBUST_LP)
            if col is None:
                break
            xi = np.clip(xi + scale * col, -1.0, 1.0)
            if A.shape[0] == 0 or np.abs(A @ xi - b).max() <= tol_a:
                best = min(best, residual_bound(G, xi, v))
        return best

    def _lp(self, G, v, A, b, lo: np.ndarray, hi: np.ndarray, options: dict | None
            ) -> tuple[object, np.ndarray | None, np.ndarray | None]:
        """``min t`` s.t. ``|G xi - v|_inf <= t``, ``A xi = b``, ``lo <= xi <= hi`` with
        HiGHS: ``(status, xi or None, row duals or None)``."""
        n, r = G.shape
        nc = A.shape[0]
        ones = np.ones((n, 1))
        M = np.block([[G, -ones], [-G, -ones], [A, np.zeros((nc, 1))]])
        m = M.shape[0]
        inf = highspy.kHighsInf
        h = self._solver()
        h.clearModel()  # keeps the options; addRows/addCols are far cheaper than a HighsLp
        h.addRows(m, np.concatenate([np.full(2 * n, -inf), b]), np.concatenate([v, -v, b]),
                  0, np.zeros(0, np.int32), np.zeros(0, np.int32), np.zeros(0))
        h.addCols(r + 1, np.concatenate([np.zeros(r), [1.0]]),
                  np.concatenate([lo, [0.0]]), np.concatenate([hi, [inf]]),
                  m * (r + 1), np.arange(0, m * (r + 1), m, dtype=np.int32),
                  np.tile(np.arange(m, dtype=np.int32), r + 1),
                  np.ascontiguousarray(M.T).ravel())  # dense, column by column
        if options is not None:
            _set_options(h, options)
        h.run()
        if options is not None:
            _set_options(h, FAST_LP)
        status = h.getModelStatus()
        if status not in (highspy.HighsModelStatus.kOptimal,
                          highspy.HighsModelStatus.kInfeasible):
            # numerical trouble of the fast settings: solve again with HiGHS's robust defaults
            h.clearSolver()
            _set_options(h, ROBUST_LP)
            h.run()
            status = h.getModelStatus()
            _set_options(h, FAST_LP)
        if status == highspy.HighsModelStatus.kInfeasible:
            return status, None, None
        sol = h.getSolution()
        col = np.asarray(sol.col_value, float)[:r] if sol.value_valid else None
        dual = (np.asarray(sol.row_dual, float)
                if sol.dual_valid and len(sol.row_dual) == m else None)
        return status, col, dual

    def _solver(self) -> highspy.Highs:
        if self._highs is None:
            h = new_highs()
            h.setOptionValue("primal_feasibility_tolerance", LP_TOL)
            h.setOptionValue("dual_feasibility_tolerance", LP_TOL)
            _set_options(h, FAST_LP)
            self._highs = h
        return self._highs

    def _count(self, m: Membership) -> Membership:
        self.counts[m.method] = self.counts.get(m.method, 0) + 1
        return m


#: small dense LPs: presolve costs more than it saves, and primal simplex is fastest ...
FAST_LP = {"presolve": "off", "simplex_strategy": 4}
#: ... but when it reports numerical trouble, HiGHS's defaults (presolve, dual simplex) retry
ROBUST_LP = {"presolve": "on", "simplex_strategy": 1}


def _set_options(h: highspy.Highs, options: dict) -> None:
    for key, value in options.items():
        h.setOptionValue(key, value)


# -- pure kernels ---------------------------------------------------------------------------
def _hull(S, hull) -> tuple[np.ndarray, np.ndarray]:
    if hull is not None:
        return np.asarray(hull[0], float), np.asarray(hull[1], float)
    I = S.interval()
    return I.lo, I.hi


def hull_distance(lo: np.ndarray, hi: np.ndarray, x: np.ndarray) -> float:
    """Infinity-norm distance from ``x`` to the box ``[lo, hi]`` (0 inside)."""
    return float(np.max(np.maximum(np.maximum(lo - x, x - hi), 0.0), initial=0.0))


def constraint_tolerance(A: np.ndarray, b: np.ndarray) -> float:
    """Tolerance on ``A xi = b`` accepted in a membership certificate (scaled 1e-9)."""
    scale = max(1.0, float(np.abs(A).max(initial=0.0)), float(np.abs(b).max(initial=0.0)))
    return 1e-9 * scale


def residual_bound(G: np.ndarray, xi: np.ndarray, v: np.ndarray) -> float:
    """``|G xi - v|_inf`` rounded outward (an upper bound of the exact value).

    Each entry of the floating-point ``G xi - v`` is within ``(r + 2) eps (|G| |xi| + |v|)``
    of the exact one (standard dot-product error bound).
    """
    res = np.abs(G @ xi - v)
    scale = np.abs(G) @ np.abs(xi) + np.abs(v)
    return float(np.max(res + (G.shape[1] + 2) * _EPS * scale, initial=0.0))


def dual_lower_bound(G, v, A, b, d, mu) -> float:
    """Weak-duality lower bound of the distance: ``d'v - mu'b - |G'd - A'mu|_1`` for
    ``|d|_1 <= 1`` (``d`` and ``mu`` are scaled down if needed), rounded downward."""
    norm = float(np.abs(d).sum())
    if not np.isfinite(norm) or norm == 0.0:
        return 0.0
    if norm > 1.0:
        d, mu = d / norm, mu / norm
    t1 = float(d @ v) - float(mu @ b)
    t2 = float(np.abs(G.T @ d - A.T @ mu).sum())
    scale = (float(np.abs(d) @ np.abs(v)) + float(np.abs(mu) @ np.abs(b))
             + float((np.abs(G.T) @ np.abs(d)).sum()) + float((np.abs(A.T) @ np.abs(mu)).sum()))
    slack = (G.shape[0] + G.shape[1] + A.shape[0] + 4) * _EPS * scale
    return max(0.0, t1 - t2 - slack)


def active_set(M: np.ndarray, t: np.ndarray, free: np.ndarray, xi: np.ndarray,
               iterations: int = ACTIVE_SET_STEPS) -> np.ndarray | None:
    """A point of the unit box that solves ``M xi = t`` up to rounding, or None if not found.

    The factors outside ``free`` stay at their values in ``xi``; the free ones are solved by
    least norm; those landing beyond +-1 are fixed at their sign and the rest re-solved.  A
    result within 1e-12 of the box is clipped into it (points exactly on the boundary).
    """
    free, xi = free.copy(), xi.copy()
    for _ in range(iterations + 1):
        if not free.any():
            return None
        Mf = M[:, free]
        rhs = t - M[:, ~free] @ xi[~free]
        try:  # least norm via the normal equations; least squares if they are singular
            if Mf.shape[1] < Mf.shape[0]:
                raise np.linalg.LinAlgError
            z = Mf.T @ np.linalg.solve(Mf @ Mf.T, rhs)
        except np.linalg.LinAlgError:
            z = np.linalg.lstsq(Mf, rhs, rcond=None)[0]
        over = np.abs(z) > 1.0 + 1e-12
        if not over.any():
            xi[free] = np.clip(z, -1.0, 1.0)
            return xi
        idx = np.flatnonzero(free)[over]
        xi[idx] = np.sign(z[over])
        free[idx] = False
    return None


def certifies(G, v, A, b, xi: np.ndarray | None, tol: float, tol_a: float) -> bool:
    """Whether the box point ``xi`` proves membership: ``|G xi - v| <= tol`` (rounded
    outward) and ``|A xi - b| <= tol_a``."""
    return xi is not None and residual_bound(G, xi, v) <= tol and (
        A.shape[0] == 0 or float(np.abs(A @ xi - b).max()) <= tol_a)


def box_certificate(G, v, A, b, tol: float, tol_a: float) -> bool:
    """Whether a factor vector in the unit box is found with ``|G xi - v| <= tol`` and
    ``|A xi - b| <= tol_a``: the least-norm solution of ``[G; A] xi = [v; b]``, then
    :func:`active_set` steps.  A ``True`` is a proof (the point is verified)."""
    r = G.shape[1]
    xi = active_set(np.vstack([G, A]), np.concatenate([v, b]), np.ones(r, bool), np.zeros(r))
    return certifies(G, v, A, b, xi, tol, tol_a)


def polish(G, v, A, b, xi: np.ndarray) -> np.ndarray | None:
    """Refine an LP point found at solver precision: keep the factors at their bounds and
    re-solve the free ones (:func:`active_set`); None if that fails."""
    xi = np.clip(xi, -1.0, 1.0)
    free = np.abs(xi) < 1.0 - 1e-9
    return active_set(np.vstack([G, A]), np.concatenate([v, b]), free,
                      np.where(free, 0.0, np.sign(xi)))


def dual_polish(G, v, A, b, d: np.ndarray, mu: np.ndarray) -> np.ndarray | None:
    """A box point guided by the LP's dual: complementary slackness puts factor ``j`` at
    ``sign(g_j'd - a_j'mu)`` where that reduced cost is clearly nonzero; the factors with a
    (relatively) zero reduced cost are re-solved (:func:`active_set`).  None if that fails
    or the dual is zero (a point exactly on the boundary of a badly scaled set, where the
    primal point's bound pattern can be wrong at solver precision)."""
    red = G.T @ d - A.T @ mu
    scale = float(np.abs(d).sum()) * max(float(np.abs(G).max(initial=0.0)), 1e-300)
    if not np.isfinite(scale) or float(np.abs(red).max(initial=0.0)) == 0.0:
        return None
    free = np.abs(red) <= 1e-9 * scale
    return active_set(np.vstack([G, A]), np.concatenate([v, b]), free,
                      np.where(free, 0.0, np.sign(red)))
