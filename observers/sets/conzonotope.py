"""Constrained zonotopes ``{c + G xi : A xi = b, ||xi||_inf <= 1}`` (Scott et al., 2016)."""

from __future__ import annotations

import numpy as np

from ..errors import SetError
from ..lp import HullLP, box_feasible, split_free
from . import conzono_ops as ops
from ._arrays import (
    CentreGenerators,
    direction,
    frozen,
    linear_map_matrix,
    matrix,
    strips,
    vector,
)
from .interval import Interval
from .reduction import Reduction, check_order, get_reduction
from .zonotope import Zonotope


class ConZonotope(CentreGenerators):
    """Constrained zonotope with centre ``c`` (n), generators ``G`` (n x r) and constraints
    ``A xi = b`` (``A``: nc x r, ``b``: nc).

    Interval hulls and support values are computed by linear programs (all directions at once
    by a batched dual simplex, HiGHS for any LP it does not finish) and are guaranteed outer
    bounds: they are evaluated from a dual point, never from the primal objective value (see
    :mod:`observers.lp.hull`).  Generators that appear in no constraint are left out of the
    LPs (their contribution ``sum |G_ij|`` is added exactly).

    A set may carry a shared LP solver (:meth:`with_solver`, used by the observers so that the
    HiGHS fallback of each step reuses one model instead of building one per set).
    The solver is not part of the value: it changes neither equality nor results beyond
    solver tolerance, and the bounds are sound whichever basis it starts from.  The interval
    hull is computed once per set and cached.
    """

    __slots__ = ("_c", "_G", "_A", "_b", "_solver", "_hull")
    __array_ufunc__ = None

    def __init__(self, c, G=None, A=None, b=None):
        c = vector(c, "constrained zonotope centre")
        n = c.shape[0]
        G = np.zeros((n, 0)) if G is None else matrix(G, "constrained zonotope generators", rows=n)
        r = G.shape[1]
        if A is None:
            if b is not None and np.size(b) > 0:
                raise SetError("constraint offsets b given without constraint matrix A")
            A, b = np.zeros((0, r)), np.zeros(0)
        else:
            A = matrix(A, "constraint matrix A", cols=r)
            b = np.zeros(0) if b is None and A.shape[0] == 0 else b
            if b is None:
                raise SetError("constraint matrix A given without offsets b")
            b = vector(b, "constraint offsets b", dim=A.shape[0]) if A.shape[0] else np.zeros(0)
        self._c, self._G, self._A, self._b = frozen(c), frozen(G), frozen(A), frozen(b)
        self._solver: HullLP | None = None
        self._hull: Interval | None = None

    @classmethod
    def trusted(cls, c, G, A, b, solver: HullLP | None = None) -> ConZonotope:
        """Build from float arrays of matching shapes without validation (hot loops).

        The arrays are frozen in place; the caller must not keep writing to them.
        """
        obj = object.__new__(cls)
        for a in (c, G, A, b):
            a.setflags(write=False)
        obj._c, obj._G, obj._A, obj._b = c, G, A, b
        obj._solver, obj._hull = solver, None
        return obj

    @classmethod
    def from_zonotope(cls, Z: Zonotope) -> ConZonotope:
        """The zonotope ``Z`` without constraints."""
        return cls(Z.c, Z.G)

    @classmethod
    def from_set(cls, S) -> ConZonotope:
        """``S`` (ConZonotope, Zonotope or Interval) as a constrained zonotope."""
        if isinstance(S, ConZonotope):
            return S
        if isinstance(S, Interval):
            S = Zonotope.from_interval(S)
        if isinstance(S, Zonotope):
            return cls.from_zonotope(S)
        raise SetError(f"cannot convert {type(S).__name__} to a constrained zonotope")

    def with_solver(self, solver: HullLP) -> ConZonotope:
        """The same set, computing its LPs with the shared solver ``solver``."""
        if not isinstance(solver, HullLP):
            raise SetError(f"solver must be a HullLP, got {type(solver).__name__}")
        return ConZonotope.trusted(self._c, self._G, self._A, self._b, solver)

    def arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """``(c, G, A, b)`` (read-only arrays)."""
        return self._c, self._G, self._A, self._b

    @property
    def doubles(self) -> int:
        """Floating-point values that define the set: ``c, G, A, b`` (memory)."""
        return self._c.size + self._G.size + self._A.size + self._b.size

    def box_form(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """``(c, G, A, b)`` of the set as ``{c + G xi : A xi = b, |xi|_inf <= 1}`` (as
        :meth:`Zonotope.box_form <observers.sets.Zonotope.box_form>`, with the constraints)."""
        return self.arrays()

    # -- data -----------------------------------------------------------------------------
    c = property(lambda self: self._c, doc="Centre.")
    G = property(lambda self: self._G, doc="Generator matrix (n x r).")
    A = property(lambda self: self._A, doc="Constraint matrix (nc x r).")
    b = property(lambda self: self._b, doc="Constraint offsets (nc).")

    @property
    def num_constraints(self) -> int:
        """Number nc of equality constraints."""
        return self._A.shape[0]

    # -- operations -------------------------------------------------------------------------
    def __add__(self, other) -> ConZonotope:
        if isinstance(other, Interval):
            other = Zonotope.from_interval(other)
        if isinstance(other, Zonotope):
            other = ConZonotope.from_zonotope(other)
        if isinstance(other, ConZonotope):
            if other.dim != self.dim:
                raise SetError(f"cannot add sets of dimensions {self.dim} and {other.dim}")
            A = np.block(
                [
                    [self._A, np.zeros((self.num_constraints, other.num_generators))],
                    [np.zeros((other.num_constraints, self.num_generators)), other._A],
                ]
            )
            return ConZonotope(
                self._c + other._c, np.hstack([self._G, other._G]), A,
                np.concatenate([self._b, other._b]),
            )
        if hasattr(other, "interval") and not isinstance(other, np.ndarray):
            return NotImplemented
        v = vector(other, "translation vector", dim=self.dim)
        return ConZonotope(self._c + v, self._G, self._A, self._b)

    __radd__ = __add__

    def __rmatmul__(self, M) -> ConZonotope:
        M = linear_map_matrix(M, self.dim)
        return ConZonotope(M @ self._c, M @ self._G, self._A, self._b)

    def __neg__(self) -> ConZonotope:
        return ConZonotope(-self._c, -self._G, self._A, self._b)

    def intersect(self, Y, R=None) -> ConZonotope:
        """Exact generalised intersection ``{x in self : R x in Y}`` (``R`` defaults to the
        identity; ``Y`` a ConZonotope, Zonotope or Interval of dimension ``R.shape[0]``)."""
        Y = ConZonotope.from_set(Y)
        if R is None and Y.dim != self.dim:
            raise SetError(f"cannot intersect sets of dimensions {self.dim} and {Y.dim}")
        R = np.eye(self.dim) if R is None else matrix(R, "intersection map R", cols=self.dim)
        if R.shape[0] != Y.dim:
            raise SetError(f"intersection map R has {R.shape[0]} rows but the set has "
                           f"dimension {Y.dim}")
        return ConZonotope.trusted(*ops.intersect(
            (self._c, self._G, self._A, self._b), (Y._c, Y._G, Y._A, Y._b), R))

    def intersect_strips(self, C, y, sigma, gain=None) -> ConZonotope:
        """Exact intersection with the strips ``|C x - y| <= sigma`` (one per row of ``C``).

        ``gain`` (n x m, default zero) only chooses the parametrisation of the result (CORA's
        ``intersectStrip`` for constrained zonotopes); the set is the same for every gain.
        """
        C, y, sigma = strips(C, y, sigma, self.dim)
        m = C.shape[0]
        Lam = np.zeros((self.dim, m)) if gain is None else matrix(
            gain, "strip gain", rows=self.dim, cols=m)
        return ConZonotope.trusted(*ops.intersect_strips(
            (self._c, self._G, self._A, self._b), C, y, sigma, Lam))

    def intersect_measurement(self, C, y, V, gain=None) -> ConZonotope:
        r"""Exact ``{x in self : y - C x in V}`` for a noise zonotope ``V`` (``Zonotope`` or
        ``Interval`` of dimension ``C.shape[0]``).

        ``gain`` (n x m, default zero) only chooses the parametrisation: centre
        ``c + L (y - C c - c_V)``, generators ``[(I - L C) G, -L G_V]`` (Alanwar et al. 2022,
        Prop. 3); the set is the same for every gain.

        Notes
        -----
        For :math:`\mathcal{Z} = \langle c, G, A_c, b_c \rangle` and
        :math:`\mathcal{V} = \langle c_V, G_V \rangle`, a new factor :math:`\xi_v` and one
        constraint row per output (Alanwar et al. 2022, eqs. (23)-(25)):

        .. math::

            \mathcal{Z} \cap \{x \mid y - C x \in \mathcal{V}\} =
            \left\langle c + L (y - C c - c_V),\
              \begin{bmatrix} (I - L C) G & -L G_V \end{bmatrix},\
              \begin{bmatrix} A_c & 0 \\ C G & G_V \end{bmatrix},\
              \begin{bmatrix} b_c \\ y - C c - c_V \end{bmatrix} \right\rangle .

        Every point :math:`c + G \xi` with :math:`y - C (c + G \xi) = c_V + G_V \xi_v` equals
        :math:`c + G \xi + L (y - C c - c_V - C G \xi - G_V \xi_v)`, which is why the gain
        :math:`L` does not change the set; :math:`L = 0` is the generalised intersection of
        Scott et al. (2016, Prop. 1).
        """
        C = matrix(C, "output matrix C", cols=self.dim)
        m = C.shape[0]
        y = vector(y, "measurement y", dim=m)
        if isinstance(V, Interval):
            V = Zonotope.from_interval(V)
        if not isinstance(V, Zonotope) or V.dim != m:
            raise SetError(f"noise set V must be a Zonotope or Interval of dimension {m}")
        L = np.zeros((self.dim, m)) if gain is None else matrix(
            gain, "measurement gain", rows=self.dim, cols=m)
        return ConZonotope.trusted(*ops.intersect_measurement(
            (self._c, self._G, self._A, self._b), C, y, (V.c, V.G), L))

    def reduce(self, order: float, method: str | Reduction = "girard", per: str = "state"
               ) -> ConZonotope:
        r"""Enclosure by reducing the lifted zonotope ``([c; -b], [G; A])`` with the zonotope
        strategy ``method`` (Scott et al. 2016, Sec. 4.3).  ``per="state"`` (CORA's
        ``reduce``): at most ``order * n + nc`` generators; ``per="lifted"``: at most
        ``order * (n + nc)``.  The number of constraints does not change; see
        :meth:`reduce_constraints`.  A strategy with a variant for lifted zonotopes (a
        ``lifted()`` method: :meth:`.reduction.PCA.lifted`, wider clusters of singular values)
        reduces with that variant.

        Notes
        -----
        The constraints are appended to the generators, the lifted zonotope in
        :math:`\mathbb{R}^{n + n_c}` is reduced and split again (after dropping all-zero
        rows and columns):

        .. math::

            \begin{bmatrix} \hat G \\ \hat A_c \end{bmatrix}
            = \operatorname{reduce}\left(\begin{bmatrix} G \\ A_c \end{bmatrix},\
            \rho\right), \qquad
            \langle c, G, A_c, b_c \rangle \subseteq \langle c, \hat G, \hat A_c, b_c \rangle,

        with the lifted order :math:`\rho = \max(1, (o\, n + n_c) / (n + n_c))` for
        ``per="state"`` and :math:`\rho = o` for ``per="lifted"`` (:math:`o` = ``order``).
        The enclosure holds because :math:`\langle [c; -b_c], [G; A_c] \rangle` is
        enclosed by the reduced lifted zonotope, and the set is its slice where the last
        :math:`n_c` coordinates are zero.
        """
        check_order(order)
        if per not in ops.ORDER_BASES:
            raise SetError(f"order must be counted per 'state' or per 'lifted' dimension, "
                           f"got {per!r}")
        return ConZonotope.trusted(*ops.lifted_reduce(
            self._c, self._G, self._A, self._b, float(order), get_reduction(method), per))

    def reduce_constraints(self, max_constraints: int, method: str = "fold") -> ConZonotope:
        r"""Enclosure keeping the ``max_constraints`` newest (last) constraints; the older ones
        are eliminated by the named strategy: ``"fold"`` (rescaling, then a least-squares
        shear of generators and kept constraints) or ``"frobenius"`` (Frobenius-optimal gain
        on the generators); see :mod:`observers.sets.conzono_ops`.

        Notes
        -----
        With the oldest rows :math:`A_S \xi = b_S` to drop and the kept rows
        :math:`A_R \xi = b_R`, ``"fold"`` first shrinks the box of :math:`\xi` to the bounds
        :math:`[l, u]` the constraints imply (exact substitution
        :math:`\xi = m + \operatorname{diag}(r) \xi'`, :math:`m = (u + l)/2`,
        :math:`r = (u - l)/2`), then adds :math:`\Lambda (b_S - A_S \xi) = 0` and
        :math:`N (b_S - A_S \xi) = 0` (true on the set) and drops the folded rows:

        .. math::

            \langle c, G, A_c, b_c \rangle \subseteq
            \langle c + \Lambda b_S,\ G - \Lambda A_S,\ A_R - N A_S,\ b_R - N b_S \rangle,
            \qquad
            \begin{bmatrix} \Lambda \\ N \end{bmatrix}
            = \begin{bmatrix} G \\ A_R \end{bmatrix} A_S^\top (A_S A_S^\top)^{+} .

        ``"frobenius"`` keeps :math:`A_R, b_R` unchanged (:math:`N = 0`, no rescaling) with
        :math:`\Lambda = G A_S^\top (A_S A_S^\top)^{+}`, the minimiser of
        :math:`\|G - \Lambda A_S\|_F`.
        """
        if isinstance(max_constraints, bool) or not isinstance(
                max_constraints, (int, np.integer)) or max_constraints < 0:
            raise SetError(f"max_constraints must be a non-negative integer, "
                           f"got {max_constraints!r}")
        try:
            eliminate = ops.CONSTRAINT_ELIMINATIONS[method]
        except (KeyError, TypeError):
            known = ", ".join(sorted(ops.CONSTRAINT_ELIMINATIONS))
            raise SetError(f"unknown constraint elimination {method!r} (known: {known})"
                           ) from None
        return ConZonotope.trusted(*eliminate(
            self._c, self._G, self._A, self._b, int(max_constraints)))

    def normalize_constraints(self) -> ConZonotope:
        """The same set with every constraint row scaled to unit largest entry (exact)."""
        return ConZonotope.trusted(*ops.normalize_constraints(self._c, self._G, self._A,
                                                               self._b))

    def rescale(self) -> ConZonotope:
        """The same set with the generator box shrunk to the bounds implied by the constraints
        (interval constraint propagation; exact)."""
        return ConZonotope.trusted(*ops.rescale(self._c, self._G, self._A, self._b))

    def compact(self) -> ConZonotope:
        """The same set without all-zero constraints and generators."""
        return ConZonotope.trusted(*ops.compact_zeros(self._c, self._G, self._A, self._b))

    def _lp(self) -> HullLP:
        return self._solver if self._solver is not None else HullLP()

    def interval(self) -> Interval:
        """Guaranteed interval hull from 2n LPs sharing one feasible set (cached)."""
        if self._hull is not None:
            return self._hull
        if self.num_constraints == 0:
            self._hull = Zonotope(self._c, self._G).interval()
            return self._hull
        self._hull = Interval(*self._lp().hull(self._c, self._G, self._A, self._b))
        return self._hull

    def support(self, d) -> float | np.ndarray:
        """Guaranteed upper bound of the support function (vector ``d`` or one per column)."""
        d = direction(d, self.dim)
        D = d.reshape(self.dim, -1)
        if self.num_constraints == 0:
            vals = D.T @ self._c + np.abs(self._G.T @ D).sum(axis=0)
        else:
            Gc, Ac, Gf = split_free(self._G, self._A)
            lp_vals = self._lp().maximize_many((Gc.T @ D).T, Ac, self._b)
            t0 = D.T @ self._c
            t1 = np.abs(Gf.T @ D).sum(axis=0)
            slack = (self.dim + Gf.shape[1] + 4) * np.finfo(float).eps * (
                np.abs(D.T) @ np.abs(self._c) + t1 + np.abs(lp_vals))
            vals = t0 + t1 + lp_vals + slack
        return float(vals[0]) if d.ndim == 1 else vals

    def contains(self, x, tol: float = 0.0) -> bool:
        """Membership of ``x`` up to ``tol`` (infinity norm in state space); one LP."""
        x = vector(x, "point", dim=self.dim)
        M = np.vstack([self._G, self._A])
        t = np.concatenate([x - self._c, self._b])
        tols = np.concatenate([np.full(self.dim, tol), np.zeros(self.num_constraints)])
        return box_feasible(M, t, tols)

    def to_zonotope(self, method: str = "frobenius") -> Zonotope:
        """Enclosing zonotope: all constraints eliminated with the named strategy (see
        :meth:`reduce_constraints`; ``"frobenius"`` by default)."""
        E = self.reduce_constraints(0, method)
        return Zonotope(E._c, E._G)

    # -- value semantics --------------------------------------------------------------------
    def __eq__(self, other) -> bool:
        return isinstance(other, ConZonotope) and all(
            a.shape == b.shape and np.array_equal(a, b)
            for a, b in zip(
                (self._c, self._G, self._A, self._b),
                (other._c, other._G, other._A, other._b),
                strict=True,
            )
        )

    def __hash__(self) -> int:
        return hash(tuple((a.shape, a.tobytes()) for a in (self._c, self._G, self._A, self._b)))

    def __repr__(self) -> str:
        return (
            f"ConZonotope(dim={self.dim}, generators={self.num_generators}, "
            f"constraints={self.num_constraints})"
        )
