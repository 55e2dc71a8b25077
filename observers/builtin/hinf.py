"""Interval observer with an offline H-infinity gain: Hinf-G."""

from __future__ import annotations

from typing import Any

import numpy as np

from ..errors import OptionError
from ..interval import IntervalObserver
from ..luenberger_gains import check_modes, hinf_g_design
from ..offline import OfflineGain
from ..registry import register


@register(
    "Hinf-G", family="interval", set_type="interval", ready_for_control=True,
    reference="Tang, Wang, Wang, Raissi, Shen, IEEE TAC 64(11), 2019, eq. 16 and Alg. 1 "
              "(Althoff & Rath 2021, Sec. 3.3)",
)
class HinfG(OfflineGain, IntervalObserver):
    """Interval observer (Tang et al., Alg. 1) with the H-infinity gain, min gamma then min trace P.

    Options
    -------
    gamma_slack : float
        The gain minimises ``trace(P)`` among the gains with
        ``gamma <= (1 + gamma_slack) * min gamma`` (default 0.1); see
        :func:`~observers.luenberger_gains.hinf_g_design`.
    convention : {"aligned", "cora-lagged"}
        ``"aligned"`` (default): the set of step k contains ``x_k``.  ``"cora-lagged"``:
        CORA's sets, one step late (for conformance tests only; see
        :mod:`observers.interval`).
    gain : array, optional
        Use this gain instead of designing one.
    """

    OPTIONS = {"gamma_slack": 0.1}

    @property
    def L(self) -> np.ndarray:
        return self.gain_matrix

    def validate_options(self) -> None:
        super().validate_options()
        v = self.options["gamma_slack"]
        if not (isinstance(v, (int, float)) and not isinstance(v, bool) and v > 0):
            raise OptionError(f"{self.name}: gamma_slack must be a positive number, got {v!r}")

    def design_params(self) -> dict[str, Any]:
        return {"gamma_slack": float(self.options["gamma_slack"])}

    def design_gain(self) -> np.ndarray:
        s = self.system
        check_modes(s, self.name)
        return hinf_g_design(s.A, s.C, s.W.G, s.V.G, float(self.options["gamma_slack"])).L
