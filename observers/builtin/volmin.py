"""Volume-minimising strip-based observers: VolMin-A (Alamo et al. 2005) and VolMin-B
(Bravo et al. 2006).

Both intersect the predicted zonotope with the measurement strips one after the other (as
CORA), with no offline design:

* **VolMin-A** (intersection method I): per strip the gain of least volume, an LP over the
  exact volume expression (:func:`observers.numerics.volmin.volume_lp_gain`).  The LP enumerates all
  n- and (n-1)-subsets of the generators, ``C(r, n) + C(r, n-1)`` of them, which explodes with
  the generator count r (Althoff & Rath 2021 could only run it on the 2-state vehicle).  The
  observer therefore checks at construction time the largest count it can meet,
  ``r_max = max(r_X0, floor(n * order) + r_W) + ny - 1`` generators at the last strip of a
  step, against the option ``max_subsets`` and **refuses** (raises
  :class:`~observers.errors.DesignFailed`, reported as ``noGain`` in tables, with the counts
  in the message) instead of hanging.  Lower ``order`` or raise ``max_subsets`` to run it.
* **VolMin-B** (intersection method III): per strip the candidate of least ``det(T T')``
  among the r + 1 zonotopes of Bravo et al., all scored at once
  (:func:`observers.numerics.volmin.bravo_scores`).  The choice depends only on the
  generators, not on the measured values, so the radii do not depend on the noise realisation.
"""

from __future__ import annotations

import decimal
import math

import numpy as np

from ..errors import DesignFailed
from ..families import Linearised, PerStripObserver, StripBasedObserver
from ..kernels import StepKernel
from ..numerics.linalg import first_best
from ..numerics.volmin import (
    ZERO_PROJECTION,
    bravo_ratios,
    bravo_scores_gram,
    bravo_update,
    gram_update,
    leverage_update,
    leverages,
    null_basis,
    projections_update,
    subset_count,
    volume_lp_gain,
)
from ..options import Integer
from ..registry import register


def _scientific(count: int) -> str:
    """``count`` in 3-digit scientific notation, also beyond the float range (e.g. ``1.2e+430``)."""
    return format(decimal.Decimal(count), ".3g")


@register(
    "VolMin-A", family="strip", set_type="zonotope", ready_for_control=False,
    reference="Alamo, Bravo, Camacho, Automatica 41(6), 2005, Sec. 6.2",
)

class VolMinA(Linearised, PerStripObserver):
    r"""Strip by strip with the volume-minimising gain of Alamo et al. (one LP per strip).

    Intersection method I with, for each strip :math:`j`, the gain of least volume (VolMin-A
    of Table 2 of Althoff & Rath 2021):

    .. math::

        \lambda^j = \arg\min_{\lambda \in \mathbb{R}^n}
        \operatorname{vol}\left((I - \lambda C_j)\,c + \lambda y_{k,j} \oplus
        [(I - \lambda C_j)\,G,\ \lambda\sigma_j]\,\mathcal{B}^{r+1}\right),

    a linear program (:func:`~observers.numerics.volmin.volume_lp_gain`).

    Options
    -------
    max_subsets : int
        Largest number of generator subsets (``C(r, n) + C(r, n-1)``) the volume LP may
        enumerate; beyond it the observer refuses at construction (``DesignFailed``).
    """

    OPTIONS = {"max_subsets": Integer(200_000, low=1)}

    def design(self) -> None:
        super().design()
        n, ny = self.C.shape[1], self.C.shape[0]
        r_x0 = int(np.count_nonzero(np.any(self.X0.G != 0, axis=0)))
        r_max = max(r_x0, math.floor(n * self.order) + self.E.shape[1]) + ny - 1
        count = subset_count(r_max, n)
        if count > self.options["max_subsets"]:
            raise DesignFailed(
                f"VolMin-A refused: up to {r_max} generators in R^{n} give {_scientific(count)} "
                f"generator subsets for the volume LP, more than max_subsets="
                f"{self.options['max_subsets']} (lower 'order' or raise 'max_subsets')"
            )

    def strip_gain(self, G: np.ndarray, i: int) -> np.ndarray:
        return volume_lp_gain(G, self.C[i], self.sigma[i])


@register(
    "VolMin-B", family="strip", set_type="zonotope", ready_for_control=False,
    reference="Bravo, Alamo, Camacho, IEEE TAC 51(7), 2006, Sec. III.B",
)
class VolMinB(Linearised, StripBasedObserver):
    r"""Strip by strip, choosing Bravo's candidate zonotope of least det(T T') (online).

    Intersection method III (Sec. 3.1 of Althoff & Rath 2021, VolMin-B of its Table 2): for
    strip :math:`i` with row :math:`C_i` and :math:`a = C_iG`, candidate :math:`j \ge 1`
    removes generator :math:`g^j` (where :math:`a_j \ne 0`),

    .. math::

        \lambda_j = \frac{g^j}{a_j}, \qquad
        c(j) = c + \lambda_j\,(y_{k,i} - C_ic),

        G(j) = (I - \lambda_jC_i)\,G \text{ with column } j \text{ replaced by }
        \sigma_i\lambda_j,

    candidate 0 is :math:`(c, G)` unchanged, and the step keeps

    .. math::

        j^\ast = \arg\min_{0 \le j \le r} \det\left(G(j)\,G(j)^T\right),

    a volume measure of the candidate, from the leverages of the generators in ``O(n r)``
    per strip (:func:`~observers.numerics.volmin.bravo_ratios`; the Gram matrix's adjugate,
    :func:`~observers.numerics.volmin.bravo_scores_gram`, where ``G G'`` is badly
    conditioned).
    """

    KERNEL = StepKernel.BRAVO

    def design(self) -> None:
        super().design()
        self.output_changed()

    def output_changed(self) -> None:
        """Null-space bases of the rows of ``C`` (per step for a nonlinear output)."""
        self._bases = [null_basis(row) for row in self.C]

    def kernel_inputs(self):
        return {"bases": np.stack(self._bases), "zero_projection": ZERO_PROJECTION}

    def intersect(self, c, G, y):
        """Strip after strip, the candidates scored from the leverages ``g_j' (G G')^-1 g_j``
        (computed once per step, then updated in ``O(n r)`` per strip: :func:`leverages`,
        :func:`bravo_ratios`, :func:`leverage_update`); where ``G G'`` is badly conditioned,
        from the Gram matrix (:func:`bravo_scores_gram`).  ``G G'`` itself is updated in
        ``O(n^2)`` per strip (:func:`gram_update`), and the projections ``a = c G`` of all
        strips are one product ``C G`` per step, carried to the later strips in ``O(m r)``
        where a strip takes a candidate (:func:`projections_update`)."""
        M = G @ G.T
        lev = leverages(G, M)
        P = self.C @ G
        for i, row in enumerate(self.C):
            a = P[i]
            if lev is None:
                j = first_best(bravo_scores_gram(G, M, row, self.sigma[i], self._bases[i], a))
            else:
                j = first_best(bravo_ratios(a, lev[1], float(row @ M @ row), self.sigma[i]))
                # None after a strip of zero width (G G' singular): the Gram scores take
                # over for the rest of the step
                lev = leverage_update(*lev, G, row, self.sigma[i], j)
            M = gram_update(M, G, row, self.sigma[i], j)
            if j:
                P[i + 1:] = projections_update(P[i + 1:], self.C[i + 1:], G[:, j - 1], a,
                                               self.sigma[i], j)
            c, G = bravo_update(c, G, row, y[i], self.sigma[i], j, a)
        return c, G
