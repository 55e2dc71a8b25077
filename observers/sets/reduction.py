"""Zonotope order-reduction strategies.

A strategy is an object with a ``name`` and ``reduce(G, order) -> G_reduced`` acting on a
generator matrix (the centre of a zonotope is never changed by these methods).  Strategies are
looked up by name with :func:`get_reduction`, so observers receive them as plain option values
(``reduction="pca"``) and users may register their own with :func:`register_reduction`.

Both built-in methods follow the definition used by CORA (``@zonotope/reduce.m``, methods ``girard``
and ``pca``):

1. all-zero generator columns are dropped (a column whose 1-norm is at most
   ``ZERO_COLUMN_RTOL`` = 1e-13 of the largest counts as zero: the rounding noise of a column
   that is zero in exact arithmetic, zero on one BLAS kernel and 1e-19 on another);
2. nothing else happens if the zonotope has at most ``n * order`` generators;
3. otherwise ``floor(n * (order - 1))`` generators are kept unchanged (in their original order)
   and the remaining ones, those with the smallest ``||g||_1 - ||g||_inf`` (ties broken by the
   original column index, i.e. a stable sort; values within ``TIE_RTOL`` = 1e-9, relative, of
   the threshold, or within ``ZERO_COLUMN_RTOL`` of the largest 1-norm of a generator, count as
   ties, so that rounding cannot order generators that tie in exact arithmetic), are replaced
   by a box of ``n`` generators;
4. the result is ``[G_unreduced, G_box]``.

``girard`` encloses the reduced generators by an axis-aligned box (Girard, HSCC 2005);
``pca`` encloses them by a box aligned with the principal axes of ``[G_red, -G_red]``
(Kopetzki et al., CDC 2017) in a deterministic basis (below); ``pca-cora`` does the same in the
basis CORA computes (:class:`CoraPCA`: the LAPACK singular vectors of the covariance matrix),
for reproducing CORA's published tables.

Deterministic PCA basis.  The principal axes are the left singular vectors of ``G_red``.  Where
singular values repeat (the boxes of ``W`` or ``X0`` give ties; a rank-deficient block gives a
repeated zero) the singular vectors of that cluster are any orthonormal basis of its subspace,
and LAPACK returns one that depends on the BLAS kernel (AVX2 and AVX-512 kernels pick
different ones), while the box, and so the set, depends on the basis.  :func:`principal_axes`
therefore makes the basis a function of the subspace only:

1. the SVD is taken of ``G_red`` itself (not of ``G_red G_red'``, which squares the condition
   number and leaves the axes of small singular values to rounding), through the triangular
   factor of a QR decomposition of ``G_red'`` when there are more generators than dimensions;
2. singular values within ``CLUSTER_RTOL * s_max`` of their neighbour form a cluster;
3. for each cluster, from its orthogonal projector ``P = V V'`` (independent of the basis
   ``V``), the basis is built by pivoted Cholesky: take the coordinate ``j`` with the largest
   ``P_jj`` (the lowest index among those within ``PIVOT_RTOL`` of the largest, so rounding
   cannot flip a tie), the axis ``P e_j / sqrt(P_jj)``, deflate ``P`` and repeat.

For a single singular value this only fixes the sign (largest component positive).  For the
lifted zonotopes of constrained zonotopes the cluster tolerance is wider (``1e-3 * s_max``,
:meth:`PCA.lifted`) on purpose: an axis is determined by the matrix only to
``eps * s_max / gap``, and axes of values closer than that moved with the BLAS kernel by enough
for those filters to amplify (see :data:`observers.kernels.step.LIFTED_CLUSTER_RTOL`).

Deterministic box.  A width of the PCA box below ``BOX_ZERO_RTOL`` (1e-12) of the widest is
set to exactly zero: the width along an axis the reduced generators do not span is zero in
exact arithmetic and rounding noise in floating point (exactly zero on one kernel, a column
later dropped, and 1e-19 on another), which changed the generator count and so every later
choice.  The sliver given up is at most 1e-12 of the box, inside the 1e-9 membership
tolerance of the containment checks.  The tolerances are defined with the compiled kernel that
shares them (:mod:`observers.kernels.step`).
"""

from __future__ import annotations

import math
from typing import Protocol

import numpy as np

from ..errors import SetError
from ..kernels import step as kernel_step
from ..kernels import switch
from ..kernels.step import (
    BOX_ZERO_RTOL,
    CLUSTER_RTOL,
    LIFTED_CLUSTER_RTOL,
    PIVOT_RTOL,
    TIE_RTOL,
    ZERO_COLUMN_RTOL,
)

#: the cluster tolerance of the data-driven observers' lifted reductions (defined with the
#: compiled kernel, :data:`observers.kernels.step.DATA_DRIVEN_CLUSTER_RTOL`, which says why)
DATA_DRIVEN_CLUSTER_RTOL = kernel_step.DATA_DRIVEN_CLUSTER_RTOL


class Reduction(Protocol):
    """Interface of an order-reduction strategy.

    ``reduce`` trusts ``order`` (a finite number >= 1): the public entries validate it once
    (:meth:`.Zonotope.reduce`, :func:`split_generators`, an observer's ``order`` option), so
    that the hot loops that call a strategy at every step do not.
    """

    name: str

    def reduce(self, G: np.ndarray, order: float) -> np.ndarray:
        """Return generators of an enclosing zonotope with at most ``n * order`` columns."""
        ...


def split_generators(G: np.ndarray, order: float) -> tuple[np.ndarray, np.ndarray] | None:
    """Split ``G`` into (unreduced, to-be-reduced) generators, or ``None`` if no reduction.

    Zero columns are dropped first.  The to-be-reduced block is returned sorted by the metric
    ``||g||_1 - ||g||_inf`` (stable), the unreduced block in the original column order.
    """
    check_order(order)
    keep, red, _ = _split(G, order)
    return keep, red


def _split(G: np.ndarray, order: float) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """:func:`split_generators` (``order`` trusted) plus ``|red|`` (``None`` if nothing is
    reduced).

    One pass of ``|G|`` serves the zero-column test (a column is zero iff its 1-norm is), the
    metric and the box of the reduced generators; a matrix without zero columns is not copied.
    """
    absG = np.abs(G)
    norm1 = absG.sum(axis=0)
    top = float(norm1.max()) if norm1.size else 0.0
    # columns at the rounding noise of a zero count as zero (ZERO_COLUMN_RTOL); a non-finite
    # column is kept, for the caller to see
    nonzero = ~(norm1 <= (ZERO_COLUMN_RTOL * top if math.isfinite(top) else 0.0))
    if not nonzero.all():
        G, absG, norm1 = G[:, nonzero], absG[:, nonzero], norm1[nonzero]
    n, r = G.shape
    if r <= n * order:
        return G, G[:, :0], None
    n_unreduced = int(math.floor(n * (order - 1)))
    n_reduced = r - n_unreduced
    picked, kept = _smallest(norm1 - absG.max(axis=0), n_reduced, top)
    return G[:, kept], G[:, picked], absG[:, picked]


def _smallest(h: np.ndarray, k: int, scale: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Indices of the ``k`` smallest entries of ``h`` in the order of a stable sort, and the
    other indices in increasing order, where values within ``TIE_RTOL`` (relative) of the
    ``k``-th smallest, or within ``ZERO_COLUMN_RTOL`` of ``scale``, count as equal and go by
    index (ties of exact arithmetic that the last bits of the BLAS kernel would otherwise
    order); found with a partition and a sort of the ``k`` picked entries only (``k`` is
    usually small).

    ``scale`` (the largest 1-norm of the generators) floors the band at the rounding noise of
    the largest generator: the metric of a generator along a coordinate axis is zero in exact
    arithmetic and, where its other entries are the rounding noise of a zero, 1e-18 or 0 by
    the BLAS kernel; relative to a threshold of zero the band was empty, and that noise picked
    the generators (VolMin-B on the 2-state vehicle at order 4 moved by 1.6 % between
    kernels, issue 37)."""
    if k >= h.size:
        return np.argsort(h, kind="stable"), np.arange(0)
    thr = np.partition(h, k - 1)[k - 1]  # the k-th smallest value
    if thr != thr:  # NaN among the k smallest: the plain stable sort decides
        ranked = np.argsort(h, kind="stable")
        return ranked[:k], np.sort(ranked[k:])
    band = max(TIE_RTOL * abs(thr), ZERO_COLUMN_RTOL * scale)
    sel = h < thr - band
    ties = np.flatnonzero(np.abs(h - thr) <= band)  # equal values go by index
    sel[ties[: k - np.count_nonzero(sel)]] = True
    picked = np.flatnonzero(sel)
    return picked[np.argsort(h[picked], kind="stable")], np.flatnonzero(~sel)


def use_compiled() -> bool:
    """Whether the built-in reductions run the compiled kernel
    :func:`observers.kernels.step.reduce` (:func:`observers.kernels.switch.use_compiled`: numba
    installed and not disabled by ``SETOBS_NUMBA=0``)."""
    return switch.use_compiled()


def _compiled(G: np.ndarray, order: float, method: str,
              cluster_rtol: float = CLUSTER_RTOL, jacobi_dim: int = 0) -> np.ndarray | None:
    """The compiled reduction ``method`` (a name of
    :data:`observers.kernels.step.REDUCTIONS`) of ``G`` (``order`` trusted; principal axes
    by Jacobi up to ``jacobi_dim`` rows), or ``None`` where the numpy path must decide (numba
    off, not a float matrix, or a non-finite entry)."""
    if not switch.use_compiled() or G.dtype != np.float64 or G.ndim != 2:
        return None
    out, ok = kernel_step.reduce(G, float(order), kernel_step.REDUCTIONS[method], cluster_rtol,
                               PIVOT_RTOL, jacobi_dim)
    return out if ok else None


def check_order(order: float) -> None:
    """Reject orders below 1 (a zonotope in R^n needs at least n generators to be reduced to)."""
    if not isinstance(order, (int, float, np.integer, np.floating)) or not math.isfinite(order):
        raise SetError(f"zonotope order must be a finite number >= 1, got {order!r}")
    if order < 1:
        raise SetError(f"zonotope order must be >= 1, got {order}")


class Girard:
    """Replace the reduced generators by their axis-aligned interval hull."""

    name = "girard"

    def reduce(self, G: np.ndarray, order: float) -> np.ndarray:
        out = _compiled(G, order, "girard")
        if out is not None:
            return out
        keep, red, abs_red = _split(G, order)
        if abs_red is None:
            return keep
        n, k = keep.shape
        out = np.zeros((n, k + n))
        out[:, :k] = keep
        out[:, k:].flat[:: n + 1] = abs_red.sum(axis=1)  # the diagonal box
        return out


def _cluster_basis(V: np.ndarray) -> np.ndarray:
    """A basis of ``span(V)`` (orthonormal columns ``V``) that depends only on the subspace."""
    P = V @ V.T
    out = np.empty_like(V)
    for i in range(V.shape[1]):
        d = np.diag(P)
        j = int(np.flatnonzero(d >= (1.0 - PIVOT_RTOL) * d.max())[0])
        axis = P[:, j] / math.sqrt(d[j])
        out[:, i] = axis
        P = P - np.outer(axis, axis)
    return out


def principal_axes(red: np.ndarray, cluster_rtol: float = CLUSTER_RTOL) -> np.ndarray:
    """Principal axes (n x n, orthonormal) of the generators ``red``, in a deterministic basis
    where singular values repeat (within ``cluster_rtol`` of the largest; see the module
    docstring)."""
    n, r = red.shape
    if r > n:  # G_red = R' Q' (QR of G_red'): same left singular vectors and values as R',
        # an n x n matrix, without forming the r x r right factor (3-10x faster when r >> n)
        U, s, _ = np.linalg.svd(np.linalg.qr(red.T, mode="r").T)
    else:
        U, s, _ = np.linalg.svd(red, full_matrices=True)
    s = np.concatenate([s, np.zeros(n - s.size)])
    tol = cluster_rtol * s[0]
    starts = np.flatnonzero(np.concatenate([[True], s[:-1] - s[1:] > tol]))
    ends = np.append(starts[1:], n)
    return np.hstack([_cluster_basis(U[:, a:b]) for a, b in zip(starts, ends, strict=True)])


def jacobi_principal_axes(red: np.ndarray, cluster_rtol: float = CLUSTER_RTOL) -> np.ndarray:
    """:func:`principal_axes` with the singular vectors from one-sided Jacobi (plain loops, no
    LAPACK: the same bits under every BLAS kernel) up to
    :data:`~observers.kernels.step.JACOBI_MAX_DIM` rows, as the compiled step kernels take
    them (``observers.kernels.step.principal_axes``, compiled where numba is, the same
    loops in Python otherwise); LAPACK's above.  For a caller whose axes feed back into the
    next step's generators: where singular values lie 1e-6 to 1e-4 apart (the identical
    tanks), LAPACK's kernel-dependent rounding turns the axes by ``eps / gap``, and the
    filter compounds it."""
    if red.shape[0] > kernel_step.JACOBI_MAX_DIM:
        return principal_axes(red, cluster_rtol)
    return kernel_step.principal_axes(np.ascontiguousarray(red, dtype=float), cluster_rtol,
                                      PIVOT_RTOL, kernel_step.JACOBI_MAX_DIM)


def _box_in_basis(keep: np.ndarray, red: np.ndarray, U: np.ndarray,
                  zero_rtol: float = 0.0) -> np.ndarray:
    """``[keep, U diag(w)]`` with ``w = |U' red| 1``: the reduced generators ``red`` replaced
    by their box in the orthonormal basis ``U`` (the widths at most ``zero_rtol`` of the
    largest set to exactly zero: the rounding noise of an axis ``red`` does not span)."""
    box = np.abs(U.T @ red).sum(axis=1)
    if zero_rtol > 0:
        box = np.where(box > zero_rtol * box.max(), box, 0.0)
    return np.hstack([keep, U * box])


class PCA:
    """Replace the reduced generators by a box aligned with their principal components
    (:func:`principal_axes`: deterministic where singular values repeat, i.e. lie within
    ``cluster_rtol`` of the largest; :data:`observers.kernels.step.CLUSTER_RTOL` by default,
    exact ties).
    """

    name = "pca"

    def __init__(self, cluster_rtol: float = CLUSTER_RTOL, jacobi_dim: int = 0):
        self.cluster_rtol = cluster_rtol
        #: up to this many rows the axes come from one-sided Jacobi (:meth:`in_step`)
        self.jacobi_dim = jacobi_dim

    def lifted(self, cluster_rtol: float = LIFTED_CLUSTER_RTOL) -> PCA:
        """The strategy for the lifted zonotopes of constrained zonotopes: clusters at least
        as wide as ``cluster_rtol`` (:data:`observers.kernels.step.LIFTED_CLUSTER_RTOL`, whose
        comment says why)."""
        return PCA(max(self.cluster_rtol, cluster_rtol), self.jacobi_dim)

    def in_step(self) -> PCA:
        """The strategy as the step kernels compute it: the axes by one-sided Jacobi up to
        :data:`~observers.kernels.step.JACOBI_MAX_DIM` rows (:func:`jacobi_principal_axes`,
        the same bits under every BLAS kernel), for a reduction whose result feeds the next
        step (the order-one deviation set of a linearisation's remainder)."""
        return PCA(self.cluster_rtol, kernel_step.JACOBI_MAX_DIM)

    def reduce(self, G: np.ndarray, order: float) -> np.ndarray:
        out = _compiled(G, order, "pca", self.cluster_rtol, self.jacobi_dim)
        if out is not None:
            return out
        keep, red, abs_red = _split(G, order)
        if abs_red is None:
            return keep
        # the covariance of [red, -red] is proportional to red @ red.T (zero mean by
        # symmetry): its eigenvectors are the left singular vectors of red
        axes = (jacobi_principal_axes(red, self.cluster_rtol) if self.jacobi_dim
                else principal_axes(red, self.cluster_rtol))
        return _box_in_basis(keep, red, axes, BOX_ZERO_RTOL)


def lifted_reduction(strategy: Reduction, **options) -> Reduction:
    """The strategy to reduce the lifted zonotope of a constrained zonotope with: the
    strategy's own variant for lifted zonotopes where it has one (a ``lifted(**options)``
    method: :meth:`PCA.lifted`), else the strategy itself."""
    lifted = getattr(strategy, "lifted", None)
    return lifted(**options) if callable(lifted) else strategy


def step_reduction(strategy: Reduction) -> Reduction:
    """The strategy as the step kernels compute it, for a reduction inside a step whose result
    feeds the next one: the strategy's ``in_step()`` variant where it has one
    (:meth:`PCA.in_step`), else the strategy itself."""
    in_step = getattr(strategy, "in_step", None)
    return in_step() if callable(in_step) else strategy


def cora_principal_axes(red: np.ndarray) -> np.ndarray:
    """Principal axes (n x n, orthonormal columns, largest variance first) of the generators
    ``red`` exactly as CORA's ``pca`` reduction obtains them: the left singular vectors, as
    LAPACK's ``gesvd`` returns them, of the sample covariance of the 2 r points
    ``[red, -red]`` (each point an observation, the sample mean subtracted, divided by
    ``2 r - 1``).

    This is the same subspace decomposition as :func:`principal_axes` where the singular values
    are distinct (up to the sign of each axis, which does not change the box), but inside a
    cluster of repeated singular values the basis is whatever the Householder
    bidiagonalisation and QR iteration of ``gesvd`` produce from the rounding of the covariance
    matrix (CORA calls MATLAB's / GNU Octave's ``svd``, whose default LAPACK driver is
    ``gesvd``).  It therefore depends on the BLAS kernel, and the covariance squares the
    condition number; use it to compare with CORA's numbers, :class:`PCA` everywhere else.
    """
    from scipy.linalg import svd  # LAPACK's gesvd (numpy's svd calls gesdd)

    pts = np.hstack([red, -red]).T  # 2r observations of n variables
    dev = pts - pts.mean(axis=0)
    cov = (dev.T @ dev) / (pts.shape[0] - 1)
    U, _, _ = svd(cov, lapack_driver="gesvd", check_finite=False)
    return U


class CoraPCA:
    """PCA reduction in CORA's basis (:func:`cora_principal_axes`): the box of the reduced
    generators ``U' G_red`` mapped back by ``U`` (Kopetzki, Schürmann, Althoff, CDC 2017, as
    CORA's ``reduce(Z, 'pca', order)`` implements it).

    Not kernel-independent (see :func:`cora_principal_axes`), and it always runs the numpy path
    (no compiled kernel); it serves the paper-table configurations that reproduce CORA's
    published rows (``reduction: pca-cora``), the regression subset keeps :class:`PCA`.
    """

    name = "pca-cora"

    def reduce(self, G: np.ndarray, order: float) -> np.ndarray:
        keep, red, abs_red = _split(np.asarray(G, dtype=float), order)
        if abs_red is None:
            return keep
        return _box_in_basis(keep, red, cora_principal_axes(red))


_REDUCTIONS: dict[str, Reduction] = {"girard": Girard(), "pca": PCA(), "pca-cora": CoraPCA()}


def register_reduction(strategy: Reduction) -> Reduction:
    """Make ``strategy`` available by its ``name`` (e.g. for YAML configs)."""
    _REDUCTIONS[strategy.name] = strategy
    return strategy


def get_reduction(method: str | Reduction) -> Reduction:
    """Return the strategy for ``method`` (a registered name or a strategy object)."""
    if isinstance(method, str):
        try:
            return _REDUCTIONS[method]
        except KeyError:
            known = ", ".join(sorted(_REDUCTIONS))
            raise SetError(f"unknown reduction method '{method}' (known: {known})") from None
    if not hasattr(method, "reduce"):
        raise SetError(f"reduction method must be a name or have .reduce(G, order), got {method!r}")
    return method


def compiled_name(strategy: Reduction) -> str | None:
    """The name under which the compiled kernels (:mod:`observers.kernels.step`) compute
    ``strategy`` (the built-in :class:`Girard` and :class:`PCA`), ``None`` for any other
    strategy."""
    return strategy.name if type(strategy) in (Girard, PCA) else None


def reduction_names() -> list[str]:
    """Names of the registered reduction strategies."""
    return sorted(_REDUCTIONS)
