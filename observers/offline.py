"""Offline gains: computed once by an LMI/SDP design, cached on disk, or passed by the user.

Observers with a constant gain mix in :class:`OfflineGain` before their family base class and
implement :meth:`OfflineGain.design_gain`; ``self.gain_matrix`` is then available online::

    class PRadB(OfflineGain, AllStripsObserver):
        DESIGN_VERSION = "1"
        def design_gain(self) -> np.ndarray: ...   # solve, verify, return (n x ny) matrix
        def gain(self, G): return self.gain_matrix

Passing ``gain=`` skips the design (e.g. to run with CORA's stored gains).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .errors import DesignFailed, OptionError
from .gaincache import cached_design


class OfflineGain:
    """Mixin: ``design()`` sets ``self.gain_matrix`` (n x ny) from ``gain=`` or the design."""

    OPTIONS: dict[str, Any] = {"gain": None}
    #: bump when the design code changes, so that cached gains are recomputed
    DESIGN_VERSION = "1"
    #: regression-gate tolerance: an SDP solution is accurate to the solver's tolerance
    #: (~1e-8) and may differ in its last digits between BLAS builds; 1e-4 still catches a
    #: 1 % change of the gain (see ``benchmarks/regression.py``)
    REGRESSION_RTOL = 1e-4

    def design_gain(self) -> np.ndarray:
        """Solve the offline design; raise :class:`DesignFailed` if there is no gain."""
        raise NotImplementedError

    def design_params(self) -> dict[str, Any]:
        """Parameters the design depends on besides the system (part of the cache key)."""
        return {k: v for k, v in self.options.items() if k not in ("gain", "order", "reduction")}

    def design_arrays(self) -> dict[str, np.ndarray]:
        """Arrays the design depends on (part of the cache key)."""
        s = self.system
        arrays = {"A": s.A, "C": s.C, "E": s.W.G, "F": s.V.G, "cW": s.W.c, "cV": s.V.c}
        return {k: np.asarray(v, float) for k, v in arrays.items()}

    def design(self) -> None:
        super().design()  # type: ignore[misc]
        n, ny = self.system.C.shape[1], self.system.C.shape[0]
        given = self.options.get("gain")
        if given is not None:
            try:
                L = np.array(given, dtype=float)
            except (TypeError, ValueError):
                raise OptionError(f"{self.name}: gain must be a numeric matrix") from None
            if L.ndim == 1 and L.size == n * ny:
                L = L.reshape(n, ny)
            if L.shape != (n, ny):
                raise OptionError(f"{self.name}: gain must have shape ({n}, {ny}), got {L.shape}")
            if not np.all(np.isfinite(L)):
                raise OptionError(f"{self.name}: gain contains non-finite values")
            self.gain_matrix = L
            return
        result = cached_design(self.name, self.DESIGN_VERSION, self.design_arrays(),
                               self.design_params(), lambda: {"gain": self.design_gain()})
        L = np.asarray(result["gain"], dtype=float)
        if L.shape != (n, ny) or not np.all(np.isfinite(L)):
            raise DesignFailed(f"{self.name}: design returned an invalid gain of shape {L.shape}")
        self.gain_matrix = L
