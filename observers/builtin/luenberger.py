"""Observers with an offline Luenberger gain: PRad-E and Nom-G (set propagation) and Hinf-G
(interval observer).

PRad-E and Nom-G run the shared loop of :class:`~observers.families.PropagationObserver`
(``S+ = (A - L C) S + B u + L y + (-L) V + W``, then order reduction), Hinf-G the interval
observer of :class:`~observers.families.IntervalObserver`; each with a constant gain designed
once in the constructor (:mod:`observers.numerics.luenberger`), cached on disk, or passed as
``gain=`` (e.g. CORA's stored gains).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..families import ConstantGainPropagationObserver, IntervalObserver
from ..numerics.lmi import cora_bisection_end
from ..numerics.luenberger import (
    HINF_G_RICCATI_ABOVE,
    check_modes,
    hinf_g_design,
    nom_g_design,
    prad_e_design,
)
from ..offline import OfflineGain
from ..options import Choice, Number
from ..registry import register


class _OfflineGainPropagation(OfflineGain, ConstantGainPropagationObserver):
    """Set propagation with ``L = L`` from :class:`OfflineGain`."""


@register(
    "PRad-E", family="propagation", set_type="zonotope", ready_for_control=True,
    reference="Wang, Zhou, Puig, Cembrano, Wang, CCC 2017, eq. 17 (Althoff & Rath 2021, Sec. 3.2)",
)
class PRadE(_OfflineGainPropagation):
    r"""Set propagation with the offline P-radius gain of Wang et al. (max trace P, beta as CORA).

    Eq. 8 of Althoff & Rath 2021 with the constant gain of their Sec. 3.2 (PRad-E, citing
    eq. 17 of Wang et al.), :math:`\beta \in (0, 1)` the contraction of the P-radius: the
    gain :math:`L = P^{-1}Y` of the LMI of
    :func:`~observers.numerics.luenberger.prad_e_design` (maximal :math:`\operatorname{tr}P`;
    its equations below), then

    .. math::

        \mathcal{S}_{k+1} = (A - LC)\,\mathcal{S}_k \oplus Bu_k \oplus Ly_k \oplus
        (-L)\,\mathcal{V} \oplus \mathcal{W}.

    Options
    -------
    beta : float or None
        Contraction factor of the P-radius in (0, 1).  ``None`` (default) takes the value at
        which CORA's bisection (tolerance 0.01) stops, 0.9921875: the LMI is feasible for
        every beta, so CORA's bisection always ends there (see
        :func:`~observers.numerics.lmi.cora_bisection_end`).
    solver : {"auto", "sdp", "riccati"}
        ``"sdp"``: maximise ``trace(P)`` with cvxpy + Clarabel (as CORA, with SDPT3).
        ``"riccati"``: the same unique optimum in closed form from a discrete Riccati
        equation, in milliseconds also for large systems where the SDP takes minutes (see
        :func:`~observers.numerics.luenberger.prad_e_design`).  ``"auto"`` (default):
        ``"riccati"`` when the noise set V is full-dimensional, else ``"sdp"``.
    gain : array, optional
        Use this gain instead of designing one.
    """

    OPTIONS = {"beta": Number(None, low=0, high=1, low_open=True, high_open=True, allow_none=True),
               "solver": Choice("auto", ("auto", "sdp", "riccati"))}

    @property
    def beta(self) -> float:
        """The contraction factor used by the design."""
        b = self.options["beta"]
        return cora_bisection_end(0.0, 1.0, 0.01) if b is None else float(b)

    def design_gain(self) -> np.ndarray:
        s = self.system
        check_modes(s, self.name, rate=np.sqrt(self.beta))
        return prad_e_design(s.A, s.C, s.W.G, s.V.G, self.beta, self.options["solver"]).L


@register(
    "Nom-G", family="propagation", set_type="zonotope", ready_for_control=True,
    reference="Wang, Puig, Cembrano, Automatica 93, 2018, eq. 36 (Althoff & Rath 2021, Sec. 3.2)",
)
class NomG(_OfflineGainPropagation):
    r"""Set propagation with the nominal gain of decay rate mu (analytic centre of its LMI).

    Eq. 8 of Althoff & Rath 2021 with the constant gain of their Sec. 3.2 (Nom-G, citing
    eq. 36 of Wang et al.), which makes the noise-free error decay at the rate
    :math:`\mu \in (0, 1]`, i.e. :math:`(A - LC)^TP(A - LC) \prec \mu P`:

    .. math::

        L = P^{-1}Y, \qquad
        \begin{bmatrix} \mu P & (PA - YC)^T \\ PA - YC & P \end{bmatrix} \succ 0,
        \quad P \succ 0

    (the analytic centre of this set with :math:`\operatorname{tr}P = n`,
    :func:`~observers.numerics.luenberger.nom_g_design`).

    Options
    -------
    mu : float
        Decay rate in (0, 1] of the nominal error (``rho(A - L C)^2 < mu``); 1 as in CORA.
    solver : {"newton", "clarabel"}
        How the analytic centre is computed: ``"newton"`` (default), a damped Newton method in
        numpy (seconds at 30 states); ``"clarabel"``, cvxpy's log-det cone with Clarabel
        (minutes at 30 states; the gain of the project before the Newton method, 2e-5 to
        7e-5 away from it relative to the largest entry of the gain).
    gain : array, optional
        Use this gain instead of designing one.

    The LMI is a feasibility problem; the gain is the analytic centre of its feasible set
    normalised by ``trace(P) = n`` (see :func:`~observers.numerics.luenberger.nom_g_design`).
    """

    OPTIONS = {"mu": Number(1.0, low=0, high=1, low_open=True),
               "solver": Choice("newton", ("newton", "clarabel"))}
    #: "3": dependent outputs refused (their cached Newton failures are not replayed)
    DESIGN_VERSION = "3"

    def design_gain(self) -> np.ndarray:
        s = self.system
        check_modes(s, self.name, rate=np.sqrt(self.options["mu"]))
        return nom_g_design(s.A, s.C, float(self.options["mu"]), self.options["solver"]).L


@register(
    "Hinf-G", family="interval", set_type="interval", ready_for_control=True,
    reference="Tang, Wang, Wang, Raissi, Shen, IEEE TAC 64(11), 2019, eq. 16 and Alg. 1 "
              "(Althoff & Rath 2021, Sec. 3.3)",
)
class HinfG(OfflineGain, IntervalObserver):
    r"""Interval observer (Tang et al., Alg. 1), H-infinity gain: min gamma, then min trace P.

    Alg. 1 of Althoff & Rath 2021 (:class:`~observers.families.IntervalObserver`) with the
    gain of their Sec. 3.3 (Hinf-G, citing eq. 16 of Tang et al.), :math:`w_k = E\tilde w_k`,
    :math:`v_k = F\tilde v_k`: the gain :math:`L = P^{-1}Y` of least
    :math:`\gamma` and then, within ``gamma_slack`` of it, of least
    :math:`\operatorname{tr}P`, from the LMIs of its design
    :func:`~observers.numerics.luenberger.hinf_g_design` (equations below).

    Options
    -------
    gamma_slack : float
        The gain minimises ``trace(P)`` among the gains with
        ``gamma <= (1 + gamma_slack) * min gamma`` (default 0.1); see
        :func:`~observers.numerics.luenberger.hinf_g_design`.
    convention : {"aligned", "cora-lagged"}
        ``"aligned"`` (default): the set of step k contains ``x_k``.  ``"cora-lagged"``:
        CORA's sets, one step late (for conformance tests only; see
        :mod:`observers.families`).
    method : {"auto", "sdp", "riccati"}
        ``"sdp"``: the two SDPs above; ``"riccati"``: the least ``gamma`` from the H-infinity
        filter Riccati equation and a gain with the same bound (not the least ``trace(P)``;
        see :func:`~observers.numerics.luenberger.hinf_g_design`), seconds at 100 states;
        ``"auto"`` (default): the SDPs up to 30 states, the Riccati equation above.
    gain : array, optional
        Use this gain instead of designing one.
    """

    #: "2": solved with the noise at unit scale (:func:`~observers.numerics.lmi.unit_noise`)
    DESIGN_VERSION = "2"
    OPTIONS = {"gamma_slack": Number(0.1, low=0, low_open=True),
               "method": Choice("auto", ("auto", "sdp", "riccati"))}

    def _method(self) -> str:
        """The resolved ``method``: ``auto`` is the Riccati route above 30 states when the
        noise set is full-dimensional."""
        method = self.options["method"]
        if method != "auto":
            return method
        s = self.system
        full = np.linalg.matrix_rank(s.V.G) == s.C.shape[0] if s.V.G.size else False
        return "riccati" if s.C.shape[1] > HINF_G_RICCATI_ABOVE and full else "sdp"

    def design_params(self) -> dict[str, Any]:
        """``gamma_slack``, and the method only when it is the Riccati route (an SDP design
        keeps the key it had before the option existed)."""
        params: dict[str, Any] = {"gamma_slack": float(self.options["gamma_slack"])}
        if self._method() == "riccati":
            params["method"] = "riccati"
        return params

    def design_gain(self) -> np.ndarray:
        s = self.system
        check_modes(s, self.name)
        return hinf_g_design(s.A, s.C, s.W.G, s.V.G, float(self.options["gamma_slack"]),
                             self._method()).L
