"""Mathematics of the nonlinear interval observer INT-CP: inclusion functions of the dynamics
over a box and contractors of a box by a measurement ``y = h(x) + v``.

The observer follows the prediction-correction scheme of guaranteed recursive state bounding
with interval analysis (Kieffer, Jaulin, Walter, "Guaranteed recursive non-linear state
bounding using interval analysis", Int. J. Adaptive Control and Signal Processing 16(3),
2002; Jaulin, Kieffer, Didrit, Walter, *Applied Interval Analysis*, Springer 2001, Ch. 2
and 4), with one box per step (no subpavings):

* **prediction**: an inclusion function of ``f(., u)`` over the box ``[x]``.  Two are
  computed and intersected (both contain the range, so their intersection does):

  - the *natural* inclusion function: ``f`` evaluated in outward-rounded interval arithmetic
    (:mod:`observers.sets.interval_arith`);
  - the *mean-value* (centred) form ``f(p) + J([x]) ([x] - p)`` with the interval Jacobian
    ``J([x])`` and the midpoint ``p`` (Moore 1966; Jaulin et al. 2001, Sec. 2.4.4):
    ``f(p) +- mag(J([x])) r``, with ``r`` the radius of the box (:func:`mean_value_box`).

  The natural form is tighter for wide boxes and monotone terms, the mean-value form for
  narrow boxes (its overestimation is quadratic in the width); the intersection keeps the
  better of the two per component and step.  A linear map ``A x + B u`` is enclosed exactly
  (:func:`linear_box`).
* **correction**: the box is contracted with ``h(x) in [y] = y - [v]``:

  - a linear output ``C x`` by the row-wise interval contractor (Gauss-Seidel on the rows:
    ``x_j in ([y_i] - sum_{k != j} C_ik [x_k]) / C_ij``, :func:`contract_linear`);
  - a nonlinear output by forward-backward constraint propagation on the expression tree of
    ``h`` (the HC4-revise contractor of Benhamou, Goualard, Granvilliers, Puget, "Revising
    hull and box consistency", ICLP 1999; Jaulin et al. 2001, Sec. 4.2.4,
    :class:`ForwardBackward`), followed by the linear contractor on a mean-value enclosure
    ``h(x) in H x + d + [-rad, rad]`` over the box (built by the plugin with
    :mod:`observers.enclosures`).

  Both are repeated until the box stops shrinking (or a sweep limit).

Soundness in floating point: every quantity that bounds a range is computed in the
outward-rounded interval arithmetic of :mod:`observers.sets.interval_arith`, or from float
sums widened by a relative slack that bounds their rounding error and then rounded outward
with ``np.nextafter``.  An empty contraction (the measurement is inconsistent with the box)
raises :class:`~observers.sets.EmptySet`: the run ends as ``empty``.
"""

from __future__ import annotations

import numpy as np

from ..sets import EmptySet, SetError
from ..sets import interval_arith as ia
from ..sets.interval_arith import Ival

_EPS = np.finfo(float).eps
_INF = np.inf


def down(x, ulps: int = 1):
    """``x`` moved ``ulps`` floating-point numbers towards ``-inf``."""
    for _ in range(ulps):
        x = np.nextafter(x, -_INF)
    return x


def up(x, ulps: int = 1):
    """``x`` moved ``ulps`` floating-point numbers towards ``+inf``."""
    for _ in range(ulps):
        x = np.nextafter(x, _INF)
    return x


def midpoint_radius(lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Midpoint ``p`` and a radius ``r`` (rounded up) with ``[lo, hi]`` inside ``p +- r``."""
    p = 0.5 * (lo + hi)
    return p, up(np.maximum(hi - p, p - lo))


def _sum_slack(terms: np.ndarray, axis: int = -1) -> np.ndarray:
    """Bound of the rounding error of ``terms.sum(axis)`` (``k`` terms: ``k eps`` times the sum
    of their magnitudes), doubled for the products that made them."""
    k = terms.shape[axis] + 2
    return 2 * k * _EPS * np.abs(terms).sum(axis=axis)


def linear_box(A: np.ndarray, lo: np.ndarray, hi: np.ndarray,
               shift: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    r"""Interval hull of ``{A x + shift : lo <= x <= hi}`` (exact up to outward rounding):
    ``A p + shift +- |A| r``.

    .. math::

        \operatorname{BOX}\{Ax + s \mid \underline{x} \le x \le \overline{x}\}
        = [Ap + s - |A|\,r,\ Ap + s + |A|\,r], \qquad
        p = \tfrac{1}{2}(\underline{x} + \overline{x}),\ r = \tfrac{1}{2}(\overline{x} -
        \underline{x}).
    """
    p, r = midpoint_radius(lo, hi)
    Ap = A * p
    c = Ap.sum(axis=1) + shift
    rad = np.abs(A) @ r
    slack = _sum_slack(Ap) + 4 * _EPS * (np.abs(shift) + np.abs(c) + rad)
    return down(c - rad - slack), up(c + rad + slack)


def mean_value_box(fp: Ival, Jlo: np.ndarray, Jhi: np.ndarray,
                   r: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    r"""The mean-value form ``[f(p)] + J([x]) ([x] - p)`` over a box of radius ``r`` around
    ``p``: ``[f(p)] +- mag(J([x])) r`` (``fp``: an enclosure of ``f(p)``; ``Jlo <= J <= Jhi``
    over the box).

    .. math::

        f([x]) \subseteq [f(p)] + J([x])\,([x] - p) \subseteq
        [f(p)] + [-1, 1]\,\operatorname{mag}(J([x]))\,r, \qquad
        \operatorname{mag}(J)_{ij} = \max(|\underline{J}_{ij}|, |\overline{J}_{ij}|).
    """
    mag = np.maximum(np.abs(Jlo), np.abs(Jhi))
    terms = mag * r
    rad = terms.sum(axis=1)
    rad = up(rad + _sum_slack(terms))
    return down(fp.lo - rad), up(fp.hi + rad)


def intersect(lo: np.ndarray, hi: np.ndarray, lo2: np.ndarray,
              hi2: np.ndarray, what: str = "the boxes") -> tuple[np.ndarray, np.ndarray]:
    """``[lo, hi] & [lo2, hi2]``; :class:`EmptySet` if they are disjoint."""
    a, b = np.maximum(lo, lo2), np.minimum(hi, hi2)
    bad = np.flatnonzero(a > b)
    if bad.size:
        j = int(bad[0])
        raise EmptySet(f"{what} do not intersect in component {j + 1} "
                       f"([{lo[j]:.6g}, {hi[j]:.6g}] and [{lo2[j]:.6g}, {hi2[j]:.6g}])")
    return a, b


def contract_linear(lo: np.ndarray, hi: np.ndarray, C: np.ndarray, ylo: np.ndarray,
                    yhi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    r"""Contract the box ``[lo, hi]`` with ``ylo <= C x <= yhi``, row after row (one
    Gauss-Seidel sweep).

    For row ``i`` and every ``j`` with ``C_ij != 0``:
    ``x_j in ([ylo_i, yhi_i] - sum_{k != j} C_ik [x_k]) / C_ij``, intersected with ``[x_j]``:

    .. math::

        [x_j] \leftarrow [x_j] \cap \frac{1}{C_{ij}}\Bigl([\underline{y}_i, \overline{y}_i] -
        \sum_{k \ne j} C_{ik}\,[x_k]\Bigr).

    The sums are taken in floating point and widened by a bound of their rounding error, the
    quotient is rounded outward.  Raises :class:`EmptySet` if a component becomes empty (no
    state of the box is consistent with the measurement).
    """
    lo, hi = lo.copy(), hi.copy()
    for i in range(C.shape[0]):
        row = C[i]
        nz = np.flatnonzero(row)
        if nz.size == 0:
            continue
        c = row[nz]
        a, b = c * lo[nz], c * hi[nz]
        plo, phi = np.minimum(a, b), np.maximum(a, b)  # products (each rounded once)
        plo, phi = down(plo), up(phi)
        slo, shi = plo.sum(), phi.sum()
        tol = _sum_slack(np.concatenate([plo, phi]))
        # sum over k != j, rounded outward (the subtraction adds one more rounding)
        rlo = down(slo - plo - tol, 2)
        rhi = up(shi - phi + tol, 2)
        nlo, nhi = down(ylo[i] - rhi), up(yhi[i] - rlo)
        q1, q2 = nlo / c, nhi / c
        qlo, qhi = down(np.minimum(q1, q2)), up(np.maximum(q1, q2))
        lo[nz], hi[nz] = intersect(lo[nz], hi[nz], qlo, qhi,
                                   f"the box and the measurement of output {i + 1}")
    return lo, hi


# -- forward-backward propagation on an expression DAG -----------------------------------------
def _hull_union(a: Ival, lo1, hi1, lo2, hi2) -> tuple[float, float]:
    """Hull of ``a & ([lo1, hi1] u [lo2, hi2])`` as ``(lo, hi)`` (``lo > hi``: empty)."""
    l1, h1 = max(a.lo, lo1), min(a.hi, hi1)
    l2, h2 = max(a.lo, lo2), min(a.hi, hi2)
    parts = [(x, y) for x, y in ((l1, h1), (l2, h2)) if x <= y]
    if not parts:
        return 1.0, 0.0
    return min(p[0] for p in parts), max(p[1] for p in parts)


#: relative margin of the inverse elementary functions of the backward pass (numpy's
#: ``log, exp, tan`` and roots are accurate to a few ulps; this is far above that)
REL = 1e-13


def _lower(t: float) -> float:
    """``t`` moved outward (down) by the relative margin :data:`REL`."""
    return float(down(t - REL * abs(t)))


def _upper(t: float) -> float:
    """``t`` moved outward (up) by the relative margin :data:`REL`."""
    return float(up(t + REL * abs(t)))


def _root(z: Ival, k: int) -> tuple[float, float]:
    """``[z & [0, inf)]^(1/k)`` rounded outward (``lo > hi`` if ``z < 0``)."""
    if z.hi < 0:
        return 1.0, 0.0
    lo = max(float(z.lo), 0.0)
    rlo = max(_lower(lo ** (1.0 / k)), 0.0) if lo > 0 else 0.0
    return rlo, _upper(float(z.hi) ** (1.0 / k))


def _odd_root(t: float, k: int) -> float:
    """``sign(t) |t|^(1/k)`` (unrounded; the caller rounds)."""
    return float(np.sign(t) * abs(t) ** (1.0 / k))


class ForwardBackward:
    """HC4-revise contractor of ``h(x) in [y]`` on the factorable representation of ``h``
    (:class:`observers.numerics.relaxation.Factorable`: a DAG of ``x, const, add, mul, pow,
    recip, sqrt, exp, log, sin, cos, atan`` nodes in topological order).

    The forward pass evaluates every node in interval arithmetic over the box; the output
    nodes are intersected with ``[y]``; the backward pass, in reverse topological order,
    projects each node's interval onto its arguments (the inverse of the operation, rounded
    outward), so a shared subexpression receives the projections of all its uses before it
    projects further.  ``sin`` and ``cos`` (not invertible on an interval without a branch
    choice) project nothing; a product projects onto a factor only if the other factor's
    interval excludes 0.  Every projection keeps all solutions, so the contracted box
    contains every state of the box consistent with ``[y]``.
    """

    def __init__(self, factorable, n: int):
        self.nodes = factorable.nodes
        self.outputs = factorable.outputs
        self.n = n

    def _forward(self, lo, hi) -> list[Ival]:
        v: list[Ival] = []
        for node in self.nodes:
            k = node.kind
            if k == "x":
                j = int(node.param)
                v.append(Ival(lo[j], hi[j]))
            elif k == "const":
                v.append(Ival(node.param))
            elif k == "add":
                acc = Ival(node.param)
                for coef, a in node.args:
                    acc = acc + Ival(coef) * v[a]
                v.append(acc)
            elif k == "mul":
                v.append(v[node.args[0]] * v[node.args[1]])
            elif k == "pow":
                v.append(v[node.args[0]] ** int(node.param))
            elif k == "recip":
                v.append(v[node.args[0]].reciprocal())
            elif k == "u":
                raise SetError("the output function depends on the input")
            else:
                v.append(_UNARY_IVAL[k](v[node.args[0]]))
        return v

    def contract(self, lo: np.ndarray, hi: np.ndarray, ylo: np.ndarray,
                 yhi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """One forward-backward pass; returns the contracted box.  Raises :class:`EmptySet`
        if no state of the box is consistent with ``[ylo, yhi]`` and
        :class:`~observers.sets.interval_arith.IntervalDomainError` if ``h`` cannot be
        evaluated over the box (the caller then skips this contractor)."""
        v = self._forward(lo, hi)
        v = [Ival(float(a.lo), float(a.hi)) for a in v]
        for i, o in enumerate(self.outputs):
            v[o] = self._meet(v[o], ylo[i], yhi[i], f"output {i + 1}")
        xlo, xhi = lo.copy(), hi.copy()
        for idx in range(len(self.nodes) - 1, -1, -1):
            node, z = self.nodes[idx], v[idx]
            k = node.kind
            if k == "x":
                j = int(node.param)
                xlo[j], xhi[j] = max(xlo[j], z.lo), min(xhi[j], z.hi)
                if xlo[j] > xhi[j]:
                    raise EmptySet(f"the measurement leaves no value of x{j + 1} in the box")
            elif k == "add":
                self._back_add(node, z, v)
            elif k == "mul":
                a, b = node.args
                if not (v[b].lo <= 0.0 <= v[b].hi):
                    v[a] = self._meet(v[a], *_bounds(z / v[b]), "a product")
                if not (v[a].lo <= 0.0 <= v[a].hi):
                    v[b] = self._meet(v[b], *_bounds(z / v[a]), "a product")
            elif k in _BACK:
                a = node.args[0]
                v[a] = self._meet(v[a], *_BACK[k](z, v[a], node.param), f"{k}")
        return xlo, xhi

    @staticmethod
    def _meet(a: Ival, lo: float, hi: float, what: str) -> Ival:
        lo, hi = max(float(a.lo), float(lo)), min(float(a.hi), float(hi))
        if lo > hi:
            raise EmptySet(f"the measurement is inconsistent with the box ({what})")
        return Ival(lo, hi)

    def _back_add(self, node, z: Ival, v: list[Ival]) -> None:
        terms = [Ival(c) * v[a] for c, a in node.args]
        for t, (c, a) in enumerate(node.args):
            rest = Ival(node.param)
            for s, term in enumerate(terms):
                if s != t:
                    rest = rest + term
            v[a] = self._meet(v[a], *_bounds((z - rest) / Ival(c)), "a sum")
            terms[t] = Ival(c) * v[a]


def _bounds(a: Ival) -> tuple[float, float]:
    return float(a.lo), float(a.hi)


def _back_pow(z: Ival, a: Ival, k: float) -> tuple[float, float]:
    k = int(k)
    if k % 2:  # odd: monotone, a = sign(z) |z|^(1/k)
        return _lower(_odd_root(float(z.lo), k)), _upper(_odd_root(float(z.hi), k))
    rlo, rhi = _root(z, k)
    if rlo > rhi:
        return 1.0, 0.0
    return _hull_union(a, -rhi, -rlo, rlo, rhi)


def _back_sqrt(z: Ival, a: Ival, _) -> tuple[float, float]:
    if z.hi < 0:
        return 1.0, 0.0
    zl = max(float(z.lo), 0.0)
    return float(down(zl * zl)), float(up(z.hi * z.hi))


def _back_exp(z: Ival, a: Ival, _) -> tuple[float, float]:
    if z.hi <= 0:
        return 1.0, 0.0
    lo = _lower(float(np.log(z.lo))) if z.lo > 0 else -_INF
    return lo, _upper(float(np.log(z.hi)))


def _back_log(z: Ival, a: Ival, _) -> tuple[float, float]:
    return _lower(float(np.exp(z.lo))), _upper(float(np.exp(z.hi)))


def _back_recip(z: Ival, a: Ival, _) -> tuple[float, float]:
    if z.lo <= 0 <= z.hi:
        return -_INF, _INF
    return _bounds(z.reciprocal())


def _back_atan(z: Ival, a: Ival, _) -> tuple[float, float]:
    h = 0.5 * np.pi
    if z.hi < -h or z.lo > h:
        return 1.0, 0.0
    margin = 1e-6  # tan is steep near +-pi/2: no contraction from there
    lo = _lower(float(np.tan(z.lo))) if z.lo > -h + margin else -_INF
    hi = _upper(float(np.tan(z.hi))) if z.hi < h - margin else _INF
    return lo, hi


def _no_projection(z: Ival, a: Ival, _) -> tuple[float, float]:
    return -_INF, _INF


_UNARY_IVAL = {"exp": ia.exp, "log": ia.log, "sqrt": ia.sqrt, "sin": ia.sin, "cos": ia.cos,
               "atan": ia.arctan}
_BACK = {"pow": _back_pow, "sqrt": _back_sqrt, "exp": _back_exp, "log": _back_log,
         "recip": _back_recip, "atan": _back_atan, "sin": _no_projection,
         "cos": _no_projection}


def shrank(lo, hi, lo2, hi2, rel: float) -> bool:
    """Whether some component of ``[lo2, hi2]`` is narrower than that of ``[lo, hi]`` by more
    than ``rel`` of its width."""
    w, w2 = hi - lo, hi2 - lo2
    return bool(np.any(w - w2 > rel * np.maximum(w, 1e-300)))
