"""Prediction strategies of the zonotopic families: how the dynamics map the current set.

A strategy encloses the image of a zonotope ``S = (c, G)`` under the noise-free dynamics as

``{f(x, u) : x in S}  subset  J S + d + R``,

returned as ``(J, d, Rgen)``: a matrix ``J`` applied to the set, an offset ``d`` and the
generators ``Rgen`` of an extra zonotope ``R`` (``n x 0`` when the map is exact).  The family
loops of :mod:`observers.families` use it in place of ``A S + B u``; nothing else in a loop
depends on the system being linear.

* :class:`LinearPrediction`: ``J = A``, ``d = B u``, no ``R`` (exact).
* :class:`ConservativeLinearisation`: at the centre ``p = c``, ``J = df/dx(p, u)``,
  ``d = f(p, u) - J p`` plus the centre of ``R``, an enclosure of the Lagrange remainder
  over the set (Hessian bounded over its interval hull); this is the on-the-fly
  conservative linearisation CORA uses for nonlinear systems (Althoff, ARCH 2021, Sec. 3;
  Althoff, Stursberg, Buss, CDC 2008).  A box leaving the model's domain ends the run as
  ``diverged`` with the step and the state named.
* :class:`MeanValuePrediction`: the mean-value extension (Rego, Raffo, Scott, Raimondo,
  Automatica 111, 2020, Sec. 4): ``f(x) in f(p) + J(B) (x - p)`` with the *interval*
  Jacobian ``J(B)`` over the box ``B`` of ``S``, enclosed as ``mid J(B)`` applied to the set
  plus the box ``rad J(B) |x - p|``.  It needs first derivatives only (enclosed by the
  system's ``jacobian_bounds``).
"""

from __future__ import annotations

import numpy as np

from .errors import Diverged
from .kernels import step as kernel_step
from .kernels import switch
from .sets.reduction import step_reduction


def _matvec(A: np.ndarray, x: np.ndarray) -> np.ndarray:
    """``A @ x`` summed in index order where the kernels are compiled (the same bits under
    every BLAS kernel up to :data:`~observers.kernels.step.FIXED_ORDER_MAX_DIM`)."""
    if not switch.use_compiled():
        return A @ x
    return kernel_step.matvec(np.ascontiguousarray(A, dtype=np.float64),
                              np.ascontiguousarray(x, dtype=np.float64))


class LinearPrediction:
    """``x+ = A x + B u`` (exact)."""

    exact = True

    def __init__(self, A: np.ndarray, B: np.ndarray):
        self.A, self.B = A, B
        self._none = np.zeros((A.shape[0], 0))

    def __call__(self, c, G, u, k):
        return self.A, self.B @ u, self._none

    def jacobian(self, c: np.ndarray) -> np.ndarray:
        """State matrix at ``c``: ``A``."""
        return self.A


def box_generators(r: np.ndarray) -> np.ndarray:
    """Generators ``diag(r)`` of the non-zero radii ``r``."""
    nz = np.flatnonzero(r > 0)
    R = np.zeros((r.shape[0], nz.size))
    R[nz, np.arange(nz.size)] = r[nz]
    return R


def quadratic_forms(Gr: np.ndarray, idx: np.ndarray, Hm: np.ndarray) -> np.ndarray:
    """``M_i = Gr' Q_i Gr`` (n x r x r), ``Q_i`` the symmetric matrix of the second derivatives
    ``Hm_e`` at ``idx = (i, j, k)`` (``j <= k``; a mixed entry fills ``(j, k)`` and ``(k, j)``)."""
    n, r = Gr.shape
    i, j, k = idx.T
    # each entry's weighted outer product added to its output i, entry after entry: a sum in
    # index order, the same bits under every BLAS kernel (a product with the scatter matrix
    # went to BLAS, whose fused multiply-adds differ between kernels)
    terms = (np.where(j != k, 1.0, 0.5) * Hm)[:, None, None] * (
        Gr[j][:, :, None] * Gr[k][:, None, :])
    P = np.zeros((n, r, r))
    np.add.at(P, i, terms)
    return P + P.transpose(0, 2, 1)


def quadratic_enclosure(M: np.ndarray, as_box: bool):
    """Enclosure of ``{1/2 beta' M_i beta : beta in [-1, 1]^r}``: a zonotope ``(c, Z)``, or
    with ``as_box`` the centre and radius ``(c, rad)`` of its interval hull.

    Squares ``beta_l^2`` lie in ``[0, 1]`` (centre 1/2, generator 1/2), products
    ``beta_l beta_m`` in ``[-1, 1]``: the quadratic map of a zonotope (Althoff, Stursberg,
    Buss, CDC 2008), as CORA computes the second-order error.  ``Z`` has ``r (r+1)/2``
    columns.
    """
    r = M.shape[1]
    dg = np.einsum("ill->il", M)
    c = 0.25 * dg.sum(axis=1)
    if as_box:
        adg = np.abs(dg).sum(axis=1)
        return c, 0.25 * adg + 0.5 * (np.abs(M).sum(axis=(1, 2)) - adg)
    lu, mu = np.triu_indices(r, 1)
    return c, np.hstack([0.25 * dg, 0.5 * (M[:, lu, mu] + M[:, mu, lu])])


class ConservativeLinearisation:
    """Linearise at the centre of the current set and add the enclosed Lagrange remainder.

    The remainder ``f(x) - f(p) - J (x - p) = 1/2 (x - p)' H(xi) (x - p)`` is enclosed as in
    CORA (tensor order 2, error order 1): the Hessian is bounded over the interval hull of
    the set (``system.hessian``, sound by contract), the deviation set ``S - p`` is reduced
    to order 1 with the observer's reduction, its quadratic map with the midpoint Hessian is
    computed exactly (:func:`quadratic_enclosure`) and the Hessian's radius adds the box
    ``1/2 sum rad(H_ijk) d_j d_k`` (``d``: radius of the hull).  ``remainder="box"`` appends
    the interval hull of that zonotope (n generators); ``"zonotope"`` keeps it
    (``n (n+1)/2`` generators per step, CORA's exact choice).
    """

    exact = False

    def __init__(self, system, reduction, remainder: str = "box"):
        self.system = system
        # the order-one reduction feeds the next step: the kernels' deterministic axes
        self.reduction = step_reduction(reduction)
        self.as_box = remainder == "box"
        self._u = np.zeros(system.nu)

    def jacobian(self, c: np.ndarray) -> np.ndarray:
        """``df/dx`` at ``c`` with the input of the latest prediction (FRad-B's and CZN-B's
        gain: CORA takes the Jacobian at the predicted centre)."""
        return self.system.jacobian(c, self._u)[0]

    def _order_one(self, G: np.ndarray) -> np.ndarray:
        """Order-1 enclosure of ``G`` (CORA's error order 1): the observer's own reduction to
        order one, so a deviation set of at most ``n`` generators is kept as it is (exact) and
        a larger one goes whole into the strategy's box (with :class:`PCA`, the box in its
        deterministic principal axes: LAPACK's eigenvectors of ``G G'``, used before 0.7.0,
        depend on the BLAS kernel where eigenvalues repeat or nearly repeat, and moved the
        18-30-tank rows of ARCH Table 6 by up to 6 % between kernels; since 0.13.0 the axes
        of the step kernels, :meth:`PCA.in_step`: LAPACK's SVD of distinct but close
        singular values still moved them by up to 7.6 %)."""
        return self.reduction.reduce(G, 1.0)

    def __call__(self, c, G, u, k):
        self._u = u
        r = np.abs(G).sum(axis=1)
        lo, hi = np.nextafter(c - r, -np.inf), np.nextafter(c + r, np.inf)
        try:
            idx, Hlo, Hhi = self.system.hessian(lo, hi, u)
        except Diverged as exc:
            raise type(exc)(str(exc), step=k) if exc.step is None else exc from None
        J, _ = self.system.jacobian(c, u)
        fc = self.system.f(c, u)
        eps = np.finfo(float).eps
        Jc = _matvec(J, c)
        rad = 4 * eps * (np.abs(fc) + np.abs(Jc))  # rounding of f(c) and J c
        cq, Z = np.zeros(c.size), np.zeros((c.size, 0))
        if len(idx):
            idx = np.asarray(idx, dtype=int).reshape(-1, 3)
            Hm, Hr = 0.5 * (Hlo + Hhi), np.nextafter(0.5 * (Hhi - Hlo), np.inf)
            M = quadratic_forms(self._order_one(G), idx, Hm)
            cq, Z = quadratic_enclosure(M, self.as_box)
            if self.as_box:  # the hull's radius joins the remainder box
                rad, Z = rad + Z, np.zeros((c.size, 0))
            i, j, kk = idx.T
            d = np.nextafter(r, np.inf)
            np.add.at(rad, i, np.where(j == kk, 0.5, 1.0) * Hr * d[j] * d[kk])
            # rounding of the quadratic map (sums of about n^2 terms): a relative margin
            mag = np.abs(cq) + np.abs(Z).sum(axis=1) + rad
            rad = np.nextafter(rad + 8 * eps * (c.size ** 2 + len(i)) * mag, np.inf)
        if not (np.all(np.isfinite(rad)) and np.all(np.isfinite(J)) and np.all(np.isfinite(Z))):
            raise Diverged("non-finite linearisation", step=k)
        return J, fc + cq - Jc, np.hstack([Z, box_generators(rad)])


class MeanValuePrediction:
    """Mean-value extension with the interval Jacobian over the box of the set (Rego et al.)."""

    exact = False

    def __init__(self, system):
        self.system = system
        self._u = np.zeros(system.nu)

    jacobian = ConservativeLinearisation.jacobian

    def __call__(self, c, G, u, k):
        self._u = u
        r = np.abs(G).sum(axis=1)
        lo, hi = np.nextafter(c - r, -np.inf), np.nextafter(c + r, np.inf)
        try:
            Jlo, Jhi = self.system.jacobian_bounds(lo, hi, u)
        except Diverged as exc:
            raise type(exc)(str(exc), step=k) if exc.step is None else exc from None
        Jm = 0.5 * (Jlo + Jhi)
        Jr = np.nextafter(0.5 * (Jhi - Jlo), np.inf)
        # f(x) - f(c) in J(B)(x - c) subset Jm (x - c) + [-Jr |x - c|, Jr |x - c|], |x - c| <= r
        rem = np.nextafter(_matvec(Jr, r) * (1 + 4 * np.finfo(float).eps * r.size), np.inf)
        Jc = _matvec(Jm, c)
        d = self.system.f(c, u) - Jc
        # rounding of f(c) and of the centre terms: a relative ulp margin on d
        rem = rem + 4 * np.finfo(float).eps * (np.abs(d) + np.abs(Jc))
        return Jm, d, box_generators(rem)


def prediction_for(system, reduction, strategy: str = "lagrange", remainder: str = "box"):
    """The prediction strategy of ``system``: exact for linear systems, else ``strategy``
    (``"lagrange"``: :class:`ConservativeLinearisation` with ``remainder`` ``"box"`` or
    ``"zonotope"``; ``"mean-value"``: :class:`MeanValuePrediction`).  ``reduction`` is the
    observer's order-reduction strategy (:mod:`observers.sets.reduction`)."""
    if getattr(system, "is_linear", True):
        return LinearPrediction(np.asarray(system.A, dtype=float),
                                np.asarray(system.B, dtype=float))
    if strategy == "mean-value":
        return MeanValuePrediction(system)
    return ConservativeLinearisation(system, reduction, remainder)
