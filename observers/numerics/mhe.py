"""Moving-horizon set estimation: the exact hull of a window of the last L steps.

At step k the estimate is the interval hull of the states ``x_k`` consistent with the window
``u_{k-L} .. u_{k-1}``, ``y_{k-L} .. y_k`` and a *prior* ``x_{k-L} in P_{k-L}``, a sound outer
bound of ``x_{k-L}`` (a box); before step L the window is the whole record and starts from
``X0`` itself, so these steps are exact.  Every trajectory consistent with the whole record
satisfies the window's constraints (its ``x_{k-L}`` lies in ``P_{k-L}`` because ``P`` is
sound), so the hull contains the exact consistent set; it approaches it as L grows, and it
is never looser than the prior propagated through the window.  The prior is the estimator's
own hull of step ``k-L`` (sound by induction), intersected, if the caller gives one, with a
box from another observer run alongside (the ``inner`` observer of
:class:`observers.builtin.mhe.MHE`).

References: the set of states consistent with bounded signals is the polytope of the
set-valued observer of Shamma & Tu (IEEE TAC 44(2), 1999), whose bounds are linear
programs; here it is kept to a finite memory of L steps, the information before the window
summarised by a set as the arrival cost of moving-horizon estimation summarises it by a
penalty (Rao, Rawlings & Mayne, IEEE TAC 48(2), 2003).  The
window's polytope is the constrained zonotope of the exact recursion over L steps (Scott,
Raimondo, Marseglia & Braatz, Automatica 69, 2016, without reduction); it is kept here in the
sparse state-space form of :mod:`observers.numerics.exact`, whose LPs are warm started.

Ring formulation
----------------
The LPs are those of :class:`~observers.numerics.exact.ExactHullLP` (states, disturbance and
noise factors as variables, one block of columns and rows per step, sound bounds from dual
points, Farkas certificates for an empty set), with the blocks kept in a ring of ``L + 1``
slots instead of a growing list: slot ``j mod (L + 1)`` holds step j, and the dynamics rows
of slot s link it to slot ``s - 1 mod (L + 1)``.  When the window slides, the slot of the
oldest step is overwritten by the new step, and the slot of the new first step ``k - L``
has its dynamics rows made free, its disturbance factors fixed at 0 and its states bounded by
the prior.  The constraint matrix never changes, only bounds and two costs per model, so
each of the 2n HiGHS models keeps its factorised basis from step to step (warm start), as in
the exact reference.  Only the filtered hull is solved (2n LPs per step; the predicted bounds
of the new states are the interval prediction, redundant).

The bounds of the states inside the window are their own sound hulls (of the step at which
they were filtered) widened by the margin, hence redundant; the prior of the first state is
a constraint.  Every bound returned is the weak-duality bound of a dual point, evaluated with
outward rounding (:meth:`ExactHullLP._dual_bounds`), so warm starts affect speed only; every
range is widened by a bound of its rounding error as in the exact reference.

Constrained-zonotope formulation
--------------------------------
:func:`window_conzonotope` writes the same window as one constrained zonotope over the
factors of the prior box, the disturbances and the noises (the exact recursion of Scott et
al. 2016 over L steps, nothing reduced: ``x_{j+1} = A x_j + B u_j + W``, then the equality
constraints ``C x_j + V = y_j``), whose interval hull is 2n LPs with ``(L + 1) m``
equality rows, solved by the project's batched dual simplex (numba) and made sound from its
dual points (:meth:`observers.sets.ConZonotope.interval`).  No warm start, but no HiGHS call
either: for small windows (``(L + 1) m`` up to a few dozen rows) it is several times cheaper
than the ring (measured on the 6-tank record, L = 5: about 1 ms per step against 4 ms).  Its
matrices are computed in floating point without outward rounding (as those of every
constrained-zonotope observer of the project): its bounds are sound for the computed set,
whose rounding errors (relative 1e-15) the observer covers by enlarging the measurement
noise by a relative 1e-7 (:data:`observers.builtin.mhe.CZN_MARGIN`, as the CZN observers'
``margin``).
"""

from __future__ import annotations

from collections import deque

import numpy as np

from ..errors import EmptySet
from ..kernels import switch
from ..kernels import window as kernel_window
from .exact import MARGIN, ExactHullLP, StepHulls, _Layout

__all__ = ["WindowHullLP", "WindowRecord", "box_factors", "window_conzonotope"]


class WindowRecord:
    """The inputs and measurements of a moving window of ``window`` transitions: the last
    ``window`` inputs ``u_{k-T} .. u_{k-1}`` and ``window + 1`` measurements
    ``y_{k-T} .. y_k`` (``T = min(k, window)``)."""

    def __init__(self, window: int, nu: int) -> None:
        self.nu = int(nu)
        self._u: deque[np.ndarray] = deque(maxlen=window)
        self._y: deque[np.ndarray] = deque(maxlen=window + 1)

    def append(self, u: np.ndarray | None, y: np.ndarray) -> None:
        """Step ``k``'s data: the input ``u_{k-1}`` (None at step 0) and ``y_k``."""
        if u is not None:
            self._u.append(u)
        self._y.append(y)

    def inputs(self) -> np.ndarray:
        """``T x nu`` inputs of the window's transitions."""
        return np.array(self._u, float).reshape(len(self._u), self.nu)

    def outputs(self) -> np.ndarray:
        """``(T + 1) x m`` measurements of the window's states."""
        return np.array(self._y, float)


def box_factors(lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A box as ``(centre, diagonal generators)`` containing ``[lo, hi]`` despite the rounding
    of its centre and radius."""
    c = 0.5 * (lo + hi)
    r = 0.5 * (hi - lo)
    r = r + _FOUR_EPS * (np.abs(lo) + np.abs(hi)) + _TINY
    return c, np.diag(r)


_FOUR_EPS = 4 * np.finfo(float).eps
_TINY = np.finfo(float).tiny


def window_conzonotope(model: tuple, u, y
                       ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The states ``x_k`` consistent with a window, as constrained-zonotope arrays.

    The window starts with ``x_{k-T} in start`` and holds ``T = len(u)`` transitions and
    ``T + 1`` measurements: ``x_{j+1} = A x_j + B u_j + w_j``, ``y_j = C x_j + v_j``.

    Parameters
    ----------
    model : tuple
        ``(A, B, C, start, W, V)``: the linear model (ndarrays, ``B`` may have zero columns)
        and the ``(centre, generators)`` of the first state's set, the disturbance and the
        noise.
    u : ndarray
        ``T x nu`` inputs ``u_{k-T} .. u_{k-1}``.
    y : ndarray
        ``(T + 1) x m`` measurements ``y_{k-T} .. y_k``.

    Returns
    -------
    c, G, Acon, b : ndarray
        ``{c + G xi : Acon xi = b, |xi| <= 1}`` (factors: the start's generators, then per
        step the noise of its measurement and the disturbance into the next state).
    """
    A, B, C, start, W, V = model
    c0, G0 = start
    cW, GW = W
    cV, GV = V
    if switch.use_compiled():  # the same recursion in one compiled call
        return kernel_window.window_arrays(*(np.ascontiguousarray(a, dtype=np.float64) for a in (
            A, B, C, c0, G0, cW, GW, cV, GV, np.reshape(u, (u.shape[0], B.shape[1])), y)))
    n, m = A.shape[0], C.shape[0]
    T = u.shape[0]
    rs, rw, rv = G0.shape[1], GW.shape[1], GV.shape[1]
    R = rs + T * rw + (T + 1) * rv
    G = np.zeros((n, R))
    G[:, :rs] = G0
    c = np.array(c0, dtype=float)
    Acon = np.zeros(((T + 1) * m, R))
    b = np.empty((T + 1) * m)
    col = rs
    for j in range(T + 1):
        if j:  # x_j = A x_{j-1} + B u_{j-1} + W (only the columns used so far are nonzero)
            c = A @ c + B @ u[j - 1] + cW
            G[:, :col] = A @ G[:, :col]
            G[:, col : col + rw] = GW
            col += rw
        rows = slice(j * m, (j + 1) * m)  # C x_j + v_j = y_j
        Acon[rows, :col] = C @ G[:, :col]
        Acon[rows, col : col + rv] = GV
        b[rows] = y[j] - C @ c - cV
        col += rv
    return c, G, Acon, b


class WindowHullLP(ExactHullLP):
    """Hulls of the consistent set of a sliding window of ``window`` steps (ring of LPs).

    Use as :class:`~observers.numerics.exact.ExactHullLP`: :meth:`first` with ``y_0``, then
    :meth:`advance` per step; steps ``0 .. window`` are exact (the window is the record).

    Parameters
    ----------
    model : tuple
        ``(A, B, C, X0, W, V)``, the arguments of
        :class:`~observers.numerics.exact.ExactHullLP`: the linear model and the
        ``(centre, generators)`` of the zonotopes of the initial state, the disturbance and
        the measurement noise.
    window : int
        Window length L >= 1 (transitions kept: the window holds ``L + 1`` states).
    margin : float
        Relative widening of the redundant state bounds.

    Attributes
    ----------
    filtered : list of tuple
        The filtered hulls ``(lo, hi)`` of the steps in the window, by slot.
    """

    def __init__(self, model: tuple, window: int, margin: float = MARGIN):
        super().__init__(*model, margin=margin)
        if isinstance(window, bool) or int(window) != window or window < 1:
            raise ValueError(f"window must be an integer >= 1, got {window!r}")
        self.window = int(window)
        self.slots = self.window + 1
        self._init: _Layout | None = None
        self._ring()
        self.filtered: list[tuple[np.ndarray, np.ndarray] | None] = [None] * self.slots

    def _ring(self) -> None:
        """Allocate the ``L + 1`` slots (dynamics rows closing the ring) and the block of
        step 0 (the general columns of X0 and their rows, on slot 0's states)."""
        n, S = self.n, self.slots
        nfac, nnu, nmeas = self.W.general, self._nu_used.size, self._meas_rows.size
        width, height = n + nfac + nnu, n + nmeas
        for s in range(S):
            col, row = s * width, s * height
            self._layout.append(_Layout(x=col, fac=col + n, nfac=nfac, nu=col + n + nfac,
                                        nnu=nnu, rows=row, nrows=n, meas=row + n,
                                        nmeas=nmeas))
        s0 = self._layout[0]
        self._init = _Layout(x=s0.x, fac=S * width, nfac=self.X0.general, nu=s0.nu, nnu=nnu,
                             rows=S * height, nrows=n if self.X0.general else 0,
                             meas=s0.meas, nmeas=nmeas)
        ri, ci, vals = [], [], []
        for s, lay in enumerate(self._layout):
            r_, c_, v_ = self._block(lay, False, self._layout[(s - 1) % S].x)
            ri += r_
            ci += c_
            vals += v_
        r_, c_, v_ = self._block(self._init, True, None, outputs=False)
        self._append(self._init.fac + self._init.nfac, self._init.rows + self._init.nrows,
                     ri + r_, ci + c_, vals + v_)

    def _lay(self, j: int) -> _Layout:
        return self._init if j == 0 else self._layout[j % self.slots]

    def _ensure(self, j: int) -> _Layout:
        return self._lay(j)

    def _start(self, k: int, prior: tuple[np.ndarray, np.ndarray] | None) -> None:
        """Slide the window to ``[k - L, k]``: free the oldest slot for step k (step 0's
        X0 rows when it is slot 0) and make step ``k - L`` the first, bounded by its prior."""
        if k == self.slots:  # x_0 leaves the window: X0's rows and factors go
            init = self._init
            self._free_rows(init.rows, init.nrows)
            self._set_cols(init.fac, np.zeros(init.nfac), np.zeros(init.nfac))
        j0 = k - self.window
        lay = self._lay(j0)
        self._free_rows(lay.rows, lay.nrows)  # no link to the step before the window
        self._set_cols(lay.fac, np.zeros(lay.nfac), np.zeros(lay.nfac))
        lo, hi = self.filtered[j0 % self.slots]
        if prior is not None:
            lo, hi = np.maximum(lo, prior[0]), np.minimum(hi, prior[1])
            if np.any(lo > hi):
                i = int(np.argmax(lo - hi))
                raise EmptySet(f"step {k}: the prior of step {j0} and the hull of the window "
                               f"ending there do not meet in x{i + 1} ({lo[i]:.17g} > "
                               f"{hi[i]:.17g}): the record is inconsistent with the model")
        self._set_cols(lay.x, lo, hi)

    def first(self, y, hulls: StepHulls | None = None) -> StepHulls:
        """Step 0: ``X0`` with ``y_0`` (exact)."""
        out = super().first(y, hulls)
        self.filtered[0] = (out.filt_lo, out.filt_hi)
        return out

    def advance(self, u, y, hulls: StepHulls | None = None, predicted: bool = False,
                prior: tuple[np.ndarray, np.ndarray] | None = None) -> StepHulls:
        """Step k: slide the window (from step ``L + 1`` on), predict with ``u_{k-1}`` and
        filter with ``y_k``.

        Parameters
        ----------
        u, y : array_like
            ``u_{k-1}`` and ``y_k``.
        hulls : StepHulls, optional
            Known hulls (no LP solved), as for the exact reference.
        predicted : bool
            Also solve the LPs of the predicted hull (default False: the interval
            prediction, which costs nothing).
        prior : tuple of ndarray, optional
            A sound box ``(lo, hi)`` of ``x_{k-L}`` intersected with the estimator's own hull
            of that step (used from step ``L + 1`` on).

        Returns
        -------
        StepHulls
            The predicted and filtered hulls of step k (sound).
        """
        k = self.k
        if k == 0:
            raise RuntimeError("advance() needs first() before it")
        if k > self.window:
            self._start(k, prior)
        out = super().advance(u, y, hulls, predicted=predicted)
        self.filtered[k % self.slots] = (out.filt_lo, out.filt_hi)
        return out
