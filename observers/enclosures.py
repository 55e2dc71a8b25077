"""Affine enclosures of a smooth vector function over a box.

For a function ``phi`` (the dynamics ``f(., u)`` or the output ``h`` of a system) and a box
``B = [lo, hi]`` with midpoint ``p`` and radius ``r``, each enclosure returns ``(J, d, rad)``
with

``phi(x) in J x + d + [-rad, rad]``  for every ``x`` in ``B``,

rounded outward so that it holds in exact arithmetic.  The observers apply ``J`` to their set
and add (or, for a measurement, widen the noise by) the box ``[d - rad, d + rad]``.

* :func:`first_order` -- first-order Taylor expansion at ``p`` with the Lagrange remainder
  ``1/2 (x - p)' H(xi) (x - p)`` bounded by the interval Hessian over ``B`` (Rego, Raffo,
  Scott, Raimondo, Automatica 111, 108614, 2020, the first-order Taylor extension; Althoff,
  Stursberg, Buss, CDC 2008 for zonotopes).
* :func:`mean_value` -- the mean-value extension ``phi(x) in phi(p) + J(B) (x - p)`` with the
  interval Jacobian over ``B`` (Rego et al. 2020, the mean-value extension).
* :func:`dc` -- a difference-of-convex decomposition ``phi_i = g_i - q_i`` with the convex
  quadratic ``q_i = 1/2 sum_j a_ij (x_j - p_j)^2`` (``a_ij`` from a Gershgorin bound of the
  interval Hessian over ``B``, so that ``g_i`` is convex over ``B``).  The tangent planes at
  ``p`` minorise both convex parts, and a convex function is majorised over ``B`` by its largest
  value at the vertices of ``B``, so ``phi_i(x) - phi_i(p) - J_i (x - p)`` lies in
  ``[-max_B (q_i - tangent), max_vertices (g_i - tangent)]``; this is the bounding principle of
  the DC-programming estimators (Alamo, Bravo, Redondo, Camacho, Automatica 44(1), 2008, for
  zonotopes; the constrained-zonotope estimator compared in Rego, Raffo, Terra, Scott, arXiv
  2504.00130).  Its vertex enumeration costs ``2^n`` evaluations (refused beyond
  :data:`DC_MAX_STATES` states).

The function is described by a :class:`Smooth` adapter over a system's ``f`` or ``h``.
"""

from __future__ import annotations

import itertools

import numpy as np

from .errors import Diverged, Unsupported
from .sets.interval_arith import Ival

_EPS = np.finfo(float).eps


class NotDerivable(ValueError):
    """The function cannot be traced symbolically (:mod:`systems` raises its ``ModelError``,
    a ``ValueError``); the enclosures then use floating-point margins instead of intervals."""

#: largest state dimension of the DC enclosure (2^n vertices per step)
DC_MAX_STATES = 12


class Smooth:
    """The dynamics ``f(., u)`` (``what="f"``) or the output ``h`` (``what="h"``) of
    ``system`` with the derivative information the enclosures need."""

    def __init__(self, system, what: str):
        self.system, self.what = system, what

    def value(self, x: np.ndarray, u: np.ndarray) -> np.ndarray:
        s = self.system
        return s.f(x, u) if self.what == "f" else s.h(x)

    def jacobian(self, x: np.ndarray, u: np.ndarray) -> np.ndarray:
        s = self.system
        return s.jacobian(x, u)[0] if self.what == "f" else s.h_jacobian(x)

    def hessian(self, lo, hi, u):
        s = self.system
        return s.hessian(lo, hi, u) if self.what == "f" else s.h_hessian(lo, hi)

    def jacobian_bounds(self, lo, hi, u):
        s = self.system
        try:
            return (s.jacobian_bounds(lo, hi, u) if self.what == "f"
                    else s.h_jacobian_bounds(lo, hi))
        except Diverged:
            raise
        except ValueError as exc:  # the model cannot be derived (a ModelError)
            raise NotDerivable(str(exc)) from None

    @property
    def derived(self):
        """:class:`~systems.derivatives.SymbolicDerivatives` of the function."""
        return self.system.derived if self.what == "f" else self.system.derived_h

    def value_bounds(self, lo: np.ndarray, hi: np.ndarray, u) -> Ival:
        """Interval enclosure (m x K) of the values over the K boxes ``[lo, hi]`` (n x K;
        points where ``lo == hi``), after the domain check."""
        self.system.check_domain(lo.min(axis=1), hi.max(axis=1))
        try:
            derived = self.derived
        except ValueError as exc:  # systems.ModelError: the model cannot be derived
            raise NotDerivable(str(exc)) from None
        return derived.value_bounds(lo, hi, u if self.what == "f" else np.zeros(0))


def _box(lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Midpoint and an outward-rounded radius of ``[lo, hi]``."""
    p = 0.5 * (lo + hi)
    r = np.nextafter(np.maximum(hi - p, p - lo), np.inf)
    return p, r


def _hull(v: Ival) -> tuple[np.ndarray, np.ndarray]:
    """Centre and outward-rounded radius of the interval ``v``."""
    c = 0.5 * (v.lo + v.hi)
    return c, np.nextafter(np.maximum(v.hi - c, c - v.lo), np.inf)


def _checked(J, d, rad, k):
    if not (np.all(np.isfinite(J)) and np.all(np.isfinite(d)) and np.all(np.isfinite(rad))):
        raise Diverged("non-finite enclosure of the nonlinearity", step=k)
    return J, d, rad


def _centre_terms(fn: Smooth, p, u, J):
    """``phi(p) - J p`` and a radius enclosing its rounding: ``phi(p)`` from the interval
    evaluation of the function at the point (rigorous whatever cancellation it involves;
    the floating-point value with a relative margin where ``phi`` cannot be derived)."""
    try:
        v = fn.value_bounds(p[:, None], p[:, None], u)
        fp, fr = _hull(Ival(v.lo[:, 0], v.hi[:, 0]))
    except NotDerivable:  # a hand-written function sympy cannot trace
        fp = fn.value(p, u)
        fr = 4 * _EPS * np.abs(fp)
    d = fp - J @ p
    return d, fr + 4 * _EPS * (np.abs(fp) + np.abs(J) @ np.abs(p) + np.abs(d))


def _slope_error(fn: Smooth, p, u, J, r):
    """Bound of ``|J' - J| r`` for the exact derivative ``J'`` at ``p``: the interval Jacobian
    at the point (rigorous), else a relative margin."""
    try:
        Jlo, Jhi = fn.jacobian_bounds(p, p, u)
        dev = np.maximum(np.abs(Jhi - J), np.abs(J - Jlo))
    except NotDerivable:
        dev = 16 * _EPS * np.abs(J)
    return np.nextafter(dev @ r * (1 + 4 * _EPS * r.size), np.inf)


def _restep(exc: Diverged, k):
    return type(exc)(str(exc), step=k) if exc.step is None else exc


def first_order(fn: Smooth, lo, hi, u, k=None):
    """First-order Taylor expansion at the midpoint with the Lagrange remainder bounded by
    the interval Hessian over the box (see the module docstring)."""
    p, r = _box(lo, hi)
    try:
        idx, Hlo, Hhi = fn.hessian(np.nextafter(lo, -np.inf), np.nextafter(hi, np.inf), u)
    except Diverged as exc:
        raise _restep(exc, k) from None
    J = np.asarray(fn.jacobian(p, u), dtype=float)
    d, rad = _centre_terms(fn, p, u, J)
    rad = rad + _slope_error(fn, p, u, J, r)
    m = J.shape[0]
    lo_rem, hi_rem = np.zeros(m), np.zeros(m)
    if len(idx):
        idx = np.asarray(idx, dtype=int).reshape(-1, 3)
        i, j, kk = idx.T
        H = Ival(np.asarray(Hlo, dtype=float), np.asarray(Hhi, dtype=float))
        # (x_j - p_j)(x_k - p_k): [0, r_j^2] on the diagonal (times 1/2), else +-r_j r_k
        rr = Ival(r[j]) * Ival(r[kk])
        prod = Ival(np.where(j == kk, 0.0, -rr.hi), rr.hi)
        term = H * prod * Ival(np.where(j == kk, 0.5, 1.0))
        np.add.at(lo_rem, i, term.lo)
        np.add.at(hi_rem, i, term.hi)
        # rounding of the sums: a relative margin on their magnitude
        mag = np.zeros(m)
        np.add.at(mag, i, np.maximum(np.abs(term.lo), np.abs(term.hi)))
        slack = 4 * _EPS * (len(i) + 2) * mag
        lo_rem, hi_rem = lo_rem - slack, hi_rem + slack
    c_rem, r_rem = _hull(Ival(lo_rem, hi_rem))
    return _checked(J, d + c_rem, np.nextafter(rad + r_rem, np.inf), k)


def mean_value(fn: Smooth, lo, hi, u, k=None):
    """Mean-value extension with the interval Jacobian over the box (see the module
    docstring)."""
    p, r = _box(lo, hi)
    try:
        Jlo, Jhi = fn.jacobian_bounds(np.nextafter(lo, -np.inf), np.nextafter(hi, np.inf), u)
    except Diverged as exc:
        raise _restep(exc, k) from None
    Jm = 0.5 * (Jlo + Jhi)
    Jr = np.nextafter(0.5 * (Jhi - Jlo), np.inf)
    # phi(x) - phi(p) in J(B)(x - p) subset Jm (x - p) + [-Jr r, Jr r]; |Jm - J(B)| <= Jr
    d, rad = _centre_terms(fn, p, u, Jm)
    rem = np.nextafter((Jr @ r) * (1 + 4 * _EPS * r.size), np.inf)
    return _checked(Jm, d, np.nextafter(rad + rem, np.inf), k)


def dc_weights(idx, Hlo, Hhi, m: int, n: int) -> np.ndarray:
    """``a`` (m x n): for each output i, diagonal weights making ``H_i(B) + diag(a_i)``
    diagonally dominant with a non-negative diagonal, hence positive semidefinite, for every
    Hessian in the interval bounds (scaled Gershgorin; absent entries are zero)."""
    diag = np.zeros((m, n))
    off = np.zeros((m, n))
    if len(idx):
        idx = np.asarray(idx, dtype=int).reshape(-1, 3)
        i, j, k = idx.T
        mag = np.maximum(np.abs(Hlo), np.abs(Hhi))
        d = j == k
        np.add.at(diag, (i[d], j[d]), np.asarray(Hlo)[d])
        np.add.at(off, (i[~d], j[~d]), mag[~d])
        np.add.at(off, (i[~d], k[~d]), mag[~d])
    a = np.maximum(0.0, off - diag)
    return np.nextafter(a * (1 + 8 * _EPS * (n + 1)), np.inf)


def dc(fn: Smooth, lo, hi, u, k=None):
    """Difference-of-convex enclosure (see the module docstring)."""
    n = lo.size
    if n > DC_MAX_STATES:
        raise Unsupported(f"the DC enclosure enumerates the 2^n vertices of a box: n = {n} > "
                          f"{DC_MAX_STATES}")
    p, r = _box(lo, hi)
    try:
        idx, Hlo, Hhi = fn.hessian(np.nextafter(lo, -np.inf), np.nextafter(hi, np.inf), u)
        J = np.asarray(fn.jacobian(p, u), dtype=float)
        m = J.shape[0]
        a = dc_weights(idx, np.asarray(Hlo, float), np.asarray(Hhi, float), m, n)
        signs = np.array(list(itertools.product((-1.0, 1.0), repeat=n))).T  # n x 2^n
        V = np.clip(p[:, None] + signs * r[:, None], lo[:, None], hi[:, None])
        fv = fn.value_bounds(V, V, u)  # m x 2^n, rigorous
        fp = fn.value_bounds(p[:, None], p[:, None], u)  # m x 1
    except Diverged as exc:
        raise _restep(exc, k) from None
    dev = Ival(V - p[:, None])  # exact up to one rounding: enclose it
    dev = Ival(np.nextafter(dev.lo, -np.inf), np.nextafter(dev.hi, np.inf))
    tangent = Ival(np.zeros((m, V.shape[1])))
    quad = Ival(np.zeros((m, V.shape[1])))
    for j in range(n):
        dj = Ival(dev.lo[j], dev.hi[j])
        tangent = tangent + Ival(J[:, j:j + 1]) * dj
        quad = quad + Ival(0.5 * a[:, j:j + 1]) * dj ** 2
    e_g = fv - fp - tangent + quad  # g - tangent of g at p, at each vertex (>= 0 exactly)
    # J is the derivative at p up to rounding: a margin for the tangent's slope error
    slope = _slope_error(fn, p, u, J, r)
    upper = np.nextafter(e_g.hi.max(axis=1) + slope, np.inf)
    q_max = np.nextafter((0.5 * a) @ (r * r) * (1 + 4 * _EPS * (n + 2)), np.inf)
    lower = -(q_max + slope)
    # phi(x) in phi(p) + J (x - p) + [lower, upper]
    fpc, fpr = _hull(Ival(fp.lo[:, 0], fp.hi[:, 0]))
    shift = 0.5 * (lower + upper)
    half = np.nextafter(0.5 * (upper - lower), np.inf)
    d = fpc - J @ p + shift
    rnd = 4 * _EPS * (np.abs(fpc) + np.abs(J) @ np.abs(p) + np.abs(d))
    return _checked(J, d, np.nextafter(fpr + half + rnd, np.inf), k)


#: affine enclosures by name (the ``linearisation`` strategies of the CZ estimators)
ENCLOSURES = {"first-order": first_order, "mean-value": mean_value, "dc": dc}
