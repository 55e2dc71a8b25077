"""Lifted polyhedral relaxations of factorable functions over constrained zonotopes.

After Rego, Raffo, Terra, Scott, "Set-based state estimation of nonlinear discrete-time
systems using constrained zonotopes and polyhedral relaxations" (arXiv 2504.00130, 2025):
a function written with sums, products, quotients, integer powers and ``sqrt, exp, log, sin,
cos`` (and ``atan``) is split into a sequence of elementary operations (its *factorable
representation*, :class:`Factorable`, built once from the sympy expressions of
:mod:`systems.derivatives`).
Over a constrained zonotope ``Z = {c + G xi : A xi = b, |xi| <= 1}`` and a box ``B``
containing it, every intermediate value of a nonlinear operation gets a variable ``z`` in its
interval (from interval arithmetic over ``B``) and the operation is replaced by linear
inequalities that hold on its graph (:func:`relax_unary`, :func:`relax_product`):

* products ``z = a b``: the four McCormick inequalities over the argument boxes;
* convex (concave) univariate operations on their interval (``exp``; ``log`` and ``sqrt``
  concave; ``1/a``, ``a^k`` and ``atan`` by sign and parity; ``sin`` and ``cos`` where the
  interval contains no inflection point): the secant above (below) and the tangent at the
  midpoint (optionally also at both ends) below (above);
* otherwise (``sin``, ``cos``, ``atan`` or an odd power across an inflection point): the
  tangent at the midpoint and the secant, each widened by the bound ``M`` of ``|phi''|`` over
  the interval (Taylor's and the interpolation remainder: ``M rho^2 / 2`` and
  ``M (u - l)^2 / 8``).

Linear operations stay exact (affine forms of the variables).  Each inequality ``l(v) <= 0``
becomes the equality ``l(v) + s = 0`` with a slack ``s`` in ``[0, s_max]``, one generator
each; so the graph of the function over ``Z`` is enclosed by a *lifted* constrained zonotope
in the variables ``(xi, z, s)``, whose image is the enclosure of ``phi(Z)`` and whose
constraints keep the link to ``xi`` (Scott et al. 2016: every bounded polytope is a
constrained zonotope).  For a measurement ``y = h(x) + v`` the output expressions are
equated to ``y - v`` instead (the update of the paper).

Soundness in floating point: each inequality's offset is moved outward by a relative margin
:data:`MARGIN` (far above the rounding of the few operations that compute it), slack bounds
are rounded up, and the intervals come from the outward-rounded arithmetic of
:mod:`observers.sets.interval_arith`; a box leaving a function's domain raises
:class:`~observers.errors.Diverged`.  Supported: ``+ - *``, ``/``, integer and half-integer
powers, ``sqrt, exp, log, sin, cos, atan``; anything else is refused when the estimator is built.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from ..errors import Diverged, Unsupported
from ..sets import SetError
from ..sets import interval_arith as ia
from ..sets.interval_arith import Ival

#: relative outward margin of each inequality's offset (rounding is ~1e-16 relative)
MARGIN = 1e-12

#: univariate operations: value, first and second derivative (numpy)
_UNARY = {
    "exp": (np.exp, np.exp, np.exp),
    "log": (np.log, lambda a: 1.0 / a, lambda a: -1.0 / a ** 2),
    "sqrt": (np.sqrt, lambda a: 0.5 / np.sqrt(a), lambda a: -0.25 / a ** 1.5),
    "sin": (np.sin, np.cos, lambda a: -np.sin(a)),
    "cos": (np.cos, lambda a: -np.sin(a), lambda a: -np.cos(a)),
    "recip": (lambda a: 1.0 / a, lambda a: -1.0 / a ** 2, lambda a: 2.0 / a ** 3),
    "atan": (np.arctan, lambda a: 1.0 / (1.0 + a * a), lambda a: -2.0 * a / (1.0 + a * a) ** 2),
}
#: bound of |atan''| on the real line: 3 sqrt(3) / 8 at a = +-1/sqrt(3) (rounded up)
_ATAN_M2 = 0.6496
_IVAL = {"exp": ia.exp, "log": ia.log, "sqrt": ia.sqrt, "sin": ia.sin, "cos": ia.cos,
         "atan": ia.arctan, "recip": lambda a: a.reciprocal()}


@dataclass(frozen=True)
class Node:
    """One operation of a factorable representation: ``kind`` in ``x, u, const, add, mul,
    pow`` or a univariate name of :data:`_UNARY`; ``args`` are node indices (``add``: pairs
    of ``(coefficient, node)``), ``param`` the state/input index, constant or exponent."""

    kind: str
    args: tuple = ()
    param: float = 0.0


class Factorable:
    """Factorable representation of sympy expressions in the states ``xs`` and inputs ``us``
    (common subexpressions shared).

    Raises
    ------
    Unsupported
        For an operation without a relaxation (e.g. ``tanh``, ``atan``, a non-integer,
        non-half-integer power).
    """

    def __init__(self, expressions, xs, us, what: str = "f"):
        import sympy

        self._sympy = sympy
        self.nodes: list[Node] = []
        self._memo: dict = {}
        self._x = {s: j for j, s in enumerate(xs)}
        self._u = {s: j for j, s in enumerate(us)}
        self.what = what
        self.outputs = [self._node(e) for e in expressions]

    def _add(self, node: Node) -> int:
        key = (node.kind, node.args, node.param)
        if key not in self._memo:
            self._memo[key] = len(self.nodes)
            self.nodes.append(node)
        return self._memo[key]

    def _node(self, e) -> int:  # noqa: C901 - one case per sympy head
        sp = self._sympy
        if e in self._x:
            return self._add(Node("x", param=self._x[e]))
        if e in self._u:
            return self._add(Node("u", param=self._u[e]))
        if e.is_Number:
            return self._add(Node("const", param=float(e)))
        if e.is_Add:
            terms = []
            const = 0.0
            for t in e.args:
                coef, rest = t.as_coeff_Mul()
                if rest == 1:
                    const += float(coef)
                else:
                    terms.append((float(coef), self._node(rest)))
            return self._add(Node("add", tuple(terms), const))
        if e.is_Mul:
            coef, rest = e.as_coeff_Mul()
            if coef != 1:
                return self._add(Node("add", ((float(coef), self._node(rest)),), 0.0))
            factors = [self._node(a) for a in e.args]
            out = factors[0]
            for f in factors[1:]:
                out = self._add(Node("mul", (out, f)))
            return out
        if e.is_Pow:
            base, p = e.args
            if p.is_Integer:
                k = int(p)
                a = self._node(base)
                if k < 0:
                    a = self._add(Node("recip", (a,)))
                    k = -k
                return a if k == 1 else self._add(Node("pow", (a,), float(k)))
            if p.is_Rational and (2 * p).is_Integer:  # (sqrt a)^q, q odd
                q = int(2 * p)
                a = self._add(Node("sqrt", (self._node(base),)))
                if abs(q) > 1:
                    a = self._add(Node("pow", (a,), float(abs(q))))
                return a if q > 0 else self._add(Node("recip", (a,)))
            raise Unsupported(f"{self.what}: no polyhedral relaxation of the power {p}")
        for name in ("exp", "log", "sin", "cos", "atan"):
            if isinstance(e, getattr(sp, name)):
                return self._add(Node(name, (self._node(e.args[0]),)))
        raise Unsupported(f"{self.what}: no polyhedral relaxation of {type(e).__name__} "
                          "(supported: + - * /, powers, sqrt, exp, log, sin, cos, atan)")

    @property
    def nonlinear_count(self) -> int:
        """Number of operations that get a variable (an upper bound of the lifted variables)."""
        return sum(n.kind not in ("x", "u", "const", "add") for n in self.nodes)


# -- affine forms and inequalities --------------------------------------------------------------
class _Lift:
    """Affine forms ``a0 + a . v`` over the variables ``v = (xi, z)``, the inequalities
    ``l(v) <= 0`` collected so far, and the boxes of the variables."""

    def __init__(self, nvar: int, r: int):
        self.nvar, self.r = nvar, r
        self.used = r
        self.centre = np.zeros(nvar)  # z_j = centre_j + radius_j eta_j (eta in [-1, 1])
        self.rows: list[np.ndarray] = []
        self.consts: list[float] = []

    def var(self, lo: float, hi: float) -> tuple[float, np.ndarray]:
        """A new variable ranging over ``[lo, hi]``, as an affine form in its unit factor."""
        j = self.used
        self.used += 1
        a = np.zeros(self.nvar)
        mid = 0.5 * (lo + hi)
        a[j] = np.nextafter(max(hi - mid, mid - lo), np.inf)
        return mid, a

    def le(self, c0: float, a: np.ndarray, scale: float) -> None:
        """Record ``c0 + a . v <= 0`` made sound by the margin ``MARGIN * scale``."""
        self.rows.append(a)
        self.consts.append(c0 - MARGIN * (1.0 + scale))


def _mag(*xs) -> float:
    return float(max(abs(float(x)) for x in xs))


class Bounded(NamedTuple):
    """An affine form ``a0 + a . v`` over the lifted variables and an interval containing its
    values.

    Attributes
    ----------
    form : tuple of (float, ndarray)
        ``(a0, a)``.
    lo, hi : float
        The bounds of its values.
    """

    form: tuple[float, np.ndarray]
    lo: float
    hi: float


def relax_unary(kind: str, lift: _Lift, arg: Bounded, res: Bounded, k: float = 0.0,
                tangents: int = 1) -> str:
    """Inequalities linking ``z = phi(a)`` for the affine forms of ``arg`` (argument, in
    ``[arg.lo, arg.hi]``) and ``res`` (result, in ``[res.lo, res.hi]``); returns the case used
    (``"convex"``, ``"concave"``, ``"generic"`` or ``"point"``).  ``kind`` is a name of
    :data:`_UNARY` or ``"pow"`` (exponent ``k``); a convex or concave operation gets its
    secant and ``tangents`` tangents (1: at the midpoint; 3: also at both ends)."""
    lo, hi, zlo, zhi = arg.lo, arg.hi, res.lo, res.hi
    m2 = 0.0  # bound of |phi''| (generic case only)
    if kind == "pow":
        ki = int(k)
        phi = (lambda a: a ** ki, lambda a: ki * a ** (ki - 1),
               lambda a: ki * (ki - 1) * a ** (ki - 2))
        if ki % 2 == 0 or lo >= 0:
            shape = "convex"
        elif hi <= 0:
            shape = "concave"
        else:
            shape = "generic"
        m2 = ki * (ki - 1) * max(abs(lo), abs(hi)) ** (ki - 2)
    else:
        phi = _UNARY[kind]
        if kind == "exp":
            shape = "convex"
        elif kind in ("log", "sqrt"):
            shape = "concave"
        elif kind == "recip":
            shape = "convex" if lo > 0 else "concave"
        elif kind == "atan":  # convex on a <= 0, concave on a >= 0
            shape = "convex" if hi <= 0 else "concave" if lo >= 0 else "generic"
            m2 = _ATAN_M2
        else:  # sin, cos: phi'' = -phi
            s = ia.sin(Ival(lo, hi)) if kind == "sin" else ia.cos(Ival(lo, hi))
            shape = "convex" if s.hi <= 0 else "concave" if s.lo >= 0 else "generic"
            m2 = float(max(abs(s.lo), abs(s.hi)))
    if hi - lo <= 1e-12 * (1.0 + abs(lo) + abs(hi)):
        return "point"  # the interval of z is the relaxation
    f, df, _ = phi
    a0, a = arg.form
    z0, z = res.form
    fl, fu = f(lo), f(hi)
    slope = (fu - fl) / (hi - lo)
    scale_base = _mag(fl, fu, zlo, zhi)
    mid = 0.5 * (lo + hi)
    if shape in ("convex", "concave"):
        sgn = 1.0 if shape == "convex" else -1.0
        # secant: sgn z <= sgn (fl + slope (a - lo))
        lift.le(sgn * (z0 - fl - slope * (a0 - lo)), sgn * (z - slope * a),
                scale_base + abs(slope) * _mag(lo, hi))
        for t in ((mid,) if tangents == 1 else (lo, mid, hi)):
            if kind in ("log", "sqrt", "recip") and t == 0.0:
                continue
            ft, dt = f(t), df(t)
            if not (np.isfinite(ft) and np.isfinite(dt)):
                continue
            # tangent: sgn z >= sgn (ft + dt (a - t))
            lift.le(sgn * (ft + dt * (a0 - t) - z0), sgn * (dt * a - z),
                    scale_base + abs(ft) + abs(dt) * _mag(lo, hi))
        return shape
    # generic: tangent at the midpoint and secant, widened by the curvature bound m2
    rho = 0.5 * (hi - lo)
    fm, dm = f(mid), df(mid)
    wt = np.nextafter(0.5 * m2 * rho * rho, np.inf)
    ws = np.nextafter(0.125 * m2 * (hi - lo) ** 2, np.inf)
    sc = scale_base + abs(fm) + (abs(dm) + abs(slope)) * _mag(lo, hi) + m2 * rho * rho
    tan0, sec0 = fm + dm * (a0 - mid), fl + slope * (a0 - lo)
    lift.le(z0 - tan0 - wt, z - dm * a, sc)       # z <= tangent + wt
    lift.le(tan0 - wt - z0, dm * a - z, sc)       # z >= tangent - wt
    lift.le(z0 - sec0 - ws, z - slope * a, sc)    # z <= secant + ws
    lift.le(sec0 - ws - z0, slope * a - z, sc)    # z >= secant - ws
    return "generic"


def relax_product(lift: _Lift, A: Bounded, B: Bounded, Z: tuple[float, np.ndarray]) -> None:
    """The four McCormick inequalities of ``z = a b`` (``Z`` the affine form of ``z``) over
    the box ``[A.lo, A.hi] x [B.lo, B.hi]`` of the factors."""
    (a0, a), alo, ahi = A
    (b0, b), blo, bhi = B
    z0, z = Z
    sc = _mag(alo, ahi) * _mag(blo, bhi) * 4 + _mag(alo, ahi) + _mag(blo, bhi)
    # z >= al b + bl a - al bl ;  z >= au b + bu a - au bu
    for (p, q) in ((alo, blo), (ahi, bhi)):
        lift.le(p * b0 + q * a0 - p * q - z0, p * b + q * a - z, sc)
    # z <= au b + bl a - au bl ;  z <= al b + bu a - al bu
    for (p, q) in ((ahi, blo), (alo, bhi)):
        lift.le(z0 - p * b0 - q * a0 + p * q, z - p * b - q * a, sc)


@dataclass
class Relaxation:
    """Outcome of :func:`relax`: affine forms of the outputs over ``v = (xi, z)``
    (``const + coef @ v``), the inequalities ``rows @ v + consts <= 0`` and the number of
    variables used."""

    const: np.ndarray
    coef: np.ndarray
    rows: np.ndarray
    consts: np.ndarray
    nvar: int


def relax(graph: Factorable, c: np.ndarray, G: np.ndarray,
          box: tuple[np.ndarray, np.ndarray], u: np.ndarray, tangents: int = 1) -> Relaxation:
    """Lifted polyhedral relaxation of ``graph`` over ``{c + G xi : |xi| <= 1}`` (with its
    constraints kept by the caller) and the box ``box = (lo, hi)`` containing the set;
    ``tangents`` as for :func:`relax_unary`."""
    lo, hi = box
    n, r = G.shape
    nvar = r + graph.nonlinear_count
    lift = _Lift(nvar, r)
    forms: list = []  # per node: (known value or None, affine form, interval)
    for node in graph.nodes:
        kind = node.kind
        if kind == "x":
            j = int(node.param)
            a = np.zeros(nvar)
            a[:r] = G[j]
            forms.append((None, (float(c[j]), a), Ival(lo[j], hi[j])))
            continue
        if kind in ("u", "const"):
            v = float(u[int(node.param)]) if kind == "u" else float(node.param)
            forms.append((v, None, Ival(v)))
            continue
        if kind == "add":
            known = all(forms[i][0] is not None for _, i in node.args)
            if known:
                v = node.param + sum(w * forms[i][0] for w, i in node.args)
                iv = Ival(node.param)
                for w, i in node.args:
                    iv = iv + Ival(w) * forms[i][2]
                forms.append((v, None, iv))
                continue
            a0, a = float(node.param), np.zeros(nvar)
            iv = Ival(node.param)
            for w, i in node.args:
                kv, form, ivi = forms[i]
                if kv is not None:
                    a0 += w * kv
                else:
                    a0 += w * form[0]
                    a = a + w * form[1]
                iv = iv + Ival(w) * ivi
            forms.append((None, (a0, a), iv))
            continue
        args = [forms[i] for i in node.args]
        if kind == "mul":
            (ka, fa, ia_), (kb, fb, ib_) = args
            iv = ia_ * ib_
            if ka is not None and kb is not None:
                forms.append((ka * kb, None, iv))
            elif ka is not None or kb is not None:  # a known factor: linear
                w, form = (ka, fb) if ka is not None else (kb, fa)
                forms.append((None, (w * form[0], w * form[1]), iv))
            else:
                Z = lift.var(float(iv.lo), float(iv.hi))
                relax_product(lift, Bounded(fa, float(ia_.lo), float(ia_.hi)),
                              Bounded(fb, float(ib_.lo), float(ib_.hi)), Z)
                forms.append((None, Z, iv))
            continue
        (ka, fa, ia_), = args
        if kind == "pow":
            iv = ia_ ** int(node.param)
        else:
            iv = _IVAL[kind](ia_)
        if ka is not None:
            value = ka ** int(node.param) if kind == "pow" else _UNARY[kind][0](ka)
            forms.append((float(value), None, iv))
            continue
        Z = lift.var(float(iv.lo), float(iv.hi))
        relax_unary(kind, lift, Bounded(fa, float(ia_.lo), float(ia_.hi)),
                    Bounded(Z, float(iv.lo), float(iv.hi)), node.param, tangents)
        forms.append((None, Z, iv))
    m = len(graph.outputs)
    const, coef = np.zeros(m), np.zeros((m, nvar))
    for i, o in enumerate(graph.outputs):
        kv, form, _ = forms[o]
        if kv is not None:
            const[i] = kv
        else:
            const[i], coef[i] = form
    rows = np.array(lift.rows).reshape(-1, nvar)
    return Relaxation(const, coef, rows, np.array(lift.consts), lift.used)


def relax_checked(graph, c, G, box, u, k=None, tangents: int = 1) -> Relaxation:
    """:func:`relax` (over the box ``box = (lo, hi)``), a domain violation (``1/0``, ``log``
    or ``sqrt`` of a non-positive interval) reported as :class:`Diverged` at step ``k``."""
    try:
        with np.errstate(divide="raise", invalid="raise"):
            return relax(graph, c, G, box, u, tangents)
    except (SetError, FloatingPointError) as exc:
        raise Diverged(f"polyhedral relaxation of {graph.what} left its domain over the "
                       f"estimate's box ({exc})", step=k) from None


def lifted_set(rel: Relaxation, A: np.ndarray, b: np.ndarray):
    """Generators over ``(xi, z, s)`` and constraints of the lifted constrained zonotope:
    the old constraints ``A xi = b`` and one equality per inequality with its slack
    ``s = s_max (1 + sigma) / 2``; returns ``(coef, A, b)`` with ``coef`` the output
    generators (m x (nvar + n_ineq)) whose centre is ``rel.const``."""
    nv = rel.nvar
    R = rel.rows[:, :nv]
    q = R.shape[0]
    # s_max = max over the variable box of -(R v + const): Sum |R| - const (rounded up)
    smax = np.abs(R).sum(axis=1) - rel.consts
    smax = np.nextafter(np.maximum(smax, 0.0) * (1 + 8 * np.finfo(float).eps * (nv + 2)),
                        np.inf)
    half = 0.5 * smax
    nc, r = A.shape
    A_new = np.zeros((nc + q, nv + q))
    A_new[:nc, :r] = A
    A_new[nc:, :nv] = R
    A_new[nc:, nv:] = np.diag(half)
    b_new = np.concatenate([b, -rel.consts - half])
    # rows on one scale, exactly (by powers of two): largest entry in [1, 2)
    s = np.abs(A_new[nc:]).max(axis=1, initial=0.0)
    s = np.exp2(np.floor(np.log2(np.where(s > 0, s, 1.0))))
    A_new[nc:] /= s[:, None]
    b_new[nc:] /= s
    coef = np.hstack([rel.coef[:, :nv], np.zeros((rel.coef.shape[0], q))])
    return coef, A_new, b_new
