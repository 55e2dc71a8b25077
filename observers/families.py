"""Shared online loops of the zonotopic observer families.

* :class:`StripBasedObserver`: prediction ``A S + B u + W``, intersection with the
  measurement strips (method I: strip by strip, :class:`PerStripObserver`; method II: all
  strips at once, :class:`AllStripsObserver`), order reduction.
* :class:`PropagationObserver`: ``S+ = (A - L C) S + B u + L y + (-L) V + W`` with a constant
  or adaptive gain, then order reduction.
* :class:`IntervalObserver`: a Luenberger point estimate plus an interval bound of its error
  (see below).

Each loop sits beside its one-step formula (:func:`strip_update`, :func:`propagate`,
:func:`interval_bound`).  Concrete observers only supply the gain (or the intersection) and,
if any, an offline design; the gains' mathematics is in :mod:`observers.numerics`.

Interval observer
-----------------
The interval observer of Tang, Wang, Wang, Raissi and Shen (TAC 2019, Alg. 1; Alg. 1 of
Althoff & Rath, Automatica 2021): a Luenberger point estimate plus an interval bound of its
error.

With ``M = A - L C`` and ``D = W + (-L) V``, the error ``e_k = x_k - x^_k`` of the point
estimate ``x^_{k+1} = A x^_k + B u_k + L (y_k - C x^_k)`` lies in
``M^k (X0 - c0) + sum_{j<k} M^j D``; Alg. 1 bounds it by
``BOX(M^k (X0 - c0)) + sum_{j<k} BOX(M^j D)``, boxing each term before summing so that no
wrapping accumulates.  That bound is exactly the interval hull of the *unreduced*
set-propagation estimate with the same gain, obtained in interval arithmetic: the state of the
loop is two generator matrices of fixed size (``M^k G_X0`` and ``M^k [G_W, -L G_V]``) and two
vectors (the centre and radius of the summed boxes), so a step costs one matrix product.
CORA instead sums the boxes into a zonotope whose generator count grows by n every step.

Conventions (``step(u_prev, y)`` receives ``u[k-1]`` and ``y[k]``):

* ``"aligned"`` (default): step k returns the bound of ``x_k`` (Alg. 1, line 5, at k); it
  needs ``y[k-1]`` only, so it is ready before ``y[k]`` arrives.  Step 0 returns ``X0``.
* ``"cora-lagged"``: CORA's ``priv_observe_interval`` stores the bound of step k-1 as its
  set of step k (``R{i+1}`` is computed before ``x^`` is updated), so its sets need not contain
  ``x_k``.  Offered only to reproduce CORA's numbers.

Deviation from CORA in both conventions: the error set starts from ``X0 - c0`` (CORA uses
``X0`` itself, which counts a non-zero centre twice; all benchmark ``X0`` are centred at 0).
"""

from __future__ import annotations

from abc import abstractmethod
from time import perf_counter
from typing import Any, ClassVar

import numpy as np

from .base import Observer
from .enclosures import ENCLOSURES, Smooth
from .errors import ObserverError, Unsupported
from .kernels import KernelByOption, StepKernel, switch
from .kernels import step as kernel_step
from .options import Choice, reduction_method, zonotope_order
from .prediction import LinearPrediction, prediction_for
from .sets import Interval, Zonotope, get_reduction
from .sets.reduction import compiled_name
from .sets.zonotope import strip_generators


# -- one-step formulas (pure functions on centre/generator arrays) --------------------
def strip_update(
    c: np.ndarray, G: np.ndarray, Lam: np.ndarray, C: np.ndarray, y: np.ndarray, sigma: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    r"""Zonotope enclosing ``(c, G)`` intersected with the strips ``|C x - y| <= sigma``.

    For any gain ``Lam`` (n x m) this is the parameterised family of Alamo et al. (2005,
    Property 3) and Le et al. (2013):
    ``c + Lam (y - C c)`` with generators ``[(I - Lam C) G, Lam diag(sigma)]`` (computed as
    ``G - Lam (C G)`` when ``2 m < n``, else with ``I - Lam C`` formed first: fewer flops):

    .. math::

        (c \oplus G\mathcal{B}^r) \cap \{x \mid |Cx - y| \le \sigma\} \subseteq
        c + \Lambda(y - Cc) \oplus \left[(I - \Lambda C)\,G,\
        \Lambda\operatorname{diag}(\sigma)\right]\mathcal{B}^{r+m}

    (method II of Sec. 3.1 of Althoff & Rath 2021; method I is one strip at a time).
    """
    return c + Lam @ (y - C @ c), strip_generators(G, Lam, C, sigma)

def propagate(
    S: tuple[np.ndarray, np.ndarray],
    prediction: tuple[np.ndarray, np.ndarray, np.ndarray | None],
    C: np.ndarray,
    L: np.ndarray,
    y: np.ndarray,
    V: tuple[np.ndarray, np.ndarray],
    W: tuple[np.ndarray, np.ndarray],
) -> tuple[np.ndarray, np.ndarray]:
    r"""One set-propagation step ``S+ = (A - L C) S + d + L y + (-L) V + W (+ R)`` (eq. 8 of
    Althoff & Rath 2021 with ``d = B u``), exact on zonotopes; generators
    ``[(A-LC) G, -L G_V, G_W, R]``, for the set ``S = (c, G)``, the prediction
    ``(A, d, R)`` (``R`` ``None`` or remainder generators), ``V = (c_V, G_V)`` and
    ``W = (c_W, G_W)``.  For a nonlinear system ``A, d`` are the linearisation at the centre
    and ``R`` the generators of its remainder box (:mod:`observers.prediction`).

    .. math::

        c^+ = (A - LC)\,c + d + L(y - c_V) + c_W, \qquad
        G^+ = \left[(A - LC)\,G,\ -LG_V,\ G_W,\ R\right]
    """
    c, G = S
    A, d, R = prediction
    cV, GV = V
    cW, GW = W
    M = A - L @ C
    c_new = M @ c + d + L @ (y - cV) + cW
    r, rv, rw = G.shape[1], GV.shape[1], GW.shape[1]
    rr = 0 if R is None else R.shape[1]
    G_new = np.empty((G.shape[0], r + rv + rw + rr))  # one allocation, no hstack copy
    np.matmul(M, G, out=G_new[:, :r])
    np.matmul(-L, GV, out=G_new[:, r : r + rv])
    G_new[:, r + rv : r + rv + rw] = GW
    if rr:
        G_new[:, r + rv + rw :] = R
    return c_new, G_new


def _fresh(a) -> np.ndarray:
    """``a`` as a writable C-ordered float array, copied only if it is not one (a user's
    Jacobian may be read-only: passed as it is, it would compile the linearised kernels once
    more for that array type)."""
    return np.require(a, np.float64, ["C", "W"])


def as_zonotope(S, what: str) -> Zonotope:
    """Zonotope view of a system set (zonotopes and intervals are accepted)."""
    if isinstance(S, Zonotope):
        return S
    if isinstance(S, Interval):
        return Zonotope.from_interval(S)
    raise ObserverError(f"{what} must be a Zonotope or an Interval, got {type(S).__name__}")


class LinearModelObserver(Observer):
    """Observers that read the linear model: ``design`` collects ``A, B, C`` and the sets
    ``X0, W, V`` as zonotopes (subclasses extend it with ``super().design()``).

    Observers whose class sets ``NONLINEAR = True`` also accept a nonlinear system
    (:class:`systems.NonlinearSystem`): their loops predict with ``self.prediction``
    (:mod:`observers.prediction`, conservative linearisation at every step) and ``self.A`` is
    then the Jacobian of the latest linearisation (what online gains such as FRad-B's and
    FRad-C's use).

    Those that also set ``NONLINEAR_OUTPUT = True`` accept a nonlinear output
    ``y = h(x) + v``: before each update the output is enclosed over the box of the predicted
    set as ``h(x) in H x + d + [-rad, rad]`` (:mod:`observers.enclosures`, strategy
    ``OUTPUT_ENCLOSURE``), and the update uses ``C = H``, the measurement ``y - d`` and the
    noise widened by ``rad`` (:meth:`ZonotopeObserver.linearise_output`), so the strips stay
    sound.  ``self.C`` is then the latest ``H``.
    """

    #: whether the online loop works with a per-step linearisation (nonlinear systems)
    NONLINEAR: bool = False
    #: whether the update works with a per-step enclosure of a nonlinear output h(x)
    NONLINEAR_OUTPUT: bool = False
    #: prediction strategy for nonlinear systems (:func:`observers.prediction.prediction_for`)
    LINEARISATION: str = "lagrange"
    #: enclosure of a nonlinear output (:data:`observers.enclosures.ENCLOSURES`)
    OUTPUT_ENCLOSURE: str = "first-order"

    def design(self) -> None:
        s = self.system
        linear = getattr(s, "is_linear", True)
        who = self.name or type(self).__name__
        if not linear and not self.NONLINEAR:
            raise Unsupported(f"{who} needs a linear system (its gain is designed offline for "
                              "fixed A, B)")
        C_out = getattr(s, "output_matrix", None) if not getattr(
            s, "output_is_linear", True) else None
        self.output_linear = bool(getattr(s, "output_is_linear", True)) or C_out is not None
        if not self.output_linear and not self.NONLINEAR_OUTPUT:
            raise Unsupported(f"{who} needs a linear output y = C x + v")
        need = ("A", "B") if linear else ("f", "jacobian", "hessian")
        missing = [a for a in need if not hasattr(s, a)]
        if missing:
            raise Unsupported(f"{who} needs a {'linear' if linear else 'nonlinear'} system with "
                              f"attributes {', '.join(need)}; missing: {', '.join(missing)}")
        self.prediction = prediction_for(
            s, get_reduction(self.options.get("reduction", "girard")),
            self.LINEARISATION, self.options.get("remainder", "box"))
        if linear:
            self.A = np.asarray(s.A, dtype=float)
            self.B = np.asarray(s.B, dtype=float)
        else:  # until the first linearisation: the Jacobian at the centre of X0
            self.A = np.asarray(s.jacobian(as_zonotope(s.X0, "X0").c, np.zeros(s.nu))[0])
            self.B = np.zeros((s.n, s.nu))
        self.X0 = as_zonotope(s.X0, "X0")
        if self.output_linear:  # C, or the matrix of an h that is linear
            self.C = np.asarray(s.C if C_out is None else C_out, dtype=float)
        else:  # until the first enclosure: the Jacobian of h at the centre of X0
            self.C = np.asarray(s.h_jacobian(self.X0.c), dtype=float)
            self._output = Smooth(s, "h")
        self.W = as_zonotope(s.W, "W")
        self.V = as_zonotope(s.V, "V")


class Linearised:
    """Mixin of the observers that also run on nonlinear systems (conservative linearisation
    at every step, :mod:`observers.prediction`).

    Options
    -------
    remainder : {"box", "zonotope"}
        Nonlinear systems only: append the interval hull of CORA's enclosure of the
        second-order remainder (n generators, default: on CORA's 20-step tank record the final
        hulls stay within 1.6e-2 of CORA's, at a third of the cost on 30 tanks) or the zonotope
        itself (``n (n+1)/2 + n`` generators, CORA's choice: within 1e-9 of CORA's stored
        results for FRad-A/B/C).
    """

    NONLINEAR = True
    REQUIRES = ("W", "V", "X0")
    OPTIONS = {"remainder": Choice("box", ("box", "zonotope"))}


class ZonotopeObserver(LinearModelObserver):
    """Common options and system data of the zonotopic observers.

    A subclass whose step a compiled kernel computes exactly declares it in ``KERNEL``
    (:mod:`observers.kernels`); on a linear system with a built-in reduction the family then
    runs each step but the first as one compiled call (:mod:`observers.kernels.step`), with
    the numpy path as fallback for a step the kernel cannot vouch for.
    """

    OPTIONS = {"order": zonotope_order(100), "reduction": reduction_method("girard")}
    #: the compiled one-step kernel of this observer (``None``: the numpy path only)
    KERNEL: ClassVar[StepKernel | KernelByOption | None] = None

    def design(self) -> None:
        """Collect the system data used online (subclasses extend with ``super().design()``)."""
        super().design()
        self.E = self.W.G
        self.F = self.V.G
        Vi = self.V.interval()
        self.sigma = np.maximum(np.abs(Vi.lo), np.abs(Vi.hi))  # strip half-widths
        self._sigma0, self._F0 = self.sigma, self.F
        self.order = float(self.options["order"])  # >= 1: checked by its option spec
        strategy = get_reduction(self.options["reduction"])
        self._reduce = strategy.reduce
        # the compiled kernel serves linear systems (linear output too) with a built-in
        # reduction; None: always the numpy path
        self._reduction_name = compiled_name(strategy)
        kernel = None if self.KERNEL is None else self.KERNEL.select(self.options)
        self._step_kernel = (kernel if self._reduction_name is not None and self.output_linear
                             else None)
        #: the model is linear: one kernel call per step; else the kernel runs on the
        #: linearisation of each step (:func:`observers.kernels.step.predict_linearised`)
        self._linear_model = isinstance(self.prediction, LinearPrediction)

    def output_enclosure(self, lo: np.ndarray, hi: np.ndarray):
        """``(H, d, rad)`` with ``h(x) in H x + d + [-rad, rad]`` over the box ``[lo, hi]``
        (strategy ``OUTPUT_ENCLOSURE``; nonlinear outputs only)."""
        return ENCLOSURES[self.OUTPUT_ENCLOSURE](self._output, lo, hi, np.zeros(0), self.k)

    def linearise_output(self, c: np.ndarray, G: np.ndarray, y: np.ndarray) -> np.ndarray:
        """The measurement to use with ``self.C`` and ``self.sigma`` / ``self.F`` for the
        predicted zonotope ``(c, G)``: ``y`` itself for a linear output; for ``y = h(x) + v``
        the enclosure of ``h`` over the box of ``(c, G)`` sets ``C = H``, widens the strips and
        the noise generators by ``rad`` and returns ``y - d`` (then :meth:`output_changed`)."""
        if self.output_linear:
            return y
        r = np.abs(G).sum(axis=1)
        H, d, rad = self.output_enclosure(c - r, c + r)
        self.C = H
        self.sigma = np.nextafter(self._sigma0 + rad, np.inf)
        self.F = np.hstack([self._F0, np.diag(rad)])
        self.output_changed()
        return y - d

    def output_changed(self) -> None:  # noqa: B027 - optional hook
        """Hook: ``self.C`` changed (a nonlinear output); refresh what depends on it."""

    def kernel_inputs(self) -> dict[str, Any]:
        """The observer's own static inputs of its compiled kernel (keywords of
        :func:`observers.kernels.step.prepare`): the constant gain ``L`` for the kernels
        that take one (default), nothing for the others."""
        return {"gain": self.L} if self._step_kernel.given_gain else {}

    def reset(self) -> None:
        super().reset()
        #: accumulated seconds per phase of the numpy path of :meth:`step` since the last
        #: reset (a compiled step is not split into phases, nor timed here)
        self.phase_times = {"prediction": 0.0, "update": 0.0, "reduction": 0.0}
        #: the compiled kernel with the static data of this run (at its first compiled step)
        self._kernel_run: kernel_step.StepRun | None = None

    def _prepare_run(self) -> kernel_step.StepRun:
        """The compiled kernel and the static data of this run (at its first compiled step).
        The data are read-only C-contiguous float copies made once per run, so that every
        step passes arguments of the same types and numba compiles each kernel once (a
        read-only array is a different type from a writable one)."""
        model = kernel_step.StepModel(A=self.A, B=self.B, W_c=self.W.c, E=self.E, C=self.C,
                                      sigma=self.sigma, F=self.F, V_c=self.V.c)
        self._kernel_run = kernel_step.prepare(
            self._step_kernel.value, self._reduction_name, self.order, model,
            **self.kernel_inputs())
        return self._kernel_run

    def kernel_state_matrix(self, c: np.ndarray) -> np.ndarray:
        """Nonlinear systems: the state matrix the compiled kernel's gain reads for the set
        with centre ``c`` (the predicted one for a strip-based observer), as the numpy gain
        does: the latest linearisation ``self.A`` (default)."""
        return self.A

    def _kernel(self) -> kernel_step.StepRun | None:
        """The compiled kernel of this run, or ``None``: the numpy path runs."""
        if self._step_kernel is None or not switch.use_compiled():
            return None
        return self._kernel_run or self._prepare_run()

    def _args(self, run: kernel_step.StepRun, c: np.ndarray) -> tuple:
        """The kernel's ``args``: the run's own on a linear model, else with
        :meth:`kernel_state_matrix` at ``c`` as its ``A``."""
        return run.args if self._linear_model else kernel_step.linearised_args(
            run, self.kernel_state_matrix(c))

    def _run_compiled(self, fn, *inputs) -> Zonotope | None:
        """``fn(*inputs) -> (c, G, ok)`` (a compiled kernel) as the set of this step, or
        ``None`` where the kernel declined it (the numpy path then runs)."""
        try:
            c, G, ok = fn(*inputs)
        except np.linalg.LinAlgError:
            return None
        return self._finish_step(c, G) if ok else None

    def _compiled_step(self, u: np.ndarray, y: np.ndarray) -> Zonotope | None:
        """The set of this step by the compiled kernel from the current set, the input ``u``
        and the measurement ``y`` the kernel consumes (a float vector), or ``None``: the numpy
        path runs (no kernel for this observer, a nonlinear model, or the kernel declined the
        step)."""
        run = self._kernel() if self._linear_model else None
        if run is None:
            return None
        # y.copy(): a fresh writable C-contiguous vector, one argument type per position;
        # the input term in index order too (kernel_step.FIXED_ORDER_MAX_DIM)
        d = kernel_step.matvec(run.data.B, np.ascontiguousarray(u, dtype=np.float64))
        return self._run_compiled(run.kernel, self._c, self._G, d, y.copy(), run.args)

    def _compiled_first(self, y: np.ndarray) -> Zonotope | None:
        """The first set (``X0`` intersected with the strips of ``y``, not reduced) by the
        compiled measurement update of this observer's kernel, the same formulas as every
        later compiled step, or ``None``: the numpy path runs."""
        run = self._kernel()
        if run is None or run.first is None:
            return None
        c = np.array(self.X0.c, dtype=np.float64)
        return self._run_compiled(run.first, c, np.ascontiguousarray(
            self.X0.G, dtype=np.float64), y.copy(), self._args(run, c))

    def _finish_step(self, c: np.ndarray, G: np.ndarray) -> Zonotope:
        """Keep ``(c, G)`` as the current set, count the step and return the set (the end of
        every step, by the compiled kernel or the numpy path)."""
        self._c, self._G = c, G
        self.k += 1
        return Zonotope.trusted(c, G)


class StripBasedObserver(ZonotopeObserver):
    r"""Predict, intersect with the measurement strips of ``y[k]``, reduce.

    A nonlinear output is used through the strips of its enclosure over the box of the
    predicted zonotope (:meth:`ZonotopeObserver.linearise_output`).

    With the estimate :math:`\mathcal{S}_{k-1} = c_{k-1} \oplus G_{k-1}\mathcal{B}^r`, the
    disturbance set :math:`\mathcal{W} = c_W \oplus E\mathcal{B}^{n_w}` and the noise bounded
    by the box :math:`[-\sigma, \sigma]`, one step is

    .. math::

        \mathcal{S}^p = A\mathcal{S}_{k-1} \oplus Bu_{k-1} \oplus \mathcal{W}
        = (Ac_{k-1} + Bu_{k-1} + c_W) \oplus [AG_{k-1},\ E]\,\mathcal{B}^{r+n_w}

        \hat{\mathcal{S}}_j = \{x \in \mathbb{R}^n \mid |C_j x - y_{k,j}| \le \sigma_j\},
        \quad j = 1, \ldots, n_y

        \mathcal{S}_k \supseteq \mathcal{S}^p \cap \hat{\mathcal{S}}_1 \cap \ldots \cap
        \hat{\mathcal{S}}_{n_y}

    (the prediction of Sec. 2.4 and eqs. 4-6 of Althoff & Rath 2021), followed by the order
    reduction of the generators to ``order``.  The subclass chooses the enclosure of the
    intersection (:meth:`intersect`); the first set is :math:`\mathcal{X}_0` intersected with
    the strips of :math:`y_0`."""

    NONLINEAR_OUTPUT = True

    def reset(self) -> None:
        super().reset()
        self._c: np.ndarray | None = None
        self._G: np.ndarray | None = None

    @abstractmethod
    def intersect(self, c: np.ndarray, G: np.ndarray, y: np.ndarray):
        """Enclose ``(c, G)`` intersected with the measurement set of ``y``."""

    def step(self, u_prev, y) -> Zonotope:
        y = self._measurement(y)
        times = self.phase_times
        if self._c is None:  # first set: X0 intersected with y[0], not reduced (as CORA)
            out = self._compiled_first(y)
            if out is not None:
                return out
            t0 = perf_counter()
            c, G = self.intersect(self.X0.c, self.X0.G,
                                  self.linearise_output(self.X0.c, self.X0.G, y))
            times["update"] += perf_counter() - t0
        else:
            u = self._input(u_prev)
            t0 = perf_counter()
            out = self._compiled_step(u, y)
            if out is not None:
                return out
            self.A, d, R = self.prediction(self._c, self._G, u, self.k)
            run = self._kernel()
            if run is not None:  # a nonlinear model: the kernel on the linearisation
                c, G = kernel_step.predict_linearised(
                    self._c, self._G, _fresh(self.A), _fresh(d), _fresh(R), run.args)
                out = self._run_compiled(kernel_step.strip_predicted, c, G, y.copy(),
                                         self._args(run, c))
                if out is not None:
                    return out
            else:
                c = self.A @ self._c + d + self.W.c
                r, re = self._G.shape[1], self.E.shape[1]
                # [A G, E, R] without hstack (R: remainder generators, none for a linear
                # system)
                G = np.empty((self.A.shape[0], r + re + R.shape[1]))
                np.matmul(self.A, self._G, out=G[:, :r])
                G[:, r : r + re] = self.E
                G[:, r + re :] = R
            t1 = perf_counter()
            c, G = self.intersect(c, G, self.linearise_output(c, G, y))
            t2 = perf_counter()
            G = self._reduce(G, self.order)
            times["prediction"] += t1 - t0
            times["update"] += t2 - t1
            times["reduction"] += perf_counter() - t2
        return self._finish_step(c, G)


class PerStripObserver(StripBasedObserver):
    r"""Intersection method I: one strip after the other, each with its own gain.

    Strip :math:`j` (row :math:`C_j` of :math:`C`) maps the current zonotope
    :math:`c \oplus G\mathcal{B}^r` with the gain vector :math:`\lambda^j \in \mathbb{R}^n`
    (:meth:`strip_gain`) to

    .. math::

        \hat{\mathcal{Z}}_j(\lambda^j) = (I - \lambda^j C_j)\,c + \lambda^j y_{k,j}
        \oplus \left[(I - \lambda^j C_j)\,G,\ \lambda^j \sigma_j\right]\mathcal{B}^{r+1},

    which encloses the intersection with the strip for every :math:`\lambda^j` (method I of
    Sec. 3.1 of Althoff & Rath 2021); after the last strip
    :math:`\mathcal{S}_k = \hat{\mathcal{Z}}_{n_y}`, with :math:`n_y` generators more than
    :math:`\mathcal{S}^p`."""

    @abstractmethod
    def strip_gain(self, G: np.ndarray, i: int) -> np.ndarray:
        """Gain vector (n,) for strip ``i`` given the current generators ``G``."""

    def intersect(self, c, G, y):
        for i in range(self.C.shape[0]):
            lam = self.strip_gain(G, i).reshape(-1, 1)
            c, G = strip_update(c, G, lam, self.C[i : i + 1], y[i : i + 1], self.sigma[i : i + 1])
        return c, G


class AllStripsObserver(StripBasedObserver):
    r"""Intersection method II: all strips at once with one gain matrix.

    With the gain :math:`\Lambda \in \mathbb{R}^{n \times n_y}` (:meth:`gain`) the
    predicted zonotope :math:`c^p \oplus G^p\mathcal{B}^r` becomes

    .. math::

        \mathcal{S}_k(\Lambda) = (I - \Lambda C)\,c^p + \Lambda y_k
        \oplus \left[(I - \Lambda C)\,G^p,\ \Lambda \operatorname{diag}(\sigma)\right]
        \mathcal{B}^{r+n_y},

    an enclosure of :math:`\mathcal{S}^p \cap \{x \mid |Cx - y_k| \le \sigma\}` for every
    :math:`\Lambda` (method II of Sec. 3.1 of Althoff & Rath 2021)."""

    @abstractmethod
    def gain(self, c: np.ndarray, G: np.ndarray) -> np.ndarray:
        """Gain matrix (n x m) for the predicted set ``(c, G)``."""

    def intersect(self, c, G, y):
        return strip_update(c, G, self.gain(c, G), self.C, y, self.sigma)


class PropagationObserver(ZonotopeObserver):
    r"""Luenberger-type set propagation; the estimate of step k+1 needs only ``y[k]``.

    The set-valued form of the Luenberger update
    :math:`\hat x_{k+1} = A\hat x_k + Bu_k + w_k + L(y_k - C\hat x_k - v_k)` (eq. 7 of
    Althoff & Rath 2021) over all :math:`w_k \in \mathcal{W}`, :math:`v_k \in \mathcal{V}`:

    .. math::

        \mathcal{S}_{k+1} = (A - L_kC)\,\mathcal{S}_k \oplus Bu_k \oplus L_ky_k
        \oplus (-L_k)\,\mathcal{V} \oplus \mathcal{W}

    (eq. 8), exact on zonotopes: with :math:`\mathcal{S}_k = c_k \oplus G_k\mathcal{B}^r`,
    :math:`\mathcal{V} = c_V \oplus F\mathcal{B}^{n_v}` and
    :math:`\mathcal{W} = c_W \oplus E\mathcal{B}^{n_w}`,

    .. math::

        c_{k+1} = (A - L_kC)\,c_k + Bu_k + L_k(y_k - c_V) + c_W, \qquad
        G_{k+1} = \left[(A - L_kC)\,G_k,\ -L_kF,\ E\right],

    then reduced to ``order``.  It contains the true state for any gain :math:`L_k`, which the
    subclass chooses (:meth:`gain`) to make the set small; the first set is
    :math:`\mathcal{X}_0`."""

    def reset(self) -> None:
        super().reset()
        self._c: np.ndarray | None = None
        self._G: np.ndarray | None = None
        self._y_prev: np.ndarray | None = None

    @abstractmethod
    def gain(self, c: np.ndarray, G: np.ndarray) -> np.ndarray:
        """Observer gain L (n x m) for the current set ``(c, G)``."""

    def step(self, u_prev, y) -> Zonotope:
        y = self._measurement(y)
        if self._c is None:  # first set: X0 itself (as CORA)
            c, G = self.X0.c, self.X0.G
        else:
            u = self._input(u_prev)
            out = self._compiled_step(u, self._y_prev)
            if out is not None:
                self._y_prev = y
                return out
            self.A, d, R = self.prediction(self._c, self._G, u, self.k)
            run = self._kernel()
            if run is not None:  # a nonlinear model: the kernel on the linearisation
                out = self._run_compiled(
                    kernel_step.propagate_linearised, self._c, self._G, _fresh(d), _fresh(R),
                    self._y_prev.copy(),
                    self._args(run, self._c))
                if out is not None:
                    self._y_prev = y
                    return out
            L = self.gain(self._c, self._G)
            c, G = propagate((self._c, self._G), (self.A, d, R), self.C, L, self._y_prev,
                             (self.V.c, self.F), (self.W.c, self.E))
            G = self._reduce(G, self.order)
        self._y_prev = y
        return self._finish_step(c, G)


class ConstantGainPropagationObserver(PropagationObserver):
    r"""Set propagation with an offline gain ``self.L`` (set by ``design``).

    Eq. 8 of Althoff & Rath 2021 with :math:`L_k = L` for every step:

    .. math::

        \mathcal{S}_{k+1} = (A - LC)\,\mathcal{S}_k \oplus Bu_k \oplus Ly_k
        \oplus (-L)\,\mathcal{V} \oplus \mathcal{W}."""

    KERNEL = StepKernel.PROPAGATION_GIVEN
    L: np.ndarray

    def gain(self, c, G) -> np.ndarray:
        return self.L


# -- interval observer ----------------------------------------------------------------------
CONVENTIONS = ("aligned", "cora-lagged")


def box_radius(G: np.ndarray) -> np.ndarray:
    """Radius of the interval hull of a zonotope with generators ``G``: ``sum |G|`` by rows."""
    return np.abs(G).sum(axis=1)


def luenberger_step(x: np.ndarray, A, B, C, L, u: np.ndarray, y: np.ndarray) -> np.ndarray:
    r"""Point estimate update ``A x + B u + L (y - C x)`` (Alg. 1, line 6):
    :math:`\hat x_{k+1} = A\hat x_k + Bu_k + L(y_k - C\hat x_k)`."""
    return A @ x + B @ u + L @ (y - C @ x)


def interval_bound(x: np.ndarray, G_x: np.ndarray, c_wv: np.ndarray, r_wv: np.ndarray):
    """Bounds ``x^ + BOX(S_x) + S_wv`` (Alg. 1, lines 4-5) as ``(lo, hi)``.

    ``G_x`` are the generators of the centred initial-error term ``M^k (X0 - c0)``;
    ``(c_wv, r_wv)`` are the centre and radius of ``S_wv``, the summed disturbance boxes.
    """
    c = x + c_wv
    r = box_radius(G_x) + r_wv
    return c - r, c + r


class IntervalObserver(LinearModelObserver):
    r"""Alg. 1 with the constant gain ``self.L`` (set by ``design``); returns intervals.

    Subclasses provide ``L`` (n x ny), e.g. through :class:`~observers.offline.OfflineGain`.

    With :math:`M = A - LC`, :math:`\mathcal{D}_0 = \mathcal{W} \oplus (-L)\mathcal{V}`,
    :math:`\hat x_0` the centre of :math:`\mathcal{X}_0`,
    :math:`\mathcal{S}_{x,0} = \mathcal{X}_0 - \hat x_0` and :math:`\mathcal{S}_{wv,0} = 0`
    (Alg. 1 of Althoff & Rath 2021, lines 1-9; the centred initial error is this project's
    choice, see the module notes):

    .. math::

        [\underline{x}_k, \overline{x}_k] = \hat x_k \oplus \operatorname{BOX}(\mathcal{S}_{x,k})
        \oplus \mathcal{S}_{wv,k}

        \hat x_{k+1} = A\hat x_k + Bu_k + L(y_k - C\hat x_k)

        \mathcal{S}_{x,k+1} = M\mathcal{S}_{x,k}, \qquad
        \mathcal{S}_{wv,k+1} = \mathcal{S}_{wv,k} \oplus \operatorname{BOX}(\mathcal{D}_k),
        \qquad \mathcal{D}_{k+1} = M\mathcal{D}_k,

    so that :math:`\mathcal{S}_{wv,k} = \bigoplus_{i<k}\operatorname{BOX}(M^i\mathcal{D}_0)`:
    each term is boxed before it is summed, and no wrapping accumulates.  The box of a
    zonotope :math:`c \oplus G\mathcal{B}^r` is
    :math:`[c - |G|\mathbf{1},\ c + |G|\mathbf{1}]` (:func:`box_radius`).
    """

    OPTIONS = {"convention": Choice("aligned", CONVENTIONS)}
    L: np.ndarray

    def design(self) -> None:
        """Collect the system data used online (subclasses extend with ``super().design()``)."""
        super().design()
        self.lagged = self.options["convention"] == "cora-lagged"

    def reset(self) -> None:
        super().reset()
        L = np.asarray(self.L, dtype=float)
        self._M = self.A - L @ self.C
        self._x = self.X0.c.copy()  # x^_0 = centre of X0
        # generators propagated by M: [initial error | D = W + (-L) V], one product per step
        self._G = np.hstack([self.X0.G, self.W.G, -L @ self.V.G])
        self._r0 = self.X0.G.shape[1]
        self._cD = self.W.c - L @ self.V.c  # centre of M^k D
        self._c_wv = np.zeros(self.A.shape[0])  # S_wv: centre and radius of the summed boxes
        self._r_wv = np.zeros(self.A.shape[0])
        self._y_prev: np.ndarray | None = None
        self._pending: Interval | None = None  # last bound (cora-lagged returns it one step late)

    def _bound(self) -> Interval:
        return Interval(*interval_bound(self._x, self._G[:, : self._r0], self._c_wv,
                                        self._r_wv))

    def _advance(self, u: np.ndarray) -> None:
        """From step k-1 to k (Alg. 1, lines 6-9)."""
        self._x = luenberger_step(self._x, self.A, self.B, self.C, self.L, u, self._y_prev)
        self._c_wv = self._c_wv + self._cD
        self._r_wv = self._r_wv + box_radius(self._G[:, self._r0 :])
        self._cD = self._M @ self._cD
        self._G = self._M @ self._G

    def step(self, u_prev, y):
        y = self._measurement(y)
        if self._y_prev is None:  # step 0: X0 itself (as CORA)
            out = self.X0
            if self.lagged:
                self._pending = self._bound()
        else:
            self._advance(self._input(u_prev))
            bound = self._bound()
            if self.lagged:
                out, self._pending = self._pending, bound
            else:
                out = bound
        self._y_prev = y
        self.k += 1
        return out
