"""Linear algebra shared by the gain computations of several plugins."""

from __future__ import annotations

import numpy as np

from ..kernels.step import TIE_RTOL


def first_best(values: np.ndarray) -> int:
    """Index of the least of ``values``, values within ``TIE_RTOL`` (1e-9, relative) of the
    least counting as equal and going by index (the first, as ``min`` in exact arithmetic).

    Candidates that tie in exact arithmetic differ in the last bits by the BLAS kernel; ranked
    by those bits a choice (and every later step) depends on the kernel (VolMin-B's best two
    candidates on the 2-state vehicle differ by 4e-16 relative; issue 37).  The compiled
    kernels apply the same rule (:func:`observers.kernels.step._least`).
    """
    values = np.asarray(values, dtype=float)
    low = float(values.min())
    return int(np.flatnonzero(values <= low + TIE_RTOL * abs(low))[0])


def psd_solve(S: np.ndarray, B: np.ndarray) -> np.ndarray:
    """``S^{-1} B`` for a symmetric positive semidefinite ``S``; the minimum-norm ``S^+ B``
    where ``S`` is singular (zero-width noise sets: no process noise, an exact sensor).

    With ``S = C R C' + F F'`` and ``B = C R`` (``R`` positive semidefinite), ``B`` vanishes
    on the null space of ``S``, so ``S^+ B`` is an exact solution of the normal equations
    there (the F-radius gain, the Kalman gain). Where even the pseudo-inverse overflows (a set
    shrunk to a point) the result is zero: the gain is then irrelevant, and every gain gives
    a sound set in the zonotopic observers.
    """
    try:
        with np.errstate(all="ignore"):
            out = np.linalg.solve(S, B)
        if np.all(np.isfinite(out)):
            return out
    except np.linalg.LinAlgError:
        pass
    with np.errstate(all="ignore"):
        out = np.linalg.pinv(S, hermitian=True) @ B
    return out if np.all(np.isfinite(out)) else np.zeros_like(B)
