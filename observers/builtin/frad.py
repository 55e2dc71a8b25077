"""F-radius observers: FRad-A, FRad-B (strip-based) and FRad-C (set propagation)."""

from __future__ import annotations

import numpy as np

from ..families import AllStripsObserver, Linearised, PerStripObserver, PropagationObserver
from ..kernels import StepKernel, by_option
from ..numerics.frad import alamo_frad_gain, alamo_frad_strips, combastel_gain, wang_frad_gain
from ..options import Choice
from ..registry import register


@register(
    "FRad-A", family="strip", set_type="zonotope", ready_for_control=False,
    reference="Alamo, Bravo, Camacho, Automatica 41(6), 2005, Sec. 6",
)
class FRadA(Linearised, PerStripObserver):
    r"""Strip by strip with the closed-form F-radius gain of Alamo et al. (online).

    Intersection method I (Sec. 3.1 of Althoff & Rath 2021, FRad-A of its Table 2) with, for
    strip :math:`j` and the current generators :math:`G`, the gain of least F-radius
    :math:`\|[(I - \lambda C_j)G,\ \lambda\sigma_j]\|_F`:

    .. math::

        \lambda^j = \frac{GG^TC_j^T}{C_jGG^TC_j^T + \sigma_j^2}.
    """

    KERNEL = StepKernel.ALAMO

    def strip_gain(self, G: np.ndarray, i: int) -> np.ndarray:
        return alamo_frad_gain(G, self.C[i], self.sigma[i])

    def intersect(self, c, G, y):
        """All strips at once on ``G G'`` (:func:`alamo_frad_strips`; the same set as the
        strip-by-strip loop of :class:`PerStripObserver` with :meth:`strip_gain`)."""
        return alamo_frad_strips(c, G, self.C, y, self.sigma)


class WangGainVariant:
    """Mixin: the all-strips F-radius gain of Wang et al. with CORA's or the textbook prior.

    Option ``variant``: ``"cora"`` (default) reproduces CORA, which computes the gain from
    the *predicted* set's ``G G'`` and applies ``A`` (and adds ``E E'``) once more:
    ``R = A G G' A' + E E'``.  ``"textbook"`` uses the predicted covariance itself,
    ``R = G G'``, as in the paper (where G is the previous estimate's, so that
    ``A G G' A' + E E'`` is the prediction).  Used by FRad-B and CZN-B.
    """

    OPTIONS = {"variant": Choice("cora", ("cora", "textbook"))}

    def wang_gain(self, c: np.ndarray, G: np.ndarray) -> np.ndarray:
        """Gain (n x m) for the predicted set ``(c, G)``; for a nonlinear system ``A`` is the
        Jacobian at the predicted centre ``c`` (as CORA, whose stored results this reproduces
        to 1e-9)."""
        return wang_frad_gain(G @ G.T, self.gain_state_matrix(c), self.C, self.E, self.F)

    def gain_state_matrix(self, c: np.ndarray) -> np.ndarray | None:
        """The ``A`` the gain applies to the predicted set with centre ``c``: ``"cora"`` the
        Jacobian at ``c`` (``A`` itself on a linear system), ``"textbook"`` none."""
        return self.prediction.jacobian(c) if self.options["variant"] == "cora" else None

    def kernel_state_matrix(self, c: np.ndarray) -> np.ndarray:
        """The compiled gain's ``A`` on a nonlinear system: :meth:`gain_state_matrix` (the
        latest linearisation where ``"textbook"``'s gain reads none)."""
        A = self.gain_state_matrix(c)
        return self.A if A is None else A


@register(
    "FRad-B", family="strip", set_type="zonotope", ready_for_control=False,
    reference="Wang, Puig, Cembrano, Automatica 93, 2018",
)
class FRadB(Linearised, WangGainVariant, AllStripsObserver):
    r"""All strips at once with the F-radius gain of Wang et al. (online).

    Intersection method II (Sec. 3.1 of Althoff & Rath 2021, FRad-B of its Table 2) with the
    Kalman-like gain of least F-radius, :math:`P = GG^T` of the predicted set:

    .. math::

        \Lambda_k = RC^T\left(CRC^T + FF^T\right)^{-1}, \qquad
        R = \begin{cases} APA^T + EE^T & \text{variant "cora"},\\
        P & \text{variant "textbook"}. \end{cases}

    Options
    -------
    variant : {"cora", "textbook"}
        See :class:`WangGainVariant` (``"cora"``: CORA's double application of ``A``).
    """

    KERNEL = by_option("variant", cora=StepKernel.WANG_CORA, textbook=StepKernel.WANG)

    def gain(self, c: np.ndarray, G: np.ndarray) -> np.ndarray:
        return self.wang_gain(c, G)


@register(
    "FRad-C", family="propagation", set_type="zonotope", ready_for_control=True,
    reference="Combastel, Automatica 55, 2015, Sec. 4.3",
)
class FRadC(Linearised, PropagationObserver):
    r"""Set propagation with the online F-radius gain of Combastel (Kalman-like).

    Eq. 8 of Althoff & Rath 2021 with, at every step, the gain that minimises the F-radius of
    :math:`\mathcal{S}_{k+1}` for the current set :math:`\mathcal{S}_k = c_k \oplus
    G_k\mathcal{B}^r` (FRad-C, their Sec. 3.2):

    .. math::

        L_k = AG_kG_k^TC^T\left(CG_kG_k^TC^T + FF^T\right)^{-1}.
    """

    KERNEL = StepKernel.COMBASTEL

    def gain(self, c: np.ndarray, G: np.ndarray) -> np.ndarray:
        return combastel_gain(G @ G.T, self.A, self.C, self.F)
